/* Odometry (odometry.c) driven as a robot would drive its encoders, against closed forms:
 * straight lines, rotations in place, arcs, a square, counter wrap-around, heading drift.
 *
 * The test programs are not linked with libm, so the few sines and cosines of the closed forms
 * come from a long double Taylor series (1e-19 accurate) defined here. */
#include <errno.h>
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <string.h>

#include <cmocka.h>

#include "fixmath.h"
#include "odometry.h"

#define PI_L 3.14159265358979323846264338327950288L
#define TURN32 4294967296.0L

/* 25 mm free wheels, 16384 counts per revolution: 2 pi 25000 / 16384 = 9.5874 um per count. */
#define K_Q16 628319u
#define TRACK_UM 280000u

/* The board's odometry for these tests, driven through the calls the board makes: the servo's
 * counter counts every tick and sums the period's heading change (servo.c, board_tick() step
 * 1-2); at the period's end the planner moves the position along the period's one arc, the
 * travels from the counts since the last period's end with the factors the period's ticks had,
 * the heading the estimate's plus the period's change (planner.c, step_pose()). New factors are
 * checked and derived apart, then installed between two periods (board_calibrate(),
 * take_wheels()); a new pose is the planner's alone (planner_set_pose()). odo_update() is a tick
 * that ends a period: the board with a period of one tick. */
struct odo {
	struct odometry_counter c;  /* the servo's */
	struct odometry_position p; /* the planner's */
	uint32_t heading_turn32;    /* the estimate's heading, the planner's */
	uint32_t dtheta_turn32;     /* the period's heading change so far (the snapshot's sum) */
	uint16_t base[2];           /* the counts at the last period's end (planner.free_base) */
	int32_t travel_left_q16;    /* the last period's wheel travels [um * 2^16] */
	int32_t travel_right_q16;
};

static int odo_init(struct odo *o, const struct odometry_config *cfg, uint16_t left, uint16_t right)
{
	o->heading_turn32 = 0;
	o->dtheta_turn32 = 0;
	o->base[0] = left;
	o->base[1] = right;
	o->travel_left_q16 = 0;
	o->travel_right_q16 = 0;
	odometry_position_init(&o->p, 0, 0);
	return odometry_counter_init(&o->c, cfg, left, right, 0);
}

/* One tick of the servo. */
static int odo_tick(struct odo *o, uint16_t left, uint16_t right)
{
	int err = odometry_count(&o->c, left, right);

	o->dtheta_turn32 += (uint32_t)o->c.step.dtheta_turn32;
	return err;
}

/* The period's end: the planner's step 0. */
static void odo_period_end(struct odo *o)
{
	struct odometry_arc a;
	int32_t dtheta = (int32_t)o->dtheta_turn32;

	o->travel_left_q16 =
		odometry_travel_q16(o->c.left.k, (int16_t)(o->c.left_count - o->base[0]));
	o->travel_right_q16 =
		odometry_travel_q16(o->c.right.k, (int16_t)(o->c.right_count - o->base[1]));
	o->base[0] = o->c.left_count;
	o->base[1] = o->c.right_count;
	o->heading_turn32 += (uint32_t)dtheta;
	o->dtheta_turn32 = 0;
	odometry_arc_of(&a, o->travel_left_q16, o->travel_right_q16, dtheta, o->heading_turn32);
	odometry_advance(&o->p, &a);
}

static int odo_update(struct odo *o, uint16_t left, uint16_t right)
{
	int err = odo_tick(o, left, right);

	odo_period_end(o);
	return err;
}

/* New wheel factors and track between two periods: 0, or -EDOM (nothing changes). The pose,
 * the counted heading and the distance are kept. */
static int odo_set_config(struct odo *o, const struct odometry_config *cfg)
{
	struct odometry_wheel wheels[2];

	if (odometry_check_config(cfg))
		return -EDOM;
	assert_int_equal(odometry_derive_config(cfg, wheels), 0);
	odometry_install_config(&o->c, cfg, wheels);
	return 0;
}

static struct odometry_pose odo_pose(const struct odo *o)
{
	struct odometry_pose p;

	p.x_um = odometry_get_x_um(&o->p);
	p.y_um = odometry_get_y_um(&o->p);
	p.heading_turn32 = o->heading_turn32;
	return p;
}

/* A new pose, as SET_NEW_POS gives it: the planner's position and heading; the servo's counter
 * goes on. */
