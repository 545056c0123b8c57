/* Template port: why the chip started, for board_restart() (board.h, keep.h), as
 * ports/avr/reset.c and ports/stm32/reset.c. */
#include "protocol_defs.h"
#include "template_port.h"

/* The cause of the last start, RESET_CAUSE_* (protocol_defs.h), from the chip's reset flags:
 * read before the start-up code clears anything (the AVR saves MCUSR in .init3), cleared once
 * read so that the next start sees its own reset only, and the most telling flag first, since a
 * power-on often sets the brown-out and pin flags too. Anything but RESET_CAUSE_POWER_ON makes
 * board_restart() resume the pose struct board_keep held, when it is valid: the board must then
 * be in RAM the start-up does not clear (main.c). A chip that cannot tell returns
 * RESET_CAUSE_POWER_ON: every start is then board_init()'s. */
uint8_t template_reset_cause(void)
{
	return RESET_CAUSE_POWER_ON;
}

/* The longest the board may have been down at a start of that cause [ms]: from the last record
 * the planner kept (it writes one every period) to the encoders counting again, i.e. the
 * start-up (a bootloader's checks included) and, after a watchdog reset, the hang before it
 * (the watchdog's window at the clock's slowest). board_restart() widens the resumed error
 * radius by what the robot may have travelled in it. Measure it (the STM32's is checked by
 * harness/stm32/test_resets.py); a port that keeps no pose (CONFIG_KEEP_POSE 0) passes 0. */
uint16_t template_down_ms(uint8_t cause)
{
	(void)cause;
	return 0;
}
