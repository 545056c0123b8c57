/* The error radius of the odometry's pose (see uncertainty.h and docs/odometry.md). */
#include "uncertainty.h"

#include <errno.h>

#include "fixmath.h"

/* Caps on the standard deviations: 2^18 um (262 mm, beyond any radius reported) and 2^18
 * heading units (0.25 rad). Past them the radius reads 255 and the covariance is frozen, which
 * keeps every product below in range. */
#define SIGMA_CAP ((int64_t)1 << 18)
#define VAR_CAP_Q16 (SIGMA_CAP * SIGMA_CAP * 65536)
#define SYS_CAP ((int64_t)1 << 62)
/* 2^32 / pi, 2 pi * 2^20, 2^32 / 1000. */
#define INV_PI_Q32 1367130551LL
#define TWO_PI_Q20 6588397LL
#define INV_1000_Q32 4294968u

/* a * b / 2^n from the 128-bit product, rounded to nearest (up = 0) or away from zero (up = 1),
 * saturated to int64. The covariance terms multiply values whose product may pass 2^63 although
 * the result does not. */
static int64_t mul_shr_any(int64_t a, int64_t b, uint8_t n, int up)
{
	const uint64_t m32 = 0xffffffffu;
	int neg = (a < 0) != (b < 0);
	uint64_t ua = a >= 0 ? (uint64_t)a : (uint64_t)0 - (uint64_t)a;
	uint64_t ub = b >= 0 ? (uint64_t)b : (uint64_t)0 - (uint64_t)b;
	uint64_t lo, hi, res;

	if (((ua | ub) >> 32) == 0) {
		/* Both below 2^32: the product fits in 64 bits (one multiplication, not four). */
		lo = ua * ub;
		hi = 0;
	} else {
		uint64_t ll = (ua & m32) * (ub & m32);
		uint64_t lh = (ua & m32) * (ub >> 32);
		uint64_t hl = (ua >> 32) * (ub & m32);
		uint64_t hh = (ua >> 32) * (ub >> 32);
		uint64_t mid = (ll >> 32) + (lh & m32) + (hl & m32);

		lo = (ll & m32) | (mid << 32);
		hi = hh + (lh >> 32) + (hl >> 32) + (mid >> 32);
	}

	if (n > 0) {
		uint64_t bias = up ? ((uint64_t)1 << n) - 1 : (uint64_t)1 << (n - 1);

		lo += bias;
		if (lo < bias)
			hi++;
		res = (lo >> n) | (hi << (64 - n));
		hi >>= n;
	} else {
		res = lo;
	}
	if (hi != 0 || res > (uint64_t)INT64_MAX)
		return neg ? -INT64_MAX : INT64_MAX;
	return neg ? -(int64_t)res : (int64_t)res;
}

static int64_t mul_shr64(int64_t a, int64_t b, uint8_t n)
{
	return mul_shr_any(a, b, n, 0);
}

/* num / den rounded up, num >= 0, den > 0: the systematic coefficients are bounds. */
static int64_t div_up(int64_t num, int64_t den)
{
	return (num + den - 1) / den;
}

static int64_t sat_add(int64_t a, int64_t b)
{
	int64_t s;

	if (b > 0 && a > SYS_CAP - b)
		return SYS_CAP;
	if (b < 0 && a < -SYS_CAP - b)
		return -SYS_CAP;
	s = a + b;
	return s;
}

static uint64_t isqrt_up(uint64_t v)
{
	uint64_t r = fx_isqrt64(v);

	return r * r < v ? r + 1 : r;
}

static uint64_t magnitude(int64_t v)
{
	return v >= 0 ? (uint64_t)v : (uint64_t)0 - (uint64_t)v;
}

