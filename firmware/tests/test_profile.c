/* The motion profile generator (profile.c): durations against the closed forms, exact arrival,
 * limits never exceeded, continuity across replanning, reversal, stop and reset, for the
 * trapezoid and the S-curve. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>

#include <cmocka.h>

#include "fixmath.h"
#include "profile.h"

#define N_OF(a) (sizeof(a) / sizeof((a)[0]))

static uint64_t rng_state = 0x9e3779b97f4a7c15u;

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
	return lo + (int32_t)(rng_next() % (uint64_t)(hi - lo + 1));
}

static int32_t iabs32(int32_t v)
{
	return v < 0 ? -v : v;
}

/* What a run saw, tick by tick. */
struct run {
	uint32_t ticks;     /* updates until done (the done tick included) */
	int32_t min_pos_um; /* extremes of the set point */
	int32_t max_pos_um;
	int32_t max_vel_um_s; /* of |vel| */
	int32_t max_acc_um_s2;
	int32_t max_dv_um_s;     /* |vel change| between two ticks */
	int32_t max_djerk_um_s2; /* |acc change| between two ticks */
	int32_t max_dp_err_um;   /* |pos change - vel / hz| (position follows velocity) */
	int32_t last_vel_um_s;
};

/* Checker state across ticks, so that replans in the middle are checked too. */
struct checker {
	struct profile_out prev;
	int have_prev;
	uint16_t hz;
	struct run r;
};

static void checker_init(struct checker *c, const struct profile *p, uint16_t hz)
{
	c->prev = p->out;
	c->have_prev = 1;
	c->hz = hz;
	c->r.ticks = 0;
	c->r.min_pos_um = p->out.pos_um;
	c->r.max_pos_um = p->out.pos_um;
	c->r.max_vel_um_s = 0;
	c->r.max_acc_um_s2 = 0;
	c->r.max_dv_um_s = 0;
	c->r.max_djerk_um_s2 = 0;
	c->r.max_dp_err_um = 0;
	c->r.last_vel_um_s = 0;
}

static void checker_tick(struct checker *c, struct profile *p)
{
	const struct profile_out *o = profile_update(p);
	int32_t dp = o->pos_um - c->prev.pos_um;
	/* Velocity over the tick, rounded: the set point moves by vel / hz. */
	int32_t dp_expect = (int32_t)fx_div_round64(o->vel_um_s, c->hz);
	int32_t d;

	c->r.ticks++;
	if (o->pos_um < c->r.min_pos_um)
		c->r.min_pos_um = o->pos_um;
	if (o->pos_um > c->r.max_pos_um)
		c->r.max_pos_um = o->pos_um;
	if (iabs32(o->vel_um_s) > c->r.max_vel_um_s)
		c->r.max_vel_um_s = iabs32(o->vel_um_s);
	if (iabs32(o->acc_um_s2) > c->r.max_acc_um_s2)
		c->r.max_acc_um_s2 = iabs32(o->acc_um_s2);
	d = iabs32(o->vel_um_s - c->prev.vel_um_s);
	if (d > c->r.max_dv_um_s)
		c->r.max_dv_um_s = d;
	d = iabs32(o->acc_um_s2 - c->prev.acc_um_s2);
	if (d > c->r.max_djerk_um_s2)
		c->r.max_djerk_um_s2 = d;
	/* The S-curve's set point is an average: vel is the mean velocity, so the position step
	 * matches it within the two roundings (1 um each side). */
	d = iabs32(dp - dp_expect);
	if (d > c->r.max_dp_err_um)
		c->r.max_dp_err_um = d;
	c->r.last_vel_um_s = o->vel_um_s;
	c->prev = *o;
}

/* Tick until done (or max ticks); returns the run. */
static struct run run_to_done(struct checker *c, struct profile *p, uint32_t max_ticks)
{
	uint32_t start = c->r.ticks;

	while (!p->out.done || c->r.ticks == start) {
		checker_tick(c, p);
		if (c->r.ticks - start >= max_ticks)
			break;
	}
	return c->r;
}

static void setup(struct profile *p, struct checker *c, uint16_t hz, int32_t v, int32_t a,
		  int32_t j, int32_t pos_um)
{
	struct profile_config cfg = {
		.tick_hz = hz,
		.limits = {.v_max_um_s = v, .a_max_um_s2 = a, .j_max_um_s3 = j},
	};

	assert_int_equal(profile_init(p, &cfg, pos_um), 0);
	checker_init(c, p, hz);
}

