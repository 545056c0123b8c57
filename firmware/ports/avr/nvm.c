/* The ATmega1284P's EEPROM (4096 bytes, erased to 0xFF) as the byte storage under hal_nvm.h:
 * the lower layer of ports/common/nvm_bytes.h, which keeps the odometry calibration's record in
 * it. One EEPROM: no handle, dev is NULL.
 *
 * A byte write erases and writes the byte in 3.4 ms (the datasheet's tWD_EEPROM, with the
 * EEPROM's own oscillator). It is never waited for: nvm_bytes_dev_write() starts one when EEPE is
 * clear and returns; the main loop polls (nvm_bytes_dev_busy(), EEPE) and starts the next at its
 * next pass, a slow period (8 ms) later with two rates. Polling rather than the EE_READY interrupt:
 * the main loop passes often enough, and one interrupt source fewer is one load fewer on the
 * control period. The EEMPE-EEPE pair must come within 4 cycles: avr-libc's eeprom_write_byte()
 * keeps interrupts off for those two instructions only (its own wait for EEPE finds it clear,
 * tested just before). Nothing else touches EEARL, EEARH, EEDR or EECR: the encoders' states left
 * them (encoder.c). */
#include <avr/eeprom.h>
#include <avr/io.h>

#include "nvm_bytes.h"

#define EEPROM_SIZE ((uint16_t)(E2END + 1u))

uint16_t nvm_bytes_dev_size(struct nvm_bytes_dev *dev)
{
	(void)dev;
	return EEPROM_SIZE;
}

int nvm_bytes_dev_read(struct nvm_bytes_dev *dev, uint16_t offset, uint8_t *buf, uint16_t n)
{
	(void)dev;
	if ((uint32_t)offset + n > EEPROM_SIZE)
		return -1;
	eeprom_read_block(buf, (const void *)(uintptr_t)offset, n); /* waits for EEPE first */
	return 0;
}

uint8_t nvm_bytes_dev_busy(struct nvm_bytes_dev *dev)
{
	(void)dev;
	return (EECR & _BV(EEPE)) != 0;
}

int nvm_bytes_dev_write(struct nvm_bytes_dev *dev, uint16_t offset, uint8_t value)
{
	(void)dev;
	if (offset >= EEPROM_SIZE)
		return -1;
	if (EECR & _BV(EEPE))
		return -2;
	eeprom_write_byte((uint8_t *)(uintptr_t)offset, value);
	return 0;
}
