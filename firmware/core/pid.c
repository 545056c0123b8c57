/* PID on a following error (see pid.h and docs/control.md "PID").
 *
 * P and D are summed in [2^-12 duty_q15], each clipped to 8 times the full duty, and the integral
 * in [2^-24 duty_q15] as an exact 48-bit sum; the products are 16 x 16 bits while the errors and
 * gains are small, which they are in use (an 8-bit AVR multiplies 16 x 16 bits in about 25
 * cycles, and calls a library routine of 200 for anything on int64_t). */
#include "pid.h"

#include "fixmath.h"

#define TERM_MAX ((int32_t)1 << 30) /* [2^-12 duty_q15]: 8 times 32768 */

static int config_valid(const struct pid_config *cfg)
{
	if (cfg->out_limit_q15 < 1)
		return 0;
	if (cfg->tick_hz < PID_TICK_HZ_MIN || cfg->tick_hz > PID_TICK_HZ_MAX)
		return 0;
	return 1;
}

/* n / d rounded to nearest, for the positive values of the gain conversion (plan time). */
static int64_t div_round_pos(int64_t n, int64_t d)
{
	return (n + d / 2) / d;
}

static int32_t err_max(int32_t k)
{
	return k == 0 ? PID_ERR_MAX_UM : (int32_t)((TERM_MAX - 1) / k);
}

/* duty_q15 = 32768 p 2^-12 e_mm = p e_um / 125;
 * duty_q15 = 32768 i 2^-12 (sum e_um / hz) / 1000 = i sum_e_um / (125 hz);
 * duty_q15 = 32768 d 2^-16 (de_um hz) / 1000 = d de_um hz / 2000.
 * The divisions are done once here. */
static void compute_gains(struct pid *c)
{
	int64_t hz = c->cfg.tick_hz;

	c->kp_q12 = (int32_t)div_round_pos((int64_t)c->cfg.p << 12, 125);
	c->kd_q12 = (int32_t)div_round_pos((int64_t)c->cfg.d * hz << 12, 2000);
	c->ki_q24 = (uint64_t)div_round_pos((int64_t)c->cfg.i << 24, 125 * hz);
	c->ki_wide = c->ki_q24 > 0xffffffffu;
	c->ki_small_q24 = (uint32_t)c->ki_q24;
	c->p_err_max_um = err_max(c->kp_q12);
	c->d_err_max_um = err_max(c->kd_q12);
}

/* The integral clipped to +-out_limit 2^24 (the limit is a whole number of 2^-8 duty). */
static struct fx48 clip_i(const struct pid *c, struct fx48 v)
{
	int32_t lim = (int32_t)c->cfg.out_limit_q15 << 8;

	if (v.hi >= lim)
		return fx48_make(lim, 0);
	if (v.hi < -lim)
		return fx48_make(-lim, 0);
	return v;
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
	c->i_acc_q24 = clip_i(c, c->i_acc_q24);
	return 0;
}

void pid_reset(struct pid *c)
{
	c->i_acc_q24 = fx48_make(0, 0);
	c->prev_err_um = 0;
	c->has_prev = 0;
	c->out_q15 = 0;
}

static int32_t clip32(int32_t v, int32_t lim)
{
	if (v > lim)
		return lim;
	if (v < -lim)
		return -lim;
	return v;
}

/* k e [2^-12 duty_q15], clipped to +-TERM_MAX (|e| <= e_max keeps the product below it). */
static int32_t term(int32_t k, int32_t e, int32_t e_max)
{
	uint32_t m = e >= 0 ? (uint32_t)e : (uint32_t)0 - (uint32_t)e;
	uint32_t t;

	if (m > (uint32_t)e_max)
		t = (uint32_t)TERM_MAX - 1;
	else if (k <= 0xffff && m <= 0xffffu)
		t = fx_mul_u16((uint16_t)k, (uint16_t)m);
	else
		t = (uint32_t)k * m; /* below 2^30 */
	return e >= 0 ? (int32_t)t : -(int32_t)t;
}

/* |ki e| [2^-24 duty_q15] as hi 2^16 + lo, exact: two 16 x 16 products while ki < 2^32 and
 * |e| < 2^16, else in 64 bits, saturated at 2^46 (the integral is clipped to the output limit,
 * below 2^39, anyway). */
