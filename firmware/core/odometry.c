/* Odometry from two free encoder wheels (see odometry.h and docs/odometry.md). */
#include "odometry.h"

#include <errno.h>

#include "fixmath.h"

/* 2 pi * 2^30, pi/4 * 2^32, 2^32/6, 2^32/120. */
#define TWO_PI_Q30 6746518852LL
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

/* The heading is kept as an exact integer (turn_acc_q16) whose conversion to turns needs the
 * turn period; computing the reciprocal here, once, keeps divisions out of the tick. */
static void derive(struct odometry *o)
{
	/* 2 pi * 2^30 is rounded to 0.5 in 6.7e9: the period is then that of a track 2e-5 um
	 * off the configured one, far below any calibration. */
	int64_t period = ((int64_t)o->cfg.track_um * TWO_PI_Q30 + (1 << 13)) / (1 << 14);
	uint64_t rem = 1, q = 0;
	uint8_t bits = 0, i;

	while ((period >> bits) != 0)
		bits++;
	/* Long division 2^(40 + bits) / period, rounded: q lands in (2^40, 2^41]. */
	for (i = 0; i < 40 + bits; i++) {
		rem <<= 1;
		q <<= 1;
		if (rem >= (uint64_t)period) {
			rem -= (uint64_t)period;
			q |= 1;
		}
	}
	if (2 * rem >= (uint64_t)period)
		q++;
	o->turn_period_q16 = period;
	o->turn_inv = q;
	o->turn_bits = bits;
}

/* acc * 2^32 / period rounded, for 0 <= acc < period < 2^40. The 80-bit product is split at
 * 2^20 so that both halves fit in 64 bits; the error stays below 0.51 unit. */
static uint32_t heading_of_acc(const struct odometry *o, int64_t acc)
{
	uint64_t a = (uint64_t)acc;
	uint64_t hi = (a >> 20) * o->turn_inv;
	uint64_t lo = ((a & 0xfffffu) * o->turn_inv + ((uint64_t)1 << 19)) >> 20;
	uint8_t shift = (uint8_t)(o->turn_bits - 12);

	return (uint32_t)((hi + lo + ((uint64_t)1 << (shift - 1))) >> shift);
}

/* Counter difference of a free-running uint16 counter, -32768..32767, without converting an
 * out-of-range unsigned value to a signed type. */
static int32_t count_delta(uint16_t now, uint16_t before)
{
	uint16_t d = (uint16_t)(now - before);

	return d < 32768u ? (int32_t)d : (int32_t)d - 65536;
}

static int64_t wheel_travel_q16(int32_t counts, uint32_t um_per_count_q16, int *err)
{
	int64_t t = (int64_t)counts * um_per_count_q16;

	if (t > ODOMETRY_STEP_Q16_MAX) {
		*err = -ERANGE;
		return ODOMETRY_STEP_Q16_MAX;
	}
	if (t < -(int64_t)ODOMETRY_STEP_Q16_MAX) {
		*err = -ERANGE;
		return -(int64_t)ODOMETRY_STEP_Q16_MAX;
	}
	return t;
}

/* sin(x) / x for x = dtheta / 2 [2^-30]: 1 - x^2/6 + x^4/120, whose next term x^6/5040 is below
 * 2e-10 while |dtheta| <= 0.2 rad per tick (60 rad/s at 300 Hz). */
static int64_t half_sinc_q30(int32_t dtheta_turn32)
{
	int64_t x = fx_shr_round64((int64_t)dtheta_turn32 * QUARTER_PI_Q32, 32);
	int64_t x2 = fx_shr_round64(x * x, 30);
	int64_t x4 = fx_shr_round64(x2 * x2, 30);

	return FX_ONE_Q30 - fx_shr_round64(x2 * SIXTH_Q32, 32) +
	       fx_shr_round64(x4 * ONE_120TH_Q32, 32);
}

int odometry_init(struct odometry *o, const struct odometry_config *cfg, uint16_t left_count,
		  uint16_t right_count)
{
	if (!config_valid(cfg))
		return -EDOM;
	o->cfg = *cfg;
	derive(o);
	o->left_count = left_count;
	o->right_count = right_count;
	o->turn_acc_q16 = 0;
	o->heading_base_turn32 = 0;
	o->heading_turn32 = 0;
	o->x_q16 = 0;
	o->y_q16 = 0;
	o->distance_q17 = 0;
	o->step.left_q16 = 0;
	o->step.right_q16 = 0;
	o->step.ds_um = 0;
	o->step.dtheta_turn32 = 0;
	o->trig_valid = 0;
	return 0;
}

