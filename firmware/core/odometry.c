/* Odometry from two free encoder wheels (see odometry.h and docs/odometry.md).
 *
 * The tick's arithmetic is products of at most 32 x 32 bits and 32-bit additions (fixmath.h
 * explains why): the heading is a 64-bit sum kept as two 32-bit words, the position and distance
 * are whole micrometres and a fraction. */
#include "odometry.h"

#include <errno.h>

#include "fixmath.h"

/* 2^64 / (2 pi), rounded (error 0.3 in 2.9e18). */
#define TURN64_PER_RAD 2935890503282001227ull
/* pi/4 * 2^32, 2^32/6, 2^32/120: the general arc correction. */
#define QUARTER_PI_Q32 3373259426LL
#define SIXTH_Q32 715827883LL
#define ONE_120TH_Q32 35791394LL

static int config_valid(const struct odometry_config *cfg)
{
	return cfg->left_um_per_count_q16 >= 1 &&
	       cfg->left_um_per_count_q16 <= ODOMETRY_UM_PER_COUNT_Q16_MAX &&
	       cfg->right_um_per_count_q16 >= 1 &&
	       cfg->right_um_per_count_q16 <= ODOMETRY_UM_PER_COUNT_Q16_MAX &&
	       cfg->track_um >= ODOMETRY_TRACK_UM_MIN && cfg->track_um <= ODOMETRY_TRACK_UM_MAX;
}

/* The heading change of one count, k / (2 pi b) turn, as round(k 2^48 / (2 pi b)) [turn * 2^64]:
 * the 86-bit product k * 2^64/(2 pi) divided by b 2^16 one bit at a time. Configuration time
 * only. The result is below 2^55.4 (k <= 2^24, b >= 2^14); its rounding is a relative error
 * below 2e-15 on the track. */
static uint64_t turn_per_count(uint32_t k_q16, uint32_t track_um)
{
	uint64_t lo = (TURN64_PER_RAD & 0xffffffffu) * k_q16;
	uint64_t hi = (TURN64_PER_RAD >> 32) * k_q16 + (lo >> 32);
	uint64_t den = (uint64_t)track_um << 16;
	uint64_t rem = 0, q = 0;

	for (int i = 85; i >= 0; i--) {
		uint64_t bit = i >= 32 ? (hi >> (i - 32)) & 1u : (lo >> i) & 1u;

		rem = rem << 1 | bit;
		q <<= 1;
		if (rem >= den) {
			rem -= den;
			q |= 1u;
		}
	}
	if (2 * rem >= den)
		q++;
	return q;
}

static void derive_wheel(struct odometry_wheel *w, uint32_t k_q16, uint32_t track_um)
{
	uint64_t u = turn_per_count(k_q16, track_um);

	w->k[0] = fx_lo16(k_q16);
	w->k[1] = fx_hi16(k_q16);
	for (uint8_t n = 0; n < ODOMETRY_TABLE_COUNTS; n++) {
		uint64_t t = u * n;

		w->move[n].travel_q16 = k_q16 * n; /* below 2^29 */
		w->move[n].turn_q64[0] = (uint32_t)t;
		w->move[n].turn_q64[1] = (uint32_t)(t >> 32);
	}
}

static void derive(struct odometry_counter *o)
{
	derive_wheel(&o->left, o->cfg.left_um_per_count_q16, o->cfg.track_um);
	derive_wheel(&o->right, o->cfg.right_um_per_count_q16, o->cfg.track_um);
}

int odometry_derive_config(const struct odometry_config *cfg, struct odometry_wheel wheels[2])
{
	if (!config_valid(cfg))
		return -EDOM;
	derive_wheel(&wheels[0], cfg->left_um_per_count_q16, cfg->track_um);
	derive_wheel(&wheels[1], cfg->right_um_per_count_q16, cfg->track_um);
	return 0;
}

void odometry_install_config(struct odometry_counter *o, const struct odometry_config *cfg,
			     const struct odometry_wheel wheels[2])
{
	o->cfg = *cfg;
	o->left = wheels[0];
	o->right = wheels[1];
}

/* m counts' travel with the factor k [um * 2^16]: k m from two 16 x 16 products (the upper
 * one below 2^31), clamped to ODOMETRY_STEP_Q16_MAX beyond it (*clamped then 1). The tables hold
 * the same products. */
static inline uint32_t travel_of(const uint16_t k[2], uint16_t m, uint8_t *clamped)
{
	uint32_t lo = fx_mul_u16(m, k[0]);
	uint32_t hi = fx_mul_u16(m, k[1]) + fx_hi16(lo);

	*clamped = hi >= 0x8000u;
	return *clamped ? ODOMETRY_STEP_Q16_MAX : (hi << 16) | fx_lo16(lo);
}

