/* Porting contract: non-volatile storage, where the board keeps its odometry calibration across
 * a power-off (docs/calibration.md, "Never lost"), at the level of the calibration's record
 * (ports/common/calib_store.h). Every port's main loop makes the same three calls: at start
 * hal_nvm_load(), then hal_nvm_poll() at each pass, and hal_nvm_pending() to know whether a
 * record is still on its way. The core never calls them, nor does the control interrupt.
 *
 * Two implementations, picked by the port's build:
 * - ports/common/nvm_bytes.c, for storage written a byte at a time, in place (an EEPROM: the
 *   AVR's; the host's RAM; the template): two slots written in turn. The port provides its
 *   lower layer, four byte functions (nvm_bytes.h), and nothing else.
 * - ports/stm32/nvm.c, for flash erased by sectors: two logs of records (stm32_nvm.h).
 * Either keeps the newest valid record whole, whenever a power cut falls.
 *
 * struct hal_nvm is the implementation's state, one per storage (the host has one per simulated
 * board). Its header, nvm_bytes.h or stm32_nvm.h, defines it; the port's main.c includes that
 * header, allocates the state, and passes it to each call. */
#ifndef ASSERV_HAL_NVM_H
#define ASSERV_HAL_NVM_H

#include <stdint.h>

struct board;
struct hal_nvm;

/* At start, after board_init() (or board_restart()) and before the first tick: find the newest
 * valid record and install its calibration (board_set_calibration()). Returns 0 (installed), a
 * CALIB_STORE_* refusal (none valid: blank, corrupt, out of range), CALIB_LOG_UNREADABLE (no
 * storage, or too small), or board_set_calibration()'s error; with any of these the board stays
 * uncalibrated and runs all the same, so a port never fails its start on it. It may wait for
 * the storage: up to 3.4 ms on the AVR (an EEPROM write in progress); up to 2 s on the STM32,
 * which may erase a sector here (stm32_nvm.h). May be called from an interrupt: no (start-up
 * only). */
int hal_nvm_load(struct hal_nvm *nvm, struct board *b);

/* From the main loop, never from the control interrupt, and never waiting: when the board's
 * calibration (b->planner.calibration, once calibrated) is not the one stored, start writing
 * its record; then start what the storage takes without waiting, and return. The AVR starts one
 * EEPROM byte (3.4 ms, which the EEPROM then writes alone), the STM32 one flash word (16 us) or,
 * with its log full and no order running, one sector erase; the host writes the whole record.
 * A calibration that changes again while its record is being written restarts the write with
 * the new one. An unchanged calibration is never written again. May be called from an
 * interrupt: no. */
void hal_nvm_poll(struct hal_nvm *nvm, const struct board *b);

/* 1 while a record is not yet completely written (a power-off now leaves the previous
 * calibration the one the next start installs), 0 when the storage holds the board's
 * calibration or nothing is to be written. Returns at once. May be called from an interrupt:
 * no. */
uint8_t hal_nvm_pending(const struct hal_nvm *nvm);

#endif
