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
#if CONFIG_QUIET_SERVO
	if (cfg->d_shift > PID_D_SHIFT_MAX)
		return 0;
	if (cfg->d_shift > 0 && (cfg->d_lag_max_um < 1 || cfg->d_lag_max_um > PID_ERR_MAX_UM))
		return 0;
#endif
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
 * duty_q15 = 32768 d 2^-16 (de_um hz) / 1000 = d de_um hz / 2000,
 * de_um the low-passed change of the error a tick: (e - prev_err_um) / 2^d_shift (pid_update_c),
 * so kd is divided by 2^d_shift. The divisions are done once here. */
static void compute_gains(struct pid *c)
{
	int64_t hz = c->cfg.tick_hz;
#if CONFIG_QUIET_SERVO
	uint8_t d_shift = c->cfg.d_shift;
#else
	const uint8_t d_shift = 0;
#endif

	c->kp_q12 = (int32_t)div_round_pos((int64_t)c->cfg.p << 12, 125);
	c->kd_q12 = (int32_t)div_round_pos((int64_t)c->cfg.d * hz << 12, (int64_t)2000 << d_shift);
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
#if CONFIG_QUIET_SERVO
	pid_forget(c);
	c->raw_d = 0;
#else
	pid_reset(c);
#endif
	return 0;
}

/* x 2^k for |x| 2^k < 2^31 (no signed shift of a negative value). */
static inline int32_t shl(int32_t x, uint8_t k)
{
	return (int32_t)((uint32_t)x << k);
}

int pid_set_config(struct pid *c, const struct pid_config *cfg)
{
#if CONFIG_QUIET_SERVO
	uint8_t k = c->cfg.d_shift;
#endif

	if (!config_valid(cfg))
		return -1;
	c->cfg = *cfg;
	compute_gains(c);
#if CONFIG_QUIET_SERVO
	if (cfg->d_shift != k) { /* a new low-pass: it starts from the last error, at rest */
		int32_t last = k == 0 ? c->prev_err_um : c->d_last_um;

		c->d_last_um = last;
		c->prev_err_um = last;
		c->d_lp = shl(last, cfg->d_shift);
	}
#endif
	c->i_acc_q24 = clip_i8(c->i_acc_q24, c->i_max_q8);
	return 0;
}

void pid_reset(struct pid *c)
{
	c->i_acc_q24 = fx48_make(0, 0);
	if (!pid_d_filtered(c))
		c->prev_err_um = 0;
	c->has_prev = 0;
	c->out_q15 = 0;
}

void pid_forget(struct pid *c)
{
	pid_reset(c);
#if CONFIG_QUIET_SERVO
	c->prev_err_um = 0;
	c->d_lp = 0;
	c->d_last_um = 0;
#endif
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

#if CONFIG_QUIET_SERVO
/* The derivative's input with the low-pass (d_shift k > 0), e - floor(f) for the low-pass f of
 * the error, and f moved by it: f += (e - floor(f)) / 2^k, that is d_lp += e - prev_err_um in
 * [2^-k um]. The low-pass of the error changes by 2^-k (e - f) a tick: that is the low-pass of
 * the error's change (both filters are linear), with kd / 2^k (compute_gains). After a reset,
 * f first moves with the error's jump: e - f is the last tick's, the speed read. f is then held
 * within d_lag_max_um of e: beyond, D reads the error's raw change (a shock, a rebound), not the
 * low-passed one. Within the bounds: |e|, |d_last_um| <= 2^22 and |f| <= 2^23, so |d_lp| < 2^30
 * and |d| (its step, d plus a move of at most 2^24 2^k) < 2^31. */
static int32_t lowpass(struct pid *c, int32_t e)
{
	uint8_t k = c->cfg.d_shift;
	int32_t d, lag;

	if (!c->has_prev) {
		int32_t frac = c->d_lp & (((int32_t)1 << k) - 1);

		lag = clip32(c->d_last_um - c->prev_err_um, PID_ERR_MAX_UM);
		c->prev_err_um = e - lag;
		c->d_lp = shl(c->prev_err_um, k) + frac;
	}
	d = e - c->prev_err_um;
	c->d_lp += d;
	c->prev_err_um = fx_floor_shr(c->d_lp, k);
	c->d_last_um = e;
	lag = c->cfg.d_lag_max_um;
	if (c->prev_err_um < e - lag || c->prev_err_um > e + lag) {
		/* Held lag_max from the error: its step this tick [2^-k um] is d plus the move
		 * (from the low-pass with its fraction). */
		int32_t f = c->prev_err_um < e - lag ? e - lag : e + lag;
		int32_t lp = shl(f, k);

		d += lp - c->d_lp;
		c->prev_err_um = f;
		c->d_lp = lp;
	}
	return d;
}

/* The derivative's input with the low-pass (d_shift k > 0) but read raw (raw_d): the error's
 * change since the last tick [2^-k um], 0 after a reset, within +/-PID_ERR_MAX_UM as lowpass()'s;
 * the low-pass at rest on the error, from which it goes on once raw_d is cleared. */
static int32_t raw_change(struct pid *c, int32_t e)
{
	uint8_t k = c->cfg.d_shift;
	int32_t d = c->has_prev ? shl(clip32(e - c->d_last_um, PID_ERR_MAX_UM >> k), k) : 0;

	c->prev_err_um = e;
	c->d_lp = shl(e, k);
	c->d_last_um = e;
	return d;
}

/* The derivative's input with the low-pass (d_shift > 0), and the architecture's mark. */
static inline int32_t filtered_change(struct pid *c, int32_t e)
{
	int32_t de = c->raw_d ? raw_change(c, e) : clip32(lowpass(c, e), PID_ERR_MAX_UM);

	c->has_prev = pid_arch_fast_mark(c->prev_err_um);
	return de;
}
#else
/* Never called: pid_d_filtered() is 0 in a build without the low-pass. */
static inline int32_t filtered_change(struct pid *c, int32_t e)
{
	(void)c;
	return e;
}
#endif

/* The derivative's input without the low-pass (d_shift 0): the change of the error since the
 * last tick, 0 after a reset, clipped like the error; and the architecture's mark. */
static inline int32_t raw_difference(struct pid *c, int32_t e)
{
	int32_t de = c->has_prev ? clip32(e - c->prev_err_um, PID_ERR_MAX_UM) : 0;

	c->prev_err_um = e;
	c->has_prev = pid_arch_fast_mark(e);
	return de;
}

int16_t pid_update_c(struct pid *c, int32_t err_um)
{
	int32_t e = clip32(err_um, PID_ERR_MAX_UM);
	int32_t de = pid_d_filtered(c) ? filtered_change(c, e) : raw_difference(c, e);

	c->out_q15 = update(c, e, de);
	return c->out_q15;
}
