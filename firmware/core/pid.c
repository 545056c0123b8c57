/* PID on a following error (see pid.h and docs/control.md "PID").
 *
 * P and D are summed in [2^-12 duty_q15], each clipped to 8 times the full duty, and the integral
 * in [2^-24 duty_q15] as an exact 48-bit sum. An architecture may have a faster form of the
 * common case, small errors (arch_pid.h: pid_arch_update_small); it must give the bits of
 * pid_update_c below, which every other case takes. */
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
	/* At most 65535 2^24 / 12500 < 2^27 (tick_hz >= 100). */
	c->ki_q24 = (uint32_t)div_round_pos((int64_t)c->cfg.i << 24, 125 * hz);
	c->p_err_max_um = err_max(c->kp_q12);
	c->d_err_max_um = err_max(c->kd_q12);
	pid_arch_fast_init(&c->fast, c->kp_q12, c->kd_q12);
	c->i_max_q8 = (int32_t)c->cfg.out_limit_q15 << 8;
}

/* The integral clipped to the output limit: |hi| <= lim [2^-8 duty_q15]. */
static inline struct fx48 clip_i8(struct fx48 v, int32_t lim)
{
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
	c->i_acc_q24 = clip_i8(c->i_acc_q24, c->i_max_q8);
	return 0;
}

void pid_reset(struct pid *c)
{
	c->i_acc_q24 = fx48_make(0, 0);
	c->prev_err_um = 0;
	c->has_prev = 0;
	c->out_q15 = 0;
}

static inline int32_t clip32(int32_t v, int32_t lim)
{
	if (v > lim)
		return lim;
	if (v < -lim)
		return -lim;
	return v;
}

/* The upper part of u = pd 2^12 + i [2^-24 duty_q15], pd = pdh 16 + pdl / 2^12; *ul the lower. */
static inline int32_t sum_hi(int32_t pdh, uint16_t pdl, struct fx48 i, uint16_t *ul)
{
	uint32_t t = (uint32_t)pdl + i.lo;

	*ul = fx_lo16(t);
	return pdh + i.hi + (int32_t)fx_hi16(t);
}

/* Conditional integration: while the output is saturated in the direction in which the error
 * pushes it, integrating would only wind up. Whether u = uh 2^16 + ul is such an output. */
static inline int winds_up(int32_t e, int32_t uh, uint16_t ul, int32_t lim)
{
	return e > 0 ? uh > lim || (uh == lim && ul != 0) : uh < -lim;
}

/* round(u / 2^24) with ties away from zero, clipped to +-out_limit, for u = uh 2^16 + ul
 * [2^-24 duty_q15]: the ties fall on multiples of 2^23, so ul only matters below zero. */
static inline int16_t duty_of(const struct pid *c, int32_t uh, uint16_t ul)
{
	int32_t lim = c->i_max_q8;
	uint32_t m;

	if (uh >= lim)
		return c->cfg.out_limit_q15;
	if (uh <= -lim)
		return (int16_t)-c->cfg.out_limit_q15;
	if (uh >= 0)
		return (int16_t)(((uint32_t)uh + 128) >> 8);
	m = (uint32_t)0 - (uint32_t)uh - (ul != 0);
	return (int16_t)(0 - (int32_t)((m + 128) >> 8));
}

/* The duty from P + D (pd [2^-12 duty_q15]) and the integral i moved by this tick's error e
 * (the stored one when e is 0): i is clipped and kept unless it winds up, in which case the
 * stored integral gives the duty. */
static inline int16_t duty_with(struct pid *c, int32_t e, int32_t pd, struct fx48 i)
{
	int32_t pdh = fx_floor_shr(pd, 4); /* pd [2^-12] in [2^-24] as pdh 2^16 + pdl */
	uint16_t pdl = (uint16_t)((uint16_t)fx_lo16((uint32_t)pd) << 12);
	int32_t uh;
	uint16_t ul;

	if (e != 0) {
		i = clip_i8(i, c->i_max_q8);
		uh = sum_hi(pdh, pdl, i, &ul);
		if (!winds_up(e, uh, ul, c->i_max_q8)) {
			c->i_acc_q24 = i;
			return duty_of(c, uh, ul);
		}
	}
	uh = sum_hi(pdh, pdl, c->i_acc_q24, &ul);
	return duty_of(c, uh, ul);
}

/* k e [2^-12 duty_q15], clipped to +-TERM_MAX (|e| <= e_max keeps the product below it). */
static int32_t term(int32_t k, int32_t e, int32_t e_max)
{
	uint32_t m = fx_mag32(e);
	uint32_t t;

	if (m > (uint32_t)e_max)
		t = (uint32_t)TERM_MAX - 1;
	else if (k <= 0xffff && m <= 0xffffu)
		t = fx_mul_u16((uint16_t)k, (uint16_t)m);
	else
		t = (uint32_t)k * m; /* below 2^30 */
	return e >= 0 ? (int32_t)t : -(int32_t)t;
}

/* P + D, and the integral moved by ki e exactly (ki < 2^27, |e| <= 2^22), its upper part
 * saturated at 2^30 (the integral is clipped to the output limit, below 2^23 there, anyway). */
static int16_t update(struct pid *c, int32_t e, int32_t de)
{
	int32_t pd = term(c->kp_q12, e, c->p_err_max_um) + term(c->kd_q12, de, c->d_err_max_um);
	struct fx48 i = c->i_acc_q24;

	if (e != 0) {
		uint32_t lo, hi = fx_mul_u32_wide(c->ki_q24, fx_mag32(e), &lo);
		uint32_t t;

		if (hi >= (uint32_t)1 << 14) {
			hi = (uint32_t)1 << 30;
			lo = 0;
		} else {
			hi = (hi << 16) | fx_hi16(lo);
		}
		if (e > 0) {
			t = (uint32_t)i.lo + fx_lo16(lo);
			i.hi += (int32_t)hi + (int32_t)fx_hi16(t);
		} else {
			t = 0x10000u + i.lo - fx_lo16(lo);
			i.hi -= (int32_t)hi + 1 - (int32_t)fx_hi16(t);
		}
		i.lo = fx_lo16(t);
	}
	return duty_with(c, e, pd, i);
}

int16_t pid_update_c(struct pid *c, int32_t err_um)
{
	int32_t e = clip32(err_um, PID_ERR_MAX_UM);
	/* Clipped like the error. */
	int32_t de = c->has_prev ? clip32(e - c->prev_err_um, PID_ERR_MAX_UM) : 0;

	c->prev_err_um = e;
	c->has_prev = pid_arch_fast_mark(e);
	c->out_q15 = update(c, e, de);
	return c->out_q15;
}