/* Checks every profile must pass on a rest-to-rest move (from rest): limits, continuity, exact
 * arrival, no overshoot in either direction. */
static void assert_clean_move(const struct run *r, const struct profile *p, int32_t from_um,
			      int32_t to_um, int32_t v, int32_t a, int32_t j, uint16_t hz)
{
	assert_true(p->out.done);
	assert_int_equal(p->out.pos_um, to_um);
	assert_int_equal(p->out.vel_um_s, 0);
	assert_true(r->max_vel_um_s <= v);
	assert_true(r->max_acc_um_s2 <= a);
	/* |dv| per tick <= a / hz, +1 LSB of rounding. */
	assert_true(r->max_dv_um_s <= a / hz + 1);
	if (j > 0)
		assert_true(r->max_djerk_um_s2 <= j / hz + 1);
	assert_true(r->max_dp_err_um <= 1);
	/* No overshoot, from rest. */
	assert_true(r->min_pos_um >= (from_um < to_um ? from_um : to_um));
	assert_true(r->max_pos_um <= (from_um < to_um ? to_um : from_um));
}

/* Closed forms in ticks * 1024, integer only (the tests are not linked with libm).
 * Trapezoid: T = d/v + v/a, or 2 sqrt(d/a) when v is never reached. */
static int64_t trap_ticks_x1024(int64_t d, int64_t v, int64_t a, int64_t hz)
{
	if (d * a >= v * v)
		return (d * hz * 1024) / v + (v * hz * 1024) / a;
	/* 2 sqrt(d/a) hz 1024 = sqrt(4 d hz^2 2^20 / a). */
	return fx_isqrt64((uint64_t)(4 * d * hz * hz * 1048576 / a));
}

static int64_t icbrt(int64_t x)
{
	int64_t r = 0;

	while ((r + 1) * (r + 1) * (r + 1) <= x)
		r++;
	return r;
}

/* S-curve, rest to rest, in ticks * 1024 (docs/control.md):
 *   long (reaches v and a):   T = d/v + v/a + a/j
 *   reaches a, not v:         T = 2 (vp/a + a/j), vp = (sqrt(a^4/j^2 + 4 a d) - a^2/j) / 2
 *   reaches neither:          T = 4 cbrt(d / (2 j)) */
static int64_t scurve_ticks_x1024(int64_t d, int64_t v, int64_t a, int64_t j, int64_t hz)
{
	/* Distance to reach v and come back: v (v/a + a/j). Compare d a j >= v (v j + a^2). */
	if (d * a / v * j >= v * j + a * a)
		return (d * hz * 1024) / v + (v * hz * 1024) / a + (a * hz * 1024) / j;
	/* Reaching a takes 2 a^3 / j^2 of distance. */
	if (d * j / a * j >= 2 * a * a) {
		/* vp in um/s * 1024. */
		int64_t a2j = a * a / j;
		int64_t vp = ((int64_t)fx_isqrt64((uint64_t)((a2j * a2j + 4 * a * d) * 1048576)) -
			      a2j * 1024) /
			     2;
		return 2 * (vp * hz / a + a * hz * 1024 / j);
	}
	/* 4 cbrt(d hz^3 / 2j) 1024, with cbrt(x 2^15) = 32 cbrt(x) to keep 1/32 tick. */
	return 4 * icbrt(d * hz * hz * hz / (2 * j) * 32768) * 32;
}

struct trap_case {
	uint16_t hz;
	int32_t from_um;
	int32_t to_um;
	int32_t v_um_s;
	int32_t a_um_s2;
};

