/* The error radius of the odometry's pose (see uncertainty.h and docs/odometry.md).
 *
 * Everything is 32-bit, in units coarse enough for the caps: x and y in 4 um, the heading in
 * 2^-16 rad; the systematic integrals are exact 48-bit sums. The products are 32 x 16 bits (two
 * of the 16 x 16 multiplications an AVR does fast). A batch is propagated in UNCERTAINTY_STAGES
 * short stages, one per tick, so that no tick pays for a whole batch. The propagation rounds to
 * nearest; every step from the variances to the radius rounds up, so that it stays a bound. */
#include "uncertainty.h"

#include <errno.h>

#include "fixmath.h"

#define VAR_CAP ((int32_t)1 << 30) /* xx, yy: sigma 2^15 units, 131 mm */
#define TT_CAP ((int32_t)1 << 28)  /* tt: sigma 2^14 units, 0.25 rad */
#define PATH_HALF_Q8 ((uint32_t)UNCERTAINTY_BATCH_PATH_UM << 7)
/* A wheel's travel in a batch stays within the stages' 16-bit lengths [um * 2^8]: 32.7 mm. */
#define WHEEL_MAX_Q8 ((uint32_t)0x7fff << 8)
/* 2 pi * 2^16 [2^-16 rad per turn], 2^32 / (2 pi) [turn * 2^32 per rad]. */
#define TWO_PI_Q16 411775u
#define TURN32_PER_RAD 683565276u

enum stage {
	STAGE_IDLE,
	/* The batch as one arc: direction, displacement, noise. */
	STAGE_DIRECTION,
	STAGE_DISPLACEMENT,
	STAGE_NOISE,
	/* The systematic integrals. */
	STAGE_W1,
	STAGE_W2,
	/* Fp Sigma Fp^T. */
	STAGE_FP_XX,
	STAGE_FP_XY,
	STAGE_FP_YY,
	/* Fd Q Fd^T. */
	STAGE_UV,
	STAGE_Q_XX,
	STAGE_Q_YY,
	STAGE_Q_XY,
	STAGE_Q_XT,
	STAGE_Q_YT,
	STAGE_Q_TT,
	/* The radius. */
	STAGE_EIGEN,
	STAGE_SIGMA,
	STAGE_SYS_RATIO,
	STAGE_SYS_TRACK,
	STAGE_RADIUS,
	/* A position fix's fusion (uncertainty_fuse_step()): held by the stages above. */
	STAGE_FUSE_X,
	STAGE_FUSE_Y,
	STAGE_FUSE_HEADING,
	STAGE_FUSE_END,
};

typedef char uncertainty_stages_counted[(STAGE_RADIUS == UNCERTAINTY_STAGES) ? 1 : -1];

/* round(v / 2^15), ties away from zero. */
static int32_t q15_of(int32_t v)
{
	return fx_shr_round(v, 15);
}

/* a + b for the systematic integrals, saturating at +-INT32_MAX. */
static int32_t sat_add(int32_t a, int32_t b)
{
	if (b > 0 && a > INT32_MAX - b)
		return INT32_MAX;
	if (b < 0 && a < -INT32_MAX - b)
		return -INT32_MAX;
	return a + b;
}

/* w += a b exactly (|b| <= 2^15): a 48-bit sum kept as hi 2^16 + lo, hi saturating. */
static void add48(struct uncertainty_sum48 *w, int32_t a, int32_t b)
{
	uint32_t ua = fx_mag32(a);
	uint16_t ub = (uint16_t)fx_mag32(b);
	uint32_t lo = fx_mul_u16(fx_lo16(ua), ub);
	int32_t hi = (int32_t)(fx_mul_u16(fx_hi16(ua), ub) + fx_hi16(lo)); /* below 2^31 */
	uint32_t t;

	if ((a < 0) != (b < 0)) {
		t = 0x10000u + w->lo - fx_lo16(lo);
		w->hi = sat_add(w->hi, -(hi + 1 - (int32_t)fx_hi16(t)));
	} else {
		t = (uint32_t)w->lo + fx_lo16(lo);
		w->hi = sat_add(w->hi, hi + (int32_t)fx_hi16(t));
	}
	w->lo = fx_lo16(t);
}

/* A 48-bit sum as int64_t and back (a recalibration's projection, not the tick). */
static int64_t int64_of48(const struct uncertainty_sum48 *w)
{
	return (int64_t)w->hi * 65536 + w->lo;
}

static void set48(struct uncertainty_sum48 *w, int64_t v)
{
	int64_t hi = v >= 0 ? v / 65536 : -((-v + 65535) / 65536);

	w->hi = fx_sat32(hi);
	w->lo = (uint16_t)(v - hi * 65536);
}

/* w = its part along l = (-s, c): (l . w) l, with the sine and cosine to 2^-15 (exact at the
 * four cardinal directions), so that the products of the 48-bit sums fit 64 bits. */
static void lateral48(struct uncertainty_sum48 w[2], int32_t s, int32_t c)
{
	int64_t s15 = fx_shr_round64(s, 15), c15 = fx_shr_round64(c, 15);
	int64_t l = fx_shr_round64(-s15 * int64_of48(&w[0]) + c15 * int64_of48(&w[1]), 15);

	set48(&w[0], fx_shr_round64(-l * s15, 15));
	set48(&w[1], fx_shr_round64(l * c15, 15));
}

/* |w| / 2^16, rounded up. */
static uint32_t mag48(const struct uncertainty_sum48 *w)
{
	if (w->hi < 0)
		return fx_mag32(w->hi);
	return (uint32_t)w->hi + (w->lo != 0);
}

/* An upper bound of |(x, y)| for magnitudes x, y: both halved (rounded up) until their squares
 * add up in 32 bits, which keeps the result within 2^-14 of the true length, above it.
 * The halvings are not made one by one (40 cycles each on an AVR, up to 18 of them): j of them
 * round x up to ceil(x / 2^j) (nested ceilings are one), (x - 1) / 2^j + 1 for x >= 1. The
 * loop stops at the first j with both below 2^15: for a larger one of L bits, L - 15 (none
 * below 16 bits), or one more, when the first leaves 2^15 itself. */
