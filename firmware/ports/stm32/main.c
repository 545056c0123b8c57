/* The asserv board on an STM32F4 Nucleo-64: start-up, then the control in interrupts. SysTick runs
 * the whole control tick at 1 kHz (one rate: the slow steps in it: tick.c) and feeds the watchdog
 * (set up by watchdog.c); the I2C interrupts preempt it. The main loop, woken by each interrupt,
 * writes the calibration to flash (hal_nvm.h, the flash log of stm32_nvm.h) and sleeps. Pin map:
 * pinmap.h; clocks: stm32_clock.h; build and flashing: docs/stm32.md. */
#include <stddef.h>

#include "hal.h"
#include "port.h"
#include "stm32_nvm.h"
#include "stm32_port.h"

/* Not cleared by the start-up (stm32f446re.ld): what a reset keeps (keep.h) is in it. */
struct board asserv_board __attribute__((section(".noinit")));
/* The calibration's log in flash (hal_nvm.h): loaded at start, written by the main loop (thread
 * mode). */
static struct hal_nvm stm32_nvm;

const struct stm32_layout stm32_layout = {
	.board_size = sizeof(struct board),
	.config_size = sizeof(struct board_config),
	.proto_offset = offsetof(struct board, proto),
};

int main(void)
{
	struct board_config cfg;
	struct board_inputs in;
	uint8_t cause = stm32_reset_cause();

	stm32_clock_init();
	stm32_encoder_init();
	stm32_motor_init();
	stm32_sensors_init();
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
	hal_nvm_load(&stm32_nvm, &asserv_board);
	hal_i2c_slave_init(PROTO_ADDRESS);
	stm32_watchdog_set(STM32_WDG_PR, STM32_WDG_RLR);
	hal_tick_start(cfg.tick_hz);
	for (;;) {
		hal_nvm_poll(&stm32_nvm, &asserv_board); /* one flash operation at most */
		stm32_idle();
	}
}
