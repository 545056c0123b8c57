/* The error radius (uncertainty.c) against closed forms: lateral variance of a straight line
 * ((kR + kL) L^3 / (3 b^2), physics.md), variance of a rotation in place, the systematic
 * offsets d^2 Ed / (2 b) and (Eb / b) theta d, monotonic growth, resets, saturation. */
#include <errno.h>
#include <math.h>
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>

#include <cmocka.h>

#include "uncertainty.h"
#include "uncertainty_setup.h"

#define PI_L 3.14159265358979323846264338327950288L
#define TRACK_UM 280000u

/* 0.1 mm^2/m per wheel (physics.md: 0.04..0.25), no systematic error, 99 %, 16 ticks. */
static const struct uncertainty_setup cfg_noise = {6554, 6554, TRACK_UM, 0, 0, 0, 776, 16, 1000};

static long double absl(long double v)
{
	return v < 0 ? -v : v;
}

/* The noise coefficient of the config [um^2 / um]. */
static long double k_of(uint32_t q16)
{
	return q16 / 65536.0L;
}

/* At 1 mm per tick on each wheel a batch ends every ceil(16384 / 2000) = 9 ticks
 * (UNCERTAINTY_BATCH_PATH_UM); it is propagated, and the radius refreshed, over the
 * UNCERTAINTY_STAGES ticks that follow. */
#define BATCH 9

/* The covariance's units: (4 um)^2 for x and y, (2^-16 rad)^2 for the heading. */
#define UM2(v) ((long double)(v)*UNCERTAINTY_POS_UM * UNCERTAINTY_POS_UM)
#define RAD2(v) ((long double)(v) / 4294967296.0L)

/* Ticks of constant wheel travels [um per tick]; the heading passed is that of the ideal robot,
 * integrated here from the same travels. */
static long double heading_rad;

static uint32_t heading_turn32(void)
{
	long double turns = heading_rad / (2 * PI_L);

	turns -= (long double)(long long)turns;
	if (turns < 0)
		turns += 1;
	return (uint32_t)(long long)(turns * 4294967296.0L);
}

static void drive(struct uncertainty *u, long double dl_um, long double dr_um, long ticks,
		  uint32_t track_um)
{
	for (long i = 0; i < ticks; i++) {
		heading_rad += (dr_um - dl_um) / track_um;
		uncertainty_update(u, (int32_t)(dl_um * 65536), (int32_t)(dr_um * 65536),
				   heading_turn32());
	}
}

/* Standing still until the travel so far has gone through the stages: the batch in progress
 * ends after batch_ticks, and each batch takes UNCERTAINTY_STAGES ticks more. */
static void settle(struct uncertainty *u)
{
	for (int i = 0; i < u->batch_ticks + 2 * UNCERTAINTY_STAGES + 2; i++)
		uncertainty_update(u, 0, 0, heading_turn32());
}

/* Straight line of L = 2 m at 1 m/s and 1 kHz along heading 0: Var(y) = (kR + kL) L^3 / (3 b^2)
 * from the heading's random walk, plus (kR + kL) L / 4 along x (Chong & Kleeman; physics.md). */
static void test_straight_lateral_sigma(void **state)
{
	struct uncertainty u;
	const long double len = 2e6L, k = k_of(cfg_noise.noise_left_mm2_per_m_q16) * 2;
	long double var_lat = k * len * len * len / (3.0L * TRACK_UM * TRACK_UM);
	long double var_long = k * len / 4;
	long double yy, xx, sigma;

	(void)state;
	assert_int_equal(uncertainty_setup_init(&u, &cfg_noise), 0);
	assert_int_equal(uncertainty_get_radius_mm(&u), 0);
	heading_rad = 0;
	drive(&u, 1000, 1000, 2000, TRACK_UM);
	settle(&u);
	yy = UM2(u.yy);
	xx = UM2(u.xx);
	print_message("lateral var %.0Lf um^2 (closed form %.0Lf), along %.0Lf (%.0Lf)\n", yy,
		      var_lat, xx, var_long);
	assert_true(absl(yy / var_lat - 1) <= 0.02L);
	assert_true(absl(xx / var_long - 1) <= 0.02L);
	/* The heading variance is (kR + kL) L / b^2 [rad^2]. */
	assert_true(absl(RAD2(u.tt) / (k * len / TRACK_UM / TRACK_UM) - 1) <= 0.02L);
	/* radius = ceil(k sigma_max), sigma_max^2 = the lateral variance here (xx being 70 times
	 * smaller and xy zero on this path): a bound, rounded up to the mm, so it is k sigma
	 * rounded up, or one more where the rounding of sigma (to 4 um) crossed a mm. */
	sigma = 0;
	while (sigma * sigma < yy)
		sigma += 1;
	print_message("radius %u mm, k sigma %.3Lf mm\n", uncertainty_get_radius_mm(&u),
		      3.03L * sigma / 1000);
	assert_true(uncertainty_get_radius_mm(&u) >=
		    (unsigned)((776.0L / 256 * sigma + 999.0L) / 1000));
	assert_true(uncertainty_get_radius_mm(&u) <=
		    (unsigned)((776.0L / 256 * (sigma + 4) + 999.0L) / 1000));
}

