/* The orders module (orders.c) through orders.h, on a small kinematic robot that follows its set
 * points: GOTO turning then going straight, GOTO_REVERSE, STOP, an order replaced while running,
 * the speed and acceleration limits and the grip's share of them, the settle and its timeout,
 * the hold after a shock, border and basket recalibration; match play's PAUSE and RESUME, the
 * speed scale and a pass-through corner's curve, and the re-aims orders_aimed() reports; then a
 * randomized soak that checks, at every update, what the module promises whatever the orders
 * and the measures. */
#include <math.h>
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include <cmocka.h>

#include "fixmath.h"
#include "orders.h"
#include "protocol.h"
#include "protocol_defs.h"

#define PI 3.14159265358979323846
#define TRACK_UM 160000     /* drive track */
#define GRIP_UM_S2 3000000  /* 3 m/s^2 */
#define FRONT_UM 125000     /* encoder axis midpoint to the front edge */
#define HALF_LENGTH 1500000 /* field borders at x = +/- 1.5 m */
#define HALF_WIDTH 1000000  /* and y = +/- 1 m */

/* The reference robot's orders settings (board_default_config()'s values), rounded to figures
 * that give whole expected numbers below. */
static void base_config(struct orders_config *c)
{
	memset(c, 0, sizeof(*c));
	c->drive_track_um = TRACK_UM;
	c->heading_window_turn32 = fx_deg_to_turn32(5);
	c->freeze_radius_um = 30000;
	c->arrive_window_um = 500;
	c->arrive_speed_um_s = 5000;
	c->settle_ms = 3;
	c->settle_timeout_ms = 1000;
	c->push_speed_um_s = 150000;
	c->push_max_um = 500000;
	c->basket_contact_um = 150000;
	c->aim_delay_steps = 0;
	c->jerk_um_s3 = 0;
	c->grip_um_s2 = GRIP_UM_S2;
	c->rot_grip_q8 = 500; /* 1.95 */
	c->basket_lateral_um = 16000;
	c->basket_bound_um = 1500;
	c->borders = 1;
	c->half_length_um = HALF_LENGTH;
	c->half_width_um = HALF_WIDTH;
	c->front_um = FRONT_UM;
	c->front_shock_mask = 0x07;
	c->border_speed_um_s = 100000;
	c->border_extra_um = 60000;
	c->border_block_um = 5000;
	c->border_depth_um = 8000;
	c->square_ms = 300;
	c->backoff_um = 60000;
	c->border_bound_um = 1000;
	c->border_heading_bound_turn32 = fx_deg_to_turn32(1) / 4;
}

/* The one place that creates the module, at rate_hz updates a second. The speed of one
 * free-wheel count: half of a 78.54 um count, rounded up, per update, as planner_init()
 * derives it. */
static int init_orders(struct orders *o, const struct orders_config *cfg, uint16_t rate_hz,
		       int32_t dist_um, int32_t angle_um)
{
	return orders_init(o, cfg, rate_hz, 40 * (int32_t)rate_hz, dist_um, angle_um);
}

static void make_orders(struct orders *o, const struct orders_config *cfg, uint16_t rate_hz)
{
	assert_int_equal(init_orders(o, cfg, rate_hz, 0, 0), 0);
}

/* A robot that follows its set points, each axis stopping stick_um short of it (dry friction),
 * optionally blocked by a wall across x (its front edge against it) or a basket ahead. Its pose
 * is the truth; the estimate the module is given is the truth plus an offset, until a
 * recalibration. Heading from the angle axis: one turn is pi * drive track of arc. */
struct robot {
	uint16_t hz;
	double x_um, y_um, h0_turn;
	int32_t dist_um, angle_um;
	int32_t dist_speed_um_s, angle_speed_um_s;
	int32_t stick_um;
	double ex_um, ey_um; /* estimate - truth */
	double wall_x_um;    /* > 0: the front edge stops at this x, and presses shocks */
	uint8_t wall_shocks; /* what touching the wall presses */
	double basket_x_um;  /* > 0: the basket switch closes (and the robot stops) at this x */
	int32_t noise_um;    /* soak: measured axes and position off by up to this */
	uint8_t shocks, basket;
};

static void robot_init(struct robot *r, uint16_t hz, double x_um, double y_um, double h_turn)
{
	memset(r, 0, sizeof(*r));
	r->hz = hz;
	r->x_um = x_um;
	r->y_um = y_um;
	r->h0_turn = h_turn;
}

static double robot_heading(const struct robot *r)
{
	return r->h0_turn + r->angle_um / (PI * TRACK_UM);
}

static uint32_t turn32_of(double turn)
{
	double f = turn - floor(turn);

	return (uint32_t)((uint64_t)llround(f * 4294967296.0) & 0xFFFFFFFFu);
}

static uint64_t rng_state = 0x2545f4914f6cdd1du;

/* xorshift64: deterministic test inputs. */
static uint64_t rng_next(void)
{
	rng_state ^= rng_state << 13;
	rng_state ^= rng_state >> 7;
	rng_state ^= rng_state << 17;
	return rng_state;
}

static int32_t rng_range(int32_t lo, int32_t hi)
{
	return lo + (int32_t)(rng_next() % (uint64_t)((int64_t)hi - lo + 1));
}

static struct orders_measure robot_measure(const struct robot *r)
{
	struct orders_measure m;
	int32_t n = r->noise_um;

	memset(&m, 0, sizeof(m));
	m.pose.x_um = (int32_t)lround(r->x_um + r->ex_um) + (n ? rng_range(-n, n) : 0);
	m.pose.y_um = (int32_t)lround(r->y_um + r->ey_um) + (n ? rng_range(-n, n) : 0);
	m.pose.heading_turn32 = turn32_of(robot_heading(r));
	m.dist_um = r->dist_um + (n ? rng_range(-n, n) : 0);
	m.angle_um = r->angle_um + (n ? rng_range(-n, n) : 0);
	m.dist_speed_um_s = r->dist_speed_um_s;
	m.angle_speed_um_s = r->angle_speed_um_s;
	m.shocks = r->shocks;
	m.basket_contact = r->basket;
	return m;
}

/* How far an axis moves towards its set point this update. */
static int32_t follow_step(int32_t err, int32_t stick)
{
	if (err > stick)
		return err - stick;
	if (err < -stick)
		return err + stick;
	return 0;
}

static void robot_follow(struct robot *r, const struct orders *o)
{
	int32_t dd = follow_step(o->sp_dist.pos_um - r->dist_um, r->stick_um);
	int32_t da = follow_step(o->sp_angle.pos_um - r->angle_um, r->stick_um);
	double h = robot_heading(r);

	if (r->wall_x_um > 0 && dd > 0) {
		double room = (r->wall_x_um - FRONT_UM - r->x_um) / cos(2 * PI * h);

		if (dd > room)
			dd = room > 0 ? (int32_t)floor(room) : 0;
	}
	if (r->basket_x_um > 0 && dd > 0 && r->x_um + dd > r->basket_x_um)
		dd = r->x_um < r->basket_x_um ? (int32_t)floor(r->basket_x_um - r->x_um) : 0;
	r->angle_um += da;
	h = (h + robot_heading(r)) / 2;
	r->x_um += dd * cos(2 * PI * h);
	r->y_um += dd * sin(2 * PI * h);
	r->dist_um += dd;
	r->dist_speed_um_s = dd * r->hz;
	r->angle_speed_um_s = da * r->hz;
	r->shocks = 0;
	if (r->wall_x_um > 0 && r->x_um + FRONT_UM >= r->wall_x_um - 1)
		r->shocks = r->wall_shocks;
	r->basket = r->basket_x_um > 0 && r->x_um >= r->basket_x_um - 1;
}

/* One update as the board runs it: measure, orders_update(), the robot follows. */
static uint8_t step(struct robot *r, struct orders *o)
{
	struct orders_measure m = robot_measure(r);
	uint8_t reason = orders_update(o, &m);

	robot_follow(r, o);
	return reason;
}

/* What a run saw, update by update. */
struct run {
	uint32_t updates;     /* until the order ended (that update included), or max */
	uint8_t reason;       /* END_REASON_* it ended with, NONE if it did not */
	uint32_t in_state[8]; /* updates after which the state was each ORDER_STATE_* */
	uint32_t first_in[8]; /* the first such update (1-based), 0 never */
	int32_t max_dist_vel, min_dist_vel, max_angle_vel, min_angle_vel;
	int32_t max_dist_acc, max_angle_acc; /* of |acc| */
	int32_t max_dist_dv, max_angle_dv;   /* |velocity change| between two updates */
};

static void run_clear(struct run *u)
{
	memset(u, 0, sizeof(*u));
}

static void run_note(struct run *u, const struct orders *o, const struct orders_axis *pd,
		     const struct orders_axis *pa)
{
	int32_t dv = o->sp_dist.vel_um_s - pd->vel_um_s;
	int32_t av = o->sp_angle.vel_um_s - pa->vel_um_s;

	u->updates++;
	if (o->state < 8) {
		if (!u->in_state[o->state])
			u->first_in[o->state] = u->updates;
		u->in_state[o->state]++;
	}
	if (o->sp_dist.vel_um_s > u->max_dist_vel)
		u->max_dist_vel = o->sp_dist.vel_um_s;
	if (o->sp_dist.vel_um_s < u->min_dist_vel)
		u->min_dist_vel = o->sp_dist.vel_um_s;
	if (o->sp_angle.vel_um_s > u->max_angle_vel)
		u->max_angle_vel = o->sp_angle.vel_um_s;
	if (o->sp_angle.vel_um_s < u->min_angle_vel)
		u->min_angle_vel = o->sp_angle.vel_um_s;
	if (abs(o->sp_dist.acc_um_s2) > u->max_dist_acc)
		u->max_dist_acc = abs(o->sp_dist.acc_um_s2);
	if (abs(o->sp_angle.acc_um_s2) > u->max_angle_acc)
		u->max_angle_acc = abs(o->sp_angle.acc_um_s2);
	if (abs(dv) > u->max_dist_dv)
		u->max_dist_dv = abs(dv);
	if (abs(av) > u->max_angle_dv)
		u->max_angle_dv = abs(av);
}

/* Updates until the running order ends, at most max. */
static void run_order(struct robot *r, struct orders *o, struct run *u, uint32_t max)
{
	run_clear(u);
	while (u->updates < max) {
		struct orders_axis pd = o->sp_dist, pa = o->sp_angle;

		u->reason = step(r, o);
		run_note(u, o, &pd, &pa);
		if (u->reason != END_REASON_NONE)
			break;
	}
}

static void run_updates(struct robot *r, struct orders *o, uint32_t n)
{
	for (uint32_t i = 0; i < n; i++)
		assert_int_equal(step(r, o), END_REASON_NONE);
}

static void goto_xy(struct robot *r, struct orders *o, int32_t x_um, int32_t y_um, uint8_t opt)
{
	struct orders_measure m = robot_measure(r);

	orders_goto(o, &m, x_um, y_um, opt);
}

