/* The control period (hal_tick.h): SysTick runs the whole control tick (one rate: the slow steps
 * in it), then feeds the watchdog (watchdog.c). Its pin PIN_TICK is high while the tick runs
 * (scope it). */
#include "hal.h"
#include "pinmap.h"
#include "port.h"
#include "stm32_gpio.h"
#include "stm32_port.h"
#include "stm32f4_regs.h"

void SysTick_Handler(void);

/* PM0214 4.5: SysTick at the processor clock, reloaded every period; its priority the lowest
 * (0xF0), under the I2C interrupts'. */
void hal_tick_start(uint16_t rate_hz)
{
	RCC_AHB1ENR |= RCC_AHB1ENR_GPIOAEN;
	GPIO_BSRR(PIN_TICK_PORT) = 1u << (PIN_TICK + 16u);
	stm32_gpio_mode(PIN_TICK_PORT, PIN_TICK, GPIO_MODE_OUT);
	SCB_SHPR3 = (SCB_SHPR3 & 0x00FFFFFFu) | 0xF0u << 24;
	SYST_RVR = STM32_SYSCLK_HZ / rate_hz - 1u;
	SYST_CVR = 0;
	SYST_CSR = SYST_CSR_ENABLE | SYST_CSR_TICKINT | SYST_CSR_CLKSOURCE;
}

void SysTick_Handler(void)
{
	GPIO_BSRR(PIN_TICK_PORT) = 1u << PIN_TICK;
	stm32_adc_sample();
	port_control_tick(&asserv_board);
	port_slow(&asserv_board);
	if (asserv_board.planner.boot_request)
		stm32_boot_enter(); /* BOOTLOADER (boot_enter.c): does not return */
	IWDG_KR = IWDG_KR_RELOAD;
	GPIO_BSRR(PIN_TICK_PORT) = 1u << (PIN_TICK + 16u);
}
