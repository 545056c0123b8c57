/* The clock tree of the board, the one file to change for another STM32F4 (docs/stm32.md).
 * The Nucleo-64's ST-LINK gives an 8 MHz clock on its MCO pin, wired to the target's OSC_IN: the
 * HSE in bypass mode (no crystal) feeds the PLL. */
#ifndef ASSERV_STM32_CLOCK_H
#define ASSERV_STM32_CLOCK_H

#define STM32_HSE_HZ 8000000u

#if !defined(STM32F401) /* the Nucleo-F446RE (default) */
/* 8 MHz / M 4 = 2 MHz at the VCO input (RM0390 6.3.2: 1..2 MHz, 2 for the least jitter);
 * * N 180 = 360 MHz; / P 2 = 180 MHz, the F446's maximum (RM0390 6.2, with the over-drive of
 * 5.1.4). Q 8 = 45 MHz and R 2 feed nothing here. AHB 180 MHz; APB1 / 4 = 45 MHz (its maximum),
 * whose timers run at 90 MHz; APB2 / 2 = 90 MHz, timers at 180 MHz (RM0390 6.2, "timer clock
 * x2 when the APB prescaler is not 1"). Flash: 5 wait states at 150..180 MHz, 2.7..3.6 V
 * (RM0390 3.4.1, Table 5). */
#define STM32_SYSCLK_HZ 180000000u
#define STM32_PLLM 4u
#define STM32_PLLN 180u
#define STM32_PLLP_BITS 0u /* / 2 */
#define STM32_PLLQ 8u
#define STM32_PLLR 2u
#define STM32_OVERDRIVE 1
#define STM32_PPRE1_BITS 5u /* / 4 */
#define STM32_PPRE2_BITS 4u /* / 2 */
#define STM32_APB1_HZ (STM32_SYSCLK_HZ / 4u)
#define STM32_APB2_TIMER_HZ STM32_SYSCLK_HZ
#define STM32_FLASH_WAIT_STATES 5u
#else /* the Nucleo-F401RE: RM0368 6.3.2, 3.5.1 Table 6 */
#define STM32_SYSCLK_HZ 84000000u
#define STM32_PLLM 4u
#define STM32_PLLN 168u
#define STM32_PLLP_BITS 1u /* / 4: 336 / 4 = 84 MHz */
#define STM32_PLLQ 7u
#define STM32_PLLR 0u /* no R divider */
#define STM32_OVERDRIVE 0
#define STM32_PPRE1_BITS 4u /* / 2: 42 MHz */
#define STM32_PPRE2_BITS 0u /* / 1: 84 MHz */
#define STM32_APB1_HZ (STM32_SYSCLK_HZ / 2u)
#define STM32_APB2_TIMER_HZ STM32_SYSCLK_HZ
#define STM32_FLASH_WAIT_STATES 2u
#endif

/* Motor PWM: 20 kHz (inaudible), edge-aligned on TIM1 from its kernel clock. */
#define STM32_PWM_HZ 20000u
#define STM32_PWM_PERIOD (STM32_APB2_TIMER_HZ / STM32_PWM_HZ) /* ARR + 1 */

#endif
