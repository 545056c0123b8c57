/* The robot this binary drives: robot/avr.toml, the reference robot of board_default_config()
 * with the motor encoders an interrupt-decoding 8-bit board can follow (avr_robot_gen.h,
 * generated from it by robot/gen_robot.py), at the control rate CONFIG_AVR_TICK_HZ with the slow
 * steps every 2^CONFIG_AVR_SLOW_SHIFT ticks (build options, docs/avr.md). A team describes its
 * robot in robot/avr.toml and edits this file for the rest. Plain C (no register access): the
 * simavr harness compiles it too, so that its native reference run has the very same
 * configuration. */
#include "robot.h"

#include "avr_robot_gen.h"

#if CONFIG_AVR_SLOW_SHIFT < 0 || CONFIG_AVR_SLOW_SHIFT > 3 ||                                      \
	(CONFIG_AVR_TICK_HZ >> CONFIG_AVR_SLOW_SHIFT) < 100
#error "CONFIG_AVR_SLOW_SHIFT: 0..3, and the slow steps at 100 Hz at least (board.h)"
#endif

/* A duration given in ticks at 1 kHz, in ticks at the build's rate (at least 1). */
static uint16_t ticks_of(uint32_t ticks_at_1khz)
{
	uint32_t t = (ticks_at_1khz * CONFIG_AVR_TICK_HZ + 500u) / 1000u;

	return (uint16_t)(t ? t : 1u);
}

void avr_robot_config(struct board_config *cfg)
{
	board_default_config(cfg);
	/* The wheels, encoders, motors and outline of robot/avr.toml: magnetic encoders on the
	 * motor shafts, 48 counts per motor turn, which the pin-change interrupts follow. */
	avr_robot_gen(cfg);

	/* The control rate, and the durations the defaults give in ticks at 1 kHz kept in time. */
	cfg->tick_hz = CONFIG_AVR_TICK_HZ;
	/* The slow steps every 2^n ticks: the port's execution model follows it (tick.c), so keep
	 * the build option. */
	cfg->slow_shift = CONFIG_AVR_SLOW_SHIFT;
	cfg->control.tick_hz = CONFIG_AVR_TICK_HZ;
	cfg->orders.tick_hz = CONFIG_AVR_TICK_HZ;
	cfg->faults.following_ticks = ticks_of(cfg->faults.following_ticks);
	cfg->faults.current_ticks = ticks_of(cfg->faults.current_ticks);
	cfg->faults.repeat_window_ticks = ticks_of(cfg->faults.repeat_window_ticks);
	cfg->orders.settle_ticks = ticks_of(cfg->orders.settle_ticks);
	cfg->orders.settle_timeout_ticks = ticks_of(cfg->orders.settle_timeout_ticks);
}