/* Durations of rest-to-rest trapezoids against T = d/v + v/a (or 2 sqrt(d/a)), within 2 ticks. */
static void test_trapezoid_durations(void **state)
{
	static const struct trap_case cases[] = {
		/* The specification's case: 1.8 m at 1 m/s and 1 m/s^2: T = 1.8 + 1 = 2.80 s. */
		{1000, 0, 1800000, 1000000, 1000000},
		/* Defaults 0.1 m/s, 0.4 m/s^2 over 1 m: T = 10 + 0.25 = 10.25 s. */
		{1000, 0, 1000000, 100000, 400000},
		/* Same, backwards, from an offset. */
		{1000, 500000, -500000, 100000, 400000},
		/* Triangle: 10 mm at 0.4 m/s^2 never reaches 0.1 m/s: T = 2 sqrt(0.025) = 0.316 s.
		 */
		{1000, 0, 10000, 100000, 400000},
		/* Exactly the limit between both: d = v^2 / a = 25 mm. */
		{1000, 0, 25000, 100000, 400000},
		/* 100 Hz and 2 kHz. */
		{100, 0, 1800000, 1000000, 1000000},
		{2000, 0, 1800000, 1000000, 1000000},
		{2000, 0, -3000, 1000000, 1500000},
		{100, 0, 1, 100000, 400000},
		/* Fast limits of physics.md: 1 m/s, 1.5 m/s^2, 3 m. */
		{1000, -1000000, 2000000, 1000000, 1500000},
		/* Odd values that do not fall on whole ticks. */
		{600, 0, 1234567, 333333, 777777},
		/* The protocol's slowest limits: 1 cm/s, 1 cm/s^2 over 3 cm: T = 3 + 1 = 4 s. */
		{1000, 0, 30000, 10000, 10000},
	};

	(void)state;
	for (size_t i = 0; i < N_OF(cases); i++) {
		const struct trap_case *k = &cases[i];
		struct profile p;
		struct checker c;
		struct run r;
		int64_t d = (int64_t)k->to_um - k->from_um;
		int64_t expect;
		int64_t got;

		setup(&p, &c, k->hz, k->v_um_s, k->a_um_s2, 0, k->from_um);
		profile_set_target(&p, k->to_um);
		r = run_to_done(&c, &p, 200000);
		expect = trap_ticks_x1024(d < 0 ? -d : d, k->v_um_s, k->a_um_s2, k->hz);
		got = (int64_t)r.ticks * 1024;
		print_message("case %zu: %u ticks, closed form %.2f\n", i, r.ticks,
			      (double)expect / 1024.0);
		assert_clean_move(&r, &p, k->from_um, k->to_um, k->v_um_s, k->a_um_s2, 0, k->hz);
		assert_true(got >= expect - 2 * 1024 && got <= expect + 2 * 1024);
	}
}

/* The spec's case tick by tick: cruise at exactly 1 m/s, acceleration exactly 1 m/s^2 in both
 * ramps, and the velocity trace is symmetric (within one tick of acceleration). */
static void test_trapezoid_symmetric(void **state)
{
	static int32_t vel[4000];
	struct profile p;
	struct checker c;
	uint32_t n = 0;

	(void)state;
	setup(&p, &c, 1000, 1000000, 1000000, 0, 0);
	profile_set_target(&p, 1800000);
	while (!p.out.done && n < N_OF(vel)) {
		checker_tick(&c, &p);
		vel[n++] = p.out.vel_um_s;
	}
	assert_true(p.out.done);
	/* 1000 ticks of ramp up, 800 at 1 m/s, 1000 of ramp down, the last of which (velocity 0)
	 * is the done tick. */
	assert_int_equal(n, 2800);
	assert_int_equal(vel[0], 1000);
	assert_int_equal(vel[999], 1000000);
	assert_int_equal(vel[1400], 1000000);
	for (uint32_t k = 0; k + 1 < n; k++)
		assert_true(iabs32(vel[k] - vel[n - 2 - k]) <= 1000 + 1);
}

/* A zero-length move is done on its first tick and never moves. */
static void test_zero_length_move(void **state)
{
	struct profile p;
	struct checker c;
	struct run r;

	(void)state;
	setup(&p, &c, 1000, 100000, 400000, 0, 123456);
	assert_true(profile_is_done(&p));
	profile_set_target(&p, 123456);
	r = run_to_done(&c, &p, 10);
	assert_int_equal(r.ticks, 1);
	assert_int_equal(r.min_pos_um, 123456);
	assert_int_equal(r.max_pos_um, 123456);
	assert_int_equal(p.out.vel_um_s, 0);
	setup(&p, &c, 1000, 100000, 400000, 1000000, -5);
	profile_set_target(&p, -5);
	r = run_to_done(&c, &p, 10);
	assert_int_equal(r.ticks, 1);
	assert_int_equal(p.out.pos_um, -5);
}