/* Updates a straight GOTO of d_um takes at v_um_s and a_um_s2 from rest (a trapezoid): SETTLE
 * starts once the set point is slower than arrive_speed (5 mm/s) near the target, and lasts
 * settle updates, the last of which ends the order; the profile ends its last creep after. */
static uint32_t straight_updates(double d_um, double v_um_s, double a_um_s2, uint16_t hz,
				 uint32_t settle)
{
	return (uint32_t)ceil((d_um / v_um_s + v_um_s / a_um_s2 - 5000 / a_um_s2) * hz) + settle -
	       1;
}

/* The updates after an order ended, while the profile finishes its last creep. */
static void finish(struct robot *r, struct orders *o)
{
	run_updates(r, o, 100);
	assert_int_equal(o->sp_dist.vel_um_s, 0);
	assert_int_equal(o->sp_angle.vel_um_s, 0);
}

/* The heading error [turn * 2^32] from the robot to a point. */
static uint32_t bearing_error(const struct robot *r, double x_um, double y_um)
{
	double b = atan2(y_um - r->y_um, x_um - r->x_um) / (2 * PI);

	return fx_angle_dist(turn32_of(b), turn32_of(robot_heading(r)));
}

static void test_init_refuses_out_of_range(void **state)
{
	struct orders o;
	struct orders_config c;

	(void)state;
	base_config(&c);
	assert_int_equal(init_orders(&o, &c, 1000, 1234, -567), 0);
	assert_int_equal(o.state, ORDER_STATE_IDLE);
	assert_int_equal(o.designation, PROTO_NONE);
	assert_int_equal(o.end_reason, END_REASON_NONE);
	assert_int_equal(orders_busy(&o), 0);
	assert_int_equal(o.sp_dist.pos_um, 1234);
	assert_int_equal(o.sp_angle.pos_um, -567);
	assert_int_equal(o.sp_dist.vel_um_s, 0);

	c.drive_track_um = 9999;
	assert_int_equal(init_orders(&o, &c, 1000, 0, 0), -1);
	base_config(&c);
	c.drive_track_um = 1000001;
	assert_int_equal(init_orders(&o, &c, 1000, 0, 0), -1);
	base_config(&c);
	c.aim_delay_steps = 2;
	assert_int_equal(init_orders(&o, &c, 1000, 0, 0), -1);
	base_config(&c);
	c.n_baskets = ORDERS_MAX_BASKETS + 1;
	assert_int_equal(init_orders(&o, &c, 1000, 0, 0), -1);
	base_config(&c);
	c.settle_ms = 0;
	assert_int_equal(init_orders(&o, &c, 1000, 0, 0), -1);
	base_config(&c);
	c.grip_um_s2 = 99999;
	assert_int_equal(init_orders(&o, &c, 1000, 0, 0), -1);
	c.grip_um_s2 = 50000001;
	assert_int_equal(init_orders(&o, &c, 1000, 0, 0), -1);
	base_config(&c);
	c.rot_grip_q8 = 0;
	assert_int_equal(init_orders(&o, &c, 1000, 0, 0), -1);
	base_config(&c);
	assert_int_equal(init_orders(&o, &c, 99, 0, 0), -1); /* below the profiles' rates */
}

/* Facing the target: no turn, a trapezoid at 10 cm/s and 40 cm/s^2 (the initial limits), the
 * settle, DONE, on the target to the um. 500 mm: 0.25 s accelerating, 4.75 s at 10 cm/s,
 * 0.25 s braking. */
static void test_goto_ahead_goes_straight_and_ends(void **state)
{
	static const uint16_t rates[] = {1000, 125};

	(void)state;
	for (size_t k = 0; k < 2; k++) {
		uint16_t hz = rates[k];
		struct orders o;
		struct orders_config c;
		struct robot r;
		struct run u;
		uint32_t t = straight_updates(500000, 100000, 400000, hz, hz == 1000 ? 3 : 1);

		base_config(&c);
		make_orders(&o, &c, hz);
		robot_init(&r, hz, 0, 0, 0);
		goto_xy(&r, &o, 500000, 0, 0);
		assert_int_equal(o.designation, PROTO_GOTO);
		assert_int_equal(orders_busy(&o), 1);
		run_order(&r, &o, &u, 10 * hz);
		assert_int_equal(u.reason, END_REASON_DONE);
		assert_int_equal(o.end_reason, END_REASON_DONE);
		assert_int_equal(o.state, ORDER_STATE_IDLE);
		assert_int_equal(orders_busy(&o), 0);
		/* 3 ms: 3 updates at 1 kHz, 1 at 125 Hz. */
		assert_in_range(u.updates, t, t + 2);
		assert_int_equal(u.in_state[ORDER_STATE_ROTATE], 0);
		assert_int_equal(u.first_in[ORDER_STATE_TRANSLATE], 1);
		assert_int_equal(u.in_state[ORDER_STATE_SETTLE], hz == 1000 ? 2 : 0);
		assert_true(abs(o.sp_dist.pos_um - 500000) < 500); /* the arrive window */
		finish(&r, &o);
		assert_int_equal(o.sp_dist.pos_um, 500000);
		assert_int_equal(o.sp_angle.pos_um, 0);
		assert_int_equal(u.max_dist_vel, 100000);
		assert_int_equal(u.min_dist_vel, 0);
		assert_in_range(u.max_dist_acc, 399000, 400000);
		assert_int_equal(u.max_angle_vel, 0);
		assert_true(fabs(r.x_um - 500000) <= 1 && fabs(r.y_um) <= 1);
	}
}

/* A target to the left: the heading turns first, the distance axis holding still, and the
 * line starts once the heading is within the 5 degree window; then re-aims on the way, the
 * last 30 mm straight along the heading (the freeze radius), and ends on the target. */
static void test_goto_turns_then_goes_straight(void **state)
{
	struct orders o;
	struct orders_config c;
	struct robot r;
	uint32_t n = 0, rotate = 0;
	uint8_t reason = END_REASON_NONE;
	uint32_t window = fx_deg_to_turn32(5);

	(void)state;
	base_config(&c);
	make_orders(&o, &c, 1000);
	robot_init(&r, 1000, 0, 0, 0);
	goto_xy(&r, &o, 0, 400000, 0);
	while (reason == END_REASON_NONE && n < 20000) {
		uint32_t err = bearing_error(&r, 0, 400000);

		reason = step(&r, &o);
		n++;
		if (o.state == ORDER_STATE_ROTATE) {
			rotate++;
			assert_int_equal(o.sp_dist.pos_um, 0);
			assert_int_equal(o.sp_dist.vel_um_s, 0);
		} else if (rotate && o.state == ORDER_STATE_TRANSLATE && n == rotate + 1) {
			/* The measure this update was taken on: within the window, and the one
			 * before it was not. */
			assert_true(err <= window);
			assert_true(err > window - fx_deg_to_turn32(1));
		}
	}
	assert_int_equal(reason, END_REASON_DONE);
	/* A quarter turn is 125.66 mm of arc: 0.25 s + 1.007 s + 0.25 s at the initial limits;
	 * the line starts 5 degrees (6.98 mm of arc, 0.187 s of braking) before its end. */
	assert_in_range(rotate, 1315, 1325);
	assert_in_range(n, 1315 + 4000, 1325 + 4400);
	assert_true(fabs(r.x_um) < 1000);
	assert_true(fabs(r.y_um - 400000) < 500);
	assert_true(fx_angle_dist(turn32_of(robot_heading(&r)), 1u << 30) < fx_deg_to_turn32(1));
}

/* GOTO_REVERSE backs along the heading, the angle axis holding. */
static void test_goto_reverse_backs_off(void **state)
{
	struct orders o;
	struct orders_config c;
	struct robot r;
	struct run u;
	struct orders_measure m;

	(void)state;
	base_config(&c);
	make_orders(&o, &c, 1000);
	robot_init(&r, 1000, 100000, 50000, 0.125);
	m = robot_measure(&r);
	orders_goto_reverse(&o, &m, 300000);
	assert_int_equal(o.designation, PROTO_GOTO_REVERSE);
	assert_int_equal(o.state, ORDER_STATE_TRANSLATE);
	run_order(&r, &o, &u, 10000);
	assert_int_equal(u.reason, END_REASON_DONE);
	assert_in_range(u.updates, straight_updates(300000, 100000, 400000, 1000, 3),
			straight_updates(300000, 100000, 400000, 1000, 3) + 2);
	finish(&r, &o);
	assert_int_equal(u.max_dist_vel, 0);
	assert_int_equal(u.min_dist_vel, -100000);
	assert_int_equal(u.max_angle_vel, 0);
	assert_int_equal(u.min_angle_vel, 0);
	assert_int_equal(o.sp_dist.pos_um, -300000);
	assert_int_equal(o.sp_angle.pos_um, 0);
	/* 300 mm back along 45 degrees. */
	assert_true(fabs(r.x_um - (100000 - 212132)) <= 2 && fabs(r.y_um - (50000 - 212132)) <= 2);
}

/* STOP at 10 cm/s brakes at 40 cm/s^2: 0.25 s and 12.5 mm, then STOPPED, holding there. */
static void test_stop_brakes_and_ends(void **state)
{
	struct orders o;
	struct orders_config c;
	struct robot r;
	struct run u;
	int32_t from;

	(void)state;
	base_config(&c);
	make_orders(&o, &c, 1000);
	robot_init(&r, 1000, 0, 0, 0);
	goto_xy(&r, &o, 1000000, 0, 0);
	run_updates(&r, &o, 1000);
	assert_int_equal(o.sp_dist.vel_um_s, 100000);
	from = o.sp_dist.pos_um;
	orders_stop(&o);
	assert_int_equal(o.designation, PROTO_STOP);
	assert_int_equal(o.state, ORDER_STATE_STOPPING);
	assert_int_equal(orders_busy(&o), 1);
	run_order(&r, &o, &u, 1000);
	assert_int_equal(u.reason, END_REASON_STOPPED);
	assert_in_range(u.updates, 250, 252);
	/* v^2 / 2a less half a tick's travel: the discrete braking of 400 um/s per update. */
	assert_int_equal(o.sp_dist.pos_um - from, 12450);
	assert_int_equal(u.max_dist_vel, 100000 - 400);
	assert_int_equal(u.min_dist_vel, 0);
	assert_true(u.max_dist_dv <= 401);
	/* And it holds: nothing moves until the next order. */
	from = o.sp_dist.pos_um;
	run_updates(&r, &o, 500);
	assert_int_equal(o.sp_dist.pos_um, from);
	assert_int_equal(o.state, ORDER_STATE_IDLE);
	assert_int_equal(o.end_reason, END_REASON_STOPPED);
}

/* A GOTO replaced by another along the same line keeps its speed (no stop in between), and ends
 * when a single GOTO to the new target from the start would have. */
