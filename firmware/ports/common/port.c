/* The control period as every port runs it (see port.h). */
#include "port.h"

#include "hal.h"

void port_sample(struct board_inputs *in)
{
	for (uint8_t s = 0; s < 2; s++) {
		in->free_count[s] = hal_encoder_free((enum hal_side)s);
		in->motor_count[s] = hal_encoder_motor((enum hal_side)s);
		in->current_ma[s] = hal_motor_current_ma((enum hal_side)s);
	}
	in->shocks = hal_shock_read();
	in->basket = hal_basket_contact();
	in->lines = hal_line_read();
}

void port_control_tick(struct board *b)
{
	struct board_inputs in;
	struct board_outputs out;

	port_sample(&in);
	board_tick(b, &in, &out);
	hal_motor_set(HAL_LEFT, out.duty_q15[0]);
	hal_motor_set(HAL_RIGHT, out.duty_q15[1]);
}