/* The same straight along 3/8 turn: the variance across the path is the same. */
static void test_straight_any_heading(void **state)
{
	struct uncertainty u;
	const long double len = 2e6L, k = k_of(cfg_noise.noise_left_mm2_per_m_q16) * 2;
	long double var_lat = k * len * len * len / (3.0L * TRACK_UM * TRACK_UM);
	long double c = -0.70710678118654752440L, s = 0.70710678118654752440L, across;

	(void)state;
	uncertainty_setup_init(&u, &cfg_noise);
	heading_rad = 3 * PI_L / 4;
	drive(&u, 1000, 1000, 2000, TRACK_UM);
	settle(&u);
	/* n^T Sigma n with n = (-sin, cos). */
	across = UM2(s * s * u.xx - 2 * s * c * u.xy + c * c * u.yy);
	assert_true(absl(across / var_lat - 1) <= 0.02L);
}

/* The same 2 m at 4 mm per tick (4 m/s at 1 kHz, 1 m/s at 250 Hz): batches that wait for the
 * stages would pass the 32.7 mm a wheel may travel in one, so they are handed over before it
 * and the variances keep their closed forms. */
static void test_straight_fast(void **state)
{
	struct uncertainty u;
	const long double len = 2e6L, k = k_of(cfg_noise.noise_left_mm2_per_m_q16) * 2;
	long double var_lat = k * len * len * len / (3.0L * TRACK_UM * TRACK_UM);
	long double var_long = k * len / 4;

	(void)state;
	uncertainty_setup_init(&u, &cfg_noise);
	heading_rad = 0;
	drive(&u, 4000, 4000, 500, TRACK_UM);
	settle(&u);
	print_message("at 4 mm per tick: lateral var %.0Lf um^2 (closed form %.0Lf), along %.0Lf "
		      "(%.0Lf)\n",
		      UM2(u.yy), var_lat, UM2(u.xx), var_long);
	assert_true(absl(UM2(u.yy) / var_lat - 1) <= 0.02L);
	assert_true(absl(UM2(u.xx) / var_long - 1) <= 0.02L);
}

/* In place, each wheel rolls pi b per turn: Var(theta) = (kR + kL) pi b n / b^2 and
 * Var(x) + Var(y) = (kR + kL) pi b n / 4, growing the radius. */
static void test_rotation_in_place_grows(void **state)
{
	struct uncertainty u;
	const long double k = k_of(cfg_noise.noise_left_mm2_per_m_q16) * 2;
	const long double path = PI_L * TRACK_UM * 10; /* 10 turns, per wheel */
	long ticks = (long)(path / 1000 + 0.5L);
	uint8_t r0;

	(void)state;
	uncertainty_setup_init(&u, &cfg_noise);
	uncertainty_reset(&u, 1000, 0);
	r0 = uncertainty_get_radius_mm(&u);
	assert_int_equal(r0, 1);
	heading_rad = 0;
	drive(&u, -1000, 1000, ticks, TRACK_UM);
	settle(&u);
	assert_true(absl(UM2(u.xx + u.yy) / (k * ticks * 1000.0L / 4 +
					     2 * (1000 * 256.0L / 776) * (1000 * 256.0L / 776)) -
			 1) <= 0.02L);
	assert_true(absl(RAD2(u.tt) / (k * ticks * 1000.0L / TRACK_UM / TRACK_UM) - 1) <= 0.02L);
	print_message("after 10 turns: radius %u mm\n", uncertainty_get_radius_mm(&u));
	assert_true(uncertainty_get_radius_mm(&u) > r0);
}