static void test_replaced_goto_keeps_its_speed(void **state)
{
	struct orders o;
	struct orders_config c;
	struct robot r;
	struct run u;

	(void)state;
	base_config(&c);
	make_orders(&o, &c, 1000);
	robot_init(&r, 1000, 0, 0, 0);
	goto_xy(&r, &o, 1000000, 0, 0);
	run_updates(&r, &o, 1000);
	assert_int_equal(o.sp_dist.vel_um_s, 100000);
	goto_xy(&r, &o, 300000, 0, 0);
	assert_int_equal(o.designation, PROTO_GOTO);
	run_order(&r, &o, &u, 10000);
	assert_int_equal(u.reason, END_REASON_DONE);
	assert_in_range(1000 + u.updates, straight_updates(300000, 100000, 400000, 1000, 3),
			straight_updates(300000, 100000, 400000, 1000, 3) + 2);
	finish(&r, &o);
	assert_int_equal(u.max_dist_vel, 100000);
	assert_true(u.max_dist_dv <= 401);
	assert_int_equal(u.in_state[ORDER_STATE_ROTATE], 0);
	assert_true(fabs(r.x_um - 300000) <= 1);
}

/* A GOTO replaced by one behind the robot: the distance axis brakes (no jump of its velocity),
 * the robot turns round, comes back and ends on the new target. */
static void test_replaced_goto_turns_round(void **state)
{
	struct orders o;
	struct orders_config c;
	struct robot r;
	struct run u;

	(void)state;
	base_config(&c);
	make_orders(&o, &c, 1000);
	robot_init(&r, 1000, 0, 0, 0);
	goto_xy(&r, &o, 1000000, 0, 0);
	run_updates(&r, &o, 1000);
	goto_xy(&r, &o, 0, 0, 0);
	assert_int_equal(o.state, ORDER_STATE_ROTATE);
	run_order(&r, &o, &u, 20000);
	assert_int_equal(u.reason, END_REASON_DONE);
	assert_true(u.max_dist_dv <= 401);
	assert_true(u.max_angle_dv <= 401);
	assert_true(u.max_dist_vel <= 100000 && u.min_dist_vel >= -100000);
	assert_true(u.in_state[ORDER_STATE_ROTATE] > 0);
	assert_true(hypot(r.x_um, r.y_um) < 1000);
}

/* SET_VITESSE_TRAJ and SET_VITESSE_ROT: the set points keep to the limits the master gives, 0
 * keeps a limit, and the accelerations are capped by the grip's share whatever the master asks:
 * of 7/8 of 3 m/s^2 the line gets 3/4 (1.96875 m/s^2) and the turn what is left divided by
 * 1.95 (0.336 m/s^2 of arc). */
static void test_limits_and_grip(void **state)
{
	struct orders o;
	struct orders_config c;
	struct robot r;
	struct run u;

	(void)state;
	base_config(&c);
	make_orders(&o, &c, 1000);
	robot_init(&r, 1000, 0, 0, 0);
	orders_set_traj_limits(&o, 50, 100);
	goto_xy(&r, &o, 1000000, 0, 0);
	run_order(&r, &o, &u, 10000);
	assert_int_equal(u.reason, END_REASON_DONE);
	assert_int_equal(u.max_dist_vel, 500000);
	assert_in_range(u.max_dist_acc, 999000, 1000000);
	assert_true(u.max_dist_dv <= 1001);
	assert_in_range(u.updates, straight_updates(1000000, 500000, 1000000, 1000, 3),
			straight_updates(1000000, 500000, 1000000, 1000, 3) + 2);

	orders_set_traj_limits(&o, 0, 0); /* both kept */
	{
		struct orders_measure m = robot_measure(&r);

		orders_goto_reverse(&o, &m, 1000000);
	}
	run_order(&r, &o, &u, 20000);
	assert_int_equal(u.reason, END_REASON_DONE);
	assert_int_equal(u.min_dist_vel, -500000);
	assert_in_range(u.max_dist_acc, 999000, 1000000);

	/* 2.55 m/s^2 asked: the line's share of the grip. */
	robot_init(&r, 1000, 0, 0, 0);
	make_orders(&o, &c, 1000);
	orders_set_traj_limits(&o, 255, 255);
	orders_set_rot_limits(&o, 255, 255);
	goto_xy(&r, &o, 1000000, 0, 0);
	run_order(&r, &o, &u, 10000);
	assert_int_equal(u.reason, END_REASON_DONE);
	assert_in_range(u.max_dist_acc, 1960000, 1968750);
	assert_true(u.max_dist_dv <= 1970);
	/* A half turn: the turn's share. */
	goto_xy(&r, &o, 0, 0, 0);
	run_order(&r, &o, &u, 20000);
	assert_int_equal(u.reason, END_REASON_DONE);
	assert_in_range(u.max_angle_acc, 330000, 336000);
	assert_true(u.max_angle_dv <= 337);

	/* Slower while moving: down to the new speed at the acceleration, and no faster after. */
	make_orders(&o, &c, 1000);
	robot_init(&r, 1000, 0, 0, 0);
	orders_set_traj_limits(&o, 50, 100);
	goto_xy(&r, &o, 2000000, 0, 0);
	run_updates(&r, &o, 1000);
	assert_int_equal(o.sp_dist.vel_um_s, 500000);
	orders_set_traj_limits(&o, 20, 0);
	run_updates(&r, &o, 300);
	assert_int_equal(o.sp_dist.vel_um_s, 200000);
	run_order(&r, &o, &u, 20000);
	assert_int_equal(u.reason, END_REASON_DONE);
	assert_int_equal(u.max_dist_vel, 200000);
}

/* Settled means within the arrive window (0.5 mm) for settle_ms; a robot that stays outside it
 * ends DONE anyway after settle_timeout_ms in SETTLE. */
static void test_settle_and_its_timeout(void **state)
{
	static const uint16_t rates[] = {1000, 125};

	(void)state;
	for (size_t k = 0; k < 2; k++) {
		uint16_t hz = rates[k];
		struct orders o;
		struct orders_config c;
		struct robot r;
		struct run u;

		base_config(&c);
		make_orders(&o, &c, hz);
		robot_init(&r, hz, 0, 0, 0);
		r.stick_um = 400; /* within the window */
		goto_xy(&r, &o, 100000, 0, 0);
		run_order(&r, &o, &u, 10 * hz);
		assert_int_equal(u.reason, END_REASON_DONE);
		/* 3 updates at 1 kHz (the last ends it); at 125 Hz 3 ms is one update: the
		 * order ends on the update that enters SETTLE. */
		assert_int_equal(u.in_state[ORDER_STATE_SETTLE], hz == 1000 ? 2 : 0);
		finish(&r, &o);
		assert_true(fabs(r.x_um - 99600) <= 1);

		make_orders(&o, &c, hz);
		robot_init(&r, hz, 0, 0, 0);
		r.stick_um = 600; /* outside it */
		goto_xy(&r, &o, 100000, 0, 0);
		run_order(&r, &o, &u, 10 * hz);
		assert_int_equal(u.reason, END_REASON_DONE);
		/* settle_timeout_ms: 1000 updates at 1 kHz, 125 at 125 Hz, the last ending it. */
		assert_int_equal(u.in_state[ORDER_STATE_SETTLE], hz - 1u);
		finish(&r, &o);
		assert_true(fabs(r.x_um - 99400) <= 1);
	}
}

/* aim_delay_steps 1 (the AVR's 125 Hz planner): a GOTO's first aim comes one update later. */
static void test_aim_delay(void **state)
{
	struct orders o;
	struct orders_config c;
	struct robot r;

	(void)state;
	base_config(&c);
	c.aim_delay_steps = 1;
	make_orders(&o, &c, 125);
	robot_init(&r, 125, 0, 0, 0);
	goto_xy(&r, &o, 500000, 0, 0);
	assert_int_equal(step(&r, &o), END_REASON_NONE);
	assert_int_equal(o.state, ORDER_STATE_ROTATE);
	assert_int_equal(o.sp_dist.vel_um_s, 0);
	assert_int_equal(step(&r, &o), END_REASON_NONE);
	assert_int_equal(o.state, ORDER_STATE_TRANSLATE);
	assert_true(o.sp_dist.vel_um_s > 0);

	base_config(&c);
	make_orders(&o, &c, 125);
	robot_init(&r, 125, 0, 0, 0);
	goto_xy(&r, &o, 500000, 0, 0);
	assert_int_equal(step(&r, &o), END_REASON_NONE);
	assert_int_equal(o.state, ORDER_STATE_TRANSLATE);
}

/* orders_abort(): the set points jump to the measure at rest, the order ends with the reason. */
static void test_abort_holds_the_measure(void **state)
{
	struct orders o;
	struct orders_config c;
	struct robot r;
	struct orders_measure m;

	(void)state;
	base_config(&c);
	make_orders(&o, &c, 1000);
	robot_init(&r, 1000, 0, 0, 0);
	r.stick_um = 2000;
	goto_xy(&r, &o, 1000000, 0, 0);
	run_updates(&r, &o, 800);
	m = robot_measure(&r);
	assert_int_not_equal(o.sp_dist.pos_um, m.dist_um);
	orders_abort(&o, &m, END_REASON_MOTOR);
	assert_int_equal(o.state, ORDER_STATE_IDLE);
	assert_int_equal(o.end_reason, END_REASON_MOTOR);
	assert_int_equal(o.sp_dist.pos_um, m.dist_um);
	assert_int_equal(o.sp_dist.vel_um_s, 0);
	assert_int_equal(o.sp_dist.acc_um_s2, 0);
	assert_int_equal(o.sp_angle.pos_um, m.angle_um);
	assert_int_equal(step(&r, &o), END_REASON_NONE);
	assert_int_equal(o.sp_dist.pos_um, m.dist_um);
	assert_int_equal(o.sp_dist.vel_um_s, 0);
}

/* 1 s into a GOTO of 1 m, cruising at 10 cm/s: the measure a shock takes (the shock tests). */
static struct orders_measure cruising_10cm_s(struct orders *o, struct orders_config *c,
					     struct robot *r)
{
	base_config(c);
	make_orders(o, c, 1000);
	robot_init(r, 1000, 0, 0, 0);
	goto_xy(r, o, 1000000, 0, 0);
	run_updates(r, o, 1000);
	return robot_measure(r);
}

/* The robot moved by move_um on the distance axis in one update (move_um a ms): its measure, the
 * robot where it says. */
static struct orders_measure moved_by(struct robot *r, int32_t move_um)
{
	struct orders_measure m = robot_measure(r);

	m.dist_um += move_um;
	m.dist_speed_um_s = move_um * 1000;
	r->dist_um = m.dist_um;
	return m;
}

/* A shock at 10 cm/s against an obstacle that gives 2 mm: the set point stops at the measure at
 * once, the feed-forward brakes at the grip (3 m/s^2) while the robot still goes on, for at most
 * what braking from 10 cm/s takes (33 updates), and once it has gone no further for 8 ms the
 * hold moves to where it stopped: never back towards the obstacle, and it stays there. */
