/* One-dimensional motion profile generator (see profile.h and docs/control.md "Profiles").
 *
 * The trapezoid is an online, discrete-time, time-optimal generator: each tick it takes the
 * largest velocity from which it can still brake onto the target exactly. The S-curve is that
 * trapezoid passed through a moving average of n_filt ticks. */
#include "profile.h"

#include "fixmath.h"

#define Q16 65536

static int64_t min64(int64_t a, int64_t b)
{
	return a < b ? a : b;
}

static int64_t max64(int64_t a, int64_t b)
{
	return a > b ? a : b;
}

/* floor(x / 2^16) without shifting a negative value. */
static int64_t floor_q16(int64_t x)
{
	if (x >= 0)
		return x / Q16;
	return -((-x + (Q16 - 1)) / Q16);
}

static int limits_valid(const struct profile_limits *lim)
{
	if (lim->v_max_um_s < 1 || lim->v_max_um_s > PROFILE_V_MAX_UM_S)
		return 0;
	if (lim->a_max_um_s2 < PROFILE_A_MIN_UM_S2 || lim->a_max_um_s2 > PROFILE_A_MAX_UM_S2)
		return 0;
	if (lim->j_max_um_s3 != 0 && lim->j_max_um_s3 < PROFILE_J_MIN_UM_S3)
		return 0;
	return 1;
}

/* Distance covered from velocity n*a (included) with h ticks of cruise, then braking by a per
 * tick: g_h(n a) = a n (n + 2h + 1) / 2. n (n + 2h + 1) is always even. */
static int64_t g_at_step(int64_t a, int64_t n, uint16_t h)
{
	return a * (n * (n + 2 * (int64_t)h + 1) / 2);
}

/* The largest n >= 0 with g_h(n a) <= r: from the square root of a n^2 + a k n = 2 r, then the
 * exact test settles the last unit. hint is the n found last time for this h: on a braking ramp
 * n drops by one per tick, and while a small correction is held it stays, so the last n and its
 * neighbours are tried first (each try is the exact test) and the 64-bit square root and
 * division are only needed when the target or the limits jumped. */
static int64_t step_count(const struct profile_params *prm, int64_t r, uint16_t h, int64_t *hint)
{
	int64_t a = prm->a_q16;
	int64_t k = 2 * (int64_t)h + 1;
	int64_t n = *hint;

	if (n >= 0) {
		if (g_at_step(a, n, h) <= r) {
			if (g_at_step(a, n + 1, h) > r)
				return n;
			if (g_at_step(a, n + 2, h) > r) {
				*hint = n + 1;
				return n + 1;
			}
		} else if (n >= 1 && g_at_step(a, n - 1, h) <= r) {
			*hint = n - 1;
			return n - 1;
		}
	}
	n = ((int64_t)fx_isqrt64((uint64_t)(k * k + 8 * (r / a))) - k) / 2;
	if (n < 0)
		n = 0;
	while (n > 0 && g_at_step(a, n, h) > r)
		n--;
	while (g_at_step(a, n + 1, h) <= r)
		n++;
	*hint = n;
	return n;
}

/* The largest velocity v >= 0 [um/tick * 2^16] such that moving v this tick, cruising h ticks
 * and then braking by a per tick (the last step a fraction of a) covers at most r.
 * With v = n a + f, 0 <= f < a, that distance is g_h(n a) + (n + h + 1) f: piecewise linear and
 * increasing, so its inverse is exact up to the floor of f, and the remainder is carried to the
 * next tick by the position itself: braking from g_h^-1(r) lands exactly on r.
 * The remainder r - g_h(n a) is below g_h((n + 1) a) - g_h(n a) = a (n + h + 1), about v_max
 * (below 2^31): when it and the divisor fit in 32 bits, which only extreme limits prevent, the
 * division is done in 32 bits (the same quotient, a fraction of the cost on an AVR). */
static int64_t max_velocity(struct profile *p, int64_t r, uint16_t h)
{
	const struct profile_params *prm = &p->prm;
	int64_t a = prm->a_q16;
	int64_t n, rem, den;

	if (r >= prm->r_far_q16)
		return (int64_t)prm->v_max_q16 + a;
	n = step_count(prm, r, h, &p->n_hint[h != 0]);
	rem = r - g_at_step(a, n, h);
	den = n + h + 1;
	if (rem <= (int64_t)UINT32_MAX && den <= (int64_t)UINT32_MAX)
		return n * a + (int64_t)((uint32_t)rem / (uint32_t)den);
	return n * a + rem / den;
}

