/* Line recalibration (recal.c): crossings of a known line built tick by tick from an ideal
 * straight motion, against the rules of recal.h: the position across the line, the heading
 * from a pair of sensors, and every refusal (angle, width, no line, two lines, disabled). */
#include <math.h>
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>

#include <cmocka.h>

#include "fixmath.h"
#include "recal.h"
#include "uncertainty_setup.h"

#define PI 3.14159265358979323846

/* Two sensors 40 mm either side of the axis; the line x = 0 along Y and y = 500 mm along X,
 * 20 mm wide. */
static void base_config(struct recal_config *c)
{
	*c = (struct recal_config){0};
	c->n_sensors = 2;
	c->sensors[0] = (struct recal_point){0, 40000};
	c->sensors[1] = (struct recal_point){0, -40000};
	c->n_lines = 2;
	c->lines[0] = (struct recal_line){0, -1000000, 0, 1000000, 20000};
	c->lines[1] = (struct recal_line){-1500000, 500000, 1500000, 500000, 20000};
	c->max_angle_turn32 = fx_deg_to_turn32(30);
	c->width_tol_um = 5000;
	c->margin_um = 10000;
	c->pair_window_um = 200000;
	c->bound_um = 1000;
	c->pair_bound_um = 300;
	c->straight_turn32 = fx_deg_to_turn32(1) / 4;
}

/* The result of driving the true robot straight from (x0, y0) at heading_deg, step_um per tick,
 * for n ticks, while the board believes it is offset by (ex, ey) um and eh_deg: the sensors see
 * the line from the truth, the estimate is moved along by the board's belief. */
struct run {
	int fixes;     /* ticks with a fix */
	int crossings; /* crossings applied (both sensors may leave the line in one tick) */
	int ignored;   /* crossings refused */
	uint8_t what;
	struct recal_fix last;
	int32_t est_x_um, est_y_um; /* estimate at the last fix, and truth then */
	double true_x_um, true_y_um, true_heading_deg;
	int heading_fixes;
};

static int on_line(const struct recal_config *c, double x, double y)
{
	for (uint8_t k = 0; k < c->n_lines; k++) {
		const struct recal_line *l = &c->lines[k];
		double half = l->width_um / 2.0;

		if (l->x0_um == l->x1_um && fabs(x - l->x0_um) <= half && y >= l->y0_um &&
		    y <= l->y1_um)
			return 1;
		if (l->y0_um == l->y1_um && fabs(y - l->y0_um) <= half && x >= l->x0_um &&
		    x <= l->x1_um)
			return 1;
	}
	return 0;
}

/* An uncertainty whose radius reads radius_mm and whose heading bound is heading_bound (the
 * reset's bounds, 99 %, no noise). */
static void uncertainty_known(struct uncertainty *u, uint8_t radius_mm, uint32_t heading_bound)
{
	static const struct uncertainty_setup quiet = {0, 0, 280000, 0, 0, 0, 776, 16, 1000};

	assert_int_equal(uncertainty_setup_init(u, &quiet), 0);
	uncertainty_reset(u, (uint32_t)radius_mm * 1000, heading_bound);
	assert_int_equal(uncertainty_get_radius_mm(u), radius_mm);
}

/* The line sensors' edge timing of the board's servo (recal_sense()), for one recalibration at a
 * time. */
static struct recal_sense sense;
static struct recal_edges edges;

/* One tick at the board's every-tick rate (slow_shift 0): the sensors' edges, then judged. */
static void recal_tick(struct recal *r, uint8_t lines, int enabled,
		       const struct odometry_pose *pose, int32_t dist_um,
		       const struct uncertainty *u, struct recal_fix *fix)
{
	recal_sense(&sense, &edges, lines & (uint8_t)((1u << r->cfg.n_sensors) - 1u), dist_um);
	recal_take(r, &edges, enabled, pose, dist_um, u, fix);
}

/* The estimate's heading turns by this much per step while the truth drives straight (a robot
 * re-aiming while it crosses, as the estimate sees it). */
static double est_turn_deg_per_step;

