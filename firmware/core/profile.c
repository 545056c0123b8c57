/* One-dimensional motion profile generator (see profile.h and docs/control.md "Profiles").
 *
 * The trapezoid is an online, discrete-time, time-optimal generator: each tick it takes the
 * largest velocity from which it can still brake onto the target exactly. The S-curve is that
 * trapezoid passed through a moving average of n_filt ticks.
 *
 * The tick's arithmetic suits an 8-bit AVR: positions are 48-bit words (fx48), the braking
 * distance of the last step count is carried from tick to tick and moved by additions, and the
 * one division left is 32 by 16 bits. 64-bit arithmetic remains where the limits change, where a
 * step count must be found afresh, and in the S-curve's averaging. */
#include "profile.h"

#include "fixmath.h"

#define Q16 65536
/* Larger than any distance between two positions [um * 2^16]: "far". */
#define FAR48 fx48_make(INT32_MAX, 0xffffu)

static int64_t min64(int64_t a, int64_t b)
{
	return a < b ? a : b;
}

static int64_t max64(int64_t a, int64_t b)
{
	return a > b ? a : b;
}

static int32_t min32(int32_t a, int32_t b)
{
	return a < b ? a : b;
}

static int32_t max32(int32_t a, int32_t b)
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

static struct fx48 fx48_of64(int64_t v)
{
	if (v >= ((int64_t)1 << 47))
		return FAR48;
	return fx48_make((int32_t)floor_q16(v), (uint16_t)((uint64_t)v & 0xffffu));
}