static uint32_t hypot_up(uint32_t ux, uint32_t uy)
{
	uint8_t j = fx_bit_length32(ux | uy); /* the larger one's */

	if (uy == 0)
		return ux;
	if (ux == 0)
		return uy;
	if (j <= 15)
		return fx_isqrt32_up(fx_mul_u16((uint16_t)ux, (uint16_t)ux) +
				     fx_mul_u16((uint16_t)uy, (uint16_t)uy));
	j = (uint8_t)(j - 15u);
	ux = fx_shr_u32(ux - 1u, j) + 1u; /* up to 2^15 */
	uy = fx_shr_u32(uy - 1u, j) + 1u;
	if (ux > 0x7fffu || uy > 0x7fffu) {
		ux = ((ux - 1u) >> 1) + 1u;
		uy = ((uy - 1u) >> 1) + 1u;
		j++;
	}
	return fx_shl_u32(fx_isqrt32_up(fx_mul_u16((uint16_t)ux, (uint16_t)ux) +
					fx_mul_u16((uint16_t)uy, (uint16_t)uy)),
			  j);
}

/* ceil(v * c / 2^32). */
static uint32_t mul_coef_up(uint32_t v, uint32_t c)
{
	uint32_t lo, hi = fx_mul_u32_wide(v, c, &lo);

	return lo != 0 ? hi + 1 : hi;
}

/* ceil(num / den), 64-bit, configuration time. */
static uint64_t div_up(uint64_t num, uint64_t den)
{
	return (num + den - 1) / den;
}

static uint32_t coef_q32(uint64_t c)
{
	return c > 0xffffffffu ? 0xffffffffu : (uint32_t)c;
}

static int config_valid(const struct uncertainty_config *cfg, uint16_t rate_hz)
{
	return cfg->noise_left_mm2_per_m_q16 <= UNCERTAINTY_NOISE_Q16_MAX &&
	       cfg->noise_right_mm2_per_m_q16 <= UNCERTAINTY_NOISE_Q16_MAX && cfg->k_q8 >= 1 &&
	       cfg->batch_ms >= 1 && rate_hz >= 1 &&
	       fx_ticks_of_ms(cfg->batch_ms, rate_hz) <= UNCERTAINTY_BATCH_TICKS_MAX;
}

static int model_valid(const struct uncertainty_model *m)
{
	return m->track_um >= ((uint32_t)1 << 14) && m->track_um <= ((uint32_t)1 << 21) &&
	       m->ratio_error_ppm <= 1000000u && m->track_error_um <= m->track_um &&
	       m->scale_error_ppm <= 1000000u;
}

/* Constants of the configuration, so that the stages multiply only. The systematic
 * coefficients are rounded up (above 1 um per unit they saturate: a larger bound). */
static void derive(struct uncertainty *u)
{
	uint64_t b = u->model.track_um;
	uint64_t g = ((uint64_t)1 << 30) / b;

	u->batch_ticks = (uint8_t)fx_ticks_of_ms(u->cfg.batch_ms, u->rate_hz);
	u->turn_per_um = (uint16_t)((((uint64_t)TURN32_PER_RAD << 16) / b + 0x8000u) >> 16);
	u->inv_track_q28 = (uint16_t)(((uint64_t)1 << 28) / b);
	u->g_q12 = (uint16_t)(g > 0xffffu ? 0xffffu : g);
	/* |w1|, |w2| in 2^14 um^2: ratio / b and track / b^2 per unit, in [um * 2^-32]. */
	u->ratio_coef_q32 = coef_q32(
		div_up(div_up((uint64_t)u->model.ratio_error_ppm << 32, 1000000) << 14, b));
	u->track_coef_q32 =
		coef_q32(div_up(div_up((uint64_t)u->model.track_error_um << 31, b) << 15, b));
	u->scale_coef_q32 = coef_q32(div_up((uint64_t)u->model.scale_error_ppm << 32, 1000000));
}

static void clear_batch(struct uncertainty_batch *b)
{
	b->left_q8 = 0;
	b->right_q8 = 0;
	b->abs_left_q8 = 0;
	b->abs_right_q8 = 0;
	b->ticks = 0;
}

/* sigma^2 of a bound at the configured probability, sigma = bound / k, in the covariance's
 * unit: for a position (pos = 1) sigma rounded down to the um (a bound of 2 mm reads 2 mm),
 * the variance in [(4 um)^2]; for a heading sigma rounded up to the unit of 2^-16 rad (which is
 * coarse: the bound read back must not be below the one set). */
static int32_t var_of_bound(struct uncertainty *u, uint32_t bound, uint8_t pos, int32_t cap)
{
	uint64_t sigma = (((uint64_t)bound << 8) + (pos ? 0 : u->cfg.k_q8 - 1u)) / u->cfg.k_q8;
	uint64_t var =
		pos ? (sigma * sigma) / (UNCERTAINTY_POS_UM * UNCERTAINTY_POS_UM) : sigma * sigma;

	if (var > (uint64_t)cap) {
		u->saturated = 1;
		return cap;
	}
	return (int32_t)var;
}

/* A heading bound [turn * 2^32] in [2^-16 rad], rounded up. */
static uint32_t heading_units(uint32_t bound_turn32)
{
	return (uint32_t)(((uint64_t)bound_turn32 * TWO_PI_Q16 + 0xffffffffu) >> 32);
}

static void run_stages(struct uncertainty *u, uint8_t n);

/* What changes the covariance first finishes the batch in flight, and abandons a fusion in
 * flight (nothing of it is committed before its end: uncertainty_fuse_step()). */
static void finish_stages(struct uncertainty *u)
{
	if (CONFIG_FIX && u->stage > STAGE_RADIUS)
		u->stage = STAGE_EIGEN;
	run_stages(u, UINT8_MAX);
}

/* After a reset the radius is refreshed at once: the batch in flight is finished, then the
 * last stages run, all in this call. A recalibration's tick pays for up to a whole batch (a few
 * per match), so that the master reading POSITION when the order ends sees the new radius. */
static void request_radius(struct uncertainty *u)
{
	finish_stages(u);
	u->stage = STAGE_EIGEN;
	run_stages(u, UINT8_MAX);
}

int uncertainty_init(struct uncertainty *u, const struct uncertainty_config *cfg, uint16_t rate_hz,
		     const struct uncertainty_model *model)
{
	if (!config_valid(cfg, rate_hz) || !model_valid(model))
		return -EDOM;
	u->cfg = *cfg;
	u->model = *model;
	u->rate_hz = rate_hz;
	derive(u);
	uncertainty_reset(u, 0, 0);
	return 0;
}

static void start_batch(struct uncertainty *u);

/* a + b, saturating. */
static uint32_t add_sat_u32(uint32_t a, uint32_t b)
{
	return a + b < a ? 0xffffffffu : a + b;
}

/* The systematic heading drift's bound [2^-16 rad], rounded up: ratio S / b + track R / b^2
 * (docs/odometry.md), S = travel2 / 2. In 64 bits: it runs at a recalibration or a change of
 * configuration, not every tick. */
