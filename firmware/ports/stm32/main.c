/* The asserv board on an STM32F4 Nucleo-64: start-up, then the control in interrupts. SysTick runs
 * the whole control tick at 1 kHz (one rate: the slow steps in it) and feeds the watchdog (set
 * up by watchdog.c); the I2C interrupts preempt it. The main loop, woken by each interrupt,
 * writes the calibration to flash (stm32_nvm.h) and sleeps. Pin map: pinmap.h; clocks:
 * stm32_clock.h; build and flashing: docs/stm32.md. */
#include <stddef.h>

#include "hal.h"
#include "pinmap.h"
#include "port.h"
#include "stm32_nvm.h"
#include "stm32_port.h"
#include "stm32f4_regs.h"

/* Not cleared by the start-up (stm32f446re.ld): what a reset keeps (keep.h) is in it. */
struct board asserv_board __attribute__((section(".noinit")));
/* The calibration's log in flash: loaded at start, written by the main loop (thread mode). */
static struct stm32_nvm stm32_nvm;

const struct stm32_layout stm32_layout = {
	.board_size = sizeof(struct board),
	.config_size = sizeof(struct board_config),
	.proto_offset = offsetof(struct board, proto),
};

void SysTick_Handler(void);

int main(void)
{
	struct board_config cfg;
	struct board_inputs in;
	uint8_t cause = stm32_reset_cause();

	stm32_clock_init();
	stm32_io_init();
	stm32_robot_config(&cfg);
	stm32_adc_sample();
	port_sample(&in);
	port_sample_period(&in);
	/* One rate only (planner_ticks 0): board_tick() runs board_slow() itself, inside
	 * port_control_tick(); the port_slow() after it in SysTick then finds nothing due. */
	if (board_restart(&asserv_board, &cfg, &in, cause, stm32_down_ms(cause)) != 0) {
		/* A configuration the core refuses: motors off, no bus, wait for a new binary. */
		for (;;)
			;
	}
	/* Before the bus and the ticks: a start-up erase stalls nothing that runs. The watchdog
	 * (watchdog.c) is already counting when the bootloader started the application: it is
	 * widened for the erase (up to 2 s), then set to its 60 ms. */
	stm32_watchdog_start(STM32_WDG_ERASE_PR, STM32_WDG_ERASE_RLR);
	stm32_nvm_load(&stm32_nvm, &asserv_board);
	hal_i2c_slave_init(PROTO_ADDRESS);
	stm32_watchdog_set(STM32_WDG_PR, STM32_WDG_RLR);
	hal_tick_start(cfg.tick_hz);
	for (;;) {
		stm32_nvm_poll(&stm32_nvm, &asserv_board); /* one flash operation at most */
		stm32_idle();
	}
}

/* PM0214 4.5: SysTick at the processor clock, reloaded every period; its priority the lowest
 * (0xF0), under the I2C interrupts'. */
void hal_tick_start(uint16_t rate_hz)
{
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