/* A target behind the motion: braking at a, reversal, exact arrival; the furthest point reached
 * is the braking distance v^2 / (2a) past the point of the replan. */
static void test_reversal(void **state)
{
	struct profile p;
	struct checker c;
	struct run r;
	int32_t at_replan;

	(void)state;
	setup(&p, &c, 1000, 500000, 500000, 0, 0);
	profile_set_target(&p, 2000000);
	for (int k = 0; k < 1500; k++)
		checker_tick(&c, &p);
	/* Cruising at 0.5 m/s since tick 1000. */
	assert_int_equal(p.out.vel_um_s, 500000);
	at_replan = p.out.pos_um;
	c.r.min_pos_um = at_replan;
	c.r.max_pos_um = at_replan;
	profile_set_target(&p, 100000);
	r = run_to_done(&c, &p, 100000);
	assert_int_equal(p.out.pos_um, 100000);
	/* Braking distance 0.25 m, within one tick of travel. */
	assert_true(iabs32(r.max_pos_um - (at_replan + 250000)) <= 500);
	assert_true(r.max_vel_um_s <= 500000);
	assert_true(r.max_acc_um_s2 <= 500000);
	assert_true(r.max_dv_um_s <= 500 + 1);
	assert_true(r.max_dp_err_um <= 1);
	/* Arrival from above: nothing below the target. */
	assert_true(r.min_pos_um >= 100000);
}

/* Replanning at random ticks with random targets and limits, trapezoid and S-curve: position,
 * velocity (and acceleration) continuous at every tick, limits never exceeded, exact arrival. */
static void replan_storm(uint16_t hz, int scurve)
{
	struct profile p;
	struct checker c;
	struct profile_limits lim = {200000, 500000, scurve ? 2000000 : 0};
	struct run r;
	int32_t target = 0;
	int32_t a_bound = lim.a_max_um_s2;
	int32_t j_in_effect = lim.j_max_um_s3;

	setup(&p, &c, hz, lim.v_max_um_s, lim.a_max_um_s2, lim.j_max_um_s3, 0);
	for (int replan = 0; replan < 60; replan++) {
		int32_t ticks = rng_range(1, hz / 2);

		if (replan % 3 == 0) {
			int32_t a_old = lim.a_max_um_s2;

			lim.v_max_um_s = rng_range(50000, 1000000);
			lim.a_max_um_s2 = rng_range(200000, 1500000);
			assert_int_equal(profile_set_limits(&p, &lim), 0);
			/* A trapezoid obeys a lowered a at once; an S-curve's window still holds
			 * older accelerations for up to n_filt ticks: bound by the range. */
			a_bound = scurve ? 1500000
					 : (a_old > lim.a_max_um_s2 ? a_old : lim.a_max_um_s2);
		} else if (!scurve) {
			a_bound = lim.a_max_um_s2;
		}
		target = rng_range(-500000, 500000);
		profile_set_target(&p, target);
		c.r.max_vel_um_s = 0;
		c.r.max_acc_um_s2 = 0;
		for (int32_t k = 0; k < ticks; k++)
			checker_tick(&c, &p);
		assert_true(c.r.max_acc_um_s2 <= a_bound);
		/* |dv| <= a / hz + 1 LSB with the largest a in effect so far. */
		assert_true(c.r.max_dv_um_s <= 1500000 / hz + 1);
		if (scurve)
			assert_true(c.r.max_djerk_um_s2 <= j_in_effect / hz + 1);
		assert_true(c.r.max_dp_err_um <= 1);
		assert_true(c.r.max_vel_um_s <= 1000000);
	}
	r = run_to_done(&c, &p, 100000);
	assert_true(p.out.done);
	assert_int_equal(p.out.pos_um, target);
	assert_int_equal(p.out.vel_um_s, 0);
	assert_true(r.max_dp_err_um <= 1);
}

static void test_replan_continuity_trapezoid(void **state)
{
	(void)state;
	replan_storm(1000, 0);
	replan_storm(100, 0);
	replan_storm(2000, 0);
}

static void test_replan_continuity_scurve(void **state)
{
	(void)state;
	replan_storm(1000, 1);
	replan_storm(250, 1);
	replan_storm(2000, 1);
}

/* A new target ahead in the middle of a move: no stop in between, and the total time is that of
 * the longer move from the start (the generator is online and time-optimal). */