/* m counts beyond the tables: the travel (-ERANGE if clamped), and four 16 x 16 products for
 * m u modulo 2^64. Only a wheel faster than the tables (2.5 m/s at 1 kHz for the reference
 * robot) comes here. */
static int wheel_move_wide(const struct odometry_wheel *w, uint16_t m, struct odometry_move *mv)
{
	uint8_t clamped;
	const uint32_t *u = w->move[1].turn_q64;
	uint32_t p0 = fx_mul_u16(m, fx_lo16(u[0]));
	uint32_t p1 = fx_mul_u16(m, fx_hi16(u[0]));
	uint32_t p2 = fx_mul_u16(m, fx_lo16(u[1]));
	uint32_t t = fx_hi16(p0) + (uint32_t)fx_lo16(p1);

	mv->turn_q64[0] = fx_lo16(p0) | (t << 16);
	mv->turn_q64[1] = p2 + fx_hi16(p1) + fx_hi16(t) +
			  ((uint32_t)(uint16_t)((uint32_t)m * fx_hi16(u[1])) << 16);
	mv->travel_q16 = travel_of(w->k, m, &clamped);
	return clamped ? -ERANGE : 0;
}

/* h += d, or h -= d, modulo 2^64 (two 32-bit words, lower first): the architecture's kernels. */
static inline void add_q64(uint32_t *h0, uint32_t *h1, const uint32_t d[2], uint8_t sub)
{
	if (sub)
		fx_sub_u64(h0, h1, d);
	else
		fx_add_u64(h0, h1, d);
}

/* round(a b / 2^31), halves up, as fx_mul_u32_shr(a, b, 31), for a product below 2^62: twice the
 * upper word, plus 0, 1, 1 or 2 for the two upper bits of the lower one (no carry to propagate:
 * about 30 cycles less on the AVR). */
static inline uint32_t mul_shr31(uint32_t a, uint32_t b)
{
	uint32_t lo, hi = fx_mul_u32_wide(a, b, &lo);

	return (hi << 1) + (((uint8_t)(lo >> 24) >> 6) + 1u) / 2u;
}

/* round(|both| (1 - sin(x)/x)) [um * 2^17], x = dtheta/2, for t = |dtheta| < 2^24 [turn * 2^32]
 * (0.0245 rad per arc, a tick's or a period's): 1 - sin(x)/x = x^2/6 - x^4/120..., x = t pi / 2^32,
 * and f = 2^32 x^2/6 = t^2 pi^2 / (6 2^32) is below 1.1e5, where x^4/120 is below 0.82 unit of f
 * (left out: at most 0.82 unit of the result). Below t = 2^15, f is below 0.41: no correction.
 * f reaches 2^16 from t = 1.31e7: its sum is taken in 32 bits (an int may have 16). */
static uint32_t arc_correction(uint32_t both, uint32_t t)
{
	uint16_t th = fx_hi16(t), tl = fx_lo16(t);
	/* q = floor(t^2 / 2^16), below 2^32 for t < 2^24 (th < 2^8). */
	uint32_t q = ((uint32_t)((uint16_t)(uint8_t)th * (uint16_t)(uint8_t)th) << 16) +
		     (fx_mul_u16(th, tl) << 1) + fx_hi16(fx_mul_u16(tl, tl));
	/* f = q pi^2/6 / 2^16 = q / 2^16 + q 42265.2 / 2^32. */
	uint32_t f =
		(uint32_t)fx_hi16(q) + fx_hi16(fx_mul_u16(fx_hi16(q), 42265u) +
					       fx_hi16(fx_mul_u16(fx_lo16(q), 42265u)) + 0x8000u);
	uint16_t bh = fx_hi16(both), fl = fx_lo16(f);
	uint32_t c;

	if (f == 0)
		return 0;
	/* both f / 2^32 with f = fh 2^16 + fl, fh 0 or 1. */
	c = fx_hi16(fx_mul_u16(bh, fl) + fx_hi16(fx_mul_u16(fx_lo16(both), fl)) + 0x8000u);
	return fx_hi16(f) ? c + bh : c;
}

/* The same for any t, in 64 bits (sin(x)/x to the x^4 term: its error stays below 2e-10 while
 * |dtheta| <= 0.2 rad per arc). Runs only above 0.0245 rad per arc: above 24 rad/s with an arc
 * a tick at 1 kHz, above 3 rad/s with an arc a period at 125 Hz (planner.c). */
