/* The robot this binary drives: the reference robot of board_default_config() with the motor
 * encoders an interrupt-decoding 8-bit board can follow, at the control rate CONFIG_AVR_TICK_HZ
 * with the slow steps every 2^CONFIG_AVR_SLOW_SHIFT ticks (build options, docs/avr.md). A team
 * edits this file for its robot. Plain C (no register access): the simavr harness compiles it
 * too, so that its native reference run has the very same configuration. */
#include "robot.h"

#if CONFIG_AVR_SLOW_SHIFT < 0 || CONFIG_AVR_SLOW_SHIFT > 3 ||                                      \
	(CONFIG_AVR_TICK_HZ >> CONFIG_AVR_SLOW_SHIFT) < 100
#error "CONFIG_AVR_SLOW_SHIFT: 0..3, and the slow steps at 100 Hz at least (board.h)"
#endif

void avr_robot_config(struct board_config *cfg)
{
	board_default_config(cfg);
	/* Magnetic encoders on the motor shafts, 12 lines (48 counts per motor turn after x4):
	 * 4760 edges/s per motor at 1 m/s through the 20.25:1 gearbox, which the pin-change
	 * interrupts follow. A 2048-count encoder would need 200 000 edges/s: a hardware decoder.
	 * 2 pi 32.5 mm / (48 * 20.25) = 210.08 um per count, * 2^16. */
	cfg->faults.motor_um_per_count_q16 = 13768191;

	/* The control rate (the durations are in ms: board_init() counts them at its rates). */
	cfg->tick_hz = CONFIG_AVR_TICK_HZ;
	/* The slow steps every 2^n ticks: the port's execution model follows it (tick.c), so keep
	 * the build option. */
	cfg->slow_shift = CONFIG_AVR_SLOW_SHIFT;
	cfg->control.tick_hz = CONFIG_AVR_TICK_HZ;
	cfg->orders.tick_hz = CONFIG_AVR_TICK_HZ;
}
