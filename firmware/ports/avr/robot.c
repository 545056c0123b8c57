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

void avr_robot_config(struct board_config *cfg)
{
	board_default_config(cfg);
	/* The wheels, encoders, motors and outline of robot/avr.toml: magnetic encoders on the
	 * motor shafts, 48 counts per motor turn, which the pin-change interrupts follow. */
	avr_robot_gen(cfg);

	/* The control rate (the durations are in ms: board_init() counts them at its rates). */
	cfg->tick_hz = CONFIG_AVR_TICK_HZ;
	/* The slow steps every 2^n ticks: the port's execution model follows it (tick.c), so keep
	 * the build option. */
	cfg->slow_shift = CONFIG_AVR_SLOW_SHIFT;
	/* The slow steps' results three ticks after their snapshot: preempted by the servo and the
	 * interrupts, their longest run (about 18 500 cycles, docs/avr.md) ends within three
	 * 1 ms ticks with a margin; bench_avr prints the overruns. One rate: in the tick itself. */
	cfg->planner_ticks = CONFIG_AVR_SLOW_SHIFT == 0 ? 0 : 3;
	/* A GOTO's first aim at the step after the one that takes it: both in one step (both
	 * profiles' first runs) take the worst load over a period from 38 % to 45 % at 1 m/s. */
	cfg->orders.aim_delay_steps = CONFIG_AVR_SLOW_SHIFT == 0 ? 0 : 1;
	/* The PIDs' derivative without its low-pass: the AVR's build leaves the quiet servo out
	 * (CONFIG_QUIET_SERVO=0, docs/avr.md); a host build of this configuration (the simavr
	 * harness's reference run) has it, and runs without it, as the AVR. */
#if CONFIG_QUIET_SERVO
	cfg->control.d_filter_ms = 0;
#endif
}