static struct run drive(const struct recal_config *c, double x0, double y0, double heading_deg,
			double step_um, int n, double ex, double ey, double eh_deg,
			uint8_t radius_mm, uint32_t heading_bound, int enabled)
{
	struct recal r;
	struct uncertainty u;
	struct run out = {0};
	double h = heading_deg * PI / 180, he = (heading_deg + eh_deg) * PI / 180;
	struct odometry_pose p;
	double est_x = x0 + ex, est_y = y0 + ey;

	p.heading_turn32 =
		(uint32_t)(int64_t)llround((heading_deg + eh_deg) / 360.0 * 4294967296.0);
	assert_int_equal(recal_init(&r, c), 0);
	recal_sense_init(&sense, &edges, 0);
	uncertainty_known(&u, radius_mm, heading_bound);
	for (int i = 1; i <= n; i++) {
		double s = i * step_um;
		double tx = x0 + s * cos(h), ty = y0 + s * sin(h);
		uint8_t lines = 0;
		struct recal_fix fix;

		for (uint8_t k = 0; k < c->n_sensors; k++) {
			double sx = c->sensors[k].x_um, sy = c->sensors[k].y_um;

			if (on_line(c, tx + sx * cos(h) - sy * sin(h),
				    ty + sx * sin(h) + sy * cos(h)))
				lines |= (uint8_t)(1u << k);
		}
		est_x += step_um * cos(he);
		est_y += step_um * sin(he);
		he += est_turn_deg_per_step * PI / 180;
		p.heading_turn32 = (uint32_t)(int64_t)llround(he / (2 * PI) * 4294967296.0);
		p.x_um = (int32_t)lround(est_x);
		p.y_um = (int32_t)lround(est_y);
		recal_tick(&r, lines, enabled, &p, (int32_t)lround(s), &u, &fix);
		if (fix.what) {
			out.fixes++;
			out.what |= fix.what;
			out.last = fix;
			if (fix.what & RECAL_FIX_HEADING)
				out.heading_fixes++;
			p = fix.pose;
			est_x = p.x_um;
			est_y = p.y_um;
			he = p.heading_turn32 / 4294967296.0 * 2 * PI;
			out.est_x_um = p.x_um;
			out.est_y_um = p.y_um;
			out.true_x_um = tx;
			out.true_y_um = ty;
			out.true_heading_deg = heading_deg;
		}
	}
	out.crossings = r.crossings;
	out.ignored = r.ignored;
	return out;
}

static double deg_of(uint32_t turn32)
{
	return (int32_t)turn32 / 4294967296.0 * 360.0;
}

/* Perpendicular crossing with the estimate 6 mm off across the line: x corrected to within the
 * tick's quantisation, y untouched; both sensors cross at once: no heading from the pair (its
 * bound is no better than a 0.1 degree heading's). */
static void test_perpendicular_crossing_fixes_x(void **state)
{
	struct recal_config c;
	struct run r;

	(void)state;
	base_config(&c);
	r = drive(&c, -200000, 0, 0, 1000, 400, 6000, -3000, 0, 10, fx_deg_to_turn32(1) / 10, 1);
	assert_int_equal(r.fixes, 1);
	assert_int_equal(r.crossings, 2);
	assert_true(r.what & RECAL_FIX_POSITION);
	assert_false(r.what & RECAL_FIX_HEADING);
	assert_true(fabs(r.est_x_um - r.true_x_um) <= 600); /* half a 1 mm tick */
	assert_true(fabs(r.est_y_um - r.true_y_um - (-3000)) <= 2);
	assert_int_equal(r.last.normal_turn32, 0);
	assert_int_equal(r.last.line, 0);
	assert_int_equal(r.last.bound_um, 1500);
}

/* At 20 degrees with a 0.8 degree heading error: the pair gives the heading back within
 * the quantisation's bound, and x is fixed with it. */
static void test_pair_gives_heading(void **state)
{
	struct recal_config c;
	struct run r;

	(void)state;
	base_config(&c);
	r = drive(&c, -300000, 0, 20, 300, 2000, 4000, 0, 0.8, 10, fx_deg_to_turn32(2), 1);
	assert_int_equal(r.heading_fixes, 1);
	assert_true(fabs(deg_of(r.last.pose.heading_turn32) - 20) < 0.15);
	assert_true(r.last.heading_bound_turn32 < fx_deg_to_turn32(1));
	assert_true(fabs(r.est_x_um - r.true_x_um) <= 500);
}

/* A pair assumes a straight path between its crossings: with the heading turning 0.6 degree
 * between them, the pair gives no heading (the position is still fixed); with 0.1 degree it
 * does, and its bound counts the turn. */
static void test_pair_needs_a_straight_path(void **state)
{
	struct recal_config c;
	struct run straight, turning, slight;

	(void)state;
	base_config(&c);
	straight = drive(&c, -300000, 0, 20, 300, 2000, 4000, 0, 0.8, 10, fx_deg_to_turn32(2), 1);
	est_turn_deg_per_step = 0.6 / 97; /* the sensors cross 29 mm apart: 97 steps */
	turning = drive(&c, -300000, 0, 20, 300, 2000, 4000, 0, 0.8, 10, fx_deg_to_turn32(2), 1);
	est_turn_deg_per_step = 0.1 / 97;
	slight = drive(&c, -300000, 0, 20, 300, 2000, 4000, 0, 0.8, 10, fx_deg_to_turn32(2), 1);
	est_turn_deg_per_step = 0;
	assert_int_equal(turning.heading_fixes, 0);
	assert_true(turning.what & RECAL_FIX_POSITION);
	assert_int_equal(slight.heading_fixes, 1);
	assert_true(slight.last.heading_bound_turn32 >
		    straight.last.heading_bound_turn32 + fx_deg_to_turn32(1) / 20);
}

