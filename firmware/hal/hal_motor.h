/* Porting contract: the two drive motors (PWM + direction, current sense). */
#ifndef ASSERV_HAL_MOTOR_H
#define ASSERV_HAL_MOTOR_H

#include <stdint.h>

#include "hal_encoder.h"

/* Apply a signed duty [2^-15 of full scale]: +32767 drives the robot forward at full voltage,
 * -32767 backward, 0 brakes or coasts as the bridge does. The port clamps to its PWM resolution.
 * May be called from an interrupt: yes. */
void hal_motor_set(enum hal_side side, int16_t duty_q15);

/* Motor current [mA], signed like the duty; 0 on a board without current sensing.
 * The port filters it over at least one control period (ADC average).
 * May be called from an interrupt: yes. */
int16_t hal_motor_current_ma(enum hal_side side);

#endif
