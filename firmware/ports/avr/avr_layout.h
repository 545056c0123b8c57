/* Where the fields a test or a debugger reads sit inside struct board, as avr-gcc laid it out:
 * the port stores one struct avr_layout in flash under the symbol avr_layout, so that the simavr
 * harness (harness/avr) reads the board's estimate and protocol state from the running binary's
 * RAM without assuming the AVR's struct layout. Every member is a uint16_t, so the host reads the
 * record with the same declaration (little-endian on both). Costs 76 bytes of flash. */
#ifndef ASSERV_AVR_LAYOUT_H
#define ASSERV_AVR_LAYOUT_H

#include <stdint.h>

#define AVR_LAYOUT_MAGIC 0xA5E7u

/* The encoder counters are not in struct board: they are the uint16_t arrays avr_free_count[2]
 * and avr_motor_count[2] (left, right; symbols of the binary), each holding its count ^
 * AVR_COUNT_BIAS (encoder.c says why). */
#define AVR_COUNT_BIAS 0x80u

struct avr_layout {
	uint16_t magic; /* AVR_LAYOUT_MAGIC */
	uint16_t size;  /* sizeof(struct avr_layout) */
	uint16_t board_size;
	/* Offsets from the start of struct board [bytes]. */
	uint16_t tick_hz;    /* uint16, cfg.tick_hz */
	uint16_t slow_shift; /* uint8, cfg.slow_shift */
	uint16_t tick;
	uint16_t slow_due;        /* uint8: the slow steps have a snapshot to work on */
	uint16_t slow_overruns;   /* uint16 */
	uint16_t since_snapshot;  /* uint8: ticks since the last snapshot */
	uint16_t planner_ticks;   /* uint8, cfg.planner_ticks: the hand-over's tick after it */
	uint16_t odo_x_um;        /* uint32, whole um of the estimate */
	uint16_t odo_y_um;        /* uint32 */
	uint16_t odo_x_frac;      /* uint16, [2^-16 um] */
	uint16_t odo_y_frac;      /* uint16 */
	uint16_t odo_heading;     /* uint32, heading_turn32 */
	uint16_t odo_left_count;  /* uint16, the counts of the last update */
	uint16_t odo_right_count; /* uint16 */
	uint16_t duty;            /* int16[2], last_out.duty_q15: the tick's outputs */
	uint16_t proto_selected;  /* uint8 */
	uint16_t proto_head;      /* uint8 */
	uint16_t proto_tail;      /* uint8 */
	uint16_t proto_queue;     /* struct proto_msg[PROTO_QUEUE_DEPTH] */
	uint16_t proto_snap;      /* struct proto_snapshot[2] */
	uint16_t proto_snap_index;
	/* Inside struct proto_msg. */
	uint16_t msg_size;
	uint16_t msg_designation;
	uint16_t msg_n_args;
	uint16_t msg_arg; /* int32[] */
	/* Inside struct proto_snapshot. */
	uint16_t snap_size;
	uint16_t snap_x_mm; /* int16 */
	uint16_t snap_y_mm; /* int16 */
	uint16_t snap_angle_2deg;
	uint16_t snap_radius_mm;
	uint16_t snap_status;
	uint16_t snap_sensors;
	/* The odometry's configuration and the calibration installed (hal_nvm.h). */
	uint16_t odo_left_factor;  /* uint32, odometry.cfg.left_um_per_count_q16 */
	uint16_t odo_right_factor; /* uint32, odometry.cfg.right_um_per_count_q16 */
	uint16_t odo_track;        /* uint32, odometry.cfg.track_um */
	uint16_t calibrated;       /* uint8 */
	uint16_t calibration;      /* struct board_calibration: int32 ratio, int32 scale, uint16 */
};

#endif
