/* The control period as every port runs it (see port.h). */
#include "port.h"

#include "hal.h"

/* Unrolled: with constant sides, an 8-bit port reads each input at a fixed address instead of
 * computing it (a tenth of its cost on the AVR). */
void port_sample(struct board_inputs *in)
{
	in->free_count[HAL_LEFT] = hal_encoder_free(HAL_LEFT);
	in->free_count[HAL_RIGHT] = hal_encoder_free(HAL_RIGHT);
	in->shocks = hal_shock_read();
	in->basket = hal_basket_contact();
	in->lines = hal_line_read();
}

void port_sample_period(struct board_inputs *in)
{
	in->motor_count[HAL_LEFT] = hal_encoder_motor(HAL_LEFT);
	in->motor_count[HAL_RIGHT] = hal_encoder_motor(HAL_RIGHT);
	in->current_ma[HAL_LEFT] = hal_motor_current_ma(HAL_LEFT);
	in->current_ma[HAL_RIGHT] = hal_motor_current_ma(HAL_RIGHT);
}

/* The period's end inputs only when the tick reads them: on the AVR the currents' conversions
 * and the motor counts' atomic reads are then 7 ticks in 8 lighter. */
void port_control_tick(struct board *b)
{
	struct board_inputs in;
	struct board_outputs out;

	port_sample(&in);
	if (board_period_ends(b))
		port_sample_period(&in);
	board_tick(b, &in, &out);
	hal_motor_set(HAL_LEFT, out.duty_q15[0]);
	hal_motor_set(HAL_RIGHT, out.duty_q15[1]);
}

void port_slow(struct board *b)
{
	if (board_slow_due(b))
		board_slow(b);
}