static void odo_set_pose(struct odo *o, const struct odometry_pose *pose)
{
	odometry_set_position(&o->p, pose->x_um, pose->y_um);
	o->heading_turn32 = pose->heading_turn32;
}

static const struct odometry_config cfg_default = {K_Q16, K_Q16, TRACK_UM};

static long double ref_sin(long double t)
{
	long double q = t / (PI_L / 2);
	long long n = (long long)(q >= 0 ? q + 0.5L : q - 0.5L);
	long double r = t - (long double)n * (PI_L / 2);
	long double term_s = r, term_c = 1.0L, s = 0.0L, c = 0.0L;

	for (int k = 0; k < 20; k++) {
		s += term_s;
		c += term_c;
		term_s *= -r * r / ((2 * k + 2) * (2 * k + 3));
		term_c *= -r * r / ((2 * k + 1) * (2 * k + 2));
	}
	switch (((n % 4) + 4) % 4) {
	case 0:
		return s;
	case 1:
		return c;
	case 2:
		return -s;
	default:
		return -c;
	}
}

static long double ref_cos(long double t)
{
	return ref_sin(t + PI_L / 2);
}

static long long round_ll(long double v)
{
	return v >= 0 ? (long long)(v + 0.5L) : -(long long)(-v + 0.5L);
}

static long double absl(long double v)
{
	return v < 0 ? -v : v;
}

/* Heading [turn32 units, wrapped to -2^31..2^31) of a rad value, for comparisons. */
static long double turn32_error(uint32_t got, long double want_rad)
{
	long double want = want_rad / (2 * PI_L) * TURN32;
	long double d = (long double)got - want;

	d -= TURN32 * (long double)round_ll(d / TURN32);
	return d;
}

/* A robot with two free wheels: it moves its wheels by real distances, the counters follow
 * the rounded cumulative travel (as a quadrature decoder would) and wrap at 65536. */
struct robot {
	long double left_um, right_um;
	uint16_t left0, right0;
	long double left_um_per_count, right_um_per_count;
};

static void robot_init(struct robot *r, const struct odometry_config *cfg, uint16_t l0, uint16_t r0)
{
	r->left_um = 0;
	r->right_um = 0;
	r->left0 = l0;
	r->right0 = r0;
	r->left_um_per_count = cfg->left_um_per_count_q16 / 65536.0L;
	r->right_um_per_count = cfg->right_um_per_count_q16 / 65536.0L;
}

static long long robot_left_counts(const struct robot *r)
{
	return round_ll(r->left_um / r->left_um_per_count);
}

static long long robot_right_counts(const struct robot *r)
{
	return round_ll(r->right_um / r->right_um_per_count);
}

static int robot_tick(struct robot *r, struct odo *o, long double dl_um, long double dr_um)
{
	r->left_um += dl_um;
	r->right_um += dr_um;
	return odo_update(o, (uint16_t)((r->left0 + robot_left_counts(r)) & 0xffff),
			  (uint16_t)((r->right0 + robot_right_counts(r)) & 0xffff));
}

/* Trapezoidal speed profile over distance d [um] with 1 m/s, 1.5 m/s^2 at 1 kHz: the travel of
 * each tick, so that the sum is d. */
static int trapezoid_ticks(long double d, long double *step, int max_ticks)
{
	const long double v = 1000.0L, a = 1.5L; /* [um/tick], [um/tick^2] */
	long double done = 0, speed = 0, sign = d < 0 ? -1 : 1;
	int n = 0;

	d = absl(d);
	while (done < d && n < max_ticks) {
		long double remaining = d - done;

		if (speed * speed / (2 * a) >= remaining)
			speed -= a;
		else if (speed < v)
			speed += a;
		if (speed < a)
			speed = a;
		if (speed > remaining)
			speed = remaining;
		step[n++] = sign * speed;
		done += speed;
	}
	return n;
}

static long double steps[20000];

static void drive_straight(struct robot *r, struct odo *o, long double d_um)
{
	int n = trapezoid_ticks(d_um, steps, 20000);

	for (int i = 0; i < n; i++)
		assert_int_equal(robot_tick(r, o, steps[i], steps[i]), 0);
}

static void drive_rotation(struct robot *r, struct odo *o, long double angle_rad)
{
	int n = trapezoid_ticks(angle_rad * TRACK_UM / 2, steps, 20000);

	for (int i = 0; i < n; i++)
		assert_int_equal(robot_tick(r, o, -steps[i], steps[i]), 0);
}

