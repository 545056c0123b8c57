/* Template port: the non-volatile storage, where the board keeps its odometry calibration across
 * a power-off (hal_nvm.h: load at start, poll from the main loop, pending). A port meets
 * hal_nvm.h in one of two ways:
 *
 * - Storage written a byte at a time, in place (an EEPROM, or an EEPROM emulated by the
 *   vendor's library): link ports/common/nvm_bytes.c, which implements hal_nvm_load(),
 *   hal_nvm_poll() and hal_nvm_pending() (two 16-byte records at offsets 0 and 16, written in
 *   turn so that a power cut never loses the calibration), and fill in the four byte functions
 *   below, its lower layer. This template does so; ports/avr/nvm.c is the finished example.
 * - Flash erased by sectors: rewriting a record in place would cost an erase per calibration,
 *   during which the CPU stalls. Write hal_nvm_load(), hal_nvm_poll() and hal_nvm_pending()
 *   and struct hal_nvm yourself, and leave nvm_bytes.c and this file out of the build:
 *   ports/stm32/nvm.c (two logs of records, calib_log.h's rule to find the newest) is the
 *   example.
 *
 * This template has no storage: nvm_bytes_dev_size() is 0, hal_nvm_load() then refuses
 * (CALIB_LOG_UNREADABLE), and the board starts uncalibrated each time, which it runs with. A
 * port that stores nothing may keep it so. */
#include "nvm_bytes.h"
#include "template_port.h"

/* dev is the handle main.c gave nvm_bytes_init(): NULL for a port with one storage chip, as
 * here; the host passes each simulated board's own RAM. */

/* The storage's size [bytes], at least 32 (two records of CALIB_STORE_SIZE) to hold the
 * calibration; 0 for none. Not from an interrupt. */
uint16_t nvm_bytes_dev_size(struct nvm_bytes_dev *dev)
{
	(void)dev;
	return 0;
}

/* Copy n bytes at offset into buf: 0, or -1 with buf untouched when [offset, offset + n) is not
 * within the storage. Bytes never written read as the storage's erased value (0xFF for an
 * EEPROM). Called at start-up (hal_nvm_load(), before the ticks), where it may wait for a write
 * in progress to end, and from the main loop once nvm_bytes_dev_busy() is 0 (one byte before
 * each record). Not from an interrupt. */
int nvm_bytes_dev_read(struct nvm_bytes_dev *dev, uint16_t offset, uint8_t *buf, uint16_t n)
{
	(void)dev;
	(void)offset;
	(void)buf;
	(void)n;
	return -1;
}

/* 1 while a byte write started by nvm_bytes_dev_write() is still going on, 0 when another may
 * start. Returns at once. Called from the main loop (hal_nvm_poll()). Not from an interrupt. */
uint8_t nvm_bytes_dev_busy(struct nvm_bytes_dev *dev)
{
	(void)dev;
	return 0;
}

/* Start writing one byte and return without waiting: 0, -1 when offset is outside the storage,
 * -2 while busy (nothing written). The write may take milliseconds (an EEPROM byte: 3.4 ms on
 * the AVR), during which nvm_bytes_dev_busy() is 1; hal_nvm_poll() calls it from the main loop,
 * never from the control interrupt, which a wait here would delay. A power-off during the write
 * may leave that byte anything: nvm_bytes.c's order of writes and the record's CRC make sure
 * the next start installs the previous calibration or the new one, never a mix. Not from an
 * interrupt. */
int nvm_bytes_dev_write(struct nvm_bytes_dev *dev, uint16_t offset, uint8_t value)
{
	(void)dev;
	(void)offset;
	(void)value;
	return -1;
}
