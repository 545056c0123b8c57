/* The update protocol the bootloader speaks at I2C address 2 (docs/update.md, "The protocol"):
 * designations, lengths, states and results, and what boot.c and boot_i2c.c share. Every write
 * ends with its SMBus PEC (CRC-8 of every byte since the START, the address included: the
 * application's rule, docs/protocol.md section 8), which is mandatory here; every read returns
 * the selected reply, then its PEC, then 0xFF. Numbers are big-endian on the bus. */
#ifndef ASSERV_BOOT_PROTO_H
#define ASSERV_BOOT_PROTO_H

#include <stdint.h>

/* 3: two slots, each run in place (A/B): the download goes into the slot that does not run, which
 * INFO names, and START copies nothing. 2: DATA is taken while the download slot erases (held
 * in RAM, programmed after), and START copied the download into the run slot (slot A). 1
 * refused DATA (BUSY) until the erase was over, and was busy (PROGRAMMING) while a chunk
 * programmed. */
#define BOOT_PROTO_VERSION 3u

/* Writes: designation, parameters, PEC. */
#define BOOT_CMD_INFO 0xB0u   /* select the INFO reply; no parameter */
#define BOOT_CMD_BEGIN 0xB1u  /* length u32, crc32 u32, version u32, board id u16 */
#define BOOT_CMD_DATA 0xB2u   /* offset u32, 4..64 bytes (a multiple of 4) */
#define BOOT_CMD_END 0xB3u    /* no parameter: read back, check, header written last */
#define BOOT_CMD_START 0xB4u  /* no parameter: reset, which starts the newest valid slot */
#define BOOT_CMD_STATUS 0xB5u /* select the STATUS reply (the default); no parameter */
#define BOOT_LEN_BEGIN 15u    /* designation and parameters, PEC excluded */
#define BOOT_CHUNK_MAX 64u
#define BOOT_FRAME_MAX (1u + 4u + BOOT_CHUNK_MAX + 1u)
/* [bytes] of the download held in RAM, received but not yet programmed: what the master can send
 * while the download slot erases (a multiple of 4: a word never wraps). */
#define BOOT_BUFFER_SIZE 0x6000u
/* Replies, PEC excluded. STATUS: state, result, next offset u32 (bytes of the download received,
 * from its start: held in RAM or programmed). INFO: 'B' 'L', protocol version, board id u16, a
 * valid slot runs, its version u32, length u32, crc32 u32, the largest image u32, state, then
 * (protocol 3) the download's slot: 0 A, 1 B, whose link the image must have. */
#define BOOT_STATUS_LEN 6u
#define BOOT_INFO_LEN 24u

enum boot_s {
	BOOT_S_IDLE,           /* no download begun (or the last one failed: begin again) */
	BOOT_S_ERASING,        /* busy: the download slot is being erased (BEGIN); DATA taken */
	BOOT_S_RECEIVING,      /* DATA and END accepted; what RAM holds is programmed meanwhile */
	BOOT_S_PROGRAMMING,    /* busy: a chunk being programmed (protocol 1 only) */
	BOOT_S_CHECKING,       /* busy: the rest programmed, the download read back (END) */
	BOOT_S_WRITING_HEADER, /* busy: its header being programmed */
	BOOT_S_READY,          /* the download is whole, checked and its header written: START */
	BOOT_S_COPYING,        /* busy: the download copied into the run slot (protocol 1, 2) */
	BOOT_S_QUEUED,         /* busy: a write taken, not yet handled (reported, never stored) */
};

static inline int boot_busy(uint8_t s)
{
	return s == BOOT_S_ERASING || s == BOOT_S_PROGRAMMING || s == BOOT_S_CHECKING ||
	       s == BOOT_S_WRITING_HEADER || s == BOOT_S_COPYING || s == BOOT_S_QUEUED;
}

enum boot_r {
	BOOT_R_OK,
	BOOT_R_BAD_PEC,        /* the frame's PEC is wrong or missing: nothing done */
	BOOT_R_BAD_LENGTH,     /* too long, or not the designation's length */
	BOOT_R_UNKNOWN,        /* no such designation */
	BOOT_R_BUSY,           /* not over, or DATA with no room in RAM: poll, send again */
	BOOT_R_WRONG_BOARD,    /* the image is for another board (BEGIN, or its own record) */
	BOOT_R_TOO_LARGE,      /* longer than a slot, empty, or not a multiple of 4 */
	BOOT_R_NOT_BEGUN,      /* DATA or END without a BEGIN */
	BOOT_R_BAD_OFFSET,     /* a chunk past the next offset, misaligned, or past the length */
	BOOT_R_MISMATCH,       /* a chunk sent again differs from what was programmed */
	BOOT_R_INCOMPLETE,     /* END before every byte was received */
	BOOT_R_BAD_CRC,        /* END: the image read back does not have the CRC of BEGIN */
	BOOT_R_BAD_VERSION,    /* END: the image's own version is not BEGIN's */
	BOOT_R_FLASH_ERROR,    /* a word did not program, or an erase failed: begin again */
	BOOT_R_NO_APPLICATION, /* START with no valid application to start */
	BOOT_R_WRONG_SLOT,     /* END: the image is linked for the other slot */
};

/* What the main loop (boot.c) and the I2C interrupt (boot_i2c.c) share. */
struct boot_state {
	volatile uint8_t state;                    /* enum boot_s */
	volatile uint8_t result;                   /* enum boot_r, of the last write */
	volatile uint32_t next;                    /* STATUS's next offset */
	uint8_t run_valid;                         /* a valid slot runs: run_slot */
	uint8_t run_slot, dl_slot;                 /* 0 A, 1 B: the download goes into dl_slot */
	uint32_t run_version, run_length, run_crc; /* the run slot's header, read at start */
	uint32_t run_sequence;
	uint32_t length, crc, version; /* the download (BEGIN) */
	uint8_t frame[BOOT_FRAME_MAX]; /* the frame the main loop handles */
};
extern struct boot_state boot;

/* boot_i2c.c: the slave at BOOT_I2C_ADDRESS. */
#define BOOT_I2C_ADDRESS 2u
void boot_i2c_init(void);
/* The frame the interrupt took (designation and parameters, PEC checked and removed) copied into
 * f, and its length; 0 if none. It stays queued (STATUS says QUEUED, another write is refused
 * with BUSY) until boot_i2c_done(), once it is handled. Main loop only. */
uint8_t boot_i2c_take(uint8_t *f);
void boot_i2c_done(void);
void I2C1_EV_IRQHandler(void);
void I2C1_ER_IRQHandler(void);

#endif
