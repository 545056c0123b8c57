/* The odometry calibration kept across a power-off, as every port with byte storage (hal_nvm.h)
 * does it: load the newest valid record at start and install it (board_set_calibration()), then
 * write a record each time the board installs a new calibration (SET_ODOMETRIE accepted).
 *
 * Two slots of calib_store.h's record, at PORT_NVM_CALIB_OFFSET and 16 bytes after it: each new
 * record goes into the slot that does not hold the newest valid one, with the next generation,
 * so that a power-off at any moment of a write leaves that newest one untouched. A record is
 * written bytes 1 to 15 first, then byte 0 (the magic's 'a'), with byte 0 spoilt before them
 * when it reads 'a' (an older record whole in that slot): until that last byte is written whole,
 * the slot cannot decode; once it is, the slot holds the new record whole. So a cut leaves the
 * last good calibration or the new one, never a mix (a mix of two records could otherwise pass
 * the CRC-16, once in 65536), even when the cut leaves the byte it writes anything (hal_nvm.h).
 *
 * Writes go from the main loop, never from the control interrupt, and never wait: each call of
 * port_nvm_poll() starts as many byte writes as the storage accepts without waiting (on the AVR
 * one, which the EEPROM then writes for 3.4 ms while the loop goes on; on the host all 16 or 17). A
 * port without storage simply does not link this file. */
#ifndef ASSERV_PORT_NVM_H
#define ASSERV_PORT_NVM_H

#include <stdint.h>

#include "board.h"
#include "calib_log.h"
#include "calib_store.h"

#define PORT_NVM_CALIB_OFFSET 0u
#define PORT_NVM_SLOTS 2u
#define PORT_NVM_STEPS (CALIB_STORE_SIZE + 1u) /* byte writes per record, byte 0 spoilt too */

struct port_nvm {
	struct board_calibration stored; /* what the storage holds, or will once written */
	uint8_t have;                    /* stored is valid */
	uint8_t rec[CALIB_STORE_SIZE];   /* the record being written */
	uint8_t pos;                     /* its next write step; PORT_NVM_STEPS: all written */
	uint8_t slot;                    /* the slot of stored's record (0, 1) */
	uint8_t gen;                     /* its generation */
	int8_t loaded;                   /* port_nvm_load()'s result */
};

/* At start, after board_init() and before the first tick: read both slots, and install the
 * calibration of the newest valid record (calib_log.h: the newer generation). Returns 0
 * (installed), a CALIB_STORE_* refusal (none valid: slot 0's, blank, corrupt, out of range: the
 * board stays uncalibrated), CALIB_LOG_UNREADABLE (storage too small or unreadable), or
 * board_set_calibration()'s error. Never fails the start: an uncalibrated board runs.
 * Interrupt-safe: no (start-up only). */
int port_nvm_load(struct port_nvm *s, struct board *b);

/* From the main loop, in the slow steps' context (after port_slow()), never from the control
 * interrupt: if the board's calibration is not the stored one, start writing its record; then
 * start the byte writes the storage takes without waiting. Returns at once. */
void port_nvm_poll(struct port_nvm *s, const struct board *b);

/* 1 while a record is not yet completely written (a power-off then leaves its slot unable to
 * decode: the next start installs the other slot's record, the previous calibration). */
uint8_t port_nvm_pending(const struct port_nvm *s);

#endif