static void test_replan_extend(void **state)
{
	struct profile p;
	struct checker c;
	struct run r;

	(void)state;
	setup(&p, &c, 1000, 1000000, 1000000, 0, 0);
	profile_set_target(&p, 900000);
	for (int k = 0; k < 700; k++)
		checker_tick(&c, &p);
	profile_set_target(&p, 1800000);
	r = run_to_done(&c, &p, 10000);
	assert_clean_move(&r, &p, 0, 1800000, 1000000, 1000000, 0, 1000);
	assert_true(r.ticks >= 2799 && r.ticks <= 2802);
}

/* Lowered v_max mid-cruise: decelerate at a to the new one and hold it; raised: accelerate. */
static void test_limits_changed_mid_move(void **state)
{
	struct profile p;
	struct checker c;
	struct profile_limits slow = {300000, 1000000, 0};
	struct profile_limits fast = {1000000, 2000000, 0};
	struct run r;

	(void)state;
	setup(&p, &c, 1000, 1000000, 1000000, 0, 0);
	profile_set_target(&p, 3000000);
	for (int k = 0; k < 1200; k++)
		checker_tick(&c, &p);
	assert_int_equal(p.out.vel_um_s, 1000000);
	assert_int_equal(profile_set_limits(&p, &slow), 0);
	/* 0.7 m/s down at 1 m/s^2: 700 ticks. */
	for (int k = 0; k < 699; k++) {
		checker_tick(&c, &p);
		assert_int_equal(p.out.acc_um_s2, -1000000);
	}
	checker_tick(&c, &p);
	assert_int_equal(p.out.vel_um_s, 300000);
	for (int k = 0; k < 200; k++) {
		checker_tick(&c, &p);
		assert_int_equal(p.out.vel_um_s, 300000);
	}
	assert_int_equal(profile_set_limits(&p, &fast), 0);
	checker_tick(&c, &p);
	assert_int_equal(p.out.acc_um_s2, 2000000);
	r = run_to_done(&c, &p, 10000);
	assert_int_equal(p.out.pos_um, 3000000);
	assert_true(r.max_vel_um_s <= 1000000);
	assert_true(r.max_dv_um_s <= 2000 + 1);
	assert_true(r.max_pos_um <= 3000000);
}

/* Stop: decelerate at a_max, come to rest at the braking distance v^2 / 2a (rounded up to a um),
 * which profile_stop() returns. */
static void test_stop(void **state)
{
	struct profile p;
	struct checker c;
	struct run r;
	int32_t at_stop;
	int32_t stop_um;

	(void)state;
	setup(&p, &c, 1000, 800000, 400000, 0, 0);
	profile_set_target(&p, -3000000);
	for (int k = 0; k < 2500; k++)
		checker_tick(&c, &p);
	assert_int_equal(p.out.vel_um_s, -800000);
	at_stop = p.out.pos_um;
	stop_um = profile_stop(&p);
	assert_false(profile_is_done(&p));
	/* v^2 / 2a = 0.8 m; the discrete braking (v - a/hz, ..., 0) covers v^2/2a - v/2hz. The
	 * acceleration in ticks, 0.4 um/tick^2 = 26214.4 units of 2^-16, is rounded down: the
	 * braking is 0.0015 % longer (12 um) and its acceleration 6 um/s^2 lower. */
	assert_true(iabs32(stop_um - (at_stop - 800000 + 400)) <= 15);
	for (int k = 0; k < 1999; k++) {
		checker_tick(&c, &p);
		assert_true(p.out.acc_um_s2 >= 400000 - 10 && p.out.acc_um_s2 <= 400000);
	}
	r = run_to_done(&c, &p, 100);
	assert_int_equal(p.out.pos_um, stop_um);
	assert_true(r.min_pos_um >= stop_um);
	/* 2500 ticks before the stop, 2000 of braking, within 2. */
	assert_true(r.ticks >= 4500 - 2 && r.ticks <= 4500 + 2);
	/* Stop from rest: nothing moves. */
	assert_int_equal(profile_stop(&p), stop_um);
	r = run_to_done(&c, &p, 100);
	assert_int_equal(p.out.pos_um, stop_um);
}

