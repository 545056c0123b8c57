/* Template port: the non-volatile storage (hal_nvm.h), where the board keeps its odometry
 * calibration across a power-off (ports/common/port_nvm.h writes 16-byte records at offsets 0
 * and 16).
 * This template has no storage: hal_nvm_size() is 0, port_nvm_load() then refuses, and the
 * board starts uncalibrated each time, which it runs with. A port with an EEPROM (the AVR:
 * ports/avr/nvm.c) or a flash page implements the four functions below; one that stores nothing
 * may instead leave ports/common/port_nvm.c out of its build and not call it. */
#include "hal.h"
#include "template_port.h"

/* The storage's size [bytes], at least 16 (CALIB_STORE_SIZE) to hold the calibration. Callable
 * from an interrupt: yes. */
uint16_t hal_nvm_size(void)
{
	return 0;
}

/* Copy n bytes at offset into buf: 0, or -1 with buf untouched when [offset, offset + n) is not
 * within the storage. Bytes never written read as the storage's erased value (0xFF for an
 * EEPROM or a NOR flash). Called at start-up, before the ticks: it may wait for a write in
 * progress to end. Not from an interrupt. */
int hal_nvm_read(uint16_t offset, uint8_t *buf, uint16_t n)
{
	(void)offset;
	(void)buf;
	(void)n;
	return -1;
}

/* 1 while a byte write started by hal_nvm_write_byte() is still going on, 0 when another may
 * start. Returns at once. Called from the main loop. Not from an interrupt. */
uint8_t hal_nvm_busy(void)
{
	return 0;
}

/* Start writing one byte and return without waiting: 0, -1 when offset is outside the storage,
 * -2 while busy (nothing written). The write may take milliseconds (an EEPROM byte: 3.4 ms on
 * the AVR), during which hal_nvm_busy() is 1; the main loop calls it, never the control
 * interrupt, which a wait here would delay. A power-off during the write may leave that byte
 * anything: the record's CRC tells the next start. A flash port erases a page first: it keeps
 * the record in RAM and writes it as the page allows. Not from an interrupt. */
int hal_nvm_write_byte(uint16_t offset, uint8_t value)
{
	(void)offset;
	(void)value;
	return -1;
}
