/* PID on a following error (see pid.h and docs/control.md "PID"). */
#include "pid.h"

#include "fixmath.h"

/* Every term is summed in [2^-24 duty_q15]: enough bits that the i gain of 1 still has 0.7 %
 * resolution at 2 kHz, few enough that the clipped terms cannot overflow int64. */
#define PID_SHIFT 24
/* A term beyond 2^48 units (2^24 times full duty) saturates anyway; clipping each term there
 * keeps their sum far from int64 overflow. */
#define PID_TERM_MAX ((int64_t)1 << 48)

static int config_valid(const struct pid_config *cfg)
{
	if (cfg->out_limit_q15 < 1)
		return 0;
	if (cfg->tick_hz < PID_TICK_HZ_MIN || cfg->tick_hz > PID_TICK_HZ_MAX)
		return 0;
	return 1;
}

static int64_t clip64(int64_t v, int64_t lim)
{
	if (v > lim)
		return lim;
	if (v < -lim)
		return -lim;
	return v;
}

/* n / d rounded to nearest, for the positive values of the gain conversion (plan time). */
static int64_t div_round_pos(int64_t n, int64_t d)
{
	return (n + d / 2) / d;
}

/* duty_q15 = 32768 p 2^-12 e_um / 1000 = p e_um / 125;
 * duty_q15 = 32768 i 2^-12 (sum e_um / hz) / 1000 = i sum_e_um / (125 hz);
 * duty_q15 = 32768 d 2^-16 (de_um hz) / 1000 = d de_um hz / 2000.
 * The divisions are done once here, on the gains scaled by 2^24. */
static void compute_gains(struct pid *c)
{
	int64_t hz = c->cfg.tick_hz;
	int64_t one = (int64_t)1 << PID_SHIFT;

	c->kp_q24 = div_round_pos((int64_t)c->cfg.p * one, 125);
	c->ki_q24 = div_round_pos((int64_t)c->cfg.i * one, 125 * hz);
	c->kd_q24 = div_round_pos((int64_t)c->cfg.d * hz * one, 2000);
}

int pid_init(struct pid *c, const struct pid_config *cfg)
{
	if (!config_valid(cfg))
		return -1;
	c->cfg = *cfg;
	compute_gains(c);
	pid_reset(c);
	return 0;
}

int pid_set_config(struct pid *c, const struct pid_config *cfg)
{
	if (!config_valid(cfg))
		return -1;
	c->cfg = *cfg;
	compute_gains(c);
	c->i_acc_q24 = clip64(c->i_acc_q24, (int64_t)cfg->out_limit_q15 << PID_SHIFT);
	return 0;
}

void pid_reset(struct pid *c)
{
	c->i_acc_q24 = 0;
	c->prev_err_um = 0;
	c->has_prev = 0;
	c->out_q15 = 0;
}

int16_t pid_update(struct pid *c, int32_t err_um)
{
	int64_t lim = (int64_t)c->cfg.out_limit_q15 << PID_SHIFT;
	int32_t e = (int32_t)clip64(err_um, PID_ERR_MAX_UM);
	/* Clipped like the error, so that kd * de stays below 2^62. */
	int32_t de = (int32_t)clip64(c->has_prev ? (int64_t)e - c->prev_err_um : 0, PID_ERR_MAX_UM);
	int64_t pd;
	int64_t i_new;
	int64_t u;

	c->prev_err_um = e;
	c->has_prev = 1;
	pd = clip64(c->kp_q24 * e, PID_TERM_MAX) + clip64(c->kd_q24 * de, PID_TERM_MAX);
	/* The integral is kept as its contribution to the output, so that it can be clipped to
	 * the limit directly and stays bumpless when the i gain changes. Integer products: exact,
	 * no rounding to accumulate. */
	i_new = clip64(c->i_acc_q24 + c->ki_q24 * e, lim);
	u = pd + i_new;
	/* Conditional integration: while the output is saturated in the direction in which the
	 * error pushes it, integrating would only wind up. */
	if ((u > lim && e > 0) || (u < -lim && e < 0))
		i_new = c->i_acc_q24;
	c->i_acc_q24 = i_new;
	u = clip64(fx_shr_round64(pd + i_new, PID_SHIFT), c->cfg.out_limit_q15);
	c->out_q15 = (int16_t)u;
	return c->out_q15;
}