static void test_no_jump_at_start(void **state)
{
	struct odo o;
	struct odometry_pose p;
	struct odometry_step s;

	(void)state;
	assert_int_equal(odo_init(&o, &cfg_default, 12345, 54321), 0);
	assert_int_equal(odo_update(&o, 12345, 54321), 0);
	p = odo_pose(&o);
	s = o.c.step;
	assert_int_equal(p.x_um, 0);
	assert_int_equal(p.y_um, 0);
	assert_int_equal(p.heading_turn32, 0);
	assert_int_equal(s.ds_um, 0);
	assert_int_equal(s.dtheta_turn32, 0);
	/* 5 counts: 5 * 628319 / 65536 = 47.94 um. */
	assert_int_equal(odo_update(&o, 12350, 54326), 0);
	p = odo_pose(&o);
	s = o.c.step;
	assert_int_equal(p.x_um, 48);
	assert_int_equal(p.y_um, 0);
	assert_int_equal(o.travel_left_q16, 5 * (int32_t)K_Q16);
	assert_int_equal(o.travel_right_q16, 5 * (int32_t)K_Q16);
	assert_int_equal(s.ds_um, 48);
	assert_int_equal(odometry_get_distance_um(&o.c), 48);
}

static void test_straight_lines(void **state)
{
	struct odo o;
	struct robot r;
	struct odometry_pose p, start = {100000, -50000, 0};
	long long n;
	long double x, y, th;

	(void)state;
	odo_init(&o, &cfg_default, 0, 0);
	robot_init(&r, &cfg_default, 0, 0);
	drive_straight(&r, &o, 1.8e6L);
	n = robot_left_counts(&r);
	assert_true(n == robot_right_counts(&r));
	p = odo_pose(&o);
	/* Straight along heading 0 the integration is exact: x = counts * factor, y = 0. */
	assert_int_equal(p.x_um, round_ll((long double)n * K_Q16 / 65536));
	assert_int_equal(p.y_um, 0);
	assert_int_equal(p.heading_turn32, 0);
	assert_int_equal(odometry_get_distance_um(&o.c), p.x_um);

	/* Backwards from another pose, along 30 degrees. */
	start.heading_turn32 = fx_deg_to_turn32(30);
	odo_set_pose(&o, &start);
	robot_init(&r, &cfg_default, (uint16_t)n, (uint16_t)n);
	drive_straight(&r, &o, -1.2e6L);
	n = robot_left_counts(&r);
	x = 100000 + (long double)n * K_Q16 / 65536 * ref_cos(PI_L / 6);
	y = -50000 + (long double)n * K_Q16 / 65536 * ref_sin(PI_L / 6);
	th = PI_L / 6;
	p = odo_pose(&o);
	print_message("30 deg line: x %d (%.2Lf) y %d (%.2Lf)\n", p.x_um, x, p.y_um, y);
	assert_true(absl(p.x_um - x) <= 1.0L);
	assert_true(absl(p.y_um - y) <= 1.0L);
	assert_true(absl(turn32_error(p.heading_turn32, th)) <= 1.0L);
}

static void test_rotation_in_place(void **state)
{
	struct odo o;
	struct robot r;
	struct odometry_pose p;
	long long nl, nr;
	long double th;

	(void)state;
	odo_init(&o, &cfg_default, 1000, 2000);
	robot_init(&r, &cfg_default, 1000, 2000);
	drive_rotation(&r, &o, 2 * PI_L / 3);
	nl = robot_left_counts(&r);
	nr = robot_right_counts(&r);
	p = odo_pose(&o);
	th = (long double)(nr - nl) * K_Q16 / 65536 / TRACK_UM;
	print_message("rotation: heading %u, error %.2Lf units, x %d y %d\n", p.heading_turn32,
		      turn32_error(p.heading_turn32, th), p.x_um, p.y_um);
	assert_true(absl(turn32_error(p.heading_turn32, th)) <= 2.0L);
	/* The wheels moved by opposite counts every tick: the centre did not move at all. */
	assert_int_equal(p.x_um, 0);
	assert_int_equal(p.y_um, 0);
	drive_rotation(&r, &o, -7 * PI_L / 3);
	nl = robot_left_counts(&r);
	nr = robot_right_counts(&r);
	th = (long double)(nr - nl) * K_Q16 / 65536 / TRACK_UM;
	p = odo_pose(&o);
	assert_true(absl(turn32_error(p.heading_turn32, th)) <= 2.0L);
	assert_int_equal(p.x_um, 0);
	assert_int_equal(p.y_um, 0);
}