/* An upper bound of |(x, y)|: halving (rounded up) until the squares fit keeps it a bound. */
static uint64_t hypot_up(int64_t x, int64_t y)
{
	uint64_t ux = magnitude(x), uy = magnitude(y);
	uint8_t j = 0;

	while (ux >= ((uint64_t)1 << 31) || uy >= ((uint64_t)1 << 31)) {
		ux = (ux + 1) >> 1;
		uy = (uy + 1) >> 1;
		j++;
	}
	return isqrt_up(ux * ux + uy * uy) << j;
}

/* sqrt of the largest eigenvalue of the xy block [um], rounded up:
 * lambda = (a + c + |(a - c, 2 b)|) / 2, with a, c, |b| <= 2^36 um^2 under the caps. */
static uint64_t sigma_max_um(const struct uncertainty *u)
{
	int64_t a = (u->xx + 0xffff) / 65536;
	int64_t c = (u->yy + 0xffff) / 65536;
	int64_t b = (int64_t)((magnitude(u->xy) + 0xffffu) >> 16);
	uint64_t lambda2;

	/* Rounding may leave a variance a hair below zero. */
	if (a < 0)
		a = 0;
	if (c < 0)
		c = 0;
	lambda2 = (uint64_t)a + (uint64_t)c + hypot_up(a - c, 2 * b);
	return isqrt_up((lambda2 + 1) >> 1);
}

static void refresh_radius(struct uncertainty *u)
{
	uint64_t r_um;

	if (u->saturated) {
		u->radius_mm = UNCERTAINTY_RADIUS_MAX_MM;
		return;
	}
	/* Systematic worst case (first order in the parameter errors), rounded up. */
	r_um = (uint64_t)mul_shr_any((int64_t)hypot_up(u->w1[0], u->w1[1]), u->ratio_coef_q60, 60,
				     1) +
	       (uint64_t)mul_shr_any((int64_t)hypot_up(u->w2[0], u->w2[1]), u->track_coef_q60, 60,
				     1) +
	       (uint64_t)mul_shr_any((int64_t)hypot_up(u->d[0], u->d[1]), u->scale_coef_q60, 60, 1);
	r_um += (sigma_max_um(u) * u->cfg.k_q8 + 255) >> 8;
	if (r_um >= (uint64_t)UNCERTAINTY_RADIUS_MAX_MM * 1000) {
		u->radius_mm = UNCERTAINTY_RADIUS_MAX_MM;
		return;
	}
	/* ceil(r / 1000) with a reciprocal, exact below 2^19. */
	u->radius_mm = (uint8_t)(((r_um + 999) * INV_1000_Q32) >> 32);
}

/* sigma^2 [unit^2 * 2^16] of a bound at the configured probability, sigma = bound / k. */
static int64_t var_of_bound(struct uncertainty *u, uint64_t bound)
{
	uint64_t sigma = (bound * 256) / u->cfg.k_q8;

	if (sigma > (uint64_t)SIGMA_CAP) {
		u->saturated = 1;
		return VAR_CAP_Q16;
	}
	return (int64_t)(sigma * sigma) * 65536;
}

static int config_valid(const struct uncertainty_config *cfg)
{
	return cfg->noise_left_mm2_per_m_q16 <= UNCERTAINTY_NOISE_Q16_MAX &&
	       cfg->noise_right_mm2_per_m_q16 <= UNCERTAINTY_NOISE_Q16_MAX &&
	       cfg->track_um >= ((uint32_t)1 << 14) && cfg->track_um <= ((uint32_t)1 << 21) &&
	       cfg->ratio_error_ppm <= 1000000u && cfg->track_error_um <= cfg->track_um &&
	       cfg->scale_error_ppm <= 1000000u && cfg->k_q8 >= 1 && cfg->batch_ticks >= 1 &&
	       cfg->batch_ticks <= UNCERTAINTY_BATCH_TICKS_MAX;
}