static void test_shock_holds_where_it_stops(void **state)
{
	struct orders o;
	struct orders_config c;
	struct robot r;
	struct orders_measure m;
	int32_t at, braked = 0, rest = -1;

	(void)state;
	m = cruising_10cm_s(&o, &c, &r);
	assert_int_equal(m.dist_speed_um_s, 100000);
	at = m.dist_um;
	orders_shock(&o, &m, END_REASON_SHOCK);
	assert_int_equal(o.state, ORDER_STATE_IDLE);
	assert_int_equal(o.end_reason, END_REASON_SHOCK);
	assert_int_equal(o.sp_dist.pos_um, at);
	assert_int_equal(o.sp_dist.vel_um_s, 0);
	assert_int_equal(orders_busy(&o), 0);
	/* The robot squeezes on 2 mm in 40 updates, then rests. */
	for (int32_t i = 0; i < 200; i++) {
		int32_t move = i < 40 ? 50 : 0;

		m = moved_by(&r, move);
		r.dist_speed_um_s = m.dist_speed_um_s;
		assert_int_equal(orders_update(&o, &m), END_REASON_NONE);
		if (o.sp_dist.acc_um_s2 == -GRIP_UM_S2)
			braked++;
		assert_true(o.sp_dist.pos_um <= m.dist_um); /* never pulled back */
		assert_int_equal(o.sp_dist.vel_um_s, 0);
		if (rest < 0 && o.sp_dist.pos_um == at + 2000)
			rest = i;
	}
	assert_int_equal(braked, 33);
	/* Still from update 40: the 8th update without progress moves the hold. */
	assert_int_equal(rest, 47);
	assert_int_equal(o.sp_dist.pos_um, at + 2000);
	assert_int_equal(o.sp_angle.pos_um, m.angle_um);
	assert_true(o.gave_way);
	assert_int_equal(o.state, ORDER_STATE_IDLE);

	/* The next order clears the hold and runs as usual. */
	goto_xy(&r, &o, 0, 0, 0);
	assert_int_equal(o.state, ORDER_STATE_ROTATE);
	assert_int_equal(o.give_way, 0);
}

/* A shock, then the robot bounces back 3 mm: the hold goes with it (it is braked along its own
 * motion, not pulled back to the obstacle), and it is held where it comes to rest. */
static void test_shock_rebound_is_not_pulled_back(void **state)
{
	struct orders o;
	struct orders_config c;
	struct robot r;
	struct orders_measure m;
	int32_t at;

	(void)state;
	m = cruising_10cm_s(&o, &c, &r);
	at = m.dist_um;
	orders_shock(&o, &m, END_REASON_SHOCK);
	for (int32_t i = 0; i < 300; i++) {
		int32_t move = i < 5 ? 20 : i < 35 ? -100 : 0; /* 0.1 mm forward, 3 mm back */

		m = moved_by(&r, move);
		assert_int_equal(orders_update(&o, &m), END_REASON_NONE);
		/* At most a tick's motion away ahead of the robot, towards the obstacle. */
		assert_true(o.sp_dist.pos_um <= m.dist_um + 100);
		if (i >= 5 && i < 35) {
			assert_true(o.sp_dist.vel_um_s <= 0);
			assert_true(o.sp_dist.acc_um_s2 >= 0); /* braking the motion away */
		}
	}
	assert_int_equal(m.dist_um, at + 100 - 3000);
	assert_int_equal(o.sp_dist.pos_um, m.dist_um);
	assert_int_equal(o.sp_dist.vel_um_s, 0);
	assert_int_equal(o.sp_dist.acc_um_s2, 0);
	/* At rest: pushed slowly back towards the obstacle, the hold stays and resists it; drifting
	 * slowly away from it, the hold stays within throw_um (a creep, the rocking of a hold), and
	 * beyond it the robot is held where it is, not pulled back. */
	at = o.sp_dist.pos_um;
	assert_true(o.throw_um > 0 && o.throw_um < 100);
	for (int32_t i = 0; i < 120; i++) {
		int32_t move = i < 20 ? 1 : -2;

		m = moved_by(&r, move);
		assert_int_equal(orders_update(&o, &m), END_REASON_NONE);
		if (i < 20 || at - m.dist_um <= o.throw_um)
			assert_int_equal(o.sp_dist.pos_um, at);
		else /* never more than throw_um on the obstacle's side of it */
			assert_in_range(o.sp_dist.pos_um - m.dist_um, 0, o.throw_um);
	}
	assert_true(o.sp_dist.pos_um < at - 180 + o.throw_um);
}

/* A shock, a rebound of 3 mm to rest, then a second throw away (a second corner meeting the
 * obstacle) at 8 mm/s: past throw_um it is braked again along its motion, in proportion below
 * arrive_speed and two ticks of braking (11 mm/s here), not below rebound_um_s: 8/11 of the
 * grip once the low-passed speed reads 8 mm/s. Once it stops, the braking ends. */
static void test_shock_thrown_again_is_braked_harder(void **state)
{
	struct orders o;
	struct orders_config c;
	struct robot r;
	struct orders_measure m;
	int32_t acc = (GRIP_UM_S2 >> 8) * ((8000 << 8) / 11000), thrown = -1;

	(void)state;
	m = cruising_10cm_s(&o, &c, &r);
	orders_shock(&o, &m, END_REASON_SHOCK);
	assert_true(o.rebound_um_s > 11000);
	for (int32_t i = 0; i < 260; i++) {
		int32_t move = i < 5 ? 20 : i < 35 ? -100 : i < 100 ? 0 : i < 190 ? -8 : 0;

		m = moved_by(&r, move);
		assert_int_equal(orders_update(&o, &m), END_REASON_NONE);
		if (i < 100)
			assert_int_equal(o.give_way & 0x20u, 0);
		else if (thrown < 0 && (o.give_way & 0x20u))
			thrown = i;
		if (i >= 180 && i < 190) { /* the low-pass has settled on 8 mm/s */
			assert_int_equal(o.sp_dist.vel_um_s, -8000);
			assert_int_equal(o.sp_dist.acc_um_s2, acc);
		}
	}
	/* Past throw_um from where it was up to 16 updates (twice rest_ticks) before. */
	assert_in_range(thrown, 100 + o.throw_um / 8, 100 + o.throw_um / 8 + 16);
	assert_int_equal(o.sp_dist.acc_um_s2, 0);
	assert_int_equal(o.sp_dist.pos_um, m.dist_um);
}

struct border_run {
	struct run u;
	uint32_t soft, expected, recals, square;
	struct orders_recal rec;
};

/* GOTO with border recalibration, the robot's updates until the order ends: the recalibration is
 * applied to the estimate as the board does. */
static void run_border(struct robot *r, struct orders *o, struct border_run *b, uint32_t max)
{
	memset(b, 0, sizeof(*b));
	while (b->u.updates < max) {
		struct orders_axis pd = o->sp_dist, pa = o->sp_angle;
		struct orders_recal rec;

		b->u.reason = step(r, o);
		run_note(&b->u, o, &pd, &pa);
		b->soft += (uint32_t)orders_soft(o);
		if (orders_expected_shocks(o) == 0x07)
			b->expected++;
		else
			assert_int_equal(orders_expected_shocks(o), 0);
		if (o->state == ORDER_STATE_SQUARE)
			b->square++;
		if (orders_take_recal(o, &rec)) {
			b->recals++;
			b->rec = rec;
			r->ex_um = rec.pose.x_um - r->x_um;
			r->ey_um = rec.pose.y_um - r->y_um;
			assert_int_equal(orders_take_recal(o, &rec), 0); /* taken once */
		}
		if (b->u.reason != END_REASON_NONE)
			break;
	}
}

/* The estimate 5 mm ahead of the truth in x: GOTO (1250, 0) with the border option reaches its
 * point, faces the nearest border (+X), pushes until the front switches close, squares up for
 * 300 ms, sets x = 1500 - 125 mm and the heading to 0, backs off 60 mm: CHOC_BORD. */
static void test_border_recalibration(void **state)
{
	struct orders o;
	struct orders_config c;
	struct robot r;
	struct border_run b;

	(void)state;
	base_config(&c);
	make_orders(&o, &c, 1000);
	robot_init(&r, 1000, 1195000, 0, 0);
	r.ex_um = 5000;
	r.wall_x_um = HALF_LENGTH;
	r.wall_shocks = 0x07;
	goto_xy(&r, &o, 1250000, 0, ORDERS_OPT_BORDER);
	run_border(&r, &o, &b, 20000);
	assert_int_equal(b.u.reason, END_REASON_BORDER);
	assert_int_equal(o.end_reason, END_REASON_BORDER);
	assert_int_equal(b.recals, 1);
	assert_int_equal(b.rec.axis, 0);
	assert_int_equal(b.rec.pose.x_um, HALF_LENGTH - FRONT_UM);
	assert_int_equal(b.rec.pose.y_um, 0);
	assert_int_equal(b.rec.pose.heading_turn32, 0);
	assert_int_equal(b.square, 300);
	assert_true(b.u.in_state[ORDER_STATE_PUSH] > 0);
	assert_int_equal(b.soft, b.u.in_state[ORDER_STATE_PUSH] + b.square);
	assert_int_equal(b.expected, b.u.in_state[ORDER_STATE_PUSH] + b.square +
					     b.u.in_state[ORDER_STATE_BACK_OFF]);
	/* The push at the border speed, capped by the line's limit (10 cm/s). */
	assert_int_equal(b.u.max_dist_vel, 100000);
	/* Backed off 60 mm from the border, and the estimate now is the truth. */
	assert_true(fabs(r.x_um - (HALF_LENGTH - FRONT_UM - 60000)) <= 1);
	assert_true(fabs(r.ex_um) <= 1);
	assert_int_equal(orders_soft(&o), 0);
	assert_int_equal(orders_expected_shocks(&o), 0);

	/* No switch: the following error (over 5 mm) is the contact; the same recalibration. */
	make_orders(&o, &c, 1000);
	robot_init(&r, 1000, 1195000, 0, 0);
	r.ex_um = 5000;
	r.wall_x_um = HALF_LENGTH;
	goto_xy(&r, &o, 1250000, 0, ORDERS_OPT_BORDER);
	run_border(&r, &o, &b, 20000);
	assert_int_equal(b.u.reason, END_REASON_BORDER);
	assert_int_equal(b.recals, 1);
	assert_int_equal(b.rec.pose.x_um, HALF_LENGTH - FRONT_UM);

	/* No border where expected: the push goes 60 mm past it and ends DONE, not CHOC_BORD. */
	make_orders(&o, &c, 1000);
	robot_init(&r, 1000, 1195000, 0, 0);
	goto_xy(&r, &o, 1250000, 0, ORDERS_OPT_BORDER);
	run_border(&r, &o, &b, 20000);
	assert_int_equal(b.u.reason, END_REASON_DONE);
	assert_int_equal(b.recals, 0);
	assert_true(fabs(r.x_um - (HALF_LENGTH - FRONT_UM + 60000)) <= 1);

	/* The nearest border is -Y: the robot turns to face it (a quarter turn clockwise). */
	make_orders(&o, &c, 1000);
	robot_init(&r, 1000, 0, -700000, 0);
	goto_xy(&r, &o, 100000, -750000, ORDERS_OPT_BORDER);
	run_border(&r, &o, &b, 30000);
	assert_int_equal(b.u.reason, END_REASON_DONE);
	assert_true(fabs(r.y_um - (-HALF_WIDTH + FRONT_UM - 60000)) <= 2);
	assert_true(fx_angle_dist(turn32_of(robot_heading(&r)), 3u << 30) < fx_deg_to_turn32(1));

	/* Without the option, or without borders configured: a plain GOTO. */
	c.borders = 0;
	make_orders(&o, &c, 1000);
	robot_init(&r, 1000, 1195000, 0, 0);
	goto_xy(&r, &o, 1250000, 0, ORDERS_OPT_BORDER);
	run_border(&r, &o, &b, 20000);
	assert_int_equal(b.u.reason, END_REASON_DONE);
	assert_int_equal(b.u.in_state[ORDER_STATE_PUSH], 0);
	finish(&r, &o);
	assert_true(fabs(r.x_um - 1250000) <= 1);
}