/* Constant counts per tick: the path is exactly a circle of radius b/2 (dr + dl) / (dr - dl),
 * whatever the angle per tick, if the arc integration is exact. */
static void check_circle(int32_t dl, int32_t dr, int ticks, long double tol_um)
{
	struct odo o;
	struct odometry_pose p;
	uint16_t l = 0, r = 0;
	long double k = K_Q16 / 65536.0L;
	long double radius = TRACK_UM / 2.0L * (dr + dl) / (dr - dl);
	long double phi = (long double)(dr - dl) * k / TRACK_UM * ticks;
	long double x = radius * ref_sin(phi), y = radius * (1 - ref_cos(phi));

	odo_init(&o, &cfg_default, 0, 0);
	for (int i = 0; i < ticks; i++) {
		l = (uint16_t)(l + dl);
		r = (uint16_t)(r + dr);
		assert_int_equal(odo_update(&o, l, r), 0);
	}
	p = odo_pose(&o);
	print_message("circle R %.1Lf mm, %.4Lf rad: x %d (%.2Lf) y %d (%.2Lf)\n", radius / 1000,
		      phi, p.x_um, x, p.y_um, y);
	assert_true(absl(p.x_um - x) <= tol_um);
	assert_true(absl(p.y_um - y) <= tol_um);
	assert_true(absl(turn32_error(p.heading_turn32, phi)) <= 2.0L);
}

static void test_arcs_of_known_radius(void **state)
{
	(void)state;
	/* R = 700 mm, 6.8e-4 rad per tick, a quarter turn and more. */
	check_circle(40, 60, 2294, 2.0L);
	check_circle(40, 60, 9000, 2.0L);
	/* R = 149.7 mm, 0.1 rad per tick (14.9 mm per tick): without the sin(x)/x factor the
	 * chord would be 6 um too long every tick. */
	check_circle(100, 3000, 16, 2.0L);
	check_circle(100, 3000, 60, 2.0L);
	/* Backwards and turning right. */
	check_circle(-700, -500, 3000, 2.0L);
}

/* A quarter circle of 500 mm radius at 1 m/s with speed ramps, counters rounded from the real
 * wheel travel: the closed form is x = y = R. The counts are at most half a count (4.8 um) from
 * the ideal wheels, which bounds the heading error by 4.8 um / b and the position error by that
 * times the 785 mm path plus the wheel error itself: below 20 um. */
static void test_driven_quarter_circle(void **state)
{
	struct odo o;
	struct robot r;
	struct odometry_pose p;
	const long double radius = 500000;
	int n = trapezoid_ticks(radius * PI_L / 2, steps, 20000);

	(void)state;
	odo_init(&o, &cfg_default, 40000, 7);
	robot_init(&r, &cfg_default, 40000, 7);
	for (int i = 0; i < n; i++) {
		long double dphi = steps[i] / radius;

		assert_int_equal(robot_tick(&r, &o, dphi * (radius - TRACK_UM / 2.0L),
					    dphi * (radius + TRACK_UM / 2.0L)),
				 0);
	}
	p = odo_pose(&o);
	print_message("quarter circle: x %d y %d heading error %.1Lf units\n", p.x_um, p.y_um,
		      turn32_error(p.heading_turn32, PI_L / 2));
	assert_true(absl(p.x_um - radius) <= 20.0L);
	assert_true(absl(p.y_um - radius) <= 20.0L);
	/* 2 * 4.8 um / 280 mm = 3.4e-5 rad = 23400 units */
	assert_true(absl(turn32_error(p.heading_turn32, PI_L / 2)) <= 23400.0L);
}

/* The position moved once per period of 2^shift ticks, as the board does with two rates (the
 * counter every tick, the position along the period's summed travels and heading change): a
 * quarter circle of 500 mm radius then a straight with speed ramps, and a rotation in place.
 * Every 8 ticks the curvature changes within a period only at the ramps' ends and at the turn's
 * start and end, and the position stays within 1 um of the one moved every tick. */
