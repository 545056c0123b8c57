/* Which of a port's kept records is the calibration: the A/B rule both implementations of
 * hal_nvm.h follow (docs/calibration.md, "Never lost"). They keep calib_store.h's records in
 * two areas of slots, byte storage two areas of one slot (nvm_bytes.c), the STM32's flash two
 * logs of 1024 (ports/stm32/nvm.c); the newest valid record is the one of the newer generation
 * (calib_store_newer()), the last valid slot of its area. Pure functions over a reader: no HAL,
 * no state. */
#ifndef ASSERV_CALIB_LOG_H
#define ASSERV_CALIB_LOG_H

#include <stdint.h>

#include "board.h"
#include "calib_store.h"

#define CALIB_LOG_AREAS 2u
#define CALIB_LOG_UNREADABLE (-4) /* the reader failed: the storage is too small, say */

/* What one area holds. */
struct calib_log_area {
	struct board_calibration cal; /* its last valid record's calibration (found) */
	uint16_t next;                /* the slot after the last one not blank, torn ones too */
	uint8_t found;                /* a valid record is there */
	uint8_t gen;                  /* its generation */
	int err;                      /* 0, or when none is valid the last slot's refusal */
};

/* Slot i of area a of the storage ctx (the caller's, passed through), CALIB_STORE_SIZE bytes: a
 * pointer to them (into buf, or to memory that holds them), or NULL when they cannot be read. */
typedef const uint8_t *(*calib_log_read)(void *ctx, uint8_t area, uint16_t i,
					 uint8_t buf[CALIB_STORE_SIZE]);

/* Scan slots 0..slots-1 of an area of the storage ctx. Interrupt-safe: as the reader. */
void calib_log_scan(calib_log_read read, void *ctx, uint8_t area, uint16_t slots,
		    struct calib_log_area *l);

/* The area to go on with: the one whose record is the newer generation, or the only one with a
 * record; with none, the emptier one (the lower next; area 0 on a tie). */
uint8_t calib_log_pick(const struct calib_log_area l[CALIB_LOG_AREAS]);

#endif