/* GOTO_PANIER: turn to the heading, push at the push speed (capped at 10 cm/s) until the basket
 * switch closes: BASKET, the set points on the measure; orders_basket_pose() then gives the pose
 * from the basket's circle. Without a contact in push_max (500 mm): NO_BASKET. */
static void test_basket(void **state)
{
	struct orders o;
	struct orders_config c;
	struct robot r;
	struct run u;
	struct orders_measure m;
	struct odometry_pose est, out;

	(void)state;
	base_config(&c);
	c.n_baskets = 2;
	c.baskets[0] = (struct orders_basket){1000000, 0, 100000};
	c.baskets[1] = (struct orders_basket){1000000, 600000, 100000};
	make_orders(&o, &c, 1000);
	robot_init(&r, 1000, 600000, 0, 0.5); /* facing -X */
	r.ex_um = -10000;
	m = robot_measure(&r);
	orders_goto_panier(&o, &m, 0);
	assert_int_equal(o.designation, PROTO_GOTO_PANIER);
	assert_int_equal(o.state, ORDER_STATE_ROTATE);
	/* The switch reaches the circle at x = 1000 - 100 - 150 mm. */
	r.basket_x_um = 750000;
	run_order(&r, &o, &u, 20000);
	assert_int_equal(u.reason, END_REASON_BASKET);
	assert_int_equal(o.end_reason, END_REASON_BASKET);
	assert_true(u.in_state[ORDER_STATE_ROTATE] > 1000);
	assert_int_equal(u.max_dist_vel, 100000);
	m = robot_measure(&r);
	assert_int_equal(o.sp_dist.vel_um_s, 0);
	assert_true(abs(o.sp_dist.pos_um - m.dist_um) <= 100); /* the measure of that update */
	est = m.pose;
	assert_int_equal(orders_basket_pose(&o, &est, &out), 0);
	assert_true(abs(out.x_um - 750000) <= 2);
	assert_true(abs(out.y_um - est.y_um) <= 2);
	assert_int_equal(out.heading_turn32, est.heading_turn32);

	/* The lateral offset clamped to the switch's window (16 mm), heading 0 exactly. */
	est.x_um = 740000;
	est.y_um = 30000;
	est.heading_turn32 = 0;
	assert_int_equal(orders_basket_pose(&o, &est, &out), 0);
	assert_int_equal(out.x_um, 750000);
	assert_int_equal(out.y_um, 16000);
	est.y_um = -5000;
	assert_int_equal(orders_basket_pose(&o, &est, &out), 0);
	assert_int_equal(out.y_um, -5000);
	/* The nearest basket to the switch: the second one. */
	est.y_um = 590000;
	assert_int_equal(orders_basket_pose(&o, &est, &out), 0);
	assert_int_equal(out.x_um, 750000);
	assert_int_equal(out.y_um, 600000 - 10000);
	/* Facing +Y below the second basket. */
	est.x_um = 1003000;
	est.y_um = 200000;
	est.heading_turn32 = 1u << 30;
	assert_int_equal(orders_basket_pose(&o, &est, &out), 0);
	assert_true(abs(out.x_um - 1003000) <= 1);
	assert_true(abs(out.y_um - 350000) <= 1);

	/* A basket-side shock ends it the same way. */
	make_orders(&o, &c, 1000);
	robot_init(&r, 1000, 600000, 0, 0);
	m = robot_measure(&r);
	orders_goto_panier(&o, &m, 0);
	run_updates(&r, &o, 100);
	assert_int_equal(o.state, ORDER_STATE_PUSH);
	m = robot_measure(&r);
	m.basket_shock = 1;
	assert_int_equal(orders_update(&o, &m), END_REASON_BASKET);
	assert_int_equal(o.sp_dist.pos_um, m.dist_um);

	/* Nothing in 500 mm: NO_BASKET, the push's whole length driven. */
	make_orders(&o, &c, 1000);
	robot_init(&r, 1000, 0, 0, 0);
	m = robot_measure(&r);
	orders_goto_panier(&o, &m, 0);
	run_order(&r, &o, &u, 20000);
	assert_int_equal(u.reason, END_REASON_NO_BASKET);
	assert_int_equal(o.sp_dist.pos_um, 500000);
	assert_in_range(u.updates, 5250, 5254);

	/* No basket configured: no pose. */
	c.n_baskets = 0;
	make_orders(&o, &c, 1000);
	assert_int_equal(orders_basket_pose(&o, &est, &out), -1);
}

/* A GOTO cruising along +X at 50 cm/s (SET_VITESSE_TRAJ 50 100), 1 kHz, from rest at the origin:
 * the set up of the match-play tests below. */
static void cruise(struct orders *o, struct robot *r, int32_t x_um)
{
	struct orders_config c;

	base_config(&c);
	make_orders(o, &c, 1000);
	robot_init(r, 1000, 0, 0, 0);
	orders_set_traj_limits(o, 50, 100);
	goto_xy(r, o, x_um, 0, 0);
	run_updates(r, o, 1000);
	assert_int_equal(o->state, ORDER_STATE_TRANSLATE);
	assert_int_equal(o->sp_dist.vel_um_s, 500000);
}

/* Updates until both set points are at rest, at most max; what the run saw in u. Returns the
 * number of updates, max + 1 if they did not come to rest. */
static uint32_t run_to_rest(struct robot *r, struct orders *o, struct run *u, uint32_t max)
{
	run_clear(u);
	while (u->updates < max) {
		struct orders_axis pd = o->sp_dist, pa = o->sp_angle;

		assert_int_equal(step(r, o), END_REASON_NONE);
		run_note(u, o, &pd, &pa);
		if (o->sp_dist.vel_um_s == 0 && o->sp_angle.vel_um_s == 0)
			return u->updates;
	}
	return max + 1;
}

/* PAUSE (docs/failure-model.md "A pause", docs/control.md "Pause, speed scale"): from 50 cm/s
 * the line brakes on its profile at the grip's share, 3/4 of 7/8 of 3 m/s^2 = 1.96875 m/s^2,
 * not the master's 1 m/s^2: at rest in 0.254 s, within v^2 / 2a = 63.49 mm, the heading kept.
 * Then it holds for 5 s: the order keeps its state and its target and does not advance (its
 * remaining 1.6 m would have taken 3.3 s), busy all the while. A second PAUSE changes nothing. */
static void test_pause_brakes_to_rest_and_holds(void **state)
{
	struct orders o, before;
	struct robot r;
	struct run u;
	int32_t from, at;

	(void)state;
	cruise(&o, &r, 2000000);
	from = o.sp_dist.pos_um;
	orders_pause(&o);
	assert_int_equal(o.designation, PROTO_GOTO);
	assert_int_equal(o.state, ORDER_STATE_TRANSLATE);
	assert_int_equal(orders_busy(&o), 1);
	assert_in_range(run_to_rest(&r, &o, &u, 1000), 254, 256);
	assert_in_range(u.max_dist_dv, 1968, 1969); /* 1968.75 um/s an update */
	assert_true(u.min_dist_vel >= 0);           /* braked, not reversed */
	assert_in_range(o.sp_dist.pos_um - from, 63000, 63492);
	assert_int_equal(u.max_angle_vel, 0);
	assert_int_equal(u.min_angle_vel, 0);
	assert_int_equal(o.sp_angle.pos_um, 0);

	/* Held for 5 s: no update moves it or ends the order. */
	at = o.sp_dist.pos_um;
	for (uint32_t i = 0; i < 5000; i++) {
		assert_int_equal(step(&r, &o), END_REASON_NONE);
		assert_int_equal(o.sp_dist.pos_um, at);
		assert_int_equal(o.sp_dist.vel_um_s, 0);
		assert_int_equal(o.sp_angle.pos_um, 0);
	}
	assert_int_equal(o.state, ORDER_STATE_TRANSLATE);
	assert_int_equal(o.designation, PROTO_GOTO);
	assert_int_equal(orders_busy(&o), 1);
	assert_true(fabs(r.x_um - at) <= 1);

	memcpy(&before, &o, sizeof(o));
	orders_pause(&o);
	assert_memory_equal(&before, &o, sizeof(o));
}

/* PAUSE in a turn brakes the turn (the line stays where it is) at the turn's share of the grip,
 * what the line leaves over 1.95: 0.336 m/s^2 of arc; from 10 cm/s, 0.298 s. */
static void test_pause_in_a_turn_brakes_the_turn(void **state)
{
	struct orders o;
	struct orders_config c;
	struct robot r;
	struct run u;
	int32_t at;

	(void)state;
	base_config(&c);
	make_orders(&o, &c, 1000);
	robot_init(&r, 1000, 0, 0, 0);
	goto_xy(&r, &o, 0, 1000000, 0);
	run_updates(&r, &o, 400);
	assert_int_equal(o.state, ORDER_STATE_ROTATE);
	assert_int_equal(o.sp_angle.vel_um_s, 100000);
	at = o.sp_angle.pos_um;
	orders_pause(&o);
	assert_in_range(run_to_rest(&r, &o, &u, 1000), 297, 299);
	assert_in_range(u.max_angle_dv, 336, 337);
	assert_true(u.min_angle_vel >= 0);
	/* v^2 / 2a = 14.88 mm of arc, less half an update's travel. */
	assert_in_range(o.sp_angle.pos_um - at, 14700, 14881);
	assert_int_equal(u.max_dist_vel, 0);
	assert_int_equal(u.min_dist_vel, 0);
	assert_int_equal(o.sp_dist.pos_um, 0);
	at = o.sp_angle.pos_um;
	run_updates(&r, &o, 2000);
	assert_int_equal(o.sp_angle.pos_um, at);
	assert_int_equal(o.state, ORDER_STATE_ROTATE);
}

/* RESUME: the paused order goes on to the same target from where the robot stands. A GOTO
 * re-aims from the estimate at the first update (the robot was pushed 20 mm aside while
 * paused), speeds up at the master's acceleration again (not PAUSE's), and ends DONE on its
 * target as it would have. A turn paused goes on turning, then goes straight to its point. */