static void drive_in_periods(uint8_t shift, struct odo *o)
{
	struct robot r;
	const long double radius = 500000;
	int n = trapezoid_ticks(radius * PI_L / 2, steps, 20000), total = 0;
	uint8_t ends = 1;

	odo_init(o, &cfg_default, 40000, 7);
	robot_init(&r, &cfg_default, 40000, 7);
	for (int leg = 0; leg < 3; leg++) {
		if (leg == 1)
			n = trapezoid_ticks(300000, steps, 20000);
		if (leg == 2)
			n = trapezoid_ticks(PI_L / 3 * TRACK_UM / 2, steps, 20000);
		for (int i = 0; i < n; i++, total++) {
			long double dphi = steps[i] / radius;
			long double dl = leg == 0   ? dphi * (radius - TRACK_UM / 2.0L)
					 : leg == 1 ? steps[i]
						    : -steps[i];
			long double dr = leg == 0 ? dphi * (radius + TRACK_UM / 2.0L) : steps[i];

			r.left_um += dl;
			r.right_um += dr;
			assert_int_equal(
				odo_tick(o, (uint16_t)((r.left0 + robot_left_counts(&r)) & 0xffff),
					 (uint16_t)((r.right0 + robot_right_counts(&r)) & 0xffff)),
				0);
			ends = ((total + 1) & ((1 << shift) - 1)) == 0;
			if (ends)
				odo_period_end(o);
		}
	}
	/* The last period, however short. */
	if (!ends)
		odo_period_end(o);
}

static void test_position_in_periods(void **state)
{
	struct odo o, t;
	struct odometry_pose p, q;

	(void)state;
	drive_in_periods(0, &t);
	drive_in_periods(3, &o);
	p = odo_pose(&o);
	q = odo_pose(&t);
	print_message("position in periods of 8 ticks: (%d, %d) um, per tick (%d, %d) um\n", p.x_um,
		      p.y_um, q.x_um, q.y_um);
	assert_int_equal(p.heading_turn32, q.heading_turn32);
	assert_int_equal(p.heading_turn32, odometry_get_heading_turn32(&o.c));
	assert_true(p.x_um - q.x_um <= 1 && q.x_um - p.x_um <= 1);
	assert_true(p.y_um - q.y_um <= 1 && q.y_um - p.y_um <= 1);
	/* It did move along the path: 500 mm up, then 300 mm along y. */
	assert_true(p.x_um > 490000 && p.x_um < 510000);
	assert_true(p.y_um > 790000 && p.y_um < 810000);
}

/* A 1 m square: straight, quarter turn in place, four times. The corners follow from the
 * counts: the heading of each side is (Nr - Nl) k / b, each side is N k long. Sides and turns
 * are whole counts of each wheel (the nearest to 1 m and a quarter turn), so that the counters
 * of a side are straight and those of a turn are a rotation in place: otherwise the rounding of
 * the counters makes the robot move by half counts along the way, which is not the closed form
 * (test_driven_quarter_circle bounds that effect). */
/* A wheel's travel over a count change is k |n| with n's sign, looked up below
 * ODOMETRY_TABLE_COUNTS and multiplied above, clamped at ODOMETRY_STEP_Q16_MAX: a period's
 * travel from its counts is the sum of its ticks'. */
static void test_travel_of_counts(void **state)
{
	struct odo o;
	struct odometry_config wide = cfg_default;

	(void)state;
	assert_int_equal(odo_init(&o, &cfg_default, 0, 0), 0);
	for (int n = -3000; n <= 3000; n += (n > -40 && n < 40) ? 1 : 37) {
		assert_int_equal(odometry_travel_q16(o.c.left.k, (int16_t)n), n * (int32_t)K_Q16);
		assert_int_equal(odometry_travel_q16(o.c.right.k, (int16_t)n), n * (int32_t)K_Q16);
	}
	/* Clamped beyond 2^31 [um * 2^16]: 3417 counts of K_Q16. */
	assert_int_equal(odometry_travel_q16(o.c.left.k, 3417), 3417 * (int32_t)K_Q16);
	assert_int_equal(odometry_travel_q16(o.c.left.k, 3418), ODOMETRY_STEP_Q16_MAX);
	assert_int_equal(odometry_travel_q16(o.c.left.k, INT16_MIN), -ODOMETRY_STEP_Q16_MAX);
	/* 256 um a count: 127 counts are 2^31 - 2^24 [um * 2^16], 128 clamp. */
	wide.left_um_per_count_q16 = ODOMETRY_UM_PER_COUNT_Q16_MAX;
	assert_int_equal(odo_set_config(&o, &wide), 0);
	assert_int_equal(odometry_travel_q16(o.c.left.k, 127), 127 * ((int32_t)1 << 24));
	assert_int_equal(odometry_travel_q16(o.c.left.k, -127), -127 * ((int32_t)1 << 24));
	assert_int_equal(odometry_travel_q16(o.c.left.k, 128), ODOMETRY_STEP_Q16_MAX);
	assert_int_equal(odometry_travel_q16(o.c.left.k, -128), -ODOMETRY_STEP_Q16_MAX);
	assert_int_equal(odometry_travel_q16(o.c.left.k, INT16_MIN), -ODOMETRY_STEP_Q16_MAX);
	assert_int_equal(odometry_travel_q16(o.c.right.k, 100), 100 * (int32_t)K_Q16);
}

