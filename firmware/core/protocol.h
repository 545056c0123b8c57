/* The board's side of the I2C protocol: byte events from the I2C slave in, validated messages
 * out to the control core, replies from a snapshot the core publishes once per tick.
 *
 * Two contexts share a struct proto:
 *   - the I2C interrupt calls proto_on_*() and proto_read_byte(): no heap, no floating point,
 *     bounded time per byte;
 *   - the control core calls proto_poll() and proto_publish() (or proto_draft() and
 *     proto_flip(), from two contexts of its own: board.h).
 * They communicate only through a single-producer single-consumer queue of messages and a
 * double-buffered snapshot whose index is one byte, so neither needs to mask the other.
 * docs/protocol.md is the master-side description of the same behaviour.
 */
#ifndef ASSERV_PROTOCOL_H
#define ASSERV_PROTOCOL_H

#include <stdint.h>

#include "protocol_defs.h"

/* A validated write, as the core receives it. */
struct proto_msg {
	uint8_t designation; /* canonical designation (aliases resolved) */
	uint8_t n_args;      /* params present: the short form of SET_VITESSE_* has fewer */
	int32_t arg[PROTO_MAX_PARAMS]; /* in table order, index with ARG_<MESSAGE>_<PARAM> */
};

/* What DEBUG reads (protocol/messages.toml gives units). */
struct proto_debug {
	uint16_t tick;
	int16_t heading_cdeg;
	int16_t speed_mm_s;
	int16_t turn_rate_cdeg_s;
	int16_t dist_err_um;
	int16_t angle_err_um;
	int16_t duty_left_q15;
	int16_t duty_right_q15;
	int16_t current_left_ma;
	int16_t current_right_ma;
	uint8_t order_state;
	uint8_t end_reason;
};

/* The extensions of issue 31 a build carries (docs/protocol.md, "Match play"): 1, or 0 to leave
 * one out (the AVR's budget); its capability bit is then clear in VERSION and its messages are
 * rejected UNSUPPORTED. */
#ifndef CONFIG_MOTION_PAUSE
#define CONFIG_MOTION_PAUSE 1 /* PAUSE, RESUME, MOTION */
#endif
#ifndef CONFIG_MOTION_SPEED_SCALE
#define CONFIG_MOTION_SPEED_SCALE 1 /* SET_SPEED_SCALE */
#endif
#ifndef CONFIG_MOTION_QUEUE
#define CONFIG_MOTION_QUEUE 1 /* APPEND */
#endif
#ifndef CONFIG_MOTION_CORNERS
#define CONFIG_MOTION_CORNERS 1 /* PASS_THROUGH, SET_CORNER */
#endif
#define PROTO_CAPS                                                                                 \
	(CAP_ALL &                                                                                 \
	 ~((CONFIG_MOTION_PAUSE ? 0u : CAP_PAUSE) |                                                \
	   (CONFIG_MOTION_SPEED_SCALE ? 0u : CAP_SPEED_SCALE) |                                    \
	   (CONFIG_MOTION_QUEUE ? 0u : CAP_QUEUE) | (CONFIG_MOTION_CORNERS ? 0u : CAP_CORNERS)))

/* The options of the motion orders (GOTO's bits 2 and 3; GOTO_REVERSE's and GOTO_PANIER's
 * bit 2). */
#define PROTO_OPT_APPEND 0x04u
#define PROTO_OPT_PASS_THROUGH 0x08u
#define PROTO_OPT_RECAL 0x03u /* GOTO's recalibrations: never with PASS_THROUGH */

/* What MOTION reads (protocol/messages.toml gives units), and what the interrupt needs of the
 * motion queue to refuse an APPEND that would not fit. */
struct proto_motion {
	uint8_t running_seq;
	uint8_t pending;
	uint8_t flags; /* PROTO_MOTION_* */
	uint8_t last_seq;
	uint8_t last_end;
	uint16_t braking_mm;
	uint16_t braking_ms;
	uint8_t scale_percent;
	uint8_t appends_done; /* APPEND orders that left the queue (started or dropped), wrapping */
};

#define PROTO_MOTION_QUEUE_DEPTH 8 /* orders that can wait behind the running one */
#define PROTO_MOTION_PAUSED 0x01u
#define PROTO_MOTION_RUNNING 0x02u

/* Everything a reply can carry, all of one control tick. */
struct proto_snapshot {
	int16_t x_mm;
	int16_t y_mm;
	int8_t angle_2deg; /* [2 degrees] -90..90 */
	uint8_t radius_mm; /* error radius, saturated at 255 */
	uint8_t status;    /* STATUS_* bits owned by the core (not COMMANDE_REJETEE) */
	uint8_t sensors;   /* shock sensor bits */
	/* An odometry calibration is installed: VERSION's CAP_CALIBRATED. */
	uint8_t calibrated;
	struct proto_debug debug;
	struct proto_motion motion;
};