/* Only a wheel ratio error: after a straight d the offset is d^2 Ed / (2 b) (physics.md: 0.1 %,
 * 300 mm, 3 m -> 15 mm); here 2.907 m (323 whole batches) gives 14.08 mm, so the radius reads
 * 15. */
static void test_systematic_ratio(void **state)
{
	const struct uncertainty_setup cfg = {0, 0, 300000, 1000, 0, 0, 776, 16, 1000};
	struct uncertainty u;

	(void)state;
	uncertainty_setup_init(&u, &cfg);
	heading_rad = 0;
	drive(&u, 1000, 1000, 323 * BATCH, 300000);
	settle(&u);
	assert_int_equal(uncertainty_get_radius_mm(&u), 15);
	/* Going on to 3.105 m: 16.07 mm -> 17. */
	drive(&u, 1000, 1000, 22 * BATCH, 300000);
	settle(&u);
	assert_int_equal(uncertainty_get_radius_mm(&u), 17);
	/* Backing up along the same line undoes it (the heading error is proportional to the
	 * net distance): back at the start, the radius is 0 again. */
	drive(&u, -1000, -1000, 345 * BATCH, 300000);
	settle(&u);
	assert_int_equal(uncertainty_get_radius_mm(&u), 0);
}

/* Only a track error Eb: a turn in place by theta gives a heading error (Eb / b) theta, then a
 * straight d an offset (Eb / b) theta d: 1 mm / 280 mm * 2 pi * 1 m = 22.44 mm -> 23. */
static void test_systematic_track(void **state)
{
	const struct uncertainty_setup cfg = {0, 0, TRACK_UM, 0, 1000, 0, 776, 16, 1000};
	struct uncertainty u;
	long ticks = (long)(PI_L * TRACK_UM / 1000 + 0.5L);

	(void)state;
	uncertainty_setup_init(&u, &cfg);
	heading_rad = 0;
	drive(&u, -1000, 1000, ticks, TRACK_UM);
	settle(&u);
	/* ticks * 1 mm is pi b within 0.5 mm: the turn is 2 pi within 3.6e-3 rad. Turning in
	 * place moves nothing yet. */
	assert_int_equal(uncertainty_get_radius_mm(&u), 0);
	drive(&u, 1000, 1000, 1000, TRACK_UM);
	settle(&u);
	assert_int_equal(uncertainty_get_radius_mm(&u), 23);
	/* Turning back cancels the heading error (it is proportional to the net turn): the
	 * offset already made stays but stops growing. */
	drive(&u, 1000, -1000, ticks, TRACK_UM);
	drive(&u, 1000, 1000, 1000, TRACK_UM);
	settle(&u);
	assert_int_equal(uncertainty_get_radius_mm(&u), 23);
}

/* Every term on, along a path of forward straights, left arcs and left turns in place: the
 * radius never decreases. (Backing up or looping back may legitimately shrink it, as the
 * first-order systematic errors and the heading-correlated covariance undo themselves: see
 * test_systematic_ratio.) */
static void test_radius_monotonic(void **state)
{
	const struct uncertainty_setup cfg = {16384, 9830, TRACK_UM, 500, 100, 300, 776, 8, 1000};
	struct uncertainty u;
	uint8_t last = 0;
	static const long double moves[][3] = {
		{1000, 1000, 800}, {600, 1200, 1000}, {-800, 800, 100},   {1300, 1300, 900},
		{5, 10, 3000},     {0, 900, 300},     {1500, 1500, 2000},
	};

	(void)state;
	uncertainty_setup_init(&u, &cfg);
	heading_rad = 0;
	for (size_t m = 0; m < sizeof(moves) / sizeof(moves[0]); m++)
		for (long i = 0; i < (long)moves[m][2]; i += 10) {
			drive(&u, moves[m][0], moves[m][1], 10, TRACK_UM);
			assert_true(uncertainty_get_radius_mm(&u) >= last);
			last = uncertainty_get_radius_mm(&u);
		}
	print_message("path: radius %u mm, heading %.2Lf rad\n", last, heading_rad);
	assert_true(last > 5);
}