static void test_square(void **state)
{
	struct odo o;
	struct robot r;
	struct odometry_pose p;
	long double k = K_Q16 / 65536.0L, x = 0, y = 0;
	long long quarter = round_ll(PI_L / 2 * TRACK_UM / 2 / k);
	long long side_counts = round_ll(1e6L / k);

	(void)state;
	odo_init(&o, &cfg_default, 0, 0);
	robot_init(&r, &cfg_default, 0, 0);
	for (int side = 0; side < 4; side++) {
		long long l0 = robot_left_counts(&r), r0 = robot_right_counts(&r);
		long double th = (long double)(r0 - l0) * k / TRACK_UM;
		long double len;

		drive_straight(&r, &o, side_counts * k);
		len = (long double)(robot_left_counts(&r) - l0) * k;
		assert_true(robot_right_counts(&r) - r0 == robot_left_counts(&r) - l0);
		x += len * ref_cos(th);
		y += len * ref_sin(th);
		p = odo_pose(&o);
		print_message("corner %d: x %d (%.2Lf) y %d (%.2Lf)\n", side, p.x_um, x, p.y_um, y);
		assert_true(absl(p.x_um - x) <= 2.0L);
		assert_true(absl(p.y_um - y) <= 2.0L);
		drive_rotation(&r, &o, 2 * quarter * k / TRACK_UM);
	}
	p = odo_pose(&o);
	assert_true(absl(p.x_um - x) <= 2.0L);
	assert_true(absl(p.y_um - y) <= 2.0L);
	/* Each whole-count turn is within k / b rad of a quarter turn: the square closes within
	 * (1 + 2 + 3) m * k / b = 205 um. */
	assert_true(absl(x) <= 6e6L * k / TRACK_UM && absl(y) <= 6e6L * k / TRACK_UM);
	assert_true(absl(turn32_error(p.heading_turn32, 8 * quarter * k / TRACK_UM)) <= 2.0L);
}

static void test_counter_wraparound(void **state)
{
	struct odo o;
	const struct odometry_config fine = {60000, 60000, TRACK_UM};
	uint16_t l = 65500, r = 30;
	struct odometry_pose p;

	(void)state;
	odo_init(&o, &cfg_default, l, r);
	/* Left wraps forwards past 65535, right wraps backwards past 0 on the way back. */
	for (int i = 0; i < 10; i++) {
		l = (uint16_t)(l + 200);
		r = (uint16_t)(r + 200);
		assert_int_equal(odo_update(&o, l, r), 0);
	}
	p = odo_pose(&o);
	assert_int_equal(p.x_um, round_ll(2000.0L * K_Q16 / 65536));
	assert_int_equal(p.heading_turn32, 0);
	for (int i = 0; i < 15; i++) {
		l = (uint16_t)(l - 200);
		r = (uint16_t)(r - 200);
		assert_int_equal(odo_update(&o, l, r), 0);
	}
	p = odo_pose(&o);
	assert_int_equal(p.x_um, round_ll(-1000.0L * K_Q16 / 65536));
	assert_int_equal(p.y_um, 0);
	assert_int_equal(p.heading_turn32, 0);
	/* The largest steps a 16-bit counter can tell apart, +32767 and -32768 counts, with a
	 * factor small enough (0.92 um per count) for them to stay below 32.8 mm. */
	odo_init(&o, &fine, 0, 0);
	assert_int_equal(odo_update(&o, 32767, 32767), 0);
	assert_int_equal(o.c.step.ds_um, round_ll(32767.0L * 60000 / 65536));
	assert_int_equal(odo_update(&o, 65535, 65535), 0);
	assert_int_equal(o.c.step.ds_um, round_ll(-32768.0L * 60000 / 65536));
}

static uint64_t rng_state = 0x9e3779b97f4a7c15u;