static void test_resume_goes_on_to_the_same_target(void **state)
{
	struct orders o;
	struct robot r;
	struct run u;

	(void)state;
	cruise(&o, &r, 2000000);
	/* Just after a re-aim: without RESUME's, the next would be aim_period updates away. */
	while (!orders_aimed(&o) && CONFIG_FIX)
		run_updates(&r, &o, 1);
	orders_pause(&o);
	assert_true(run_to_rest(&r, &o, &u, 1000) < 1000);
	run_updates(&r, &o, 500);
	r.y_um += 20000;
	orders_resume(&o);
	assert_int_equal(o.state, ORDER_STATE_TRANSLATE);
	assert_int_equal(orders_busy(&o), 1);
	assert_int_equal(step(&r, &o), END_REASON_NONE);
	assert_int_equal(orders_aimed(&o), CONFIG_FIX);
	run_order(&r, &o, &u, 20000);
	assert_int_equal(u.reason, END_REASON_DONE);
	assert_int_equal(o.designation, PROTO_GOTO);
	assert_int_equal(u.max_dist_vel, 500000);
	assert_in_range(u.max_dist_dv, 999, 1001); /* 1 m/s^2, the master's */
	assert_true(u.min_dist_vel >= 0);
	finish(&r, &o);
	assert_true(hypot(r.x_um - 2000000, r.y_um) < 500);

	/* A GOTO_REVERSE (no re-aim) paused and resumed: the whole 300 mm back, DONE there. */
	{
		struct orders_config c;
		struct orders_measure m;

		base_config(&c);
		make_orders(&o, &c, 1000);
		robot_init(&r, 1000, 0, 0, 0);
		m = robot_measure(&r);
		orders_goto_reverse(&o, &m, 300000);
		run_updates(&r, &o, 1000);
		assert_int_equal(o.sp_dist.vel_um_s, -100000);
		orders_pause(&o);
		assert_true(run_to_rest(&r, &o, &u, 1000) < 1000);
		run_updates(&r, &o, 300);
		assert_true(o.sp_dist.pos_um > -100000);
		orders_resume(&o);
		run_order(&r, &o, &u, 20000);
		assert_int_equal(u.reason, END_REASON_DONE);
		assert_int_equal(o.designation, PROTO_GOTO_REVERSE);
		finish(&r, &o);
		assert_int_equal(o.sp_dist.pos_um, -300000);
		assert_true(fabs(r.x_um + 300000) <= 1);
	}

	/* Paused mid-turn, resumed: the turn goes on, then the line. */
	{
		struct orders_config c;

		base_config(&c);
		make_orders(&o, &c, 1000);
	}
	robot_init(&r, 1000, 0, 0, 0);
	goto_xy(&r, &o, 0, 1000000, 0);
	run_updates(&r, &o, 400);
	orders_pause(&o);
	assert_true(run_to_rest(&r, &o, &u, 1000) < 1000);
	run_updates(&r, &o, 300);
	orders_resume(&o);
	run_order(&r, &o, &u, 30000);
	assert_int_equal(u.reason, END_REASON_DONE);
	assert_true(u.first_in[ORDER_STATE_ROTATE] > 0);
	assert_true(u.max_angle_vel <= 100000 && u.max_dist_vel <= 100000);
	finish(&r, &o);
	assert_true(hypot(r.x_um, r.y_um - 1000000) < 1000);
	assert_true(fx_angle_dist(turn32_of(robot_heading(&r)), 1u << 30) < fx_deg_to_turn32(1));
}

/* What PAUSE and RESUME leave alone (orders.h, docs/protocol.md 16.3): PAUSE while idle or
 * stopping, RESUME without a pause; a STOP or a new order ends the pause. */
static void test_pause_and_resume_leave_alone(void **state)
{
	struct orders o, before;
	struct orders_config c;
	struct robot r;
	struct run u;

	(void)state;
	base_config(&c);
	make_orders(&o, &c, 1000);
	robot_init(&r, 1000, 0, 0, 0);
	run_updates(&r, &o, 10);
	memcpy(&before, &o, sizeof(o));
	orders_pause(&o);
	assert_memory_equal(&before, &o, sizeof(o));
	orders_resume(&o);
	assert_memory_equal(&before, &o, sizeof(o));

	/* RESUME on a running order that is not paused. */
	cruise(&o, &r, 2000000);
	memcpy(&before, &o, sizeof(o));
	orders_resume(&o);
	assert_memory_equal(&before, &o, sizeof(o));

	/* PAUSE while STOP brakes: the STOP goes on at its own deceleration (the master's
	 * 1 m/s^2: 1 mm/s an update), and ends STOPPED. */
	orders_stop(&o);
	run_updates(&r, &o, 10);
	memcpy(&before, &o, sizeof(o));
	orders_pause(&o);
	assert_memory_equal(&before, &o, sizeof(o));
	run_order(&r, &o, &u, 2000);
	assert_int_equal(u.reason, END_REASON_STOPPED);
	assert_in_range(u.max_dist_dv, 999, 1001);

	/* STOP ends a pause: STOPPED, at once at rest. */
	cruise(&o, &r, 2000000);
	orders_pause(&o);
	assert_true(run_to_rest(&r, &o, &u, 1000) < 1000);
	orders_stop(&o);
	run_order(&r, &o, &u, 10);
	assert_int_equal(u.reason, END_REASON_STOPPED);

	/* A new order ends it: it runs, and a RESUME after it changes nothing. */
	cruise(&o, &r, 2000000);
	orders_pause(&o);
	assert_true(run_to_rest(&r, &o, &u, 1000) < 1000);
	goto_xy(&r, &o, 1000000, 0, 0);
	memcpy(&before, &o, sizeof(o));
	orders_resume(&o);
	assert_memory_equal(&before, &o, sizeof(o));
	run_order(&r, &o, &u, 20000);
	assert_int_equal(u.reason, END_REASON_DONE);
	finish(&r, &o);
	assert_true(fabs(r.x_um - 1000000) <= 1);
}

/* SET_SPEED_SCALE (docs/protocol.md 16.4): the running order slows from 50 to 20 cm/s at 40 %
 * at its acceleration limit (1 m/s^2: 0.3 s), and never goes faster; back at 100 % it speeds up
 * again the same way, and ends on its target. Above 100 reads 100; 0 leaves 1 um/s, a creep.
 * The scale holds for the orders that follow, on both axes. */
static void test_speed_scale(void **state)
{
	struct orders o;
	struct orders_config c;
	struct robot r;
	struct run u;

	(void)state;
	cruise(&o, &r, 3000000);
	orders_set_speed_scale(&o, 40);
	assert_int_equal(o.state, ORDER_STATE_TRANSLATE);
	run_order(&r, &o, &u, 300);
	assert_int_equal(u.reason, END_REASON_NONE);
	assert_int_equal(o.sp_dist.vel_um_s, 200000);
	assert_in_range(u.max_dist_dv, 999, 1001);
	assert_true(u.max_dist_vel < 500000);
	for (uint32_t i = 0; i < 1000; i++) {
		assert_int_equal(step(&r, &o), END_REASON_NONE);
		assert_int_equal(o.sp_dist.vel_um_s, 200000);
	}
	orders_set_speed_scale(&o, 100);
	run_order(&r, &o, &u, 300);
	assert_int_equal(o.sp_dist.vel_um_s, 500000);
	assert_in_range(u.max_dist_dv, 999, 1001);
	run_order(&r, &o, &u, 20000);
	assert_int_equal(u.reason, END_REASON_DONE);
	assert_int_equal(u.max_dist_vel, 500000);
	finish(&r, &o);
	assert_true(fabs(r.x_um - 3000000) <= 1);

	/* 255 reads 100 %. */
	cruise(&o, &r, 3000000);
	orders_set_speed_scale(&o, 255);
	for (uint32_t i = 0; i < 1000; i++) {
		assert_int_equal(step(&r, &o), END_REASON_NONE);
		assert_int_equal(o.sp_dist.vel_um_s, 500000);
	}

	/* 0: braked to 1 um/s at the acceleration limit (0.5 s), still running. */
	orders_set_speed_scale(&o, 0);
	run_order(&r, &o, &u, 600);
	assert_int_equal(u.reason, END_REASON_NONE);
	assert_in_range(o.sp_dist.vel_um_s, 0, 1);
	assert_in_range(u.max_dist_dv, 999, 1001);
	assert_int_equal(orders_busy(&o), 1);

	/* Set while idle: the next GOTO cruises at 5 cm/s (50 % of 10), and its turn at 5 cm/s
	 * of arc. */
	base_config(&c);
	make_orders(&o, &c, 1000);
	robot_init(&r, 1000, 0, 0, 0);
	orders_set_speed_scale(&o, 50);
	goto_xy(&r, &o, 0, 300000, 0);
	run_order(&r, &o, &u, 20000);
	assert_int_equal(u.reason, END_REASON_DONE);
	assert_int_equal(u.max_angle_vel, 50000);
	assert_int_equal(u.max_dist_vel, 50000);
	finish(&r, &o);
	assert_true(hypot(r.x_um, r.y_um - 300000) < 1000);
}

/* The angle set point on a curve of turn_um after s um of it (docs/control.md "Corners"): a
 * clothoid, the arc, a clothoid back. */
static double curve_angle_at(const struct orders_curve *c, double turn_um, double s)
{
	double w = (double)c->clothoid_um + c->arc_um, len = w + c->clothoid_um;

	if (s <= c->clothoid_um)
		return turn_um * s * s / (2.0 * c->clothoid_um * w);
	if (s <= w)
		return turn_um * (2 * s - c->clothoid_um) / (2 * w);
	return turn_um - turn_um * (len - s) * (len - s) / (2.0 * c->clothoid_um * w);
}

/* Where a curve of turn_um [um of arc] ends, from the origin heading 0. */
static void curve_end(const struct orders_curve *c, double turn_um, double *x, double *y)
{
	double len = 2.0 * c->clothoid_um + c->arc_um, ds = 10;

	*x = *y = 0;
	for (double s = 0; s < len; s += ds) {
		double h = curve_angle_at(c, turn_um, s + ds / 2) / (TRACK_UM / 2.0);

		*x += ds * cos(h);
		*y += ds * sin(h);
	}
}

/* One GOTO through a pass-through corner's curve (orders_curve_start()), with PAUSE and RESUME
 * at update pause_at of the curve (0: none): the curve's updates run in ROTATE, the line never
 * stopping. Returns the curve's updates. */
