/* The odometry calibration kept across a power-off, as every port with storage (hal_nvm.h) does
 * it: load the record at start and install it (board_set_calibration()), then write the record
 * again each time the board installs a new calibration (SET_ODOMETRIE accepted). The record is
 * calib_store.h's, at offset PORT_NVM_CALIB_OFFSET of the storage.
 *
 * Writes go from the main loop, never from the control interrupt, and never wait: each call of
 * port_nvm_poll() starts as many byte writes as the storage accepts without waiting (on the AVR
 * one, which the EEPROM then writes for 3.4 ms while the loop goes on; on the host all 16). A
 * port without storage simply does not link this file. */
#ifndef ASSERV_PORT_NVM_H
#define ASSERV_PORT_NVM_H

#include <stdint.h>

#include "board.h"
#include "calib_store.h"

#define PORT_NVM_CALIB_OFFSET 0u

struct port_nvm {
	struct board_calibration stored; /* what the storage holds, or will once written */
	uint8_t have;                    /* stored is valid */
	uint8_t rec[CALIB_STORE_SIZE];   /* the record being written */
	uint8_t pos;                     /* its next byte to write; CALIB_STORE_SIZE: all written */
	int8_t loaded;                   /* port_nvm_load()'s result */
};

/* At start, after board_init() and before the first tick: read the record, and install its
 * calibration if it is valid. Returns 0 (installed), a CALIB_STORE_* refusal (blank, corrupt, out
 * of range: the board stays uncalibrated), -1 (storage too small or unreadable), or
 * board_set_calibration()'s error. Never fails the start: an uncalibrated board runs.
 * Interrupt-safe: no (start-up only). */
int port_nvm_load(struct port_nvm *s, struct board *b);

/* From the main loop, in the slow steps' context (after port_slow()), never from the control
 * interrupt: if the board's calibration is not the stored one, start writing its record; then
 * start the byte writes the storage takes without waiting. Returns at once. */
void port_nvm_poll(struct port_nvm *s, const struct board *b);

/* 1 while a record is not yet completely written (a power-off then leaves it torn: the next
 * start finds it corrupt and runs uncalibrated). */
uint8_t port_nvm_pending(const struct port_nvm *s);

#endif