static uint32_t rng_next(void)
{
	rng_state ^= rng_state << 13;
	rng_state ^= rng_state >> 7;
	rng_state ^= rng_state << 17;
	return (uint32_t)(rng_state >> 32);
}

/* 10^6 ticks of back-and-forth rotation with unequal wheel factors: the heading stays within 2
 * units (4.6e-10 turn) of its closed form from the absolute counts, and coming back to the
 * starting counts gives back the starting heading bit for bit. */
static void test_heading_does_not_drift(void **state)
{
	static int16_t dl_log[500000], dr_log[500000];
	const struct odometry_config cfg = {628319, 629001, 281234};
	const struct odometry_pose start = {0, 0, 0x12345678u};
	struct odo o;
	long long nl = 0, nr = 0;
	uint16_t l = 777, r = 65000;
	long double worst = 0;

	(void)state;
	odo_init(&o, &cfg, l, r);
	odo_set_pose(&o, &start);
	for (int i = 0; i < 1000000; i++) {
		int32_t dl, dr;

		if (i < 500000) {
			int32_t w = (int32_t)(rng_next() % 121) - 60;

			dr = w + (int32_t)(rng_next() % 3) - 1;
			dl = -w + (int32_t)(rng_next() % 3) - 1;
			dl_log[i] = (int16_t)dl;
			dr_log[i] = (int16_t)dr;
		} else {
			dl = -dl_log[999999 - i];
			dr = -dr_log[999999 - i];
		}
		nl += dl;
		nr += dr;
		l = (uint16_t)(l + dl);
		r = (uint16_t)(r + dr);
		assert_int_equal(odo_update(&o, l, r), 0);
		if (i % 997 == 0) {
			long double th = ((long double)nr * cfg.right_um_per_count_q16 -
					  (long double)nl * cfg.left_um_per_count_q16) /
					 65536 / cfg.track_um;
			long double e =
				absl(turn32_error(odo_pose(&o).heading_turn32,
						  th + 2 * PI_L * start.heading_turn32 / TURN32));

			if (e > worst)
				worst = e;
		}
	}
	print_message("worst heading error %.2Lf units\n", worst);
	assert_true(worst <= 2.0L);
	assert_true(nl == 0 && nr == 0);
	assert_int_equal(odo_pose(&o).heading_turn32, start.heading_turn32);
}

/* 100 turns the same way: the heading follows the closed form within 2 units plus the effective
 * track's relative error (below 1e-10, odometry.c) times the angle. */
static void test_many_turns(void **state)
{
	struct odo o;
	uint16_t l = 0, r = 0;
	long long n = 0;
	long double worst = 0;

	(void)state;
	odo_init(&o, &cfg_default, 0, 0);
	while (n < 100LL * 91749) { /* a turn is pi b = 91749 counts of each wheel */
		n += 150;
		l = (uint16_t)(l - 150);
		r = (uint16_t)(r + 150);
		assert_int_equal(odo_update(&o, l, r), 0);
		if (n % 15000 == 0) {
			long double th = 2.0L * n * K_Q16 / 65536 / TRACK_UM;
			long double tol = 2.0L + th / (2 * PI_L) * TURN32 * 1e-10L;
			long double e = absl(turn32_error(odo_pose(&o).heading_turn32, th));

			assert_true(e <= tol);
			if (e > worst)
				worst = e;
		}
	}
	print_message("100 turns: worst heading error %.2Lf units\n", worst);
	assert_int_equal(odo_pose(&o).x_um, 0);
	assert_int_equal(odo_pose(&o).y_um, 0);
}

/* Right factor 0.1 % larger: equal counts drive a circle of radius b/2 (kr + kl) / (kr - kl)
 * (280 m), and the lateral offset after d is about d^2 (Ed - 1) / (2 b) (physics.md). */