static uint32_t run_curve(uint32_t pause_at)
{
	const struct orders_curve c = {.v_um_s = 100000,
				       .a_um_s2 = 400000,
				       .clothoid_um = 100000,
				       .arc_um = 200000,
				       .rest_um = 500000};
	double turn = PI * TRACK_UM / 4; /* a quarter turn */
	double ex, ey, x0, tx, ty;
	struct orders o;
	struct orders_config cfg;
	struct orders_measure m;
	struct robot r;
	int32_t d0, a0;
	uint32_t n = 0, paused_for = 0, rest = 0;
	uint8_t reason = END_REASON_NONE;

	base_config(&cfg);
	make_orders(&o, &cfg, 1000);
	robot_init(&r, 1000, 0, 0, 0);
	goto_xy(&r, &o, 2000000, 0, 0);
	run_updates(&r, &o, 1000);
	assert_int_equal(o.sp_dist.vel_um_s, 100000);
	/* The next line, at up to 30 cm/s once off the curve: from where the curve ends, 500 mm
	 * along +Y. */
	orders_set_traj_limits(&o, 30, 0);
	x0 = r.x_um;
	curve_end(&c, turn, &ex, &ey);
	tx = x0 + ex;
	ty = ey + c.rest_um;
	m = robot_measure(&r);
	orders_goto(&o, &m, (int32_t)lround(tx), (int32_t)lround(ty), 0);
	assert_int_equal(o.state, ORDER_STATE_ROTATE);
	d0 = o.sp_dist.pos_um;
	a0 = o.sp_angle.pos_um;
	orders_curve_start(&o, &m, &c, 1u << 30);
	while (o.state == ORDER_STATE_ROTATE && n < 20000) {
		struct orders_axis pd = o.sp_dist;
		double s, rate;

		if (pause_at && n == pause_at)
			orders_pause(&o);
		if (pause_at && n > pause_at && !rest && o.sp_dist.vel_um_s == 0)
			rest = n;
		if (rest && paused_for < 300 && ++paused_for == 300)
			orders_resume(&o);
		reason = step(&r, &o);
		assert_int_equal(reason, END_REASON_NONE);
		n++;
		if (o.state != ORDER_STATE_ROTATE)
			break;
		/* The heading slaved to the line along the curve, whatever its speed does. */
		s = o.sp_dist.pos_um - d0;
		assert_true(fabs(o.sp_angle.pos_um - a0 - curve_angle_at(&c, turn, s)) <= 2);
		/* At most the curve's speed and acceleration; the line only stops paused. */
		assert_true(o.sp_dist.vel_um_s <= c.v_um_s);
		assert_true(abs(o.sp_dist.vel_um_s - pd.vel_um_s) <= c.a_um_s2 / 1000 + 1);
		if (!pause_at)
			assert_int_equal(o.sp_dist.vel_um_s, c.v_um_s);
		/* On the arc, the heading's rate is the line's over the radius. */
		rate = turn * o.sp_dist.vel_um_s / (c.clothoid_um + c.arc_um);
		if (s > c.clothoid_um + 1000 && s < c.clothoid_um + c.arc_um - 1000)
			assert_true(fabs(o.sp_angle.vel_um_s - rate) <= 1);
	}
	/* The curve's end: the next line's heading exactly, then its point, DONE. */
	assert_int_equal(o.state, ORDER_STATE_TRANSLATE);
	assert_true(o.sp_dist.pos_um - d0 >= 2 * c.clothoid_um + c.arc_um);
	assert_true(fabs(o.sp_angle.pos_um - a0 - turn) <= 1);
	assert_true(fx_angle_dist(turn32_of(robot_heading(&r)), 1u << 30) < fx_deg_to_turn32(1));
	if (pause_at) {
		assert_true(rest > pause_at);
		assert_int_equal(paused_for, 300);
	}
	while (reason == END_REASON_NONE && n < 40000) {
		reason = step(&r, &o);
		n++;
	}
	assert_int_equal(reason, END_REASON_DONE);
	finish(&r, &o);
	assert_true(hypot(r.x_um - tx, r.y_um - ty) < 1000);
	return n;
}

/* orders_curve_start() (docs/control.md "Corners"): the GOTO that has just started from a robot
 * moving at 10 cm/s turns a quarter turn on a clothoid (100 mm), an arc (200 mm) and a clothoid
 * back, translating at the curve's speed all the way (the line's limit, 30 cm/s, capped at it),
 * its heading a function of the distance travelled; then the line to its point. A PAUSE on the
 * arc brakes the line at the curve's acceleration along the curve, and RESUME goes on along it.
 * Nothing for an order that is not a GOTO that has just started. */
static void test_curve_start(void **state)
{
	const struct orders_curve c = {100000, 400000, 100000, 200000, 0, 500000};
	struct orders o, before;
	struct robot r;
	struct orders_measure m;

	(void)state;
	run_curve(0);
	run_curve(2000);

	cruise(&o, &r, 2000000); /* TRANSLATE */
	m = robot_measure(&r);
	memcpy(&before, &o, sizeof(o));
	orders_curve_start(&o, &m, &c, 1u << 30);
	assert_memory_equal(&before, &o, sizeof(o));
	orders_goto_reverse(&o, &m, 100000);
	memcpy(&before, &o, sizeof(o));
	orders_curve_start(&o, &m, &c, 1u << 30);
	assert_memory_equal(&before, &o, sizeof(o));
	orders_goto_panier(&o, &m, 1u << 30); /* ROTATE, but not a GOTO */
	memcpy(&before, &o, sizeof(o));
	orders_curve_start(&o, &m, &c, 1u << 30);
	assert_memory_equal(&before, &o, sizeof(o));
	goto_xy(&r, &o, m.pose.x_um + 10000, 20000, 0); /* within the freeze radius */
	memcpy(&before, &o, sizeof(o));
	orders_curve_start(&o, &m, &c, 1u << 30);
	assert_memory_equal(&before, &o, sizeof(o));
}

/* orders_aimed() (what the planner keeps a fix's fusion out of): 1 after the updates that
 * re-aimed a GOTO, every aim_period updates (4 at 1 kHz, every one at 125 Hz) until the target
 * is within the freeze radius, never for GOTO_REVERSE, STOP or while idle; always 0 without
 * CONFIG_FIX. */
static void test_aimed(void **state)
{
	static const uint16_t rates[] = {1000, 125};

	(void)state;
	for (size_t k = 0; k < 2; k++) {
		uint16_t hz = rates[k];
		uint32_t period = hz == 1000 ? 4 : 1;
		struct orders o;
		struct orders_config c;
		struct robot r;
		struct orders_measure m;
		uint32_t n = 0, aims = 0, last = 0, gap_bad = 0;
		double last_dist = 0;
		uint8_t reason = END_REASON_NONE;

		base_config(&c);
		make_orders(&o, &c, hz);
		robot_init(&r, hz, 0, 0, 0);
		run_updates(&r, &o, 3);
		assert_int_equal(orders_aimed(&o), 0);
		goto_xy(&r, &o, 300000, 0, 0);
		while (reason == END_REASON_NONE && n < 10u * hz) {
			double dist = hypot(300000 - r.x_um, r.y_um);

			reason = step(&r, &o);
			n++;
			if (!orders_aimed(&o))
				continue;
			/* The first update aims twice (ROTATE, then TRANSLATE): one report. */
			if (aims > 0 && n - last != period)
				gap_bad++;
			aims++;
			last = n;
			last_dist = dist;
		}
		assert_int_equal(reason, END_REASON_DONE);
		assert_int_equal(orders_aimed(&o), 0);
		if (!CONFIG_FIX) {
			assert_int_equal(aims, 0);
			continue;
		}
		assert_int_equal(gap_bad, 0);
		assert_int_equal(aims, (last - 1) / period + 1);
		/* The last one found the target within 30 mm, and froze it; the one before, a
		 * period's travel at 10 cm/s earlier, did not. */
		assert_true(last_dist <= 30000 && last_dist > 30000 - 100000.0 / hz * period);
		run_updates(&r, &o, 10);
		assert_int_equal(orders_aimed(&o), 0);

		m = robot_measure(&r);
		orders_goto_reverse(&o, &m, 100000);
		for (uint32_t i = 0; i < hz; i++) {
			step(&r, &o);
			assert_int_equal(orders_aimed(&o), 0);
		}
		goto_xy(&r, &o, 500000, 0, 0);
		run_updates(&r, &o, hz / 2);
		orders_stop(&o);
		for (uint32_t i = 0; i < hz; i++) {
			step(&r, &o);
			assert_int_equal(orders_aimed(&o), 0);
		}
	}
}

/* The states an update may move to from each state (bit per ORDER_STATE_*). */
static const uint8_t next_states[8] = {
	[ORDER_STATE_IDLE] = 1u << ORDER_STATE_IDLE,
	[ORDER_STATE_ROTATE] =
		1u << ORDER_STATE_ROTATE | 1u << ORDER_STATE_TRANSLATE | 1u << ORDER_STATE_PUSH,
	[ORDER_STATE_TRANSLATE] = 1u << ORDER_STATE_TRANSLATE | 1u << ORDER_STATE_SETTLE |
				  1u << ORDER_STATE_IDLE | 1u << ORDER_STATE_ROTATE,
	[ORDER_STATE_SETTLE] =
		1u << ORDER_STATE_SETTLE | 1u << ORDER_STATE_IDLE | 1u << ORDER_STATE_ROTATE,
	[ORDER_STATE_PUSH] =
		1u << ORDER_STATE_PUSH | 1u << ORDER_STATE_SQUARE | 1u << ORDER_STATE_IDLE,
	[ORDER_STATE_STOPPING] = 1u << ORDER_STATE_STOPPING | 1u << ORDER_STATE_IDLE,
	[ORDER_STATE_SQUARE] = 1u << ORDER_STATE_SQUARE | 1u << ORDER_STATE_BACK_OFF,
	[ORDER_STATE_BACK_OFF] = 1u << ORDER_STATE_BACK_OFF | 1u << ORDER_STATE_IDLE,
};

/* What the soak checks of one update. */
struct soak {
	uint16_t hz;
	int32_t traj_v, traj_a, rot_v, rot_a; /* the limits the master gave, [um/s], [um/s^2] */
	uint32_t since_order;                 /* updates since the running order started */
	uint32_t bound;                       /* it must have ended by then */
	uint32_t orders, ended, replaced, longest;
	uint32_t reasons[16];
};