/* Reciprocals computed once so that the batch update multiplies only. */
static void derive(struct uncertainty *u)
{
	int64_t b = u->cfg.track_um;
	int64_t ratio = div_up((int64_t)u->cfg.ratio_error_ppm << 40, 1000000);
	int64_t track = div_up((int64_t)u->cfg.track_error_um << 30, b);

	u->inv_track_q44 = fx_div_round64((int64_t)1 << 44, b);
	u->ratio_coef_q60 = div_up(ratio << 20, b);
	u->track_coef_q60 = div_up(track << 30, b);
	u->scale_coef_q60 = div_up((int64_t)u->cfg.scale_error_ppm << 40, 1000000) << 20;
}

static void clear_batch(struct uncertainty *u)
{
	u->batch_left_q16 = 0;
	u->batch_right_q16 = 0;
	u->batch_abs_left_q16 = 0;
	u->batch_abs_right_q16 = 0;
	u->batch_n = 0;
}

int uncertainty_init(struct uncertainty *u, const struct uncertainty_config *cfg)
{
	if (!config_valid(cfg))
		return -EDOM;
	u->cfg = *cfg;
	derive(u);
	uncertainty_reset(u, 0, 0);
	return 0;
}

int uncertainty_set_config(struct uncertainty *u, const struct uncertainty_config *cfg)
{
	if (!config_valid(cfg))
		return -EDOM;
	u->cfg = *cfg;
	derive(u);
	refresh_radius(u);
	return 0;
}

void uncertainty_reset(struct uncertainty *u, uint32_t radius_um, uint32_t heading_turn32)
{
	u->saturated = 0;
	u->xx = var_of_bound(u, radius_um);
	u->yy = u->xx;
	u->xy = 0;
	u->xt = 0;
	u->yt = 0;
	u->tt = var_of_bound(u, ((uint64_t)heading_turn32 * TWO_PI_Q20 + 0xffffffffu) >> 32);
	u->travel_q17 = 0;
	u->turn_q16 = 0;
	u->w1[0] = u->w1[1] = 0;
	u->w2[0] = u->w2[1] = 0;
	u->d[0] = u->d[1] = 0;
	clear_batch(u);
	refresh_radius(u);
}

void uncertainty_reset_axis(struct uncertainty *u, enum uncertainty_axis axis, uint32_t bound_um)
{
	int i = axis == UNCERTAINTY_AXIS_X ? 0 : 1;
	int64_t v = var_of_bound(u, bound_um);

	/* Dropping the correlations leaves the other coordinate's variance as it was, larger than
	 * its variance given this one: conservative. */
	if (i == 0) {
		u->xx = v;
		u->xt = 0;
	} else {
		u->yy = v;
		u->yt = 0;
	}
	u->xy = 0;
	u->w1[i] = 0;
	u->w2[i] = 0;
	u->d[i] = 0;
	refresh_radius(u);
}

void uncertainty_reset_heading(struct uncertainty *u, uint32_t bound_turn32)
{
	u->tt = var_of_bound(u, ((uint64_t)bound_turn32 * TWO_PI_Q20 + 0xffffffffu) >> 32);
	u->xt = 0;
	u->yt = 0;
	u->travel_q17 = 0;
	u->turn_q16 = 0;
	refresh_radius(u);
}

/* a * b / 2^30 for a unit vector component b [2^-30]. */
static int64_t mul_unit(int64_t a, int32_t b)
{
	return mul_shr64(a, b, 30);
}

