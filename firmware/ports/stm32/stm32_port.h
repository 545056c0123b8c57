/* What the files of the STM32F4 port share: the board instance, the set-up of each peripheral,
 * and the unit conversions of the PWM and the current sense (plain integer C: the emulator
 * harness, harness/stm32, mirrors them for its native reference run). The HAL itself is
 * firmware/hal/. */
#ifndef ASSERV_STM32_PORT_H
#define ASSERV_STM32_PORT_H

#include <stdint.h>

#include "board.h"
#include "stm32_clock.h"

/* The one board, shared by the control tick (SysTick) and the I2C interrupts (its proto). The
 * emulator harness finds it by this symbol name. */
extern struct board asserv_board;

/* Sizes and offsets the emulator harness checks against the host build's before it compares
 * the board's RAM with the native run byte for byte (main.c). */
struct stm32_layout {
	uint32_t board_size;
	uint32_t config_size;
	uint32_t proto_offset;
};
extern const struct stm32_layout stm32_layout;

/* Set-up, once, interrupts off: the clocks first (clock.c), then the encoders (encoder.c), the
 * motors and their current sense (motor.c), the switches and sensors (sensors.c). Each enables
 * its own peripherals' clocks; hal_i2c_slave_init() (i2c.c) and hal_tick_start() (tick.c) too. */
void stm32_clock_init(void);
void stm32_encoder_init(void);
void stm32_motor_init(void);
void stm32_sensors_init(void);

/* The current-sense conversions of both motors, at the start of each tick (motor.c). */
void stm32_adc_sample(void);

/* The robot this binary drives (robot.c). */
void stm32_robot_config(struct board_config *cfg);

/* One sleep of the main loop (startup.c): wfi, then return once an interrupt has run. */
void stm32_idle(void);

/* The independent watchdog (watchdog.c): LSI / (4 << pr) counts, (rlr + 1) of them, then a
 * reset. STM32_WDG_*: 60 ms, fed after each tick (41..113 ms with the LSI's 17..47 kHz);
 * STM32_WDG_ERASE_*: 5 s (3.4..9.4 s), while a flash erase stalls the ticks, up to 2 s for
 * sector 7's 128 KiB at x32 (STM32F446xC/E data sheet, tERASE128KB; nvm.c). */
#define STM32_WDG_PR 0u
#define STM32_WDG_RLR 479u
#define STM32_WDG_ERASE_PR 5u
#define STM32_WDG_ERASE_RLR 1249u

/* Start the watchdog (or keep it running: the bootloader starts it too) with that window.
 * Thread mode, start-up. */
void stm32_watchdog_start(uint32_t pr, uint32_t rlr);

/* A new window, and a reload. Thread mode only. */
void stm32_watchdog_set(uint32_t pr, uint32_t rlr);

/* The cause of this start (RESET_CAUSE_*) from RCC_CSR's reset flags, which it then clears
 * (reset.c). Called once, first thing in main(). */
uint8_t stm32_reset_cause(void);

/* The longest the board is down at a reset [ms], from the last record the planner kept
 * (keep.h) to the encoders counting again (stm32_encoder_init()): STM32_START_MS for the start-up,
 * the bootloader's checks included (harness/stm32/test_resets.py measures it, and fails when
 * a larger image outgrows it: the bootloader's CRC takes about 1.1 ms a KiB; 192 ms measured
 * once the emulator counted every instruction, where it had counted under 140), and for a
 * watchdog reset the hang before it, STM32_WDG_MAX_MS: the 60 ms window (STM32_WDG_RLR) at
 * the LSI's slowest, 17 kHz: 480 * 4 / 17000 s. */
#define STM32_START_MS 220u
#define STM32_WDG_MAX_MS 113u
uint16_t stm32_down_ms(uint8_t cause);

/* BOOTLOADER accepted: the motors off, then a reset into the bootloader (boot_enter.c,
 * docs/update.md). Does not return. */
void stm32_boot_enter(void);

/* TIM1 compare counts for a duty [2^-15]: |duty| * (ARR + 1) / 32768, rounded; ARR + 1 is full
 * on (PWM mode 1 keeps the output high while CNT < CCR). */
static inline uint32_t stm32_pwm_counts(int16_t duty_q15)
{
	uint32_t a = (uint32_t)(duty_q15 < 0 ? -(int32_t)duty_q15 : duty_q15);

	return (a * STM32_PWM_PERIOD + 16384u) >> 15;
}

/* Motor current [mA] of a 12-bit reading of the sense amplifier (1.65 V at 0 A, 100 mV/A, 3.3 V
 * reference): (code - 2048) * 3300 mV / 4096 / 0.1 V/A, rounded down (arithmetic shift). */
static inline int16_t stm32_current_ma(uint32_t code)
{
	return (int16_t)(((int32_t)code - 2048) * 33000 >> 12);
}

#endif