static void soak_check(struct soak *s, const struct orders *o, uint8_t before, uint8_t reason,
		       const struct orders_axis *pd, const struct orders_axis *pa, int jumped)
{
	int32_t dv = o->sp_dist.vel_um_s - pd->vel_um_s;
	int32_t av = o->sp_angle.vel_um_s - pa->vel_um_s;

	assert_true(o->state <= ORDER_STATE_BACK_OFF);
	assert_true(next_states[before] & (1u << o->state));
	assert_int_equal(orders_busy(o), o->state != ORDER_STATE_IDLE);
	if (reason != END_REASON_NONE) {
		assert_int_equal(o->state, ORDER_STATE_IDLE);
		assert_int_equal(o->end_reason, reason);
		assert_true(reason == END_REASON_DONE || reason == END_REASON_STOPPED ||
			    reason == END_REASON_BASKET || reason == END_REASON_BORDER ||
			    reason == END_REASON_NO_BASKET);
	} else {
		/* An order ends only with a reason. */
		assert_true(before == ORDER_STATE_IDLE || o->state != ORDER_STATE_IDLE);
	}
	if (o->state == ORDER_STATE_STOPPING)
		assert_int_equal(o->designation, PROTO_STOP);
	if (o->state == ORDER_STATE_SQUARE || o->state == ORDER_STATE_BACK_OFF)
		assert_int_equal(o->designation, PROTO_GOTO);
	if (o->state == ORDER_STATE_PUSH)
		assert_true(o->designation == PROTO_GOTO_PANIER || o->designation == PROTO_GOTO);
	/* The hold after a shock brakes a rebound at the robot's own speed: not a profile. */
	if (jumped || o->give_way)
		return;
	/* Speeds within the limits given, or slowing down to a new lower one. */
	assert_true(abs(o->sp_dist.vel_um_s) <= s->traj_v ||
		    abs(o->sp_dist.vel_um_s) <= abs(pd->vel_um_s));
	assert_true(abs(o->sp_angle.vel_um_s) <= s->rot_v ||
		    abs(o->sp_angle.vel_um_s) <= abs(pa->vel_um_s));
	/* Accelerations within the limits given (the grip may lower them further), in the
	 * velocity's change from one update to the next and in the feed-forward. */
	assert_true((int64_t)abs(dv) * s->hz <= (int64_t)s->traj_a + 2 * s->hz);
	assert_true((int64_t)abs(av) * s->hz <= (int64_t)s->rot_a + 2 * s->hz);
	assert_true(abs(o->sp_dist.acc_um_s2) <= s->traj_a + 2 * s->hz);
	assert_true(abs(o->sp_angle.acc_um_s2) <= s->rot_a + 2 * s->hz);
	/* The set point moves by its velocity. */
	assert_true(abs(o->sp_dist.pos_um - pd->pos_um - o->sp_dist.vel_um_s / s->hz) <= 2);
	assert_true(abs(o->sp_angle.pos_um - pa->pos_um - o->sp_angle.vel_um_s / s->hz) <= 2);
}

/* An upper bound of an order's duration [updates]: its distance, a half turn and three pushes'
 * lengths at the lower of the speeds in effect, four accelerations to it at the lower of the
 * accelerations, the settle timeout, a border's square, and twice that as margin. */
static uint32_t order_bound(const struct soak *s, uint32_t dist_um)
{
	int32_t v = s->traj_v < s->rot_v ? s->traj_v : s->rot_v;
	int32_t a = s->traj_a < s->rot_a ? s->traj_a : s->rot_a;
	double t = (dist_um + PI * TRACK_UM / 2 + 3 * 500000.0) / v + 4.0 * v / a + 1.0 + 0.3 + 2;

	return (uint32_t)(t * s->hz) * 2;
}

/* Random orders, limits, measures, contacts, shocks and aborts, on robots that stop up to
 * 0.7 mm short of their set points with up to 0.2 mm of noise in their measures: at every
 * update the states move only along the state machine, an order ends with a reason, the set
 * points keep to the limits given and move by their velocity, and every order that is not
 * replaced ends within its bound. */
static void soak(uint16_t hz, uint8_t aim_delay, uint64_t seed, uint32_t n_orders)
{
	struct orders o;
	struct orders_config c;
	struct robot r;
	struct soak s;

	rng_state = seed;
	base_config(&c);
	c.aim_delay_steps = aim_delay;
	c.n_baskets = 1;
	c.baskets[0] = (struct orders_basket){0, 0, 100000};
	make_orders(&o, &c, hz);
	robot_init(&r, hz, 0, 0, 0);
	memset(&s, 0, sizeof(s));
	s.hz = hz;
	s.traj_v = s.rot_v = 100000;
	s.traj_a = s.rot_a = 400000;
	while (s.orders < n_orders || orders_busy(&o)) {
		struct orders_measure m;
		struct orders_axis pd = o.sp_dist, pa = o.sp_angle;
		uint8_t before, reason;
		int jumped = 0;
		uint32_t dice = (uint32_t)rng_range(0, 99999);

		r.stick_um = rng_range(0, 700);
		r.noise_um = rng_range(0, 200);
		/* Contacts about once in 4 s of pushing: some pushes end without. */
		r.basket = o.state == ORDER_STATE_PUSH && rng_range(0, 4 * hz) == 0;
		r.shocks = o.state == ORDER_STATE_PUSH && rng_range(0, 4 * hz) == 0 ? 0x01 : 0;
		m = robot_measure(&r);
		if (s.orders < n_orders && (!orders_busy(&o) || dice < 40)) {
			int32_t kind = rng_range(0, 9);
			double far;

			if (orders_busy(&o))
				s.replaced++;
			s.orders++;
			s.since_order = 0;
			if (kind <= 4) {
				int32_t x = rng_range(-1200000, 1200000);
				int32_t y = rng_range(-800000, 800000);

				if (kind == 4) { /* a short one, within the freeze radius */
					x = m.pose.x_um + rng_range(-30000, 30000);
					y = m.pose.y_um + rng_range(-30000, 30000);
				}
				orders_goto(
					&o, &m, x, y,
					(uint8_t)(rng_range(0, 3) == 0 ? ORDERS_OPT_BORDER : 0));
				far = hypot(x - r.x_um, y - r.y_um) + 2000000;
			} else if (kind <= 6) {
				int32_t d = rng_range(-500000, 500000);

				orders_goto_reverse(&o, &m, d);
				far = abs(d);
			} else if (kind == 7) {
				orders_goto_panier(&o, &m, (uint32_t)rng_next());
				far = 500000;
			} else {
				orders_stop(&o);
				far = 0;
			}
			s.bound = order_bound(&s, (uint32_t)far);
		} else if (dice < 60) {
			uint8_t sp = (uint8_t)rng_range(0, 255), ac = (uint8_t)rng_range(0, 255);
			int traj = rng_range(0, 1);

			if (sp > 0 && sp < 5)
				sp = 5; /* at least 5 cm/s: bounds of seconds, not minutes */
			if (ac > 0 && ac < 5)
				ac = 5;
			if (traj)
				orders_set_traj_limits(&o, sp, ac);
			else
				orders_set_rot_limits(&o, sp, ac);
			if (sp && traj)
				s.traj_v = sp * 10000;
			if (ac && traj)
				s.traj_a = ac * 10000;
			if (sp && !traj)
				s.rot_v = sp * 10000;
			if (ac && !traj)
				s.rot_a = ac * 10000;
			if (orders_busy(&o))
				s.bound = s.since_order + order_bound(&s, 3000000);
		} else if (dice < 65 && orders_busy(&o)) {
			orders_abort(&o, &m, END_REASON_MOTOR);
			s.reasons[END_REASON_MOTOR]++;
			jumped = 1;
		} else if (dice < 70 && orders_busy(&o)) {
			m.dist_speed_um_s = o.sp_dist.vel_um_s;
			m.angle_speed_um_s = o.sp_angle.vel_um_s;
			orders_shock(&o, &m, END_REASON_SHOCK);
			s.reasons[END_REASON_SHOCK]++;
			jumped = 1;
		}
		before = o.state;
		reason = orders_update(&o, &m);
		if (reason == END_REASON_BASKET || o.state == ORDER_STATE_SQUARE ||
		    before == ORDER_STATE_SQUARE)
			jumped = 1; /* set points reset on the measure */
		soak_check(&s, &o, before, reason, &pd, &pa, jumped);
		robot_follow(&r, &o);
		{ /* the board applies a recalibration to its estimate */
			struct orders_recal rec;

			if (orders_take_recal(&o, &rec)) {
				r.ex_um = rec.pose.x_um - r.x_um;
				r.ey_um = rec.pose.y_um - r.y_um;
			}
		}
		if (orders_busy(&o)) {
			s.since_order++;
			assert_true(s.since_order <= s.bound);
			if (s.since_order > s.longest)
				s.longest = s.since_order;
		}
		if (reason != END_REASON_NONE) {
			s.ended++;
			s.reasons[reason]++;
		}
	}
	/* Every path was taken. */
	assert_int_equal(s.orders, n_orders);
	assert_true(s.replaced > n_orders / 20);
	assert_true(s.reasons[END_REASON_DONE] > n_orders / 10);
	assert_true(s.reasons[END_REASON_STOPPED] > 0);
	assert_true(s.reasons[END_REASON_BASKET] > 0);
	assert_true(s.reasons[END_REASON_NO_BASKET] > 0);
	assert_true(s.reasons[END_REASON_BORDER] > 0);
	assert_true(s.reasons[END_REASON_MOTOR] > 0);
	assert_true(s.reasons[END_REASON_SHOCK] > 0);
	print_message(
		"soak %u Hz: %u orders, %u replaced, %u ended (done %u, stopped %u, basket %u, "
		"no basket %u, border %u), longest %u updates\n",
		hz, s.orders, s.replaced, s.ended, s.reasons[END_REASON_DONE],
		s.reasons[END_REASON_STOPPED], s.reasons[END_REASON_BASKET],
		s.reasons[END_REASON_NO_BASKET], s.reasons[END_REASON_BORDER], s.longest);
}

static void test_soak_1khz(void **state)
{
	(void)state;
	soak(1000, 0, 0x9e3779b97f4a7c15u, 400);
}

static void test_soak_125hz(void **state)
{
	(void)state;
	soak(125, 1, 0xd1b54a32d192ed03u, 400);
}

int main(void)
{
	const struct CMUnitTest tests[] = {
		cmocka_unit_test(test_init_refuses_out_of_range),
		cmocka_unit_test(test_goto_ahead_goes_straight_and_ends),
		cmocka_unit_test(test_goto_turns_then_goes_straight),
		cmocka_unit_test(test_goto_reverse_backs_off),
		cmocka_unit_test(test_stop_brakes_and_ends),
		cmocka_unit_test(test_replaced_goto_keeps_its_speed),
		cmocka_unit_test(test_replaced_goto_turns_round),
		cmocka_unit_test(test_limits_and_grip),
		cmocka_unit_test(test_settle_and_its_timeout),
		cmocka_unit_test(test_aim_delay),
		cmocka_unit_test(test_abort_holds_the_measure),
		cmocka_unit_test(test_shock_holds_where_it_stops),
		cmocka_unit_test(test_shock_rebound_is_not_pulled_back),
		cmocka_unit_test(test_shock_thrown_again_is_braked_harder),
		cmocka_unit_test(test_border_recalibration),
		cmocka_unit_test(test_basket),
		cmocka_unit_test(test_pause_brakes_to_rest_and_holds),
		cmocka_unit_test(test_pause_in_a_turn_brakes_the_turn),
		cmocka_unit_test(test_resume_goes_on_to_the_same_target),
		cmocka_unit_test(test_pause_and_resume_leave_alone),
		cmocka_unit_test(test_speed_scale),
		cmocka_unit_test(test_curve_start),
		cmocka_unit_test(test_aimed),
		cmocka_unit_test(test_soak_1khz),
		cmocka_unit_test(test_soak_125hz),
	};

	return cmocka_run_group_tests(tests, NULL, NULL);
}