static uint64_t sys_heading_units(const struct uncertainty *u)
{
	uint64_t b = u->model.track_um;
	uint64_t s = fx_mag32(u->travel2_um), r = fx_mag32(u->turn_um);
	/* ratio [1e-6] * S [um] / b [um] * 2^16, with S = travel2 / 2 */
	uint64_t h1 = div_up(u->model.ratio_error_ppm * s << 15, 1000000u * b);
	uint64_t h2 = div_up(div_up(u->model.track_error_um * r << 16, b), b);

	return h1 + h2;
}

/* sqrt(var) + add, squared, capped (a bound added to a sigma: var in the covariance's unit). */
static int32_t var_plus_sigma(struct uncertainty *u, int32_t var, uint64_t add, int32_t cap)
{
	uint64_t sigma = fx_isqrt32_up((uint32_t)(var > 0 ? var : 0)) + add;

	if (sigma * sigma > (uint64_t)cap) {
		u->saturated = 1;
		return cap;
	}
	return (int32_t)(sigma * sigma);
}

/* A bound [unit] as a sigma [unit], rounded up: bound / k. */
static uint64_t sigma_of_bound(const struct uncertainty *u, uint64_t bound)
{
	return div_up(bound << 8, u->cfg.k_q8);
}

/* What the current residual bounds accumulated, made independent of them: the systematic
 * position terms into fixed errors per coordinate, the heading drift into the heading variance,
 * the integrals from zero. */
static void fold_terms(struct uncertainty *u);

static void fold_systematic(struct uncertainty *u)
{
	start_batch(u); /* the travel so far, propagated under the bounds that measured it */
	run_stages(u, UINT8_MAX);
	fold_terms(u);
}

/* The systematic integrals so far into fixed errors and the heading variance, from zero. */
static void fold_terms(struct uncertainty *u)
{
	for (int i = 0; i < 2; i++) {
		uint32_t e = mul_coef_up(mag48(&u->w1[i]), u->ratio_coef_q32);

		e = add_sat_u32(e, mul_coef_up(mag48(&u->w2[i]), u->track_coef_q32));
		e = add_sat_u32(e, mul_coef_up(fx_mag32(u->d[i]), u->scale_coef_q32));
		u->fixed_um[i] = add_sat_u32(u->fixed_um[i], e);
		u->w1[i].hi = 0;
		u->w1[i].lo = 0;
		u->w2[i].hi = 0;
		u->w2[i].lo = 0;
		u->d[i] = 0;
	}
	if (!u->saturated)
		u->tt = var_plus_sigma(u, u->tt, sigma_of_bound(u, sys_heading_units(u)), TT_CAP);
	u->travel2_um = 0;
	u->turn_um = 0;
}

int uncertainty_set_model(struct uncertainty *u, const struct uncertainty_model *model)
{
	if (!model_valid(model))
		return -EDOM;
	fold_systematic(u);
	u->model = *model;
	derive(u);
	request_radius(u);
	return 0;
}

/* The systematic terms and the fixed errors from zero (a reset, or folded into the covariance). */
static void clear_terms(struct uncertainty *u)
{
	for (int i = 0; i < 2; i++) {
		u->w1[i].hi = 0;
		u->w1[i].lo = 0;
		u->w2[i].hi = 0;
		u->w2[i].lo = 0;
		u->d[i] = 0;
		u->fixed_um[i] = 0;
	}
	u->travel2_um = 0;
	u->turn_um = 0;
}

void uncertainty_reset(struct uncertainty *u, uint32_t radius_um, uint32_t heading_turn32)
{
	u->saturated = 0;
	u->xx = var_of_bound(u, radius_um, 1, VAR_CAP);
	u->yy = u->xx;
	u->xy = 0;
	u->xt = 0;
	u->yt = 0;
	u->tt = var_of_bound(u, heading_units(heading_turn32), 0, TT_CAP);
	clear_terms(u);
	clear_batch(&u->acc);
	u->stage = STAGE_IDLE;
	u->radius_um = radius_um;
	/* What the covariance gives back, but without its rounding: the bound that was set. */
	u->radius_mm = u->saturated || radius_um > (uint32_t)UNCERTAINTY_RADIUS_MAX_MM * 1000
			       ? UNCERTAINTY_RADIUS_MAX_MM
			       : (uint8_t)((radius_um + 999) / 1000);
}

void uncertainty_reset_axis(struct uncertainty *u, enum uncertainty_axis axis, uint32_t bound_um)
{
	int i = axis == UNCERTAINTY_AXIS_X ? 0 : 1;
	int32_t v = var_of_bound(u, bound_um, 1, VAR_CAP);

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
	u->w1[i].hi = 0;
	u->w1[i].lo = 0;
	u->w2[i].hi = 0;
	u->w2[i].lo = 0;
	u->d[i] = 0;
	u->fixed_um[i] = 0;
	request_radius(u);
}

void uncertainty_reset_heading(struct uncertainty *u, uint32_t bound_turn32)
{
	u->tt = var_of_bound(u, heading_units(bound_turn32), 0, TT_CAP);
	u->xt = 0;
	u->yt = 0;
	u->travel2_um = 0;
	u->turn_um = 0;
	request_radius(u);
}

/* The covariance turned into (along, lateral) coordinates of a direction, the along variance set
 * from the bound and its correlations dropped, the lateral variance and the lateral-heading
 * covariance kept. In 64 bits with the Q30 sine and cosine: it runs at a recalibration, not
 * every tick. */
static int32_t round_q30(int64_t v)
{
	return fx_sat32(fx_shr_round64(v, 30));
}

/* The along variance set to r; with cap, only when it is larger than r (the lateral unit vector
 * is then the direction itself turned a quarter: l^T S l is the along variance of the turned
 * direction). Returns 0 when nothing was changed. */