static void test_resets(void **state)
{
	struct uncertainty u, v;
	uint8_t before;
	/* sigma = bound / k rounded down to the um, 2000 * 256 / 776 -> 659 um; the variance in
	 * (4 um)^2 rounded down. */
	const int32_t sigma = 659;

	(void)state;
	uncertainty_setup_init(&u, &cfg_noise);
	uncertainty_reset(&u, 10000, 0);
	assert_int_equal(uncertainty_get_radius_mm(&u), 10);
	uncertainty_reset(&u, 10001, 0);
	assert_int_equal(uncertainty_get_radius_mm(&u), 11);

	/* Along x for 3 m: y is the uncertain one. Knowing y again leaves x's variance. */
	uncertainty_reset(&u, 0, 0);
	heading_rad = 0;
	drive(&u, 1000, 1000, 3000, TRACK_UM);
	settle(&u);
	before = uncertainty_get_radius_mm(&u);
	uncertainty_reset_axis(&u, UNCERTAINTY_AXIS_Y, 2000);
	assert_int_equal(u.yy, sigma * sigma / 16);
	assert_int_equal(u.xy, 0);
	assert_int_equal(u.yt, 0);
	/* The radius follows within the stages. */
	settle(&u);
	assert_true(uncertainty_get_radius_mm(&u) < before);
	assert_int_equal(uncertainty_get_radius_mm(&u), 2);

	/* Knowing the heading again slows the growth of the lateral error. */
	v = u;
	uncertainty_reset_heading(&v, 0);
	assert_int_equal(v.tt, 0);
	drive(&u, 1000, 1000, 1000, TRACK_UM);
	settle(&u);
	heading_rad = 0;
	drive(&v, 1000, 1000, 1000, TRACK_UM);
	settle(&v);
	assert_true(v.yy < u.yy);
	assert_true(uncertainty_get_radius_mm(&v) <= uncertainty_get_radius_mm(&u));

	/* A full reset with a heading bound: sigma_theta = bound / k. 2^20 turn32 is 1.534e-3
	 * rad, 100.53 units of 2^-16 rad, rounded up to 101; sigma 101 * 256 / 776 = 33.3, rounded
	 * up to 34. */
	uncertainty_reset(&u, 0, 1u << 20);
	assert_int_equal(u.tt, 34 * 34);
	assert_int_equal(uncertainty_get_radius_mm(&u), 0);
	/* ... which adds (sigma_theta d)^2 to the lateral variance: after 1 m (111 whole
	 * batches), sigma 518 um from the heading and 921 um from the wheels' noise: k sigma
	 * = 3.20 mm -> 4. */
	heading_rad = 0;
	drive(&u, 1000, 1000, 111 * BATCH, TRACK_UM);
	settle(&u);
	{
		long double len = 111 * BATCH * 1000.0L, st = 34.0L / 65536;
		long double want = st * st * len * len + k_of(cfg_noise.noise_left_mm2_per_m_q16) *
								 2 * len * len * len /
								 (3.0L * TRACK_UM * TRACK_UM);

		print_message("heading residual then 1 m: var %.0Lf (%.0Lf), radius %u\n",
			      UM2(u.yy), want, uncertainty_get_radius_mm(&u));
		assert_true(absl(UM2(u.yy) / want - 1) <= 0.02L);
	}
	assert_int_equal(uncertainty_get_radius_mm(&u), 4);
}

static void test_saturation(void **state)
{
	struct uncertainty_setup cfg = cfg_noise;
	struct uncertainty u;

	(void)state;
	cfg.noise_left_mm2_per_m_q16 = UNCERTAINTY_NOISE_Q16_MAX;
	cfg.noise_right_mm2_per_m_q16 = UNCERTAINTY_NOISE_Q16_MAX;
	assert_int_equal(uncertainty_setup_init(&u, &cfg), 0);
	heading_rad = 0;
	/* 16 mm^2/m per wheel: after 1 m the lateral sigma is 11.7 mm (radius 36 mm), after
	 * 16 m 750 mm. */
	drive(&u, 1000, 1000, 1000, TRACK_UM);
	assert_true(uncertainty_get_radius_mm(&u) < 255);
	drive(&u, 1500, 1500, 10000, TRACK_UM);
	assert_int_equal(uncertainty_get_radius_mm(&u), 255);
	drive(&u, 1500, 1500, 20000, TRACK_UM);
	assert_int_equal(uncertainty_get_radius_mm(&u), 255);
	assert_int_equal(u.saturated, 1);
	uncertainty_reset(&u, 5000, 0);
	assert_int_equal(uncertainty_get_radius_mm(&u), 5);
	uncertainty_reset(&u, 300000, 0);
	assert_int_equal(uncertainty_get_radius_mm(&u), 255);
	uncertainty_reset(&u, 254000, 0);
	assert_int_equal(uncertainty_get_radius_mm(&u), 254);
}