/* Beyond r_far, braking cannot limit the velocity (max_velocity() >= v_max + a for any h up to
 * hold_len), so the far part of a move costs no square root. */
static void params_update_far(struct profile_params *prm)
{
	int64_t a = prm->a_q16;
	int64_t v = (int64_t)prm->v_max_q16 + a;
	int64_t n = (v - 1) / a;
	int64_t f = v - n * a;

	prm->r_far_q16 = g_at_step(a, n, prm->hold_len) + (n + prm->hold_len + 1) * f;
}

/* Acceleration [um/tick^2 * 2^16] whose ramp over n ticks keeps the jerk at most j [um/s^3]. */
static int64_t accel_for_window(const struct profile_params *prm, int64_t n)
{
	int64_t hz = prm->tick_hz;
	/* Rounded down: the jerk limit is a limit. */
	int64_t a = (int64_t)prm->j_um_s3 * n * Q16 / (hz * hz * hz);

	return min64(a, prm->a_full_q16);
}

static void params_set_limits(struct profile_params *prm, const struct profile_limits *lim)
{
	int64_t hz = prm->tick_hz;

	prm->lim = *lim;
	/* Rounded down, so that the limits are never exceeded. */
	prm->v_max_q16 = (int32_t)((int64_t)lim->v_max_um_s * Q16 / hz);
	prm->a_full_q16 = (int32_t)((int64_t)lim->a_max_um_s2 * Q16 / (hz * hz));
}

static int at_rest(const struct profile *p)
{
	return p->vel_in_q16 == 0 && p->quiet >= p->prm.n_filt;
}

/* At rest only: choose the smoothing window for a move of dist_q16, and empty the filter.
 * A long S-curve uses n = a/j; a short one (that never reaches a_max) uses the n for which the
 * jerk-only profile is time-optimal: the smallest n with 2 (j n) n^2 >= d. */
static void choose_window(struct profile *p, int64_t dist_q16)
{
	struct profile_params *prm = &p->prm;
	int64_t n = 1;

	if (prm->lim.j_max_um_s3 == 0) {
		prm->j_um_s3 = 0;
		prm->a_q16 = prm->a_full_q16;
		prm->hold_len = 0;
	} else {
		int64_t hz = prm->tick_hz;
		int64_t j = prm->lim.j_max_um_s3;
		int64_t n_full = ((int64_t)prm->lim.a_max_um_s2 * hz + j - 1) / j;

		prm->j_um_s3 = prm->lim.j_max_um_s3;
		n_full = max64(1, min64(n_full, CONFIG_PROFILE_JERK_TICKS_MAX));
		n = n_full;
		if (dist_q16 > 0) {
			int64_t lo = 1;
			int64_t hi = n_full;

			while (lo < hi) {
				int64_t mid = (lo + hi) / 2;
				int64_t a = accel_for_window(prm, mid);

				if (a >= 1 && 2 * a * mid * mid >= dist_q16)
					hi = mid;
				else
					lo = mid + 1;
			}
			n = lo;
		}
		prm->a_q16 = (int32_t)accel_for_window(prm, n);
		prm->hold_len = (uint16_t)n;
	}
	prm->n_filt = (uint16_t)n;
	params_update_far(prm);
	p->far_ready = 1;
	for (uint16_t i = 0; i < prm->n_filt; i++)
		p->hist_q16[i] = 0;
	p->idx = 0;
	p->vel_sum_q16 = 0;
	p->pos_sum_q16 = p->pos_in_q16 * prm->n_filt;
	p->quiet = prm->n_filt;
	p->hold = 0;
	p->hold_sign = 0;
}

int profile_init(struct profile *p, const struct profile_config *cfg, int32_t pos_um)
{
	if (cfg->tick_hz < PROFILE_TICK_HZ_MIN || cfg->tick_hz > PROFILE_TICK_HZ_MAX)
		return -1;
	if (!limits_valid(&cfg->limits))
		return -1;
	p->prm.tick_hz = cfg->tick_hz;
	params_set_limits(&p->prm, &cfg->limits);
	p->prm.n_filt = 1;
	p->far_ready = 0;
	p->n_hint[0] = -1;
	p->n_hint[1] = -1;
	profile_reset(p, pos_um);
	return 0;
}