static uint32_t arc_correction_wide(uint32_t both, uint32_t t)
{
	int64_t x = fx_shr_round64((int64_t)t * QUARTER_PI_Q32, 32);
	int64_t x2 = fx_shr_round64(x * x, 30);
	int64_t x4 = fx_shr_round64(x2 * x2, 30);
	int64_t f = fx_shr_round64(x2 * SIXTH_Q32, 32) - fx_shr_round64(x4 * ONE_120TH_Q32, 32);

	return (uint32_t)fx_shr_round64((int64_t)both * f, 30);
}

/* (*whole, *frac) += d / 2^16, on a value kept as whole units (modulo 2^32) and a 16-bit
 * fraction. */
static inline void add_q16(uint32_t *whole, uint16_t *frac, uint32_t mag, uint8_t neg)
{
	uint32_t t;

	if (!neg) {
		t = (uint32_t)*frac + fx_lo16(mag);
		*whole += fx_hi16(mag) + fx_hi16(t);
	} else {
		t = 0x10000u + *frac - fx_lo16(mag);
		*whole -= fx_hi16(mag) + 1u - fx_hi16(t);
	}
	*frac = fx_lo16(t);
}

int odometry_counter_init(struct odometry_counter *o, const struct odometry_config *cfg,
			  uint16_t left_count, uint16_t right_count, uint32_t heading_turn32)
{
	if (!config_valid(cfg))
		return -EDOM;
	o->cfg = *cfg;
	derive(o);
	o->left_count = left_count;
	o->right_count = right_count;
	o->heading_q64[0] = 0;
	o->heading_q64[1] = heading_turn32;
	o->heading_turn32 = heading_turn32;
	o->distance_um = 0;
	o->distance_frac = 0;
	o->step.ds_um = 0;
	o->step.dtheta_turn32 = 0;
	return 0;
}

void odometry_position_init(struct odometry_position *o, int32_t x_um, int32_t y_um)
{
	odometry_set_position(o, x_um, y_um);
	/* The sine and cosine kept are those of heading 0. */
	o->trig_turn32 = 0;
	fx_sincos(0, &o->trig_sin_q30, &o->trig_cos_q30);
}

int odometry_check_config(const struct odometry_config *cfg)
{
	return config_valid(cfg) ? 0 : -EDOM;
}

/* Twice the midpoint travel [um * 2^16], |left + right|, from each wheel's sign and magnitude;
 * *neg its sign. Modulo 2^32. */
static inline uint32_t twice_ds(uint32_t al, uint8_t lneg, uint32_t ar, uint8_t rneg, uint8_t *neg)
{
	if (lneg == rneg) {
		*neg = lneg;
		return al + ar;
	}
	if (al >= ar) {
		*neg = lneg;
		return al - ar;
	}
	*neg = rneg;
	return ar - al;
}

/* The distance += both [um * 2^17] with its sign: whole um and 17 bits of fraction. */
static inline void add_distance(struct odometry_counter *o, uint32_t both, uint8_t neg)
{
	if (both == 0)
		return;
	{
		uint32_t fr = both & 0x1ffffu;
		uint32_t wh = fx_shr_u32(both, 17);

		if (!neg) {
			fr += o->distance_frac;
			if (fr >= 0x20000u) {
				fr -= 0x20000u;
				wh++;
			}
			o->distance_um += wh;
		} else {
			if (fr > o->distance_frac) {
				fr = o->distance_frac + 0x20000u - fr;
				wh++;
			} else {
				fr = o->distance_frac - fr;
			}
			o->distance_um -= wh;
		}
		o->distance_frac = fr;
	}
}

