/* The storage of hal_nvm.h on the ATmega1284P's EEPROM (4096 bytes, erased to 0xFF): the
 * odometry calibration's record (ports/common/port_nvm.h).
 *
 * A byte write erases and writes the byte in 3.4 ms (the datasheet's tWD_EEPROM, with the
 * EEPROM's own oscillator). It is never waited for: hal_nvm_write_byte() starts one when EEPE is
 * clear and returns; the main loop polls (hal_nvm_busy(), EEPE) and starts the next at its next
 * pass, a slow period (8 ms) later with two rates. Polling rather than the EE_READY interrupt:
 * the main loop passes often enough, and one interrupt source fewer is one load fewer on the
 * control period. The EEMPE-EEPE pair must come within 4 cycles: avr-libc's eeprom_write_byte()
 * keeps interrupts off for those two instructions only (its own wait for EEPE finds it clear,
 * tested just before). Nothing else touches EEARL, EEARH, EEDR or EECR: the encoders' states left
 * them (encoder.c). */
#include <avr/eeprom.h>
#include <avr/io.h>

#include "hal.h"

#define EEPROM_SIZE ((uint16_t)(E2END + 1u))

uint16_t hal_nvm_size(void)
{
	return EEPROM_SIZE;
}

int hal_nvm_read(uint16_t offset, uint8_t *buf, uint16_t n)
{
	if ((uint32_t)offset + n > EEPROM_SIZE)
		return -1;
	eeprom_read_block(buf, (const void *)(uintptr_t)offset, n); /* waits for EEPE first */
	return 0;
}

uint8_t hal_nvm_busy(void)
{
	return (EECR & _BV(EEPE)) != 0;
}

int hal_nvm_write_byte(uint16_t offset, uint8_t value)
{
	if (offset >= EEPROM_SIZE)
		return -1;
	if (EECR & _BV(EEPE))
		return -2;
	eeprom_write_byte((uint8_t *)(uintptr_t)offset, value);
	return 0;
}