int profile_set_limits(struct profile *p, const struct profile_limits *lim)
{
	if (!limits_valid(lim))
		return -1;
	params_set_limits(&p->prm, lim);
	p->far_ready = 0; /* new limits: r_far is computed again */
	if (at_rest(p)) {
		choose_window(p, p->target_q16 - p->pos_in_q16 >= 0
					 ? p->target_q16 - p->pos_in_q16
					 : p->pos_in_q16 - p->target_q16);
		return 0;
	}
	/* Moving: the window cannot change without a jump, so the jerk in effect stays and the
	 * acceleration is capped to what that window allows. */
	if (p->prm.j_um_s3 == 0)
		p->prm.a_q16 = p->prm.a_full_q16;
	else
		p->prm.a_q16 = (int32_t)max64(1, accel_for_window(&p->prm, p->prm.n_filt));
	params_update_far(&p->prm);
	return 0;
}

/* At rest, a trapezoid already set up for the current limits: choose_window() would change
 * nothing (the filter is one slot, empty, its position sum the position; r_far is that of
 * these limits). The common case of a GOTO re-aiming a resting angle axis every tick, spared
 * the division of params_update_far(). */
static int window_current(const struct profile *p)
{
	const struct profile_params *prm = &p->prm;

	return prm->lim.j_max_um_s3 == 0 && prm->j_um_s3 == 0 && prm->n_filt == 1 &&
	       prm->hold_len == 0 && prm->a_q16 == prm->a_full_q16 && p->far_ready;
}

void profile_set_target(struct profile *p, int32_t target_um)
{
	p->target_q16 = (int64_t)target_um * Q16;
	p->stopping = 0;
	if (at_rest(p) && !window_current(p)) {
		int64_t d = p->target_q16 - p->pos_in_q16;

		choose_window(p, d >= 0 ? d : -d);
	}
	p->out.done = (uint8_t)(at_rest(p) && p->pos_in_q16 == p->target_q16);
}

int32_t profile_stop(struct profile *p)
{
	int64_t a = p->prm.a_q16;
	int64_t v = p->vel_in_q16;
	int s = v >= 0 ? 1 : -1;
	int64_t vm = v >= 0 ? v : -v;
	int64_t h = (p->hold > 0 && p->hold_sign == s) ? p->hold : 0;
	int64_t dist = h * vm;
	int64_t stop_q16;
	int64_t stop_um;

	if (vm > 0) {
		int64_t n = (vm - 1) / a;
		int64_t f = vm - n * a;

		/* Velocities vm - a, ..., f, 0: n steps of f plus a (n - 1) n / 2. */
		dist += n * f + a * (n * (n - 1) / 2);
	}
	stop_q16 = p->pos_in_q16 + s * dist;
	/* Rounded away to a whole um, so that the end is exact and the braking never harder. */
	stop_um = s > 0 ? -floor_q16(-stop_q16) : floor_q16(stop_q16);
	p->target_q16 = stop_um * Q16;
	p->stopping = 1;
	p->out.done = (uint8_t)(at_rest(p) && p->pos_in_q16 == p->target_q16);
	return (int32_t)stop_um;
}

void profile_reset(struct profile *p, int32_t pos_um)
{
	p->pos_in_q16 = (int64_t)pos_um * Q16;
	p->target_q16 = p->pos_in_q16;
	p->vel_in_q16 = 0;
	p->stopping = 0;
	choose_window(p, 0);
	p->out.pos_um = pos_um;
	p->out.vel_um_s = 0;
	p->out.acc_um_s2 = 0;
	p->out.done = 1;
}

/* The trapezoid's velocity for this tick [um/tick * 2^16]. Worked in the frame where the target
 * is ahead (r >= 0), so that braking, reversing and cruising are the same code in both
 * directions. In S-curve mode, after an acceleration of one sign none of the other sign is
 * allowed for hold_len ticks: the moving average then never sees +a and -a in one window, which
 * bounds its jerk by a / n_filt. */