void uncertainty_reset_along(struct uncertainty *u, uint32_t direction_turn32, uint32_t bound_um)
{
	int32_t s, c;
	int64_t r = var_of_bound(u, bound_um);
	int64_t lat, lt, cs;
	int64_t *vec[3] = {u->w1, u->w2, u->d};

	fx_sincos(direction_turn32, &s, &c);
	/* Lateral unit vector l = (-s, c): the lateral variance l^T S l and the lateral-heading
	 * covariance. The along ones are replaced; dropping the along-lateral correlation leaves
	 * the lateral variance larger than it would be given the measurement: conservative. */
	lat = mul_unit(mul_unit(u->xx, s), s) - 2 * mul_unit(mul_unit(u->xy, c), s) +
	      mul_unit(mul_unit(u->yy, c), c);
	if (lat < 0)
		lat = 0;
	lt = -mul_unit(u->xt, s) + mul_unit(u->yt, c);
	cs = mul_shr64(c, s, 30);
	u->xx = mul_unit(mul_unit(r, c), c) + mul_unit(mul_unit(lat, s), s);
	u->yy = mul_unit(mul_unit(r, s), s) + mul_unit(mul_unit(lat, c), c);
	u->xy = mul_unit(r - lat, (int32_t)cs);
	u->xt = -mul_unit(lt, s);
	u->yt = mul_unit(lt, c);
	/* Rounding may leave a hair below the exact values: the radius rounds up anyway. */
	for (uint8_t i = 0; i < 3; i++) {
		int64_t *v = vec[i];
		int64_t l = -mul_unit(v[0], s) + mul_unit(v[1], c);

		v[0] = -mul_unit(l, s);
		v[1] = mul_unit(l, c);
	}
	refresh_radius(u);
}

uint32_t uncertainty_get_heading_bound_turn32(const struct uncertainty *u)
{
	/* sigma [rad * 2^20] = sqrt(tt / 2^16); bound = k sigma; turn32 = rad * 2^32 / (2 pi). */
	uint64_t sigma = isqrt_up((uint64_t)(u->tt > 0 ? u->tt : 0) >> 16);
	uint64_t bound = (sigma * u->cfg.k_q8 + 255) >> 8; /* [rad * 2^20] */

	if (u->saturated || bound >= ((uint64_t)1 << 22))
		return (uint32_t)1 << 31;
	/* 2^12 / (2 pi) = 651.9 per rad * 2^20 -> turn * 2^32: 652 rounds up. */
	return (uint32_t)(bound * 652);
}

/* One covariance step over the batch, taken as one arc: Sigma' = Fp Sigma Fp^T + Fd Q Fd^T with
 * Q = diag(kR |dsR|, kL |dsL|) (Chong & Kleeman 1997, eq. for the circular-arc model; Kelly
 * 2000, section 3). h = 1/(2b), u = (dx, dy) h, g = 2^20 / b heading units per um. */