static int set_along(struct uncertainty *u, uint32_t direction_turn32, uint32_t bound_um, int cap)
{
	int32_t s, c;
	int64_t r = var_of_bound(u, bound_um, 1, VAR_CAP);
	int64_t ss, cc, cs, lat, lt, along;

	fx_sincos(direction_turn32, &s, &c);
	ss = fx_shr_round64((int64_t)s * s, 30);
	cc = fx_shr_round64((int64_t)c * c, 30);
	cs = fx_shr_round64((int64_t)c * s, 30);
	along = fx_shr_round64(cc * u->xx + 2 * cs * u->xy + ss * u->yy, 30);
	if (cap && along <= r)
		return 0;
	/* Lateral unit vector l = (-s, c): l^T S l and the lateral-heading covariance. Dropping the
	 * along-lateral correlation leaves the lateral variance larger than it would be given the
	 * measurement: conservative. */
	lat = fx_shr_round64(ss * u->xx - 2 * cs * u->xy + cc * u->yy, 30);
	if (lat < 0)
		lat = 0;
	lt = fx_shr_round64(-(int64_t)s * u->xt + (int64_t)c * u->yt, 30);
	u->xx = round_q30(r * cc + lat * ss);
	u->yy = round_q30(r * ss + lat * cc);
	u->xy = round_q30((r - lat) * cs);
	u->xt = round_q30(-lt * s);
	u->yt = round_q30(lt * c);
	/* The systematic terms keep their lateral part. */
	{
		int64_t l = fx_shr_round64(-(int64_t)s * u->d[0] + (int64_t)c * u->d[1], 30);

		u->d[0] = round_q30(-l * s);
		u->d[1] = round_q30(l * c);
	}
	lateral48(u->w1, s, c);
	lateral48(u->w2, s, c);
	/* The fixed errors, a box: its lateral extent, as a box along the lateral direction. */
	if ((u->fixed_um[0] | u->fixed_um[1]) != 0) {
		uint64_t as = (uint64_t)fx_mag32(s), ac = (uint64_t)fx_mag32(c);
		uint64_t l = div_up(as * u->fixed_um[0] + ac * u->fixed_um[1], (uint64_t)1 << 30);

		u->fixed_um[0] = (uint32_t)div_up(l * as, (uint64_t)1 << 30);
		u->fixed_um[1] = (uint32_t)div_up(l * ac, (uint64_t)1 << 30);
	}
	request_radius(u);
	return 1;
}

void uncertainty_reset_along(struct uncertainty *u, uint32_t direction_turn32, uint32_t bound_um)
{
	set_along(u, direction_turn32, bound_um, 0);
}

int uncertainty_cap_along(struct uncertainty *u, uint32_t direction_turn32, uint32_t bound_um)
{
	return set_along(u, direction_turn32, bound_um, 1);
}

void uncertainty_widen(struct uncertainty *u, uint32_t position_um, uint32_t wheel_um)
{
	/* [4 um], rounded up */
	uint64_t pos =
		sigma_of_bound(u, ((uint64_t)position_um * 2 + wheel_um + 2 * UNCERTAINTY_POS_UM -
				   1) / (2 * UNCERTAINTY_POS_UM));
	/* wheel / track [rad] in 2^-16 rad */
	uint64_t heading = sigma_of_bound(u, div_up((uint64_t)wheel_um << 16, u->model.track_um));

	if ((position_um | wheel_um) == 0 || u->saturated)
		return;
	finish_stages(u); /* a batch in flight propagates what it started with */
	u->xx = var_plus_sigma(u, u->xx, pos, VAR_CAP);
	u->yy = var_plus_sigma(u, u->yy, pos, VAR_CAP);
	u->tt = var_plus_sigma(u, u->tt, heading, TT_CAP);
	if (u->stage == STAGE_IDLE)
		u->stage = STAGE_EIGEN; /* the radius follows */
}

uint32_t uncertainty_get_heading_bound_turn32(const struct uncertainty *u)
{
	/* sigma [2^-16 rad] = sqrt(tt); bound = k sigma, rounded up; turn32 = rad 2^32 / (2 pi):
	 * 2^16 / (2 pi) = 10430.4 per unit, 10431 rounds up. */
	uint32_t sigma = fx_isqrt32_up((uint32_t)(u->tt > 0 ? u->tt : 0));
	uint32_t ks = sigma * u->cfg.k_q8; /* sigma <= 2^14 under the cap */
	uint64_t bound = ((ks + 255) >> 8) + sys_heading_units(u);

	if (u->saturated || bound >= 205887u) /* beyond half a turn */
		return (uint32_t)1 << 31;
	return (uint32_t)bound * 10431u;
}

/* Travel [um * 2^8] rounded to um, and clamped to 16 bits (32 mm: a batch is shorter). */
static int32_t um_of_q8(int32_t v)
{
	uint32_t m = (fx_mag32(v) + 0x80u) >> 8;
	int32_t r = m > 0x7fffu ? 0x7fff : (int32_t)m;

	return v >= 0 ? r : -r;
}

static int16_t clamp16(int32_t v)
{
	return fx_sat16(v);
}

/* The batch as one arc through its mean heading; directions to 16 bits are plenty for an error
 * model. */
static void stage_direction(struct uncertainty *u)
{
	const struct uncertainty_batch *b = &u->run;
	int32_t lum = um_of_q8(b->left_q8), rum = um_of_q8(b->right_q8);
	/* [turn * 2^32]; a batch's heading change is far below a quarter turn (clamped). */
	int32_t dtheta = (int32_t)clamp16(rum - lum) * (int32_t)u->turn_per_um;

	u->s2_um = lum + rum;
	u->diff_um = rum - lum;
	fx_sincos_q14(b->heading_turn32 - (uint32_t)(dtheta / 2), &u->s_q14, &u->c_q14);
}

static void stage_displacement(struct uncertainty *u)
{
	u->dx_um = clamp16(fx_mul_q(u->s2_um, u->c_q14, 15));
	u->dy_um = clamp16(fx_mul_q(u->s2_um, u->s_q14, 15));
}

/* The noise of the batch's wheel travels, Var = k |ds| (Chong & Kleeman): k [um^2/um * 2^16]
 * |ds| [um] / 16 [(4 um)^2]. */
static void stage_noise(struct uncertainty *u)
{
	const struct uncertainty_batch *b = &u->run;
	int32_t qr = fx_mul_q((int32_t)u->cfg.noise_right_mm2_per_m_q16,
			      um_of_q8((int32_t)b->abs_right_q8), 20);
	int32_t ql = fx_mul_q((int32_t)u->cfg.noise_left_mm2_per_m_q16,
			      um_of_q8((int32_t)b->abs_left_q8), 20);

	u->qp = qr + ql;
	u->qm = qr - ql;
}

/* First-order position error per unit parameter error, integrated along the path with the
 * heading error at the batch's midpoint (exact on straight lines), in exact integers: 4 times the
 * midpoint's travel and right - left travel [um] times the displacement [um]. */
static void stage_w1(struct uncertainty *u)
{
	int32_t s4 = sat_add(sat_add(u->travel2_um, u->travel2_um), u->s2_um);

	add48(&u->w1[0], -s4, u->dy_um);
	add48(&u->w1[1], s4, u->dx_um);
	u->travel2_um = sat_add(u->travel2_um, u->s2_um);
}

