/* The independent watchdog (RM0390 19.3: started, then configured, then reloaded; stm32_port.h):
 * fed by the SysTick handler after each tick (main.c), so that if the ticks stop (a fault
 * handler's loop, an interrupt that never ends) it resets the chip within 60 ms, and the reset
 * stops the motors (the PWM pins float: the bridge's enable inputs need pull-downs,
 * docs/stm32.md). 60 ms at the LSI's nominal 32 kHz: (479 + 1) * 4 / 32000; the LSI's spread
 * (17..47 kHz) makes it 41..113 ms. Widened while a flash erase stalls the CPU (nvm.c). */
#include "stm32_port.h"
#include "stm32f4_regs.h"

void stm32_watchdog_start(uint32_t pr, uint32_t rlr)
{
	IWDG_KR = IWDG_KR_START;
	stm32_watchdog_set(pr, rlr);
}

/* RM0390 19.3.2: the access key opens PR and RLR until the next key, so the tick's reload must
 * not come in between (PRIMASK); the new values are taken once SR's PVU and RVU clear (up to 5
 * LSI periods), and the reload that follows loads RLR. */
void stm32_watchdog_set(uint32_t pr, uint32_t rlr)
{
	__asm__ volatile("cpsid i" ::: "memory");
	IWDG_KR = IWDG_KR_ACCESS;
	IWDG_PR = pr;
	IWDG_RLR = rlr;
	__asm__ volatile("cpsie i" ::: "memory");
	while (IWDG_SR != 0)
		;
	IWDG_KR = IWDG_KR_RELOAD;
}