static void test_config_checks(void **state)
{
	struct uncertainty_setup cfg = cfg_noise;
	struct uncertainty u;

	(void)state;
	cfg.batch_ms = 0;
	assert_int_equal(uncertainty_setup_init(&u, &cfg), -EDOM);
	cfg = cfg_noise;
	cfg.k_q8 = 0;
	assert_int_equal(uncertainty_setup_init(&u, &cfg), -EDOM);
	cfg = cfg_noise;
	cfg.track_error_um = TRACK_UM + 1;
	assert_int_equal(uncertainty_setup_init(&u, &cfg), -EDOM);
	assert_int_equal(uncertainty_setup_init(&u, &cfg_noise), 0);
	assert_int_equal(uncertainty_setup_set(&u, &cfg), -EDOM);
	assert_int_equal(u.model.track_error_um, 0);
}

/* A component along a direction known again: the covariance turned into (along, lateral)
 * coordinates keeps the lateral variance and the lateral-heading covariance, the along one is
 * the bound's. Checked on an oblique straight line (30 degrees), against the rotated matrix. */
static void test_reset_along(void **state)
{
	struct uncertainty u, v, orig;
	long double c = cosl(PI_L / 6), s = sinl(PI_L / 6);
	/* Bound 2 mm at k = 3.03: sigma 659 um (var_of_bound), the variance in (4 um)^2. */
	long double lat, lt, sigma = 2000 * 256 / 776;
	uint8_t before;

	(void)state;
	assert_int_equal(uncertainty_setup_init(&u, &cfg_noise), 0);
	uncertainty_reset(&u, 0, 1u << 21); /* a heading error to make it oblique and large */
	heading_rad = PI_L / 6;
	drive(&u, 1000, 1000, 2000, TRACK_UM);
	settle(&u);
	orig = u;
	before = uncertainty_get_radius_mm(&u);
	lat = UM2(s * s * u.xx - 2 * c * s * u.xy + c * c * u.yy);
	lt = -s * u.xt + c * u.yt;
	v = u;
	/* Along the direction of travel: the large lateral error stays, the radius hardly moves. */
	uncertainty_reset_along(&v, 1u << 29 /* 45 deg: not the travel */, 2000);
	uncertainty_reset_along(&u, (uint32_t)(4294967296.0L / 12), 2000);
	/* Within the covariance's units, (4 um)^2 and 4 um * 2^-16 rad, and their rounding. */
	assert_true(absl(UM2(c * c * u.xx + 2 * c * s * u.xy + s * s * u.yy) - sigma * sigma) <=
		    3 * UM2(1));
	assert_true(absl(UM2(s * s * u.xx - 2 * c * s * u.xy + c * c * u.yy) - lat) <= 3 * UM2(1));
	assert_true(absl(c * u.xt + s * u.yt) <= 2);
	assert_true(absl(-s * u.xt + c * u.yt - lt) <= 2);
	/* The radius follows within the stages. */
	settle(&u);
	assert_true(uncertainty_get_radius_mm(&u) <= before);
	assert_true(uncertainty_get_radius_mm(&u) + 2 >= before);
	/* Across the travel: the lateral error is the one removed. */
	u = v;
	uncertainty_reset_along(&u, (uint32_t)(4294967296.0L / 12) + (1u << 30), 2000);
	settle(&u);
	assert_true(uncertainty_get_radius_mm(&u) < before / 2);
	/* The systematic terms keep only their part across the direction known. */
	u = v;
	u.d[0] = 1000;
	u.d[1] = 0;
	uncertainty_reset_along(&u, 0, 2000);
	assert_true(u.d[0] == 0 && u.d[1] == 0);
	u.d[0] = 0;
	u.d[1] = 1000;
	uncertainty_reset_along(&u, 0, 2000);
	assert_true(u.d[0] == 0 && u.d[1] == 1000);

	/* A cap: the lateral component (large) is brought down to a 2 mm bound, the along one
	 * (below it) is left as it was. */
	u = orig;
	v = orig;
	assert_int_equal(uncertainty_cap_along(&u, (uint32_t)(4294967296.0L / 12), 2000), 0);
	assert_memory_equal(&u, &v, sizeof u);
	assert_int_equal(
		uncertainty_cap_along(&u, (uint32_t)(4294967296.0L / 12) + (1u << 30), 2000), 1);
	settle(&u);
	assert_true(uncertainty_get_radius_mm(&u) < before / 2);
}