static int64_t next_velocity(struct profile *p)
{
	const struct profile_params *prm = &p->prm;
	int64_t r = p->target_q16 - p->pos_in_q16;
	int64_t v = p->vel_in_q16;
	int s = (r > 0 || (r == 0 && v < 0)) ? 1 : -1;
	int64_t rm = s > 0 ? r : -r;
	int64_t vm = s > 0 ? v : -v;
	int hs = p->hold > 0 ? s * p->hold_sign : 0;
	int64_t a = prm->a_q16;
	int64_t lo = hs > 0 ? vm : vm - a;
	int64_t cap = max64(prm->v_max_q16, lo);
	int64_t vb;
	int64_t vn;

	/* Accelerate toward the target if we can still brake after the hold that follows. */
	if (hs >= 0 && !(p->stopping && vm > 0)) {
		int64_t up = min64(vm + a, cap);

		if (up > vm) {
			int64_t v1 = max_velocity(p, rm, prm->hold_len);

			/* A residual below hold_len + 1 units (< 0.004 um) cannot be moved with
			 * the hold: move it without. */
			if (v1 == 0 && vm == 0 && rm > 0)
				v1 = max_velocity(p, rm, 0);
			if (v1 > vm) {
				vn = min64(up, v1);
				return s * vn;
			}
		}
	}
	/* Moving away without leave to turn yet, or not allowed to brake yet: keep going. */
	if (vm <= 0 || hs > 0)
		return s * vm;
	vb = max_velocity(p, rm, 0);
	if (vm <= prm->v_max_q16 && vb >= vm)
		return s * vm;
	/* Brake: the largest feasible velocity, not below what a allows. Below lo only when the
	 * target cannot be reached without passing it: then brake fully, pass, and come back. */
	vn = max64(lo, min64(cap, vb));
	return s * vn;
}

const struct profile_out *profile_update(struct profile *p)
{
	struct profile_params *prm = &p->prm;
	int64_t v_new = 0;
	int64_t acc;
	int64_t dsum;
	int64_t den;
	int64_t hz = prm->tick_hz;

	if (p->pos_in_q16 != p->target_q16 || p->vel_in_q16 != 0)
		v_new = next_velocity(p);
	acc = v_new - p->vel_in_q16;
	if (acc != 0 && prm->hold_len > 0) {
		p->hold = prm->hold_len;
		p->hold_sign = acc > 0 ? 1 : -1;
	} else if (p->hold > 0) {
		p->hold--;
	}
	p->vel_in_q16 = (int32_t)v_new;
	p->pos_in_q16 += v_new;

	/* Moving average: the set point times n_filt is the sum of the last n_filt trapezoid
	 * positions, updated exactly by the sum of the last n_filt velocities. */
	dsum = v_new - p->hist_q16[p->idx];
	p->hist_q16[p->idx] = (int32_t)v_new;
	p->idx = (uint16_t)(p->idx + 1 == prm->n_filt ? 0 : p->idx + 1);
	p->vel_sum_q16 += dsum;
	p->pos_sum_q16 += p->vel_sum_q16;
	if (v_new != 0)
		p->quiet = 0;
	else if (p->quiet < prm->n_filt)
		p->quiet++;

	den = (int64_t)prm->n_filt * Q16;
	if (prm->n_filt == 1) {
		p->out.pos_um = fx_sat32(fx_shr_round64(p->pos_sum_q16, 16));
		p->out.vel_um_s = fx_sat32(fx_shr_round64(p->vel_sum_q16 * hz, 16));
		p->out.acc_um_s2 = fx_sat32(fx_shr_round64(dsum * hz * hz, 16));
	} else {
		p->out.pos_um = fx_sat32(fx_div_round64(p->pos_sum_q16, den));
		p->out.vel_um_s = fx_sat32(fx_div_round64(p->vel_sum_q16 * hz, den));
		p->out.acc_um_s2 = fx_sat32(fx_div_round64(dsum * hz * hz, den));
	}
	/* All the window at rest on the target: the set point is the target exactly (the sums
	 * are exact, so this only states it). */
	p->out.done = (uint8_t)(at_rest(p) && p->pos_in_q16 == p->target_q16);
	return &p->out;
}

int profile_is_done(const struct profile *p)
{
	return p->out.done;
}
