/* The clock tree (stm32_clock.h): the ST-LINK's 8 MHz on OSC_IN (HSE bypass) through the PLL to
 * the chip's maximum, in the order RM0390 5.1.4 gives for the over-drive: PLL on, over-drive
 * on and switched, flash wait states and bus prescalers, PLL locked, system clock switched. */
#include "stm32_clock.h"
#include "stm32_port.h"
#include "stm32f4_regs.h"

void stm32_clock_init(void)
{
	RCC_APB1ENR |= RCC_APB1ENR_PWREN;
	PWR_CR |= PWR_CR_VOS_SCALE1; /* RM0390 5.4.1: scale 1 for 168..180 MHz */
	RCC_CR |= RCC_CR_HSEBYP | RCC_CR_HSEON;
	while (!(RCC_CR & RCC_CR_HSERDY))
		;
	RCC_PLLCFGR = STM32_PLLM << RCC_PLLCFGR_PLLM_POS | STM32_PLLN << RCC_PLLCFGR_PLLN_POS |
		      STM32_PLLP_BITS << RCC_PLLCFGR_PLLP_POS | RCC_PLLCFGR_PLLSRC_HSE |
		      STM32_PLLQ << RCC_PLLCFGR_PLLQ_POS | STM32_PLLR << RCC_PLLCFGR_PLLR_POS;
	RCC_CR |= RCC_CR_PLLON;
#if STM32_OVERDRIVE
	PWR_CR |= PWR_CR_ODEN;
	while (!(PWR_CSR & PWR_CSR_ODRDY))
		;
	PWR_CR |= PWR_CR_ODSWEN;
	while (!(PWR_CSR & PWR_CSR_ODSWRDY))
		;
#endif
	/* The wait states before the clock rises (RM0390 3.4.1: "check that the new number of wait
	 * states is taken into account by reading FLASH_ACR"). */
	FLASH_ACR = FLASH_ACR_PRFTEN | FLASH_ACR_ICEN | FLASH_ACR_DCEN | STM32_FLASH_WAIT_STATES;
	while ((FLASH_ACR & FLASH_ACR_LATENCY_MASK) != STM32_FLASH_WAIT_STATES)
		;
	RCC_CFGR = STM32_PPRE1_BITS << RCC_CFGR_PPRE1_POS | STM32_PPRE2_BITS << RCC_CFGR_PPRE2_POS;
	while (!(RCC_CR & RCC_CR_PLLRDY))
		;
	RCC_CFGR |= RCC_CFGR_SW_PLL;
	while (((RCC_CFGR >> RCC_CFGR_SWS_POS) & RCC_CFGR_SW_MASK) != RCC_CFGR_SW_PLL)
		;
}