/* The heading bound reads back the bound a reset put in, rounded up. */
static void test_heading_bound(void **state)
{
	struct uncertainty u;
	uint32_t b;

	(void)state;
	assert_int_equal(uncertainty_setup_init(&u, &cfg_noise), 0);
	assert_int_equal(uncertainty_get_heading_bound_turn32(&u), 0);
	uncertainty_reset(&u, 0, 1u << 24);
	b = uncertainty_get_heading_bound_turn32(&u);
	assert_true(b >= (1u << 24) && b <= (1u << 24) + (1u << 24) / 200);
	u.saturated = 1;
	assert_int_equal(uncertainty_get_heading_bound_turn32(&u), 1u << 31);
}

/* New residual bounds keep what the old ones accumulated: after 3.105 m with a 1000 ppm ratio
 * bound (17 mm), bounds of 0 leave the radius at 17 mm, and backing up no longer undoes it (the
 * systematic offset became a fixed error); a reset of that coordinate clears it. */
static void test_new_bounds_keep_what_was_accumulated(void **state)
{
	const struct uncertainty_setup cfg = {0, 0, 300000, 1000, 0, 0, 776, 16, 1000};
	struct uncertainty_setup none = cfg;
	struct uncertainty u;

	(void)state;
	none.ratio_error_ppm = 0;
	uncertainty_setup_init(&u, &cfg);
	heading_rad = 0;
	drive(&u, 1000, 1000, 345 * BATCH, 300000);
	settle(&u);
	assert_int_equal(uncertainty_get_radius_mm(&u), 17);
	assert_int_equal(uncertainty_setup_set(&u, &none), 0);
	assert_int_equal(uncertainty_get_radius_mm(&u), 17);
	drive(&u, -1000, -1000, 345 * BATCH, 300000);
	settle(&u);
	assert_true(uncertainty_get_radius_mm(&u) >= 17);
	uncertainty_reset_axis(&u, UNCERTAINTY_AXIS_Y, 0);
	uncertainty_reset_axis(&u, UNCERTAINTY_AXIS_X, 0);
	assert_int_equal(uncertainty_get_radius_mm(&u), 0);
}

/* The heading's bound counts the systematic drift: a 1000 ppm ratio over 1 m of a 300 mm track
 * is 1000e-6 * 1 m / 0.3 m = 3.33 mrad (0.19 degree), with no noise at all. */
static void test_heading_bound_counts_the_drift(void **state)
{
	const struct uncertainty_setup cfg = {0, 0, 300000, 1000, 0, 0, 776, 16, 1000};
	struct uncertainty u;
	long double rad;

	(void)state;
	uncertainty_setup_init(&u, &cfg);
	heading_rad = 0;
	drive(&u, 1000, 1000, 1000, 300000);
	settle(&u);
	rad = uncertainty_get_heading_bound_turn32(&u) / 4294967296.0L * 2 * PI_L;
	assert_true(rad >= 1e-3L / 0.3L && rad <= 1e-3L / 0.3L * 1.01L);
}

/* A wheel's unseen travel w widens the position's bound by w / 2 and the heading's by w / b;
 * a position bound p adds p. From a radius of 0: 10 mm unseen gives 5 mm, then 10 mm of slide
 * 15 mm; the heading's bound 10 mm / 280 mm. */
