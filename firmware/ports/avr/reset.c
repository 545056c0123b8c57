/* Why the chip started (the ATmega1284P's MCUSR, datasheet 10.2: PORF, EXTRF, BORF, WDRF,
 * JTRF), for board_restart() (board.h, keep.h). main.c's .init3 code reads MCUSR before the
 * start-up clears anything and before it turns the watchdog off. */
#include <avr/io.h>

#include "avr_port.h"
#include "protocol_defs.h"

uint8_t avr_reset_cause(uint8_t mcusr)
{
	/* A power-on may set BORF too (the supply rising through the brown-out level): the most
	 * telling flag first. */
	if (mcusr & _BV(PORF))
		return RESET_CAUSE_POWER_ON;
	if (mcusr & _BV(BORF))
		return RESET_CAUSE_BROWN_OUT;
	if (mcusr & _BV(WDRF))
		return RESET_CAUSE_WATCHDOG;
	if (mcusr & (_BV(EXTRF) | _BV(JTRF)))
		return RESET_CAUSE_PIN; /* the reset pin, or a JTAG programmer's reset */
	/* No flag: a jump to address 0 without a reset, as avr-libc's __bad_interrupt does for
	 * an interrupt without a handler. */
	return RESET_CAUSE_SOFTWARE;
}