static void stage_w2(struct uncertainty *u)
{
	int32_t r4 = sat_add(sat_add(u->turn_um, u->turn_um), u->diff_um);

	r4 = sat_add(r4, r4);
	add48(&u->w2[0], -r4, u->dy_um);
	add48(&u->w2[1], r4, u->dx_um);
	u->d[0] = sat_add(u->d[0], u->dx_um);
	u->d[1] = sat_add(u->d[1], u->dy_um);
	u->turn_um = sat_add(u->turn_um, u->diff_um);
}

/* Fp Sigma Fp^T, Fp = [1 0 -DY; 0 1 DX; 0 0 1] with (DX, DY) the displacement [4 um] per 2^16
 * heading units. xx, xy and yy take the old xt, yt; those change last. m = (DX, DY) tt. */
static void stage_fp_xx(struct uncertainty *u)
{
	int32_t dy = u->dy_um / UNCERTAINTY_POS_UM;

	u->my = fx_mul_q(u->tt, dy, 16);
	u->xx += -2 * fx_mul_q(u->xt, dy, 16) + fx_mul_q(u->my, dy, 16);
}

static void stage_fp_xy(struct uncertainty *u)
{
	int32_t dx = u->dx_um / UNCERTAINTY_POS_UM, dy = u->dy_um / UNCERTAINTY_POS_UM;

	u->xy += fx_mul_q(u->xt, dx, 16) - fx_mul_q(u->yt, dy, 16) - fx_mul_q(u->my, dx, 16);
}

static void stage_fp_yy(struct uncertainty *u)
{
	int32_t dx = u->dx_um / UNCERTAINTY_POS_UM;
	int32_t mx = fx_mul_q(u->tt, dx, 16);

	u->yy += 2 * fx_mul_q(u->yt, dx, 16) + fx_mul_q(mx, dx, 16);
	u->xt -= u->my;
	u->yt += mx;
}

/* Fd Q Fd^T with the columns (C - U, S + V, G) and (C + U, S - V, -G) per 4 um of wheel
 * travel: C, S = cos, sin / 2 and U, V = (dy, dx) / (2 b) [2^-15] (the Q14 cosine read as Q15
 * is half of it), G the heading per 4 um of right - left travel [2^-16 rad]. Chong & Kleeman
 * 1997, Kelly 2000 section 3. The squares and products [2^-30] are taken to 2^-15. */
static void stage_uv(struct uncertainty *u)
{
	u->u_q15 = clamp16(fx_mul_q(u->dy_um, u->inv_track_q28, 14));
	u->v_q15 = clamp16(fx_mul_q(u->dx_um, u->inv_track_q28, 14));
}

static void stage_q_xx(struct uncertainty *u)
{
	int16_t c = u->c_q14;

	u->xx += fx_mul_q(u->qp, q15_of(fx_mul_s16(c, c) + fx_mul_s16(u->u_q15, u->u_q15)), 15) -
		 2 * fx_mul_q(u->qm, q15_of(fx_mul_s16(c, u->u_q15)), 15);
}

static void stage_q_yy(struct uncertainty *u)
{
	int16_t s = u->s_q14;

	u->yy += fx_mul_q(u->qp, q15_of(fx_mul_s16(s, s) + fx_mul_s16(u->v_q15, u->v_q15)), 15) +
		 2 * fx_mul_q(u->qm, q15_of(fx_mul_s16(s, u->v_q15)), 15);
}

static void stage_q_xy(struct uncertainty *u)
{
	int16_t c = u->c_q14, s = u->s_q14;

	u->xy += fx_mul_q(u->qp, q15_of(fx_mul_s16(c, s) - fx_mul_s16(u->u_q15, u->v_q15)), 15) +
		 fx_mul_q(u->qm, q15_of(fx_mul_s16(c, u->v_q15) - fx_mul_s16(u->u_q15, s)), 15);
}

static void stage_q_xt(struct uncertainty *u)
{
	int32_t e = fx_mul_q(u->qm, u->c_q14, 15) - fx_mul_q(u->qp, u->u_q15, 15); /* [4 um] */

	u->xt += fx_mul_q(e, u->g_q12, 12);
}

static void stage_q_yt(struct uncertainty *u)
{
	int32_t e = fx_mul_q(u->qm, u->s_q14, 15) + fx_mul_q(u->qp, u->v_q15, 15);

	u->yt += fx_mul_q(e, u->g_q12, 12);
}

static void stage_q_tt(struct uncertainty *u)
{
	u->tt += fx_mul_q(fx_mul_q(u->qp, u->g_q12, 12), u->g_q12, 12);
	if (u->xx > VAR_CAP || u->yy > VAR_CAP || u->tt > TT_CAP)
		u->saturated = 1;
}

/* The largest eigenvalue of the xy block, lambda = (a + c + |(a - c, 2 b)|) / 2: the length
 * first (rounded up), then lambda and sigma. */
static void stage_eigen(struct uncertainty *u)
{
	int32_t a = u->xx > 0 ? u->xx : 0, c = u->yy > 0 ? u->yy : 0;
	uint32_t b = fx_mag32(u->xy);

	u->h = hypot_up(fx_mag32(a - c), b > 0x7fffffffu ? 0xfffffffeu : 2 * b);
}

/* k sigma_max [um], rounded up at every step. */
static void stage_sigma(struct uncertainty *u)
{
	int32_t a = u->xx > 0 ? u->xx : 0, c = u->yy > 0 ? u->yy : 0;
	uint32_t h = u->h;
	/* ceil((a + c + h) / 2), a sum that may pass 2^32 */
	uint32_t lambda = ((uint32_t)a >> 1) + ((uint32_t)c >> 1) + (h >> 1) +
			  (((uint32_t)a & 1u) + ((uint32_t)c & 1u) + (h & 1u) + 1u) / 2;
	uint32_t sigma, ks;

	/* k sigma [um], rounded up: sigma to 1/4 um while it is below 16 mm, where the mm of the
	 * radius depends on it; to 4 um above. */
	if (lambda < ((uint32_t)1 << 24)) {
		sigma = fx_isqrt32_up(lambda << 8); /* [2^-2 um] */
		ks = fx_mul_u16((uint16_t)sigma, u->cfg.k_q8);
		u->radius_um = fx_shr_u32(ks, 10) + ((ks & 1023u) != 0);
		return;
	}
	sigma = fx_isqrt32_up(lambda); /* [4 um] */
	if (sigma >= 0x10000u) {
		u->radius_um = 0xffffffffu;
		return;
	}
	ks = fx_mul_u16((uint16_t)sigma, u->cfg.k_q8);
	u->radius_um = fx_shr_u32(ks, 6) + ((ks & 63u) != 0);
}

/* The systematic worst case over the allowed parameters (triangle inequality), one term per
 * stage, added to k sigma; each term is below 2^32 (a length times at most 1). */