static uint32_t i_step(const struct pid *c, uint32_t m, uint16_t *lo16)
{
	if (!c->ki_wide && m <= 0xffffu) {
		uint32_t k = c->ki_small_q24;
		uint32_t lo = fx_mul_u16(fx_lo16(k), (uint16_t)m);

		*lo16 = fx_lo16(lo);
		return fx_mul_u16(fx_hi16(k), (uint16_t)m) + fx_hi16(lo);
	} else {
		uint64_t p = c->ki_q24 > ((uint64_t)1 << 46) / (m ? m : 1) ? (uint64_t)1 << 46
									   : c->ki_q24 * m;

		*lo16 = (uint16_t)p;
		return (uint32_t)(p >> 16);
	}
}

/* round(u / 2^24) with ties away from zero, clipped to +-lim, for u = (u8 2^16 + ul) [2^-24
 * duty_q15]: the ties fall on multiples of 2^23, so the fraction ul does not move them. */
static int16_t duty_of(int32_t u8, uint16_t ul, int16_t lim)
{
	uint32_t m = u8 >= 0 ? (uint32_t)u8 : (uint32_t)0 - (uint32_t)u8 - (ul != 0);
	uint32_t d = m >= ((uint32_t)lim << 8) ? (uint32_t)lim : (m + 128) >> 8;

	if (d > (uint32_t)lim)
		d = (uint32_t)lim;
	return (int16_t)(u8 >= 0 ? (int32_t)d : -(int32_t)d);
}

int16_t pid_update(struct pid *c, int32_t err_um)
{
	int32_t e = clip32(err_um, PID_ERR_MAX_UM);
	/* Clipped like the error. */
	int32_t de = c->has_prev ? clip32(e - c->prev_err_um, PID_ERR_MAX_UM) : 0;
	int32_t pd = term(c->kp_q12, e, c->p_err_max_um) + term(c->kd_q12, de, c->d_err_max_um);
	int32_t lim = (int32_t)c->cfg.out_limit_q15 << 8; /* [2^-8 duty_q15] */
	/* pd [2^-12] in [2^-24] as pdh 2^16 + pdl: pdh = floor(pd / 16). */
	int32_t pdh = (pd - (pd & 15)) / 16;
	uint16_t pdl = (uint16_t)((uint32_t)(pd & 15) << 12);
	/* The integral [2^-24 duty_q15] as ihi 2^16 + ilo; |ihi| <= lim. */
	int32_t ihi = c->i_acc_q24.hi;
	uint16_t ilo = c->i_acc_q24.lo;
	uint32_t t;

	c->prev_err_um = e;
	c->has_prev = 1;
	/* The integral is kept as its contribution to the output, so that it can be clipped to
	 * the limit directly and stays bumpless when the i gain changes. Integer products: exact,
	 * no rounding to accumulate. */
	if (e != 0) {
		uint16_t lo;
		uint32_t hi = i_step(c, e >= 0 ? (uint32_t)e : (uint32_t)0 - (uint32_t)e, &lo);
		int32_t uh;

		if (hi > ((uint32_t)1 << 30))
			hi = (uint32_t)1 << 30; /* far past any limit: still clipped below */
		if (e > 0) {
			t = (uint32_t)ilo + lo;
			ihi += (int32_t)hi + (int32_t)fx_hi16(t);
		} else {
			t = 0x10000u + ilo - lo;
			ihi -= (int32_t)hi + 1 - (int32_t)fx_hi16(t);
		}
		ilo = fx_lo16(t);
		if (ihi >= lim) {
			ihi = lim;
			ilo = 0;
		} else if (ihi < -lim) {
			ihi = -lim;
			ilo = 0;
		}
		/* Conditional integration: while the output is saturated in the direction in
		 * which the error pushes it, integrating would only wind up. */
		t = (uint32_t)pdl + ilo;
		uh = pdh + ihi + (int32_t)fx_hi16(t);
		if ((e > 0 && (uh > lim || (uh == lim && fx_lo16(t) != 0))) ||
		    (e < 0 && uh < -lim)) {
			ihi = c->i_acc_q24.hi;
			ilo = c->i_acc_q24.lo;
		}
		c->i_acc_q24 = fx48_make(ihi, ilo);
	}
	t = (uint32_t)pdl + ilo;
	c->out_q15 = duty_of(pdh + ihi + (int32_t)fx_hi16(t), fx_lo16(t), c->cfg.out_limit_q15);
	return c->out_q15;
}