int odometry_count(struct odometry_counter *o, uint16_t left_count, uint16_t right_count)
{
	int err = 0;
	uint32_t both;
	uint8_t neg;
	int32_t dtheta;

	{
		uint32_t before = o->heading_turn32;
		/* Counter differences as sign and magnitude (-32768 is 0x8000 either way). */
		uint16_t ml = (uint16_t)(left_count - o->left_count);
		uint16_t mr = (uint16_t)(right_count - o->right_count);
		uint8_t lneg = ml >= 0x8000u, rneg = mr >= 0x8000u;
		uint32_t h0 = o->heading_q64[0], h1 = o->heading_q64[1];
		const struct odometry_move *l, *r;
		struct odometry_move wide[2];
		uint32_t al, ar;

		o->left_count = left_count;
		o->right_count = right_count;
		if (lneg)
			ml = (uint16_t)(0u - ml);
		if (rneg)
			mr = (uint16_t)(0u - mr);
		if (ml < ODOMETRY_TABLE_COUNTS) {
			l = &o->left.move[ml];
		} else {
			err |= wheel_move_wide(&o->left, ml, &wide[0]);
			l = &wide[0];
		}
		if (mr < ODOMETRY_TABLE_COUNTS) {
			r = &o->right.move[mr];
		} else {
			err |= wheel_move_wide(&o->right, mr, &wide[1]);
			r = &wide[1];
		}
		/* The heading is a function of the counts alone (a sum modulo 2^64, one turn), so
		 * coming back to the same counts returns to the same heading bit for bit. The left
		 * wheel going forward turns the robot clockwise: its change is subtracted. */
		add_q64(&h0, &h1, l->turn_q64, !lneg);
		add_q64(&h0, &h1, r->turn_q64, rneg);
		o->heading_q64[0] = h0;
		o->heading_q64[1] = h1;
		o->heading_turn32 = h1 + (h0 >> 31);
		dtheta = fx_angle_diff(o->heading_turn32, before);

		al = l->travel_q16;
		ar = r->travel_q16;
		both = twice_ds(al, lneg, ar, rneg, &neg); /* below 2^32: al, ar below 2^31 */
	}
	o->step.dtheta_turn32 = dtheta;
	{
		int32_t ds = (int32_t)(fx_shr_u32(both, 17) + (fx_hi16(both) & 1u));

		o->step.ds_um = neg ? -ds : ds;
	}

	add_distance(o, both, neg);
	return err;
}

void odometry_arc_of(struct odometry_arc *a, int32_t left_q16, int32_t right_q16,
		     int32_t dtheta_turn32, uint32_t heading_turn32)
{
	uint32_t al = fx_mag32(left_q16), ar = fx_mag32(right_q16);
	uint8_t lneg = left_q16 < 0, rneg = right_q16 < 0;

	a->twice_ds_q16 = twice_ds(al, lneg, ar, rneg, &a->neg);
	/* Two magnitudes of 2^31 (saturated sums) wrap to 0: kept at the largest instead. */
	if (lneg == rneg && a->twice_ds_q16 < al)
		a->twice_ds_q16 = UINT32_MAX;
	a->dtheta_turn32 = dtheta_turn32;
	a->heading_turn32 = heading_turn32;
}

void odometry_advance(struct odometry_position *o, const struct odometry_arc *a)
{
	uint32_t both = a->twice_ds_q16, t, chord, mid;
	int32_t dtheta = a->dtheta_turn32;
	uint8_t neg = a->neg;

	/* Exact arc: the chord, ds * sin(dtheta/2) / (dtheta/2), along the mean heading. With no
	 * travel of the midpoint (standing still, or turning on the spot) the position does not
	 * move: the sine and cosine are skipped. */
	if (both == 0)
		return;
	t = fx_mag32(dtheta);
	chord = both; /* [um * 2^17] */
	/* The heading before the arc plus dtheta / 2 rounded half away from zero: the heading
	 * after it less the rest, |dtheta| / 2 rounded down. */
	mid = dtheta >= 0 ? a->heading_turn32 - (t >> 1) : a->heading_turn32 + (t >> 1);
	if (t >= ((uint32_t)1 << 24))
		chord -= arc_correction_wide(both, t);
	else if (t >= ((uint32_t)1 << 15))
		chord -= arc_correction(both, t);
	/* While the robot goes straight the mean heading repeats from arc to arc: the last sine
	 * and cosine are kept with their angle (same input, same output). */
	if (mid != o->trig_turn32) {
		fx_sincos(mid, &o->trig_sin_q30, &o->trig_cos_q30);
		o->trig_turn32 = mid;
	}
	/* chord [um * 2^17] * cos [2^-30] / 2^31 = [um * 2^16], below 2^31. */
	add_q16(&o->x_um, &o->x_frac, mul_shr31(chord, fx_mag32(o->trig_cos_q30)),
		neg != (o->trig_cos_q30 < 0));
	add_q16(&o->y_um, &o->y_frac, mul_shr31(chord, fx_mag32(o->trig_sin_q30)),
		neg != (o->trig_sin_q30 < 0));
}

int32_t odometry_travel_q16(const uint16_t k[2], int16_t counts)
{
	uint16_t m = counts >= 0 ? (uint16_t)counts : (uint16_t)(0u - (uint16_t)counts);
	uint8_t clamped;
	int32_t t = (int32_t)travel_of(k, m, &clamped);

	return counts >= 0 ? t : -t;
}

void odometry_set_position(struct odometry_position *o, int32_t x_um, int32_t y_um)
{
	o->x_um = (uint32_t)x_um;
	o->y_um = (uint32_t)y_um;
	o->x_frac = 0;
	o->y_frac = 0;
}