static void test_widen(void **state)
{
	struct uncertainty u;
	long double rad;
	uint8_t r;

	(void)state;
	assert_int_equal(uncertainty_setup_init(&u, &cfg_noise), 0);
	uncertainty_widen(&u, 0, 10000);
	settle(&u);
	/* rounded up at each step: sigma to 4 um, then the millimetre */
	assert_in_range(uncertainty_get_radius_mm(&u), 5, 6);
	rad = uncertainty_get_heading_bound_turn32(&u) / 4294967296.0L * 2 * PI_L;
	assert_true(rad >= 10.0L / 280 && rad <= 10.0L / 280 * 1.01L);
	uncertainty_widen(&u, 10000, 0);
	settle(&u);
	assert_in_range(uncertainty_get_radius_mm(&u), 15, 16);
	r = uncertainty_get_radius_mm(&u);
	/* Nothing to widen by: nothing changes. */
	uncertainty_widen(&u, 0, 0);
	settle(&u);
	assert_int_equal(uncertainty_get_radius_mm(&u), r);
}

/* The covariance and the radius of two errors radii, equal. */
static void assert_same_cov(const struct uncertainty *a, const struct uncertainty *b)
{
	assert_int_equal(a->xx, b->xx);
	assert_int_equal(a->xy, b->xy);
	assert_int_equal(a->yy, b->yy);
	assert_int_equal(a->xt, b->xt);
	assert_int_equal(a->yt, b->yt);
	assert_int_equal(a->tt, b->tt);
	assert_int_equal(a->saturated, b->saturated);
	assert_int_equal(a->radius_um, b->radius_um);
	assert_int_equal(a->radius_mm, b->radius_mm);
}

/* A fix 5 mm off in x, of sigma 1 mm, no heading, nothing since. */
static const struct uncertainty_fix fix_5mm = {5000, 0, 0, 1000, 0, 0, 0, 0, 0};

/* From a 30 mm radius after some driving (systematic terms to fold: a ratio error). */
static void fusion_start(struct uncertainty *u)
{
	static const struct uncertainty_setup s = {6554, 6554, TRACK_UM, 300, 0, 0, 776, 16, 1000};

	heading_rad = 0;
	assert_int_equal(uncertainty_setup_init(u, &s), 0);
	uncertainty_reset(u, 30000, 0);
	drive(u, 1000, 1000, 200, TRACK_UM);
	settle(u);
}

/* A fusion in steps (uncertainty.h): begin, then x, y, the heading, the end, one step a planner
 * period with the odometry's update before each. The covariance is not touched until the end
 * (the batch of the travel meanwhile waits for the stages), the correction then pulls by the
 * noises (a prior of sigma 30 / k = 9.9 mm against 1 mm: 99 % of 5 mm), and the travel of the
 * fusion's periods is propagated after it. */
static void test_fusion_in_steps(void **state)
{
	struct uncertainty u, before;
	struct uncertainty_correction c;
	int steps = 0;

	(void)state;
	fusion_start(&u);
	before = u;
	assert_true(uncertainty_fuse_ready(&u));
	assert_int_equal(uncertainty_fuse_begin(&u, &fix_5mm), 0);
	assert_false(uncertainty_fuse_ready(&u)); /* one fusion at a time */
	for (;;) {
		enum uncertainty_fuse_result r;

		drive(&u, 1000, 1000, 1, TRACK_UM);
		r = uncertainty_fuse_step(&u, &c);
		steps++;
		if (r != UNCERTAINTY_FUSE_BUSY) {
			assert_int_equal(r, UNCERTAINTY_FUSE_FUSED);
			break;
		}
		assert_same_cov(&u, &before);
		assert_true(steps < 10);
	}
	assert_int_equal(steps, 4);
	assert_in_range(c.dx_um, 4900, 5000);
	assert_int_equal(c.dy_um, 0);
	assert_true(c.d2_q8 > 0);
	/* The radius follows: within k sigma of the fix's 1 mm, and the travel since (4 mm,
	 * then 96 more) propagated from there. */
	settle(&u);
	assert_in_range(uncertainty_get_radius_mm(&u), 3, 8);
	assert_int_equal(uncertainty_fuse_step(&u, &c), UNCERTAINTY_FUSE_ABANDONED); /* none */
	drive(&u, 1000, 1000, 96, TRACK_UM);
	settle(&u);
	assert_true(u.xx > 0 && u.yy > 0);
	assert_in_range(uncertainty_get_radius_mm(&u), 4, 12);
}

