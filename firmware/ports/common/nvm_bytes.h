/* hal_nvm.h on storage written a byte at a time, in place, as an EEPROM: the AVR's EEPROM, the
 * host's RAM, the template's stubs. The port provides the lower layer below (four
 * nvm_bytes_dev_*() functions); this file's nvm_bytes.c provides hal_nvm_load(), hal_nvm_poll()
 * and hal_nvm_pending() on it. A port with flash erased by sectors writes its own hal_nvm
 * instead (ports/stm32/nvm.c).
 *
 * Two slots of calib_store.h's record, at NVM_BYTES_CALIB_OFFSET and 16 bytes after it: each new
 * record goes into the slot that does not hold the newest valid one, with the next generation,
 * so that a power-off at any moment of a write leaves that newest one untouched. A record is
 * written bytes 1 to 15 first, then byte 0 (the magic's 'a'), with byte 0 spoilt before them
 * when it reads 'a' (an older record whole in that slot): until that last byte is written whole,
 * the slot cannot decode; once it is, the slot holds the new record whole. So a cut leaves the
 * last good calibration or the new one, never a mix (a mix of two records could otherwise pass
 * the CRC-16, once in 65536), even when the cut leaves the byte it writes anything.
 *
 * Each hal_nvm_poll() starts as many byte writes as the storage accepts without waiting: on the
 * AVR one, which the EEPROM then writes for 3.4 ms while the loop goes on; on the host all 16
 * or 17. */
#ifndef ASSERV_NVM_BYTES_H
#define ASSERV_NVM_BYTES_H

#include <stdint.h>

#include "board.h"
#include "calib_log.h"
#include "calib_store.h"
#include "hal_nvm.h"

#define NVM_BYTES_CALIB_OFFSET 0u
#define NVM_BYTES_SLOTS 2u
#define NVM_BYTES_STEPS (CALIB_STORE_SIZE + 1u) /* byte writes per record, byte 0 spoilt too */

/* ---- The lower layer: the port's byte storage, which the port provides ----
 *
 * struct nvm_bytes_dev is the port's handle on its storage, passed back to each call: the host
 * defines it (the RAM of one simulated board: host.h); a port with one storage chip may leave it
 * undefined and pass NULL (the AVR, the template). Addressed by byte from 0; a byte never
 * written reads as the storage's erased value (0xFF on an EEPROM). None of these may be called
 * from an interrupt: nvm_bytes.c calls them from hal_nvm_load() and hal_nvm_poll() only. */
struct nvm_bytes_dev;

/* Bytes of storage the port offers (at least NVM_BYTES_SLOTS * CALIB_STORE_SIZE, 32, to keep
 * the calibration; the ATmega1284P's EEPROM has 4096; 0: no storage, the board then starts
 * uncalibrated each time). */
uint16_t nvm_bytes_dev_size(struct nvm_bytes_dev *dev);

/* Copy n bytes from offset into buf. Returns 0, or -1 when the range leaves the storage (buf
 * untouched). May wait for a write in progress to end (up to 3.4 ms on the AVR), then takes 4
 * cycles a byte there: nvm_bytes.c reads at start-up, and from the main loop only once
 * nvm_bytes_dev_busy() is 0 (one byte before each record). */
int nvm_bytes_dev_read(struct nvm_bytes_dev *dev, uint16_t offset, uint8_t *buf, uint16_t n);

/* 1 while a write started by nvm_bytes_dev_write() is still in progress (no write may start), 0
 * when a write may start. Returns at once. */
uint8_t nvm_bytes_dev_busy(struct nvm_bytes_dev *dev);

/* Start writing one byte and return at once, without waiting for it: the write takes up to
 * 3.4 ms on the AVR (an EEPROM byte, erase and write), during which nvm_bytes_dev_busy() is 1;
 * the host's is done on return. A power-off during a write may leave that byte anything.
 * Returns 0, -1 when offset is outside the storage, or -2 when busy (nothing written). */
int nvm_bytes_dev_write(struct nvm_bytes_dev *dev, uint16_t offset, uint8_t value);

/* ---- The implementation's state (hal_nvm.h) ---- */
struct hal_nvm {
	struct nvm_bytes_dev *dev;       /* the storage (nvm_bytes_init()) */
	struct board_calibration stored; /* what the storage holds, or will once written */
	uint8_t have;                    /* stored is valid */
	uint8_t rec[CALIB_STORE_SIZE];   /* the record being written */
	uint8_t pos;                     /* its next write step; NVM_BYTES_STEPS: all written */
	uint8_t slot;                    /* the slot of stored's record (0, 1) */
	uint8_t gen;                     /* its generation */
	int8_t loaded;                   /* hal_nvm_load()'s result */
};

/* Once, before the first hal_nvm_load(): the storage the state keeps its records in (dev, NULL
 * for a port with one storage chip). Nothing is pending until hal_nvm_load(). Interrupt-safe:
 * no. */
void nvm_bytes_init(struct hal_nvm *nvm, struct nvm_bytes_dev *dev);

#endif