static void propagate(struct uncertainty *u, uint32_t heading_end_turn32)
{
	int64_t both = u->batch_left_q16 + u->batch_right_q16;
	int64_t diff = u->batch_right_q16 - u->batch_left_q16;
	int64_t dtheta_q30 = mul_shr64(diff, u->inv_track_q44, 30); /* [rad * 2^30] */
	uint32_t mid =
		heading_end_turn32 - (uint32_t)fx_sat32(mul_shr64(dtheta_q30, INV_PI_Q32, 32));
	int32_t s, c;
	int64_t ds_um = fx_shr_round64(both, 17);
	int64_t dx, dy, ux, uy, g, qr, ql, qp, qm, mx, my, xt, yt, t, s_mid, r_mid;

	fx_sincos(mid, &s, &c);
	dx = fx_shr_round64(ds_um * c, 30);
	dy = fx_shr_round64(ds_um * s, 30);

	/* Systematic: first-order position error per unit parameter error, integrated along the
	 * path with the heading error at the batch's midpoint. */
	s_mid = fx_shr_round64(2 * u->travel_q17 + both, 18);
	r_mid = fx_shr_round64(2 * u->turn_q16 + diff, 17);
	u->w1[0] = sat_add(u->w1[0], -s_mid * dy);
	u->w1[1] = sat_add(u->w1[1], s_mid * dx);
	u->w2[0] = sat_add(u->w2[0], -r_mid * dy);
	u->w2[1] = sat_add(u->w2[1], r_mid * dx);
	u->d[0] = sat_add(u->d[0], dx);
	u->d[1] = sat_add(u->d[1], dy);
	u->travel_q17 = sat_add(u->travel_q17, both);
	u->turn_q16 = sat_add(u->turn_q16, diff);

	if (u->saturated)
		return;

	/* Fp Sigma Fp^T, with Fp = [1 0 -dy/2^20; 0 1 dx/2^20; 0 0 1]. */
	t = u->tt;
	xt = u->xt;
	yt = u->yt;
	mx = mul_shr64(dx, t, 20);
	my = mul_shr64(dy, t, 20);
	u->xx += -2 * mul_shr64(dy, xt, 20) + mul_shr64(dy, my, 20);
	u->xy += mul_shr64(dx, xt, 20) - mul_shr64(dy, yt, 20) - mul_shr64(dx, my, 20);
	u->yy += 2 * mul_shr64(dx, yt, 20) + mul_shr64(dx, mx, 20);
	u->xt = xt - my;
	u->yt = yt + mx;

	/* Fd Q Fd^T with the columns (c/2 - uy, s/2 + ux, g) and (c/2 + uy, s/2 - ux, -g). */
	qr = mul_shr64(u->cfg.noise_right_mm2_per_m_q16, u->batch_abs_right_q16, 16);
	ql = mul_shr64(u->cfg.noise_left_mm2_per_m_q16, u->batch_abs_left_q16, 16);
	qp = qr + ql;
	qm = qr - ql;
	ux = mul_shr64(dx, u->inv_track_q44, 15); /* [2^-30] */
	uy = mul_shr64(dy, u->inv_track_q44, 15);
	g = u->inv_track_q44 * 64; /* [heading units per um * 2^30] */
	u->xx += mul_shr64(qp, fx_shr_round64((int64_t)c * c, 32) + mul_shr64(uy, uy, 30), 30) -
		 mul_shr64(qm, mul_shr64(c, uy, 30), 30);
	u->xy += mul_shr64(qp, fx_shr_round64((int64_t)c * s, 32) - mul_shr64(ux, uy, 30), 30) +
		 mul_shr64(qm, mul_shr64(c, ux, 30) - mul_shr64(s, uy, 30), 31);
	u->yy += mul_shr64(qp, fx_shr_round64((int64_t)s * s, 32) + mul_shr64(ux, ux, 30), 30) +
		 mul_shr64(qm, mul_shr64(s, ux, 30), 30);
	u->xt += mul_shr64(g, mul_shr64(qm, c, 31) - mul_shr64(qp, uy, 30), 30);
	u->yt += mul_shr64(g, mul_shr64(qm, s, 31) + mul_shr64(qp, ux, 30), 30);
	u->tt += mul_shr64(mul_shr64(qp, g, 30), g, 30);

	if (u->xx > VAR_CAP_Q16 || u->yy > VAR_CAP_Q16 || u->tt > VAR_CAP_Q16)
		u->saturated = 1;
}

void uncertainty_update(struct uncertainty *u, int32_t left_q16, int32_t right_q16,
			uint32_t heading_turn32)
{
	u->batch_left_q16 += left_q16;
	u->batch_right_q16 += right_q16;
	u->batch_abs_left_q16 += left_q16 >= 0 ? left_q16 : -(int64_t)left_q16;
	u->batch_abs_right_q16 += right_q16 >= 0 ? right_q16 : -(int64_t)right_q16;
	u->batch_n++;
	if (u->batch_n < u->cfg.batch_ticks && u->batch_abs_left_q16 + u->batch_abs_right_q16 <
						       ((int64_t)UNCERTAINTY_BATCH_PATH_UM << 16))
		return;
	if (u->batch_abs_left_q16 == 0 && u->batch_abs_right_q16 == 0) {
		/* A batch without travel propagates nothing (the steps and the noise are zero,
		 * Fp is the identity) and the radius is already that of the current state. */
		clear_batch(u);
		return;
	}
	propagate(u, heading_turn32);
	clear_batch(u);
	refresh_radius(u);
}

uint8_t uncertainty_get_radius_mm(const struct uncertainty *u)
{
	return u->radius_mm;
}