/* Hold here: a reset while moving puts the set point at the given position, at rest. */
static void test_reset_hold_here(void **state)
{
	struct profile p;
	struct checker c;

	(void)state;
	setup(&p, &c, 1000, 1000000, 1000000, 5000000, 0);
	profile_set_target(&p, 1000000);
	for (int k = 0; k < 300; k++)
		checker_tick(&c, &p);
	assert_true(p.out.vel_um_s > 0);
	profile_reset(&p, 42);
	assert_true(profile_is_done(&p));
	for (int k = 0; k < 10; k++) {
		profile_update(&p);
		assert_int_equal(p.out.pos_um, 42);
		assert_int_equal(p.out.vel_um_s, 0);
		assert_true(p.out.done);
	}
	/* And moves again from there. */
	checker_init(&c, &p, 1000);
	profile_set_target(&p, -100000);
	run_to_done(&c, &p, 10000);
	assert_int_equal(p.out.pos_um, -100000);
}

/* Out-of-range settings are refused. */
/* The limits in per-tick units are floor(v 2^16 / hz) and floor(a 2^16 / hz^2), to the bit, over
 * the accepted ranges (their bounds, and a pseudo-random sweep): what the AVR computes with a
 * division steps of fx_udiv_shl16(), the host's 64-bit division says. */
static void test_limits_in_tick_units(void **state)
{
	struct profile p;
	uint32_t x = 12345u;

	(void)state;
	for (int i = 0; i < 20000; i++) {
		uint16_t hz =
			(uint16_t)(i < 4 ? (i & 1 ? PROFILE_TICK_HZ_MAX : PROFILE_TICK_HZ_MIN)
					 : PROFILE_TICK_HZ_MIN + x % (PROFILE_TICK_HZ_MAX -
								      PROFILE_TICK_HZ_MIN + 1));
		int32_t v = i < 4 ? (i & 2 ? PROFILE_V_MAX_UM_S : 1)
				  : 1 + (int32_t)((x >> 3) % PROFILE_V_MAX_UM_S);
		int32_t a = i < 4 ? (i & 2 ? PROFILE_A_MAX_UM_S2 : PROFILE_A_MIN_UM_S2)
				  : PROFILE_A_MIN_UM_S2 +
					    (int32_t)((x >> 7) % (PROFILE_A_MAX_UM_S2 -
								  PROFILE_A_MIN_UM_S2 + 1));
		struct profile_config cfg = {.tick_hz = hz, .limits = {v, a, 0}};

		x = x * 1103515245u + 12345u;
		assert_int_equal(profile_init(&p, &cfg, 0), 0);
		assert_int_equal(p.prm.v_max_q16, (int32_t)(((uint64_t)v << 16) / hz));
		assert_int_equal(p.prm.a_full_q16,
				 (int32_t)(((uint64_t)a << 16) / ((uint64_t)hz * hz)));
	}
}

static void test_bad_settings(void **state)
{
	struct profile p;
	struct profile_config cfg = {1000, {100000, 400000, 0}};
	struct profile_limits bad = {0, 400000, 0};

	(void)state;
	assert_int_equal(profile_init(&p, &cfg, 0), 0);
	assert_int_equal(profile_set_limits(&p, &bad), -1);
	bad = (struct profile_limits){100000, 10, 0};
	assert_int_equal(profile_set_limits(&p, &bad), -1);
	bad = (struct profile_limits){100000, 400000, 5};
	assert_int_equal(profile_set_limits(&p, &bad), -1);
	cfg.tick_hz = 50;
	assert_int_equal(profile_init(&p, &cfg, 0), -1);
	cfg.tick_hz = 2001;
	assert_int_equal(profile_init(&p, &cfg, 0), -1);
}

struct scurve_case {
	uint16_t hz;
	int32_t d_um;
	int32_t v_um_s;
	int32_t a_um_s2;
	int32_t j_um_s3;
};

/* S-curve durations against the closed forms of docs/control.md, within 3 ticks: long moves
 * T = d/v + v/a + a/j; shorter ones that reach a but not v; and short ones that reach neither. */
