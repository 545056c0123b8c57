/* Porting contract: non-volatile storage, what the board keeps across a power-off (its odometry
 * calibration: ports/common/calib_store.h). Addressed by byte from 0; a byte never written reads
 * as the port's erased value (0xFF on the AVR's EEPROM). */
#ifndef ASSERV_HAL_NVM_H
#define ASSERV_HAL_NVM_H

#include <stdint.h>

/* Bytes of storage the port offers the board (at least CALIB_STORE_SIZE, 16, for a port that
 * stores the calibration; the ATmega1284P's EEPROM has 4096). May be called from an interrupt:
 * yes. */
uint16_t hal_nvm_size(void);

/* Copy n bytes from offset into buf. Returns 0, or -1 when the range leaves the storage (buf
 * untouched). On the AVR it waits for a write in progress to end (up to 3.4 ms), then takes 4
 * cycles a byte: at start-up, or from the main loop once hal_nvm_busy() is 0 (port_nvm.c reads
 * one byte before each record). May be called from an interrupt: no. */
int hal_nvm_read(uint16_t offset, uint8_t *buf, uint16_t n);

/* 1 while a write started by hal_nvm_write_byte() is still in progress (no write may start),
 * 0 when a write may start. Returns at once. May be called from an interrupt: no. */
uint8_t hal_nvm_busy(void);

/* Start writing one byte and return at once, without waiting for it: the write takes up to
 * 3.4 ms on the AVR (an EEPROM byte, erase and write), during which hal_nvm_busy() is 1; a host
 * port's is done on return. A power-off during a write may leave that byte anything. Returns 0,
 * -1 when offset is outside the storage, or -2 when busy (nothing written). The common port
 * layer (port_nvm.h) calls it from the main loop, never from the control interrupt.
 * May be called from an interrupt: no. */
int hal_nvm_write_byte(uint16_t offset, uint8_t value);

#endif
