/* Why the chip started (RM0390 6.3.21, RCC_CSR's reset flags), and how long the board may have
 * been down, for board_restart() (board.h, keep.h). The bootloader (firmware/boot/stm32) never
 * writes RCC_CSR: the flags reach the application as the reset left them. */
#include "protocol_defs.h"
#include "stm32_port.h"
#include "stm32f4_regs.h"

uint8_t stm32_reset_cause(void)
{
	uint32_t f = RCC_CSR;

	RCC_CSR = f | RCC_CSR_RMVF; /* the next start sees its own reset only */
	/* A power-on sets BORRSTF and PINRSTF too, and every reset PINRSTF: the most telling
	 * flag first. */
	if (f & RCC_CSR_PORRSTF)
		return RESET_CAUSE_POWER_ON;
	if (f & RCC_CSR_BORRSTF)
		return RESET_CAUSE_BROWN_OUT;
	if (f & (RCC_CSR_IWDGRSTF | RCC_CSR_WWDGRSTF))
		return RESET_CAUSE_WATCHDOG;
	if (f & (RCC_CSR_SFTRSTF | RCC_CSR_LPWRRSTF))
		return RESET_CAUSE_SOFTWARE;
	if (f & RCC_CSR_PINRSTF)
		return RESET_CAUSE_PIN;
	return RESET_CAUSE_SOFTWARE; /* no flag: a jump to the reset handler (a debugger's) */
}

uint16_t stm32_down_ms(uint8_t cause)
{
	/* A watchdog reset ends a hang in which the motors kept their duty: its longest window
	 * (the LSI at its slowest) before the start-up. */
	return (uint16_t)(STM32_START_MS + (cause == RESET_CAUSE_WATCHDOG ? STM32_WDG_MAX_MS : 0u));
}