static void test_scurve_durations(void **state)
{
	static const struct scurve_case cases[] = {
		/* 1.8 m, 1 m/s, 1 m/s^2, 5 m/s^3: T = 1.8 + 1 + 0.2 = 3.00 s. */
		{1000, 1800000, 1000000, 1000000, 5000000},
		/* Defaults 0.1 m/s, 0.4 m/s^2, 4 m/s^3 over 0.5 m: T = 5 + 0.25 + 0.1 = 5.35 s. */
		{1000, 500000, 100000, 400000, 4000000},
		{1000, -500000, 100000, 400000, 4000000},
		/* Reaches a, not v: 0.2 m at 1 m/s, 1 m/s^2, 10 m/s^3. */
		{1000, 200000, 1000000, 1000000, 10000000},
		/* Reaches neither: 1 mm at 1 m/s^2, 10 m/s^3 (2 a^3/j^2 = 20 mm). */
		{1000, 1000, 1000000, 1000000, 10000000},
		{1000, 15000, 1000000, 1000000, 10000000},
		{2000, 1800000, 1000000, 1500000, 20000000},
		{100, 1800000, 1000000, 1000000, 5000000},
		{500, -777777, 250000, 600000, 3000000},
	};

	(void)state;
	for (size_t i = 0; i < N_OF(cases); i++) {
		const struct scurve_case *k = &cases[i];
		struct profile p;
		struct checker c;
		struct run r;
		int32_t d = k->d_um < 0 ? -k->d_um : k->d_um;
		int64_t expect;
		int64_t got;

		setup(&p, &c, k->hz, k->v_um_s, k->a_um_s2, k->j_um_s3, 0);
		profile_set_target(&p, k->d_um);
		r = run_to_done(&c, &p, 200000);
		expect = scurve_ticks_x1024(d, k->v_um_s, k->a_um_s2, k->j_um_s3, k->hz);
		got = (int64_t)r.ticks * 1024;
		print_message("case %zu: %u ticks, closed form %.2f\n", i, r.ticks,
			      (double)expect / 1024.0);
		assert_clean_move(&r, &p, 0, k->d_um, k->v_um_s, k->a_um_s2, k->j_um_s3, k->hz);
		assert_true(got >= expect - 3 * 1024 && got <= expect + 3 * 1024);
	}
}

/* S-curve reversal and stop: the acceleration never jumps by more than j / hz. */
static void test_scurve_reversal_and_stop(void **state)
{
	struct profile p;
	struct checker c;
	struct run r;
	int32_t stop_um;

	(void)state;
	setup(&p, &c, 1000, 500000, 1000000, 5000000, 0);
	profile_set_target(&p, 1000000);
	for (int k = 0; k < 300; k++)
		checker_tick(&c, &p);
	/* Still accelerating. */
	assert_true(p.out.acc_um_s2 > 0);
	profile_set_target(&p, -200000);
	r = run_to_done(&c, &p, 100000);
	assert_int_equal(p.out.pos_um, -200000);
	assert_true(r.max_djerk_um_s2 <= 5000 + 1);
	assert_true(r.max_acc_um_s2 <= 1000000);
	assert_true(r.max_vel_um_s <= 500000);
	assert_true(r.min_pos_um >= -200000);

	profile_set_target(&p, 600000);
	for (int k = 0; k < 900; k++)
		checker_tick(&c, &p);
	stop_um = profile_stop(&p);
	r = run_to_done(&c, &p, 100000);
	assert_int_equal(p.out.pos_um, stop_um);
	assert_true(r.max_pos_um <= stop_um);
	assert_true(r.max_djerk_um_s2 <= 5000 + 1);
	assert_true(r.max_dp_err_um <= 1);
}

int main(void)
{
	const struct CMUnitTest tests[] = {
		cmocka_unit_test(test_trapezoid_durations),
		cmocka_unit_test(test_trapezoid_symmetric),
		cmocka_unit_test(test_zero_length_move),
		cmocka_unit_test(test_reversal),
		cmocka_unit_test(test_replan_continuity_trapezoid),
		cmocka_unit_test(test_replan_continuity_scurve),
		cmocka_unit_test(test_replan_extend),
		cmocka_unit_test(test_limits_changed_mid_move),
		cmocka_unit_test(test_stop),
		cmocka_unit_test(test_reset_hold_here),
		cmocka_unit_test(test_limits_in_tick_units),
		cmocka_unit_test(test_bad_settings),
		cmocka_unit_test(test_scurve_durations),
		cmocka_unit_test(test_scurve_reversal_and_stop),
	};
	return cmocka_run_group_tests(tests, NULL, NULL);
}
