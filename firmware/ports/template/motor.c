/* Template port: the two drive motors, PWM and direction, and their current (hal_motor.h). */
#include "hal.h"
#include "template_port.h"

/* Apply the duty the board computed this tick [2^-15 of full scale], signed: +32767 drives the
 * robot forward at the full supply voltage, -32767 backward, 0 stops driving (brake or coast,
 * as the bridge does). What the core expects:
 * - the duty is applied as given, at once: no ramp and no dead band of the port's own (the
 *   control loop closes around it; a ramp here is a delay the loop was not tuned for);
 * - forward is the robot's forward on both sides: the two motors face opposite ways, so one
 *   side's direction is usually inverted here;
 * - the port clamps to its PWM resolution: compare = |duty| * (top + 1) / 32768 for a timer
 *   counting 0..top, with the direction pin from the sign.
 * After a reset and until the first tick, the outputs must be off (pins as inputs with
 * pull-downs on the bridge's enables, or the bridge disabled): a watchdog reset must stop the
 * motors by itself. Called from the control interrupt, every tick, after board_tick(). */
void hal_motor_set(enum hal_side side, int16_t duty_q15)
{
	(void)side;
	(void)duty_q15; /* e.g. TIMx->CCRn = |duty| * (ARR + 1) / 32768; GPIO direction = sign */
}

/* The motor's current [mA], signed like its duty (positive while driving forward), or 0 on a
 * board without current sensing (the board then does not detect a stalled motor by its
 * current). Averaged over at least one control period, so that the PWM's ripple is gone; the
 * conversion runs by itself (ADC triggered by the PWM timer, or started at the end of the last
 * tick): this function returns the last result and never waits for a conversion. Called from the
 * control interrupt, at the end of a planner period (port_sample_period()). */
int16_t hal_motor_current_ma(enum hal_side side)
{
	(void)side;
	return 0; /* no current sensing */
}