/* An outlier changes nothing: the covariance, the radius and the stages are those of before. */
static void test_fusion_outlier_changes_nothing(void **state)
{
	struct uncertainty u, before;
	struct uncertainty_correction c;
	struct uncertainty_fix far = fix_5mm;
	enum uncertainty_fuse_result r;

	(void)state;
	far.dx_um = 200000; /* 200 mm against 30 */
	far.gate_q8 = 16u << 8;
	fusion_start(&u);
	before = u;
	assert_int_equal(uncertainty_fuse_begin(&u, &far), 0);
	do
		r = uncertainty_fuse_step(&u, &c);
	while (r == UNCERTAINTY_FUSE_BUSY);
	assert_int_equal(r, UNCERTAINTY_FUSE_OUTLIER);
	assert_int_equal(c.d2_q8 > (16u << 8), 1);
	assert_same_cov(&u, &before);
	assert_int_equal(u.stage, before.stage);
	assert_true(uncertainty_fuse_ready(&u));
	/* Beyond the field: refused at once, nothing started. */
	far.dx_um = 300000000;
	assert_int_equal(uncertainty_fuse_begin(&u, &far), 1);
	assert_true(uncertainty_fuse_ready(&u));
}

/* What changes the covariance while a fusion is in flight abandons it before anything of it
 * was committed: the covariance is then exactly what the change alone makes of it, and the
 * stages run again. Each change, after each number of steps. */
enum change { WIDEN, RESET_AXIS, RESET_HEADING, RESET_ALONG, CAP_ALONG, NEW_MODEL, RESET, GIVE_UP };

static void change(struct uncertainty *u, enum change k)
{
	static const struct uncertainty_model m = {TRACK_UM, 500, 100, 200};

	switch (k) {
	case WIDEN:
		uncertainty_widen(u, 3000, 2000);
		break;
	case RESET_AXIS:
		uncertainty_reset_axis(u, UNCERTAINTY_AXIS_X, 2000);
		break;
	case RESET_HEADING:
		uncertainty_reset_heading(u, 1u << 22);
		break;
	case RESET_ALONG:
		uncertainty_reset_along(u, 1u << 29, 2000);
		break;
	case CAP_ALONG:
		assert_int_equal(uncertainty_cap_along(u, 1u << 29, 2000), 1);
		break;
	case NEW_MODEL:
		assert_int_equal(uncertainty_set_model(u, &m), 0);
		break;
	case RESET:
		uncertainty_reset(u, 7000, 1u << 20);
		break;
	case GIVE_UP:
		uncertainty_fuse_abandon(u);
		break;
	}
}

static void test_fusion_abandoned_by_a_change(void **state)
{
	(void)state;
	for (int k = WIDEN; k <= GIVE_UP; k++)
		for (int n = 0; n < 4; n++) {
			struct uncertainty u, twin;
			struct uncertainty_correction c;

			fusion_start(&u);
			twin = u;
			assert_int_equal(uncertainty_fuse_begin(&u, &fix_5mm), 0);
			for (int i = 0; i < n; i++)
				assert_int_equal(uncertainty_fuse_step(&u, &c),
						 UNCERTAINTY_FUSE_BUSY);
			change(&u, (enum change)k);
			change(&twin, (enum change)k);
			assert_int_equal(uncertainty_fuse_step(&u, &c), UNCERTAINTY_FUSE_ABANDONED);
			settle(&u);
			settle(&twin);
			assert_same_cov(&u, &twin);
			assert_true(uncertainty_fuse_ready(&u));
		}
}

int main(void)
{
	const struct CMUnitTest tests[] = {
		cmocka_unit_test(test_reset_along),
		cmocka_unit_test(test_heading_bound),
		cmocka_unit_test(test_new_bounds_keep_what_was_accumulated),
		cmocka_unit_test(test_heading_bound_counts_the_drift),
		cmocka_unit_test(test_widen),
		cmocka_unit_test(test_straight_lateral_sigma),
		cmocka_unit_test(test_straight_any_heading),
		cmocka_unit_test(test_straight_fast),
		cmocka_unit_test(test_rotation_in_place_grows),
		cmocka_unit_test(test_systematic_ratio),
		cmocka_unit_test(test_systematic_track),
		cmocka_unit_test(test_radius_monotonic),
		cmocka_unit_test(test_resets),
		cmocka_unit_test(test_saturation),
		cmocka_unit_test(test_config_checks),
		cmocka_unit_test(test_fusion_in_steps),
		cmocka_unit_test(test_fusion_outlier_changes_nothing),
		cmocka_unit_test(test_fusion_abandoned_by_a_change),
	};

	return cmocka_run_group_tests(tests, NULL, NULL);
}