struct proto {
	/* Interrupt side: the transaction in progress. */
	uint8_t rx[PROTO_MAX_WRITE];
	uint8_t rx_len;
	uint8_t rx_overflow;
	uint8_t in_write;
	uint8_t in_read;
	uint8_t tx[PROTO_MAX_REPLY + 1]; /* reply + PEC */
	uint8_t tx_len;                  /* reply + PEC */
	uint8_t tx_pos;
	uint8_t selected;    /* designation whose reply is ready in tx[], or PROTO_NONE */
	uint8_t write_crc;   /* CRC-8 of address + every byte of the last write */
	uint8_t restart_crc; /* 1 when the read continues that write (repeated start) */
	uint8_t read_crc;    /* the read's PEC so far: that write if so, address, bytes sent */

	/* Interrupt side: transactions addressed to the board, wrapping (a write at its start, a
	 * read at its end): the tick sees the master alive when it changes (SET_TIMEOUT). */
	volatile uint8_t transactions;

	/* Interrupt side: rejections. */
	uint8_t rejected; /* COMMANDE_REJETEE */
	uint8_t last_reject;
	uint8_t last_reject_designation;
	uint8_t reject_count;

	/* Orders accepted by the interrupt vs orders the core has taken and published, so that a
	 * status read between the two shows the order as running. */
	uint8_t orders_in;
	uint8_t orders_taken;              /* core side */
	volatile uint8_t orders_published; /* core side, read by the interrupt */
	uint8_t pending_status;            /* busy bits of the last accepted order */
	/* APPEND orders accepted, wrapping: with the snapshot's motion.appends_done, how full the
	 * motion queue may be (an upper bound: the core may have started or dropped more). */
	uint8_t appends_in;

	/* Queue: the interrupt advances head, the core advances tail (free-running counters). */
	struct proto_msg queue[PROTO_QUEUE_DEPTH];
	volatile uint8_t head;
	volatile uint8_t tail;

	/* Snapshot: the core writes the buffer the interrupt does not read, then flips. */
	struct proto_snapshot snap[2];
	volatile uint8_t snap_index;
};

#define PROTO_NONE 0xFFu

/* SMBus CRC-8 (polynomial 0x07, initial value crc) of n bytes. Interrupt-safe: yes. */
uint8_t proto_crc8(uint8_t crc, const uint8_t *data, uint8_t n);

/* Reset to power-on state: no reply selected, nothing queued, an all-zero snapshot. */
void proto_init(struct proto *p);

/* The I2C slave saw its own address with the write bit (after a START or a repeated start).
 * Ends a write or read in progress first. Interrupt-safe: yes. */
void proto_on_write_start(struct proto *p);

/* A data byte was received in a write. The board always acknowledges: a frame is judged as a
 * whole at its end, so that a rejected frame changes nothing. Interrupt-safe: yes. */
void proto_on_byte(struct proto *p, uint8_t byte);

/* A repeated start on the bus, for a port whose I2C slave reports it (optional): a write in
 * progress ends and is judged now, and its reply packed, so that the own address with the
 * read bit that follows only starts sending. Interrupt-safe: yes. */
void proto_on_restart(struct proto *p);

/* The I2C slave saw its own address with the read bit. A write in progress (repeated start)
 * ends first. Interrupt-safe: yes. */
void proto_on_read_start(struct proto *p);

/* The next byte to send to the master; 0xFF past the reply and its PEC. Outside a read it
 * changes nothing the next read returns. Interrupt-safe: yes. */
uint8_t proto_read_byte(struct proto *p);

/* STOP on the bus: a write ends and is judged, a read ends and its selection is used up.
 * Interrupt-safe: yes. */
void proto_on_stop(struct proto *p);

/* A whole transaction of an in-process master (the simulator's bus, the test harnesses), as
 * the bus events above: a write of n bytes, ended by STOP (stop 1) or left for a read by
 * repeated start (stop 0); a read of n bytes, ended by STOP. Interrupt-safe: as proto_on_*(). */
void proto_master_write(struct proto *p, const uint8_t *data, uint8_t n, int stop);
void proto_master_read(struct proto *p, uint8_t *out, uint8_t n);

/* A bus error cut the transaction: a write in progress is rejected (REJECT_ABORTED), never
 * applied. Interrupt-safe: yes. */
void proto_on_abort(struct proto *p);

/* Control tick: take the oldest accepted ORDRE or SET message. Returns 1 and fills *out, or 0
 * when the queue is empty. Interrupt-safe: no (one consumer). */
int proto_poll(struct proto *p, struct proto_msg *out);

/* Control tick: publish the state replies are built from, once per tick after the messages
 * taken by proto_poll() have been applied. Interrupt-safe: no (one producer). */
void proto_publish(struct proto *p, const struct proto_snapshot *s);

/* proto_publish() in two steps: the buffer the interrupt does not read, to fill, then the flip
 * that makes it the published one. Nothing may flip between the two. Interrupt-safe: no. */
struct proto_snapshot *proto_draft(struct proto *p);
void proto_flip(struct proto *p);

/* The status byte a read would return now: the core's bits, COMMANDE_REJETEE, and the busy bits
 * of an order accepted but not yet published. Interrupt-safe: yes. */
uint8_t proto_status(const struct proto *p);

/* Pack one reply (without PEC) from a snapshot into out[], which holds PROTO_MAX_REPLY bytes.
 * Returns its length, 0 for a designation with no reply. Interrupt-safe: yes. */
uint8_t proto_pack_reply(const struct proto *p, uint8_t designation, const struct proto_snapshot *s,
			 uint8_t *out);

#endif
