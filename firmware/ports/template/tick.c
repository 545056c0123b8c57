/* Template port: the control period (hal_tick.h), a timer interrupt that runs the board. */
#include "hal.h"
#include "port.h"
#include "template_port.h"

/* Start the control interrupt at rate_hz [Hz] (the board configuration's tick_hz, 100..2000;
 * 1000 on the reference robot): a timer whose period is 1/rate_hz as exactly as the clock
 * allows, since the core's speeds, durations and profiles all count in its ticks. Its priority
 * is below the I2C interrupt's. Called once, from main(), last, when everything it touches is
 * ready. */
void hal_tick_start(uint16_t rate_hz)
{
	(void)rate_hz; /* e.g. reload = CPU_HZ / rate_hz - 1; enable the timer and its interrupt */
}

/* The control interrupt: one period. What the core expects of it:
 * - it is not re-entered: a tick that runs over its period delays the next one, and a port
 *   whose timer would nest it counts the overrun instead (the AVR's avr_tick_overruns);
 * - port_control_tick() samples the HAL, runs board_tick() and applies the duties, in that
 *   order, within the period;
 * - with one rate (slow_shift 0, planner_ticks 0: board_default_config()) board_tick() runs
 *   the planner itself, and port_slow() after it finds nothing due. A port with two rates
 *   (slow_shift > 0, planner_ticks > 0) calls port_slow() from its main loop instead, preempted
 *   by this interrupt (the AVR at 125 Hz: firmware/ports/avr/tick.c);
 * - the watchdog is fed here or in the main loop (where a stuck main loop must stop the
 *   motors), never from a timer of its own that would outlive a stopped tick. */
void template_tick_isr(void)
{
	port_control_tick(&asserv_board);
	port_slow(&asserv_board);
	template_watchdog_feed(); /* or in the main loop (above) */
}