static void add_systematic(struct uncertainty *u, uint32_t x, uint32_t y, uint32_t coef)
{
	if (u->radius_um < (uint32_t)UNCERTAINTY_RADIUS_MAX_MM * 1000)
		u->radius_um += mul_coef_up(hypot_up(x, y), coef);
}

/* The radius in mm, rounded up: ceil(r / 1000) by binary subtraction (r < 255 mm). */
static void stage_radius(struct uncertainty *u)
{
	uint32_t r = u->radius_um;
	uint32_t k = (uint32_t)1000 << 7;
	uint8_t mm = 0, bit = 128;

	add_systematic(u, fx_mag32(u->d[0]), fx_mag32(u->d[1]), u->scale_coef_q32);
	if ((u->fixed_um[0] | u->fixed_um[1]) != 0)
		add_systematic(u, u->fixed_um[0], u->fixed_um[1], 0xffffffffu);
	r = u->radius_um;
	if (u->saturated || r >= (uint32_t)UNCERTAINTY_RADIUS_MAX_MM * 1000) {
		u->radius_mm = UNCERTAINTY_RADIUS_MAX_MM;
		return;
	}
	while (bit != 0) {
		if (r >= k) {
			r -= k;
			mm |= bit;
		}
		k >>= 1;
		bit >>= 1;
	}
	u->radius_mm = r != 0 ? (uint8_t)(mm + 1) : mm;
}

/* Up to n stages, until idle. */
static void run_stages(struct uncertainty *u, uint8_t n)
{
	for (; n != 0 && u->stage != STAGE_IDLE; n--) {
		switch (u->stage) {
		case STAGE_DIRECTION:
			stage_direction(u);
			break;
		case STAGE_DISPLACEMENT:
			stage_displacement(u);
			break;
		case STAGE_NOISE:
			stage_noise(u);
			break;
		case STAGE_W1:
			stage_w1(u);
			break;
		case STAGE_W2:
			stage_w2(u);
			/* Past a cap the covariance is frozen (the radius reads 255): no more
			 * products. */
			if (u->saturated)
				u->stage = STAGE_RADIUS - 1;
			break;
		case STAGE_FP_XX:
			stage_fp_xx(u);
			break;
		case STAGE_FP_XY:
			stage_fp_xy(u);
			break;
		case STAGE_FP_YY:
			stage_fp_yy(u);
			break;
		case STAGE_UV:
			stage_uv(u);
			break;
		case STAGE_Q_XX:
			stage_q_xx(u);
			break;
		case STAGE_Q_YY:
			stage_q_yy(u);
			break;
		case STAGE_Q_XY:
			stage_q_xy(u);
			break;
		case STAGE_Q_XT:
			stage_q_xt(u);
			break;
		case STAGE_Q_YT:
			stage_q_yt(u);
			break;
		case STAGE_Q_TT:
			stage_q_tt(u);
			break;
		case STAGE_EIGEN:
			stage_eigen(u);
			break;
		case STAGE_SIGMA:
			stage_sigma(u);
			break;
		case STAGE_SYS_RATIO:
			add_systematic(u, mag48(&u->w1[0]), mag48(&u->w1[1]), u->ratio_coef_q32);
			break;
		case STAGE_SYS_TRACK:
			add_systematic(u, mag48(&u->w2[0]), mag48(&u->w2[1]), u->track_coef_q32);
			break;
		case STAGE_RADIUS:
			stage_radius(u);
			u->stage = STAGE_IDLE;
			return;
		default:
			return;
		}
		u->stage++;
	}
}

/* Hands the accumulated batch to the stages (finishing the one in flight first if there is one).
 * A batch without travel propagates nothing: Fp is the identity, the noise is zero. */
static void start_batch(struct uncertainty *u)
{
	finish_stages(u);
	if (u->acc.abs_left_q8 != 0 || u->acc.abs_right_q8 != 0) {
		u->run = u->acc;
		u->stage = STAGE_DIRECTION;
	}
	clear_batch(&u->acc);
}

/* Travel [um * 2^16] to [um * 2^8], rounded: the error model needs no more, and the batch's
 * sums then hold 8.4 m. */
static int32_t q8_of_q16(int32_t v)
{
	int32_t r = (int32_t)((fx_mag32(v) + 0x80u) >> 8);

	return v >= 0 ? r : -r;
}

void uncertainty_update(struct uncertainty *u, int32_t left_q16, int32_t right_q16,
			uint32_t heading_turn32)
{
	struct uncertainty_batch *b = &u->acc;
	int32_t l = q8_of_q16(left_q16), r = q8_of_q16(right_q16);

	/* A batch starts with its first tick of travel. One that waits for the stages (below) is
	 * handed over at once, the stages in flight finished in this tick, before a wheel's travel
	 * in it would pass 32.7 mm: at 1 kHz only above 1.5 m/s (docs/odometry.md). */
	if ((b->ticks | l | r) != 0) {
		if (b->ticks == 0xffu || b->abs_left_q8 + fx_mag32(l) > WHEEL_MAX_Q8 ||
		    b->abs_right_q8 + fx_mag32(r) > WHEEL_MAX_Q8)
			start_batch(u);
		b->left_q8 += l;
		b->right_q8 += r;
		b->abs_left_q8 += fx_mag32(l);
		b->abs_right_q8 += fx_mag32(r);
		b->heading_turn32 = heading_turn32;
		b->ticks++;
		/* A batch that is due waits until the stages are done. */
		if (u->stage == STAGE_IDLE &&
		    (b->ticks >= u->batch_ticks ||
		     (b->abs_left_q8 >> 1) + (b->abs_right_q8 >> 1) >= PATH_HALF_Q8)) {
			start_batch(u); /* its first stage runs next tick */
			return;
		}
	}
	if (u->stage != STAGE_IDLE)
		run_stages(u, 1);
}

void uncertainty_advance(struct uncertainty *u, uint8_t n)
{
	if (u->stage != STAGE_IDLE)
		run_stages(u, n);
}

uint8_t uncertainty_get_radius_mm(const struct uncertainty *u)
{
	return u->radius_mm;
}

int uncertainty_fuse_ready(const struct uncertainty *u)
{
	return u->stage == STAGE_IDLE || u->stage == STAGE_EIGEN;
}

#if CONFIG_FIX
/* The covariance as a 3 x 3 matrix (x, y in 4 um, the heading in 2^-16 rad), for a fusion. */
struct cov3 {
	int64_t p[3][3];
};

/* Everything the radius adds to the covariance, folded into it: the systematic terms (as
 * fold_systematic()), then the fixed errors, each bound a sigma of bound / k. */