static int64_t int64_of_fx48(struct fx48 v)
{
	return (int64_t)v.hi * Q16 + v.lo;
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

/* a b [unit of a * unit of b] as a 48-bit value, "far" from 2^47 on: four 16 x 16 products. */
static struct fx48 fx48_mul(uint32_t a, uint32_t b)
{
	uint32_t lo, hi = fx_mul_u32_wide(a, b, &lo);

	if (hi >= 0x8000u)
		return FAR48;
	return fx48_make((int32_t)((hi << 16) | fx_hi16(lo)), fx_lo16(lo));
}

/* Distance covered from velocity n*a (included) with h ticks of cruise, then braking by a per
 * tick: g_h(n a) = a n (n + 2h + 1) / 2, exact (n (n + 2h + 1) is always even); saturated to
 * "far". While n (n + 2h + 1) fits 32 bits (n below 2^15, as for any limits in use), 32-bit
 * products; 64 bits otherwise. */
static struct fx48 g_at_step(int32_t a, uint32_t n, uint16_t h)
{
	uint32_t k = n + 2u * (uint32_t)h + 1u;
	uint64_t m, g;

	if (n < 0x8000u && k <= 0xffffu)
		return fx48_mul((uint32_t)a, fx_mul_u16((uint16_t)n, (uint16_t)k) / 2);
	m = (uint64_t)n * k / 2;
	/* a < 2^27: below 2^36 the product fits 63 bits. */
	if (m >= ((uint64_t)1 << 36))
		return FAR48;
	g = (uint64_t)a * m;
	if (g >= ((uint64_t)1 << 47))
		return FAR48;
	return fx48_of64((int64_t)g);
}

static uint8_t slot_of(const struct profile_params *prm, uint16_t h)
{
	return h != 0 && h == prm->hold_len;
}

/* A step count to start from, close to the largest n with g_h(n a) <= r: from the square root of
 * a n^2 + a k n = 2 r (k = 2h + 1). In 32 bits while r is below 2^31 (32 mm), 64 otherwise.
 * Only when the target or the limits jumped; step_count() settles the last units. */
static void hint_seed(const struct profile_params *prm, struct fx48 r, uint16_t h,
		      struct profile_hint *hint)
{
	uint32_t a = (uint32_t)prm->a_q16;
	uint32_t k = 2u * h + 1u;
	uint32_t n, lo, hi;

	if (r.hi >= 0 && r.hi <= 0x7fff) {
		uint32_t rr = (uint32_t)fx48_to32(r);
		uint8_t rb = fx_bit_length32(rr), ab = prm->a_bits;
		/* a >= 16 (1 mm/s^2 at 2 kHz): q < 2^27, k^2 + 8 q < 2^31. */
		uint32_t q = rb >= ab ? fx_udiv_small(rr, a, (uint8_t)(rb - ab + 1)) : 0;

		n = (fx_isqrt64(k * k + 8u * q) - k) / 2;
	} else {
		int64_t q = int64_of_fx48(r) / (int64_t)a;

		n = (uint32_t)(((int64_t)fx_isqrt64((uint64_t)(k * (int64_t)k + 8 * q)) - k) / 2);
	}
	hint->n = n;
	hint->g_q16 = g_at_step(prm->a_q16, n, h);
	hi = fx_mul_u32_wide(a, n, &lo);
	hint->an_q16 = hi != 0 || lo > (uint32_t)INT32_MAX ? INT32_MAX : (int32_t)lo;
	hint->valid = 1;
}

/* The largest n >= 0 with g_h(n a) <= r. Tried first from the last n, moving by one: on a braking
 * ramp n drops by one per tick, and while a small correction is held it stays; each move is two
 * additions, g_h((n + 1) a) - g_h(n a) = a (n + h + 1). A jump of more than a few steps seeds
 * again. */
static uint32_t step_count(const struct profile_params *prm, struct fx48 r, uint16_t h,
			   struct profile_hint *hint)
{
	struct fx48 up; /* a (n + h + 1) */
	uint8_t moves = 0;
	uint8_t seeded = 0;

	if (!hint->valid) {
		hint_seed(prm, r, h, hint);
		seeded = 1;
	}
	for (;;) {
		if (moves > 4 && !seeded) {
			hint_seed(prm, r, h, hint);
			seeded = 1;
		}
		up = h ? fx48_add32(prm->a_hold_q16, hint->an_q16)
		       : fx48_of32(hint->an_q16 + prm->a_q16);
		if (fx48_lt(r, hint->g_q16)) {
			if (hint->n == 0)
				return 0;
			moves++;
			hint->n--;
			hint->an_q16 -= prm->a_q16;
			up = h ? fx48_add32(prm->a_hold_q16, hint->an_q16)
			       : fx48_of32(hint->an_q16 + prm->a_q16);
			hint->g_q16 = fx48_sub(hint->g_q16, up);
			continue;
		}
		if (fx48_lt(r, fx48_add(hint->g_q16, up)))
			return hint->n;
		moves++;
		hint->n++;
		hint->an_q16 += prm->a_q16;
		hint->g_q16 = fx48_add(hint->g_q16, up);
	}
}

/* The largest velocity v >= 0 [um/tick * 2^16] such that moving v this tick, cruising h ticks
 * and then braking by a per tick (the last step a fraction of a) covers at most r.
 * With v = n a + f, 0 <= f < a, that distance is g_h(n a) + (n + h + 1) f: piecewise linear and
 * increasing, so its inverse is exact up to the floor of f, and the remainder is carried to the
 * next tick by the position itself: braking from g_h^-1(r) lands exactly on r.
 * The remainder r - g_h(n a) is below a (n + h + 1), about v_max, so f comes from a 32 by 16-bit
 * division of at most as many steps as a has bits, when both fit (extreme limits: 64 bits). */
static int32_t max_velocity(struct profile *p, struct fx48 r, uint16_t h)
{
	const struct profile_params *prm = &p->prm;
	struct profile_hint *hint = &p->hint[slot_of(prm, h)];
	struct fx48 rem48;
	uint32_t den;
	uint32_t n;

	if (!fx48_lt(r, prm->r_far_q16))
		return prm->v_max_q16 + prm->a_q16;
	n = step_count(prm, r, h, hint);
	rem48 = fx48_sub(r, hint->g_q16);
	den = n + h + 1;
	if (den <= 0xffffu && rem48.hi >= 0 && rem48.hi <= 0x7fff)
		return hint->an_q16 +
		       (int32_t)fx_udiv_small((uint32_t)fx48_to32(rem48), den, prm->a_bits);
	return (int32_t)min64((int64_t)hint->an_q16 + int64_of_fx48(rem48) / den, INT32_MAX);
}

/* Beyond r_far, braking cannot limit the velocity (max_velocity() >= v_max + a for any h up to
 * hold_len), so the far part of a move costs no step count. Also the constants of the outputs,
 * and step counts to start the braking from (where r first drops below r_far). 32-bit
 * arithmetic: it runs when the limits change, in an order's tick. */
static void params_update_far(struct profile *p)
{
	struct profile_params *prm = &p->prm;
	uint32_t a = (uint32_t)prm->a_q16;
	uint32_t v = (uint32_t)prm->v_max_q16 + a; /* below 2^31 */
	uint8_t vb = fx_bit_length32(v - 1), ab = fx_bit_length32(a);
	uint32_t n = vb >= ab ? fx_udiv_small(v - 1, a, (uint8_t)(vb - ab + 1)) : 0;
	uint32_t f = v - n * a;
	uint16_t hz = prm->tick_hz;

	prm->a_bits = ab; /* a changes only before this call */
	prm->r_far_q16 = fx48_add(g_at_step(prm->a_q16, n, prm->hold_len),
				  fx48_mul(n + prm->hold_len + 1u, f));
	prm->a_hold_q16 = fx48_mul(a, (uint32_t)prm->hold_len + 1u);
	prm->hz2 = fx_mul_u16(hz, hz);
	prm->vel_full_um_s = fx_mul_q(prm->v_max_q16, hz, 16);
	prm->acc_full_um_s2 = (int32_t)fx_mul_u32_shr(a, prm->hz2, 16);
	for (uint8_t i = 0; i < 2; i++) {
		uint16_t h = i ? prm->hold_len : 0;

		p->hint[i].n = n;
		p->hint[i].g_q16 = g_at_step(prm->a_q16, n, h);
		p->hint[i].an_q16 = (int32_t)(n * a);
		p->hint[i].valid = 1;
	}
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
	uint32_t v = (uint32_t)lim->v_max_um_s, a = (uint32_t)lim->a_max_um_s2;
	uint16_t hz = prm->tick_hz;

	prm->lim = *lim;
	/* Rounded down, so that the limits are never exceeded: v 2^16 / hz (below 2^31 for the
	 * accepted limits) and a 2^16 / hz^2 (below 2^27). */
	prm->v_max_q16 = (int32_t)fx_udiv_shl16(v, hz);
	prm->a_full_q16 = (int32_t)fx_udiv_shl16(a, fx_mul_u16(hz, hz));
}

/* |target - position| [um * 2^16], for the S-curve's window (64-bit: at rest, S-curve only). */
static int64_t move_length(const struct profile *p)
{
	int64_t d = int64_of_fx48(fx48_sub(p->target_q16, p->pos_in_q16));

	return d >= 0 ? d : -d;
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
	params_update_far(p);
	p->far_ready = 1;
	for (uint16_t i = 0; i < prm->n_filt; i++)
		p->hist_q16[i] = 0;
	p->idx = 0;
	p->vel_sum_q16 = 0;
	p->pos_sum_q16 = int64_of_fx48(p->pos_in_q16) * prm->n_filt;
	p->quiet = prm->n_filt;
	p->hold = 0;
	p->hold_sign = 0;
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
	profile_reset(p, pos_um);
	return 0;
}

int profile_set_limits(struct profile *p, const struct profile_limits *lim)
{
	if (!limits_valid(lim))
		return -1;
	/* The same limits again (an order entering a state re-applies them): nothing changes,
	 * unless an S-curve at rest would choose its window for another distance. */
	if (lim->v_max_um_s == p->prm.lim.v_max_um_s &&
	    lim->a_max_um_s2 == p->prm.lim.a_max_um_s2 &&
	    lim->j_max_um_s3 == p->prm.lim.j_max_um_s3 && p->far_ready &&
	    (window_current(p) || !at_rest(p)))
		return 0;
	params_set_limits(&p->prm, lim);
	p->far_ready = 0; /* new limits: r_far is computed again */
	if (at_rest(p)) {
		choose_window(p, p->prm.lim.j_max_um_s3 ? move_length(p) : 0);
		return 0;
	}
	/* Moving: the window cannot change without a jump, so the jerk in effect stays and the
	 * acceleration is capped to what that window allows. */
	if (p->prm.j_um_s3 == 0)
		p->prm.a_q16 = p->prm.a_full_q16;
	else
		p->prm.a_q16 = (int32_t)max64(1, accel_for_window(&p->prm, p->prm.n_filt));
	params_update_far(p);
	return 0;
}

void profile_set_target(struct profile *p, int32_t target_um)
{
	p->target_q16 = fx48_make(target_um, 0);
	p->stopping = 0;
	if (at_rest(p) && !window_current(p))
		choose_window(p, p->prm.lim.j_max_um_s3 ? move_length(p) : 0);
	p->out.done = (uint8_t)(at_rest(p) && fx48_eq(p->pos_in_q16, p->target_q16));
}

int32_t profile_stop(struct profile *p)
{
	uint32_t a = (uint32_t)p->prm.a_q16;
	int32_t v = p->vel_in_q16;
	int s = v >= 0 ? 1 : -1;
	uint32_t vm = v >= 0 ? (uint32_t)v : (uint32_t)0 - (uint32_t)v;
	uint32_t h = (p->hold > 0 && p->hold_sign == s) ? p->hold : 0;
	struct fx48 dist = fx48_mul(h, vm);
	struct fx48 stop;

	if (vm > 0) {
		uint8_t vb = fx_bit_length32(vm - 1), ab = p->prm.a_bits;
		uint32_t n = vb >= ab ? fx_udiv_small(vm - 1, a, (uint8_t)(vb - ab + 1)) : 0;
		uint32_t f = vm - n * a;

		/* Velocities vm - a, ..., f, 0: n steps of f plus a (n - 1) n / 2. */
		dist = fx48_add(dist, fx48_add(fx48_mul(n, f), g_at_step(p->prm.a_q16, n, 0)));
		dist = fx48_sub(dist, fx48_mul(n, a)); /* g_0(n a) - n a = a n (n - 1) / 2 */
	}
	stop = s > 0 ? fx48_add(p->pos_in_q16, dist) : fx48_sub(p->pos_in_q16, dist);
	/* Rounded away to a whole um, so that the end is exact and the braking never harder. */
	if (s > 0 && stop.lo != 0)
		stop.hi++;
	p->target_q16 = fx48_make(stop.hi, 0);
	p->stopping = 1;
	p->out.done = (uint8_t)(at_rest(p) && fx48_eq(p->pos_in_q16, p->target_q16));
	return stop.hi;
}

void profile_reset(struct profile *p, int32_t pos_um)
{
	p->pos_in_q16 = fx48_make(pos_um, 0);
	p->target_q16 = p->pos_in_q16;
	p->vel_in_q16 = 0;
	p->stopping = 0;
	choose_window(p, 0);
	p->out.pos_um = pos_um;
	p->out.vel_um_s = 0;
	p->out.acc_um_s2 = 0;
	p->out.done = 1;
}

void profile_follow(struct profile *p, int32_t pos_um, int32_t vel_um_s)
{
	/* [um/tick * 2^16], rounded towards zero: the braking never longer than the speed's */
	int64_t v = (int64_t)vel_um_s * Q16 / p->prm.tick_hz;

	p->pos_in_q16 = fx48_make(pos_um, 0);
	p->vel_in_q16 = fx_sat32(v);
	p->hold = 0;
	p->hold_sign = 0;
	p->quiet = p->vel_in_q16 != 0 ? 0 : p->prm.n_filt;
	p->out.pos_um = pos_um;
	p->out.vel_um_s = vel_um_s;
	p->out.acc_um_s2 = 0;
	profile_stop(p);
}

/* s v for a sign s of +-1. */
static int32_t signed_by(int s, int32_t v)
{
	return s > 0 ? v : -v;
}

/* The trapezoid's velocity for this tick [um/tick * 2^16]. Worked in the frame where the target
 * is ahead (r >= 0), so that braking, reversing and cruising are the same code in both
 * directions. In S-curve mode, after an acceleration of one sign none of the other sign is
 * allowed for hold_len ticks: the moving average then never sees +a and -a in one window, which
 * bounds its jerk by a / n_filt. */
static int32_t next_velocity(struct profile *p)
{
	const struct profile_params *prm = &p->prm;
	struct fx48 r = fx48_sub(p->target_q16, p->pos_in_q16);
	int32_t v = p->vel_in_q16;
	int s = (!fx48_is_neg(r) && !(r.hi == 0 && r.lo == 0)) || (r.hi == 0 && r.lo == 0 && v < 0)
			? 1
			: -1;
	struct fx48 rm = s > 0 ? r : fx48_neg(r);
	int32_t vm = s > 0 ? v : -v;
	int hs = p->hold > 0 ? s * p->hold_sign : 0;
	int32_t a = prm->a_q16;
	int32_t lo = hs > 0 ? vm : vm - a;
	int32_t cap = max32(prm->v_max_q16, lo);
	int32_t vb = -1; /* max_velocity(rm, 0), once computed */
	int32_t vn;

	/* Accelerate toward the target if we can still brake after the hold that follows. */
	if (hs >= 0 && !(p->stopping && vm > 0)) {
		int32_t up = min32(vm + a, cap);

		if (up > vm) {
			int32_t v1 = max_velocity(p, rm, prm->hold_len);

			if (prm->hold_len == 0)
				vb = v1;
			/* A residual below hold_len + 1 units (< 0.004 um) cannot be moved with
			 * the hold: move it without. */
			if (v1 == 0 && vm == 0 && (rm.hi | rm.lo) != 0)
				v1 = max_velocity(p, rm, 0);
			if (v1 > vm)
				return signed_by(s, min32(up, v1));
		}
	}
	/* Moving away without leave to turn yet, or not allowed to brake yet: keep going. */
	if (vm <= 0 || hs > 0)
		return signed_by(s, vm);
	if (vb < 0)
		vb = max_velocity(p, rm, 0);
	if (vm <= prm->v_max_q16 && vb >= vm)
		return signed_by(s, vm);
	/* Brake: the largest feasible velocity, not below what a allows. Below lo only when the
	 * target cannot be reached without passing it: then brake fully, pass, and come back. */
	vn = max32(lo, min32(cap, vb));
	return signed_by(s, vn);
}

/* round(v hz / 2^16) [um/s] for |v| < 2^31 [um/tick * 2^16], hz <= 2000: two 16 x 16 products. */
static int32_t um_per_s(int32_t v, uint16_t hz)
{
	uint32_t m = v >= 0 ? (uint32_t)v : (uint32_t)0 - (uint32_t)v;
	uint32_t r = fx_mul_u16(fx_hi16(m), hz) + fx_hi16(fx_mul_u16(fx_lo16(m), hz) + 0x8000u);

	return v >= 0 ? (int32_t)r : -(int32_t)r;
}

const struct profile_out *profile_update(struct profile *p)
{
	struct profile_params *prm = &p->prm;
	int32_t v_new = 0;
	int32_t acc;

	if (!fx48_eq(p->pos_in_q16, p->target_q16) || p->vel_in_q16 != 0)
		v_new = next_velocity(p);
	acc = v_new - p->vel_in_q16;
	if (acc != 0 && prm->hold_len > 0) {
		p->hold = prm->hold_len;
		p->hold_sign = acc > 0 ? 1 : -1;
	} else if (p->hold > 0) {
		p->hold--;
	}
	p->vel_in_q16 = v_new;
	p->pos_in_q16 = fx48_add32(p->pos_in_q16, v_new);
	if (v_new != 0)
		p->quiet = 0;
	else if (p->quiet < prm->n_filt)
		p->quiet++;

	if (prm->n_filt == 1) {
		/* The set point is the trapezoid itself. The velocity and acceleration are v hz and
		 * acc hz^2: cruising, at rest or on a ramp, the precomputed ones. */
		p->out.pos_um = fx48_round(p->pos_in_q16);
		p->out.vel_um_s = v_new == prm->v_max_q16    ? prm->vel_full_um_s
				  : v_new == -prm->v_max_q16 ? -prm->vel_full_um_s
							     : um_per_s(v_new, prm->tick_hz);
		if (acc == 0 || acc == prm->a_q16 || acc == -prm->a_q16)
			p->out.acc_um_s2 = acc == 0  ? 0
					   : acc > 0 ? prm->acc_full_um_s2
						     : -prm->acc_full_um_s2;
		else
			p->out.acc_um_s2 =
				acc >= 0 ? (int32_t)fx_mul_u32_shr((uint32_t)acc, prm->hz2, 16)
					 : -(int32_t)fx_mul_u32_shr((uint32_t)-acc, prm->hz2, 16);
	} else {
		/* Moving average: the set point times n_filt is the sum of the last n_filt
		 * trapezoid positions, updated exactly by the sum of the last n_filt velocities. */
		int64_t hz = prm->tick_hz;
		int64_t den = (int64_t)prm->n_filt * Q16;
		int64_t dsum = (int64_t)v_new - p->hist_q16[p->idx];

		p->hist_q16[p->idx] = v_new;
		p->idx = (uint16_t)(p->idx + 1 == prm->n_filt ? 0 : p->idx + 1);
		p->vel_sum_q16 += dsum;
		p->pos_sum_q16 += p->vel_sum_q16;
		p->out.pos_um = fx_sat32(fx_div_round64(p->pos_sum_q16, den));
		p->out.vel_um_s = fx_sat32(fx_div_round64(p->vel_sum_q16 * hz, den));
		p->out.acc_um_s2 = fx_sat32(fx_div_round64(dsum * hz * hz, den));
	}
	/* All the window at rest on the target: the set point is the target exactly (the sums
	 * are exact, so this only states it). */
	p->out.done = (uint8_t)(at_rest(p) && fx48_eq(p->pos_in_q16, p->target_q16));
	return &p->out;
}

int profile_is_done(const struct profile *p)
{
	return p->out.done;
}
