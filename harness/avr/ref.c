/* The native reference run (ref.h). */
#include "ref.h"

#include "avr_units.h"
#include "avrsim.h"

static void inputs(const struct ref *r, struct board_inputs *in)
{
	struct sim_sensors s;

	sim_read_sensors(&r->sim, &s);
	for (int i = 0; i < 2; i++) {
		int32_t ma = s.current_mA[i];

		in->free_count[i] = s.enc_count[i];
		in->motor_count[i] = s.motor_count[i];
		in->current_ma[i] = (int16_t)(ma > 32767 ? 32767 : ma < -32767 ? -32767 : ma);
	}
	in->shocks = s.shock_mask;
	in->basket = s.basket ? 1 : 0;
	in->lines = s.line_mask & 0x0Fu; /* the AVR board has 4 line inputs */
}

int ref_init(struct ref *r, const struct board_config *bc, const struct sim_config *sc,
	     const struct sim_field *f)
{
	struct board_inputs in;

	if (sim_init(&r->sim, sc, f))
		return -1;
	r->tick_ns = 1000000000u / bc->tick_hz;
	r->ticks = 0;
	inputs(r, &in);
	return board_init(&r->board, bc, &in);
}

static int16_t pwm(int16_t duty_q15)
{
	return avrsim_duty_q15(avr_pwm_counts(duty_q15), duty_q15 < 0);
}

void ref_tick(struct ref *r)
{
	struct board_inputs in;
	struct board_outputs out;

	inputs(r, &in);
	board_tick(&r->board, &in, &out);
	if (board_slow_due(&r->board))
		board_slow(&r->board);
	sim_set_duty(&r->sim, pwm(out.duty_q15[0]), pwm(out.duty_q15[1]));
	/* One substep per call, as the AVR's lockstep runs it (it needs the encoder positions of
	 * each substep): the simulator sums a call's encoder travel at its end, so a longer call
	 * would round differently. */
	for (uint64_t t = 0; t < r->tick_ns; t += r->sim.cfg.substep_ns)
		sim_step(&r->sim);
	r->ticks++;
}

void ref_i2c_write(struct ref *r, const uint8_t *data, uint8_t n, int stop)
{
	proto_master_write(&r->board.proto, data, n, stop);
}

void ref_i2c_read(struct ref *r, uint8_t *out, uint8_t n)
{
	proto_master_read(&r->board.proto, out, n);
}