int odometry_set_config(struct odometry *o, const struct odometry_config *cfg)
{
	if (!config_valid(cfg))
		return -EDOM;
	/* The accumulated differential travel only means something with the old track: fold it
	 * into the base heading. */
	o->heading_base_turn32 = o->heading_turn32;
	o->turn_acc_q16 = 0;
	o->cfg = *cfg;
	derive(o);
	return 0;
}

int odometry_update(struct odometry *o, uint16_t left_count, uint16_t right_count)
{
	int err = 0;
	int64_t left = wheel_travel_q16(count_delta(left_count, o->left_count),
					o->cfg.left_um_per_count_q16, &err);
	int64_t right = wheel_travel_q16(count_delta(right_count, o->right_count),
					 o->cfg.right_um_per_count_q16, &err);
	int64_t both = left + right; /* twice the midpoint travel [um * 2^16] */
	uint32_t before = o->heading_turn32;
	int32_t dtheta;
	uint32_t mid;
	int64_t chord_q17;
	int32_t s, c;

	o->left_count = left_count;
	o->right_count = right_count;

	/* The heading is a function of an exact integer sum, so returning to the same counts
	 * returns to the same heading bit for bit. |right - left| <= 2^32 and the period is
	 * above 2^32, so one correction each way is enough. When right == left the sum, hence the
	 * heading, is unchanged: the conversion is skipped (the same bits, fewer cycles). */
	if (right != left) {
		o->turn_acc_q16 += right - left;
		if (o->turn_acc_q16 >= o->turn_period_q16)
			o->turn_acc_q16 -= o->turn_period_q16;
		if (o->turn_acc_q16 < 0)
			o->turn_acc_q16 += o->turn_period_q16;
		o->heading_turn32 = o->heading_base_turn32 + heading_of_acc(o, o->turn_acc_q16);
	}
	dtheta = fx_angle_diff(o->heading_turn32, before);

	/* Exact arc: the chord, ds * sin(dtheta/2) / (dtheta/2), along the mean heading. With no
	 * travel of the midpoint (standing still, or turning on the spot) the chord is 0 and the
	 * position does not move: the sine and cosine are skipped. sinc(0) is exactly 1. */
	if (both != 0) {
		chord_q17 = dtheta != 0 ? fx_shr_round64(both * half_sinc_q30(dtheta), 30) : both;
		mid = before + (uint32_t)fx_shr_round(dtheta, 1);
		/* While the robot goes straight the mean heading repeats from tick to tick: the
		 * last sine and cosine are kept with their angle (same input, same output). */
		if (mid != o->trig_turn32 || !o->trig_valid) {
			fx_sincos(mid, &o->trig_sin_q30, &o->trig_cos_q30);
			o->trig_turn32 = mid;
			o->trig_valid = 1;
		}
		s = o->trig_sin_q30;
		c = o->trig_cos_q30;
		o->x_q16 += fx_shr_round64(chord_q17 * c, 31);
		o->y_q16 += fx_shr_round64(chord_q17 * s, 31);
		o->distance_q17 += both;
	}

	o->step.left_q16 = (int32_t)left;
	o->step.right_q16 = (int32_t)right;
	o->step.ds_um = (int32_t)fx_shr_round64(both, 17);
	o->step.dtheta_turn32 = dtheta;
	return err;
}

struct odometry_pose odometry_get_pose(const struct odometry *o)
{
	struct odometry_pose p;

	p.x_um = fx_sat32(fx_shr_round64(o->x_q16, 16));
	p.y_um = fx_sat32(fx_shr_round64(o->y_q16, 16));
	p.heading_turn32 = o->heading_turn32;
	return p;
}

void odometry_set_pose(struct odometry *o, const struct odometry_pose *pose)
{
	o->x_q16 = (int64_t)pose->x_um * 65536;
	o->y_q16 = (int64_t)pose->y_um * 65536;
	o->heading_base_turn32 = pose->heading_turn32;
	o->heading_turn32 = pose->heading_turn32;
	o->turn_acc_q16 = 0;
}

struct odometry_step odometry_get_step(const struct odometry *o)
{
	return o->step;
}

int32_t odometry_get_distance_um(const struct odometry *o)
{
	return fx_sat32(fx_shr_round64(o->distance_q17, 17));
}