static void fold_all(struct uncertainty *u, struct cov3 *m)
{
	fold_terms(u); /* the batches keep their travel: it is propagated after the fix */
	if (!u->saturated) {
		u->xx = var_plus_sigma(u, u->xx, sigma_of_bound(u, div_up(u->fixed_um[0], 4)),
				       VAR_CAP);
		u->yy = var_plus_sigma(u, u->yy, sigma_of_bound(u, div_up(u->fixed_um[1], 4)),
				       VAR_CAP);
	}
	u->fixed_um[0] = 0;
	u->fixed_um[1] = 0;
	m->p[0][0] = u->xx;
	m->p[0][1] = m->p[1][0] = u->xy;
	m->p[1][1] = u->yy;
	m->p[0][2] = m->p[2][0] = u->xt;
	m->p[1][2] = m->p[2][1] = u->yt;
	m->p[2][2] = u->tt;
}

/* The covariance carried along a travel (dx, dy) [um] with the heading error: F m F^T with
 * F = [[1, 0, a], [0, 1, b], [0, 0, 1]], a = -dy, b = dx in [4 um per 2^-16 rad] (sign -1: back
 * to the measured time). */
static void carry_cov(struct cov3 *m, int32_t dx_um, int32_t dy_um, int sign)
{
	int64_t a = -(int64_t)dy_um / UNCERTAINTY_POS_UM * sign; /* [2^-16] */
	int64_t b = (int64_t)dx_um / UNCERTAINTY_POS_UM * sign;
	int64_t at, bt, xt = m->p[0][2], yt = m->p[1][2];

	if (a == 0 && b == 0) /* F = I: the same covariance, without the products */
		return;
	at = (a * m->p[2][2]) >> 16;
	bt = (b * m->p[2][2]) >> 16;

	m->p[0][0] += 2 * ((a * xt) >> 16) + ((a * at) >> 16);
	m->p[1][1] += 2 * ((b * yt) >> 16) + ((b * bt) >> 16);
	m->p[0][1] += ((a * yt) >> 16) + ((b * xt) >> 16) + ((a * bt) >> 16);
	m->p[1][0] = m->p[0][1];
	m->p[0][2] = m->p[2][0] = xt + at;
	m->p[1][2] = m->p[2][1] = yt + bt;
}

/* The correlations within what the variances allow (after the variances were lowered). */
static void shrink_cov(struct cov3 *m)
{
	int64_t root[3]; /* each variance's root, once */

	for (uint8_t j = 0; j < 3; j++)
		root[j] = (int64_t)fx_isqrt32_up((uint32_t)(m->p[j][j] > 0 ? m->p[j][j] : 0));
	for (uint8_t j = 0; j < 3; j++)
		for (uint8_t k = (uint8_t)(j + 1u); k < 3; k++) {
			int64_t lim = root[j] * root[k];

			lim = lim * 15 / 16; /* strictly inside: the matrix stays positive */
			if (m->p[j][k] > lim)
				m->p[j][k] = lim;
			if (m->p[j][k] < -lim)
				m->p[j][k] = -lim;
			m->p[k][j] = m->p[j][k];
		}
}

/* round(a / b), b > 0. */
static int64_t div_round_s64(int64_t a, int64_t b)
{
	return a >= 0 ? (a + b / 2) / b : -((-a + b / 2) / b);
}

/* One coordinate i of the fix, of variance r and innovation nu[i]: the state moves by the gain
 * times the innovation (delta[], and the later coordinates' innovations with it), the
 * covariance loses the gain times its row i (the diagonal rounded up: it stays a bound).
 * Returns nu[i]^2 / s [2^-8], saturating. */
static uint64_t fuse_one(struct uncertainty_fusion *z, uint8_t i, int64_t r)
{
	int64_t s = z->p[i][i] + r;
	int64_t g[3] = {z->p[0][i], z->p[1][i], z->p[2][i]};
	int64_t v = z->nu[i];
	uint64_t d2 = ((uint64_t)(v * v) << 8) / (uint64_t)s;

	for (uint8_t j = 0; j < 3; j++) {
		int64_t d = div_round_s64(g[j] * v, s);

		z->delta[j] += d;
		z->nu[j] -= d;
		for (uint8_t k = j; k < 3; k++) {
			z->p[j][k] -= j == k ? (g[j] * g[k]) / s : div_round_s64(g[j] * g[k], s);
			z->p[k][j] = z->p[j][k];
		}
	}
	return d2;
}

/* A 64-bit variance back into the covariance's 32 bits, within 0..cap. */
static int32_t var_back(int64_t v, int32_t cap)
{
	return v < 0 ? 0 : v > cap ? cap : (int32_t)v;
}

/* A covariance term back into 32 bits, within +-root_a root_b (a valid correlation: the roots
 * of the two variances, rounded up). */
static int32_t cov_back(int64_t v, uint32_t root_a, uint32_t root_b)
{
	int64_t lim = (int64_t)root_a * root_b;

	return (int32_t)(v > lim ? lim : v < -lim ? -lim : v);
}

/* The innovations in the covariance's units, rounded; 1 when one is beyond any use (264 m). */
#define FAR_UNITS ((int64_t)1 << 26)
static int innovations(const struct uncertainty_fix *f, int64_t nu[3])
{
	nu[0] = div_round_s64(f->dx_um, UNCERTAINTY_POS_UM);
	nu[1] = div_round_s64(f->dy_um, UNCERTAINTY_POS_UM);
	nu[2] = fx_shr_round64((int64_t)f->dheading_turn32 * TWO_PI_Q16, 32);
	return nu[0] > FAR_UNITS || nu[0] < -FAR_UNITS || nu[1] > FAR_UNITS || nu[1] < -FAR_UNITS;
}

/* Until the stages refresh it, the radius at least what the fused covariance gives: its largest
 * eigenvalue is at most max(xx, yy) + |xy|. */
static void cover_now(struct uncertainty *u)
{
	uint32_t v = (uint32_t)(u->xx > u->yy ? u->xx : u->yy) + fx_mag32(u->xy);
	uint64_t r_um = ((uint64_t)fx_isqrt32_up(v) * UNCERTAINTY_POS_UM * u->cfg.k_q8 + 255u) >> 8;

	if (r_um > u->radius_um)
		u->radius_um = r_um > UINT32_MAX ? UINT32_MAX : (uint32_t)r_um;
	if (r_um > (uint64_t)u->radius_mm * 1000u)
		u->radius_mm = r_um > (uint64_t)UNCERTAINTY_RADIUS_MAX_MM * 1000u
				       ? UNCERTAINTY_RADIUS_MAX_MM
				       : (uint8_t)((r_um + 999u) / 1000u);
}