static void test_wheel_gain_effect(void **state)
{
	const struct odometry_config cfg = {628319, 628947, TRACK_UM};
	struct odo o;
	struct odometry_pose p;
	uint16_t c = 0;
	long double kl = cfg.left_um_per_count_q16 / 65536.0L;
	long double kr = cfg.right_um_per_count_q16 / 65536.0L;
	long double radius = TRACK_UM / 2.0L * (kr + kl) / (kr - kl);
	long double phi = 100.0L * 2000 * (kr - kl) / TRACK_UM;
	long double d = 100.0L * 2000 * (kr + kl) / 2;

	(void)state;
	odo_init(&o, &cfg, 0, 0);
	for (int i = 0; i < 2000; i++) {
		c = (uint16_t)(c + 100);
		assert_int_equal(odo_update(&o, c, c), 0);
	}
	p = odo_pose(&o);
	print_message("gain: x %d (%.1Lf) y %d (%.1Lf), d^2 dE / 2b = %.1Lf\n", p.x_um,
		      radius * ref_sin(phi), p.y_um, radius * (1 - ref_cos(phi)),
		      d * d * (kr / kl - 1) / (2 * TRACK_UM));
	assert_true(absl(p.x_um - radius * ref_sin(phi)) <= 1.0L);
	assert_true(absl(p.y_um - radius * (1 - ref_cos(phi))) <= 1.0L);
	assert_true(absl(p.y_um - d * d * (kr / kl - 1) / (2 * TRACK_UM)) <= 10.0L);
	assert_true(absl(turn32_error(p.heading_turn32, phi)) <= 2.0L);
}

static void test_config_and_pose_changes(void **state)
{
	struct odo o;
	struct odometry_config bad = cfg_default, wide = cfg_default;
	struct odometry_pose p, q = {-123456, 654321, 1u << 30};
	uint16_t l = 0, r = 0;

	(void)state;
	bad.track_um = 0;
	assert_int_equal(odo_init(&o, &bad, 0, 0), -EDOM);
	assert_int_equal(odo_init(&o, &cfg_default, 0, 0), 0);
	for (int i = 0; i < 500; i++) {
		l = (uint16_t)(l + 30);
		r = (uint16_t)(r + 50);
		odo_update(&o, l, r);
	}
	p = odo_pose(&o);
	assert_int_equal(odo_set_config(&o, &bad), -EDOM);
	wide.track_um = 2 * TRACK_UM;
	assert_int_equal(odo_set_config(&o, &wide), 0);
	assert_true(odo_pose(&o).x_um == p.x_um);
	assert_true(odo_pose(&o).y_um == p.y_um);
	assert_true(odo_pose(&o).heading_turn32 == p.heading_turn32);
	/* With twice the track the same counts turn half as much. */
	l = (uint16_t)(l - 1000);
	r = (uint16_t)(r + 1000);
	odo_update(&o, l, r);
	assert_true(absl(turn32_error(odo_pose(&o).heading_turn32 - p.heading_turn32,
				      2000.0L * K_Q16 / 65536 / (2 * TRACK_UM))) <= 2.0L);

	odo_set_pose(&o, &q);
	p = odo_pose(&o);
	assert_int_equal(p.x_um, q.x_um);
	assert_int_equal(p.y_um, q.y_um);
	assert_int_equal(p.heading_turn32, q.heading_turn32);
	/* Straight on along +y (heading a quarter turn). */
	l = (uint16_t)(l + 1000);
	r = (uint16_t)(r + 1000);
	odo_update(&o, l, r);
	p = odo_pose(&o);
	assert_int_equal(p.x_um, q.x_um);
	assert_int_equal(p.y_um, q.y_um + round_ll(1000.0L * K_Q16 / 65536));

	/* 20000 counts of 256 um in one tick is 5 m: reported, and clamped to 32.8 mm. */
	wide.left_um_per_count_q16 = ODOMETRY_UM_PER_COUNT_Q16_MAX;
	wide.right_um_per_count_q16 = ODOMETRY_UM_PER_COUNT_Q16_MAX;
	assert_int_equal(odo_set_config(&o, &wide), 0);
	assert_int_equal(odo_update(&o, (uint16_t)(l + 20000), (uint16_t)(r + 20000)), -ERANGE);
	assert_int_equal(o.travel_left_q16, ODOMETRY_STEP_Q16_MAX);
}

int main(void)
{
	const struct CMUnitTest tests[] = {
		cmocka_unit_test(test_no_jump_at_start),
		cmocka_unit_test(test_straight_lines),
		cmocka_unit_test(test_rotation_in_place),
		cmocka_unit_test(test_arcs_of_known_radius),
		cmocka_unit_test(test_driven_quarter_circle),
		cmocka_unit_test(test_position_in_periods),
		cmocka_unit_test(test_travel_of_counts),
		cmocka_unit_test(test_square),
		cmocka_unit_test(test_counter_wraparound),
		cmocka_unit_test(test_heading_does_not_drift),
		cmocka_unit_test(test_many_turns),
		cmocka_unit_test(test_wheel_gain_effect),
		cmocka_unit_test(test_config_and_pose_changes),
	};

	return cmocka_run_group_tests(tests, NULL, NULL);
}