/* Beyond 30 degrees from the normal: ignored, nothing applied. */
static void test_oblique_crossing_ignored(void **state)
{
	struct recal_config c;
	struct run r;

	(void)state;
	base_config(&c);
	r = drive(&c, -300000, 0, 40, 1000, 600, 4000, 0, 0, 10, fx_deg_to_turn32(2), 1);
	assert_int_equal(r.fixes, 0);
	assert_int_equal(r.ignored, 2);
}

/* The width seen is not the line's (a 60 mm wide stripe where the table says 20 mm). */
static void test_wrong_width_ignored(void **state)
{
	struct recal_config c;
	struct recal rr;
	struct uncertainty u;

	(void)state;
	base_config(&c);
	assert_int_equal(recal_init(&rr, &c), 0);
	recal_sense_init(&sense, &edges, 0);
	uncertainty_known(&u, 10, 0);
	{
		struct odometry_pose p = {0, 0, 0};
		struct recal_fix fix;
		int fixes = 0;

		/* 60 mm on the line, then off: the board knows a 20 mm line there. */
		for (int i = 0; i <= 100; i++) {
			p.x_um = -30000 + i * 1000;
			recal_tick(&rr, (i >= 1 && i <= 60) ? 3 : 0, 1, &p, p.x_um + 30000, &u,
				   &fix);
			fixes += fix.what != 0;
		}
		assert_int_equal(fixes, 0);
		assert_int_equal(rr.ignored, 2);
	}
}

/* No known line within the radius of the crossing: ignored. Two within it: ambiguous, ignored. */
static void test_no_line_or_two_lines_ignored(void **state)
{
	struct recal_config c;
	struct run r;

	(void)state;
	base_config(&c);
	/* The estimate 40 mm off with a 10 mm radius: the line is out of reach. */
	r = drive(&c, -200000, 0, 0, 1000, 400, 40000, 0, 0, 10, 0, 1);
	assert_int_equal(r.fixes, 0);
	/* A second line 30 mm from the first: both within a 25 mm radius. */
	c.n_lines = 3;
	c.lines[2] = (struct recal_line){30000, -1000000, 30000, 1000000, 20000};
	r = drive(&c, -200000, 0, 0, 1000, 400, 0, 0, 0, 25, 0, 1);
	assert_int_equal(r.fixes, 0);
	assert_int_equal(r.ignored, 4);
	/* With a 5 mm radius the same crossings are unambiguous. */
	r = drive(&c, -200000, 0, 0, 1000, 400, 0, 0, 0, 5, 0, 1);
	assert_int_equal(r.crossings, 4);
	assert_int_equal(r.ignored, 0);
}

/* Disabled (no option, or not driving straight): nothing, even across a line. */
static void test_disabled_does_nothing(void **state)
{
	struct recal_config c;
	struct run r;

	(void)state;
	base_config(&c);
	r = drive(&c, -200000, 0, 0, 1000, 400, 6000, 0, 0, 10, 0, 0);
	assert_int_equal(r.fixes, 0);
	assert_int_equal(r.ignored, 0);
	/* The same run enabled does cross (the test above is not vacuous). */
	r = drive(&c, -200000, 0, 0, 1000, 400, 6000, 0, 0, 10, 0, 1);
	assert_int_equal(r.crossings, 2);
}

/* Horizontal line crossed going down (-90 degrees): y corrected, normal a quarter turn. */
static void test_horizontal_line(void **state)
{
	struct recal_config c;
	struct run r;

	(void)state;
	base_config(&c);
	r = drive(&c, 300000, 700000, -90, 1000, 400, 0, 5000, 0, 10, 0, 1);
	assert_int_equal(r.crossings, 2);
	assert_true(fabs(r.est_y_um - r.true_y_um) <= 600);
	assert_int_equal(r.last.normal_turn32, (uint32_t)1 << 30);
	assert_int_equal(r.last.line, 1);
}

static void test_config_checked(void **state)
{
	struct recal_config c;
	struct recal r;

	(void)state;
	base_config(&c);
	c.n_sensors = RECAL_MAX_SENSORS + 1;
	assert_int_equal(recal_init(&r, &c), -1);
	base_config(&c);
	c.max_angle_turn32 = (uint32_t)1 << 30;
	assert_int_equal(recal_init(&r, &c), -1);
	base_config(&c);
	c.pair_window_um = 0;
	assert_int_equal(recal_init(&r, &c), -1);
}

int main(void)
{
	const struct CMUnitTest tests[] = {
		cmocka_unit_test(test_perpendicular_crossing_fixes_x),
		cmocka_unit_test(test_pair_gives_heading),
		cmocka_unit_test(test_pair_needs_a_straight_path),
		cmocka_unit_test(test_oblique_crossing_ignored),
		cmocka_unit_test(test_wrong_width_ignored),
		cmocka_unit_test(test_no_line_or_two_lines_ignored),
		cmocka_unit_test(test_disabled_does_nothing),
		cmocka_unit_test(test_horizontal_line),
		cmocka_unit_test(test_config_checked),
	};

	return cmocka_run_group_tests(tests, NULL, NULL);
}