int uncertainty_fuse_begin(struct uncertainty *u, const struct uncertainty_fix *f)
{
	struct uncertainty_fusion *z = &u->fusion;
	struct uncertainty w = *u; /* folded here: u keeps its terms unless the fix is fused */
	struct cov3 m;
	int64_t rp = (int64_t)((f->sigma_um + UNCERTAINTY_POS_UM - 1) / UNCERTAINTY_POS_UM);
	int64_t rt = (int64_t)heading_units(f->sigma_turn32);

	if (innovations(f, z->nu)) /* beyond the field: nothing to fuse */
		return 1;
	fold_all(&w, &m);
	carry_cov(&m, f->since_dx_um, f->since_dy_um, -1);
	z->g = 0;
	if (f->growth_um) { /* the prior then: now's, less what grew since (added back later) */
		int64_t g = (int64_t)sigma_of_bound(&w, div_up(f->growth_um, UNCERTAINTY_POS_UM));

		m.p[0][0] = m.p[0][0] - g * g > m.p[0][0] / 4 ? m.p[0][0] - g * g : m.p[0][0] / 4;
		m.p[1][1] = m.p[1][1] - g * g > m.p[1][1] / 4 ? m.p[1][1] - g * g : m.p[1][1] / 4;
		shrink_cov(&m);
		z->g = g;
	}
	for (uint8_t i = 0; i < 3; i++) {
		for (uint8_t j = 0; j < 3; j++)
			z->p[i][j] = m.p[i][j];
		z->delta[i] = 0;
	}
	z->r[0] = rp * rp + 1;
	z->r[1] = rt * rt + 1;
	z->since_dx_um = f->since_dx_um;
	z->since_dy_um = f->since_dy_um;
	z->gate_q8 = f->gate_q8;
	z->heading = f->sigma_turn32 != 0;
	z->saturated = w.saturated;
	z->stage_before = u->stage;
	z->d2 = 0;
	u->stage = STAGE_FUSE_X;
	return 0;
}

/* The end of a fusion: the gate, then the fused covariance carried forward to now and made the
 * radius's (the systematic terms it folded in, from zero), the growth since added back. */
static enum uncertainty_fuse_result fuse_end(struct uncertainty *u,
					     struct uncertainty_correction *c)
{
	struct uncertainty_fusion *z = &u->fusion;
	struct cov3 m;
	uint32_t rx, ry, rh; /* the fused variances' roots */

	c->d2_q8 = z->d2 > UINT32_MAX ? UINT32_MAX : (uint32_t)z->d2;
	if (!z->saturated && z->gate_q8 && z->d2 > z->gate_q8) {
		u->stage = z->stage_before;
		return UNCERTAINTY_FUSE_OUTLIER;
	}
	for (uint8_t i = 0; i < 3; i++)
		for (uint8_t j = 0; j < 3; j++)
			m.p[i][j] = z->p[i][j];
	carry_cov(&m, z->since_dx_um, z->since_dy_um, 1);
	u->saturated = 0;
	u->xx = var_back(m.p[0][0], VAR_CAP);
	u->yy = var_back(m.p[1][1], VAR_CAP);
	u->tt = var_back(m.p[2][2], TT_CAP);
	rx = fx_isqrt32_up((uint32_t)u->xx);
	ry = fx_isqrt32_up((uint32_t)u->yy);
	rh = fx_isqrt32_up((uint32_t)u->tt);
	u->xy = cov_back(m.p[0][1], rx, ry);
	u->xt = cov_back(m.p[0][2], rx, rh);
	u->yt = cov_back(m.p[1][2], ry, rh);
	/* The growth since the measured time, as an independent variance (sigma = growth / k): the
	 * fixes in flight each add theirs, which a sum of sigmas would count over and over. */
	if (z->g) {
		u->xx = var_back((int64_t)u->xx + z->g * z->g, VAR_CAP);
		u->yy = var_back((int64_t)u->yy + z->g * z->g, VAR_CAP);
	}
	clear_terms(u);
	u->stage = STAGE_EIGEN; /* the radius from the fused covariance, over the next ticks */
	cover_now(u);
	c->dx_um = (int32_t)(z->delta[0] * UNCERTAINTY_POS_UM);
	c->dy_um = (int32_t)(z->delta[1] * UNCERTAINTY_POS_UM);
	c->dheading_turn32 = (int32_t)fx_shr_round64(z->delta[2] * TURN32_PER_RAD, 16);
	return UNCERTAINTY_FUSE_FUSED;
}

enum uncertainty_fuse_result uncertainty_fuse_step(struct uncertainty *u,
						   struct uncertainty_correction *c)
{
	struct uncertainty_fusion *z = &u->fusion;

	switch (u->stage) {
	case STAGE_FUSE_X:
		z->d2 += fuse_one(z, 0, z->r[0]);
		u->stage = STAGE_FUSE_Y;
		return UNCERTAINTY_FUSE_BUSY;
	case STAGE_FUSE_Y:
		z->d2 += fuse_one(z, 1, z->r[0]);
		u->stage = STAGE_FUSE_HEADING;
		return UNCERTAINTY_FUSE_BUSY;
	case STAGE_FUSE_HEADING:
		if (z->heading)
			z->d2 += fuse_one(z, 2, z->r[1]);
		u->stage = STAGE_FUSE_END;
		return UNCERTAINTY_FUSE_BUSY;
	case STAGE_FUSE_END:
		return fuse_end(u, c);
	default:
		return UNCERTAINTY_FUSE_ABANDONED;
	}
}

void uncertainty_fuse_abandon(struct uncertainty *u)
{
	if (u->stage > STAGE_RADIUS)
		u->stage = u->fusion.stage_before;
}
#endif

void uncertainty_keep(const struct uncertainty *u, struct uncertainty_kept *k)
{
	k->tt = u->saturated ? TT_CAP : u->tt;
	k->travel2_um = u->travel2_um;
	k->turn_um = u->turn_um;
}

void uncertainty_resume(struct uncertainty *u, uint32_t radius_um, const struct uncertainty_kept *k,
			uint32_t position_um, uint32_t wheel_um)
{
	uncertainty_reset(u, radius_um, 0);
	u->tt = k->tt < 0 ? TT_CAP : k->tt > TT_CAP ? TT_CAP : k->tt;
	u->travel2_um = k->travel2_um;
	u->turn_um = k->turn_um;
	if (!u->saturated)
		u->tt = var_plus_sigma(u, u->tt, sigma_of_bound(u, sys_heading_units(u)), TT_CAP);
	u->travel2_um = 0;
	u->turn_um = 0;
	uncertainty_widen(u, position_um, wheel_um);
	request_radius(u);
}
