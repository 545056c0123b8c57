/* The polar control's feed-forward (control.c): its acceleration term is kept from one tick to
 * the next while the acceleration holds. With the PIDs' gains at zero the duties are the
 * feed-forward alone: a control that runs a whole sequence of set points must give, at every
 * tick, the duties of a control initialised afresh for that tick (which keeps nothing), for
 * coefficients below 2^16 (the AVR's assembly) and above; and a hand-computed duty. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>

#include <cmocka.h>

#include "control.h"

static void config(struct control_config *cfg, int32_t ff_speed, int32_t ff_accel,
		   int32_t ff_angle_accel)
{
	*cfg = (struct control_config){0};
	cfg->duty_max_q15 = 32767;
	cfg->ff_speed_q15_per_m_s = ff_speed;
	cfg->ff_accel_q15_per_m_s2 = ff_accel;
	cfg->ff_angle_accel_q15_per_m_s2 = ff_angle_accel;
	cfg->gain_slew_q15_per_s[0] = 131800;
	cfg->gain_slew_q15_per_s[1] = 43400;
	/* presets all zero: no PID output */
}

static uint32_t next(uint32_t *seed)
{
	*seed = *seed * 1664525u + 1013904223u;
	return *seed >> 8;
}

/* A value in [-range, range]. */
static int32_t pick(uint32_t *seed, int32_t range)
{
	return (int32_t)(next(seed) % (uint32_t)(2 * range + 1)) - range;
}

/* acc_range [um/s^2]: the duties stay clear of saturation, which would hide a difference */
static void run_sequence(const struct control_config *cfg, uint32_t seed, int32_t acc_range)
{
	struct control kept, fresh;
	struct orders_axis d = {0, 0, 0}, a = {0, 0, 0};

	assert_int_equal(control_init(&kept, cfg, 1000), 0);
	for (int t = 0; t < 4000; t++) {
		uint32_t r = next(&seed) % 16;

		/* The accelerations change about once in 8 ticks, as at a hand-over; now and then
		 * they come back to 0 or to the value of two changes before. */
		if (r == 0) {
			d.acc_um_s2 = pick(&seed, acc_range);
			a.acc_um_s2 = pick(&seed, acc_range);
		} else if (r == 1) {
			d.acc_um_s2 = 0;
		} else if (r == 2) {
			int32_t s = d.acc_um_s2;

			d.acc_um_s2 = a.acc_um_s2;
			a.acc_um_s2 = s;
		}
		d.vel_um_s = pick(&seed, 500000);
		a.vel_um_s = pick(&seed, 300000);
		d.pos_um += d.vel_um_s / 1000;
		a.pos_um += a.vel_um_s / 1000;
		control_update(&kept, &d, &a, d.pos_um, a.pos_um);
		assert_int_equal(control_init(&fresh, cfg, 1000), 0);
		control_update(&fresh, &d, &a, d.pos_um, a.pos_um);
		assert_true(fresh.duty_q15[0] > -32767 && fresh.duty_q15[0] < 32767);
		assert_true(fresh.duty_q15[1] > -32767 && fresh.duty_q15[1] < 32767);
		if (kept.duty_q15[0] != fresh.duty_q15[0] || kept.duty_q15[1] != fresh.duty_q15[1])
			fail_msg("tick %d (acc %ld, %ld): duties %d, %d where afresh %d, %d", t,
				 (long)d.acc_um_s2, (long)a.acc_um_s2, kept.duty_q15[0],
				 kept.duty_q15[1], fresh.duty_q15[0], fresh.duty_q15[1]);
	}
}

static void test_accel_term_kept_narrow(void **state)
{
	struct control_config cfg;

	(void)state;
	config(&cfg, 20000, 3000, 2000); /* coefficients 20972, 3146, 2097 [2^-20] */
	run_sequence(&cfg, 1u, 2000000);
}

static void test_accel_term_kept_wide(void **state)
{
	struct control_config cfg;

	(void)state;
	config(&cfg, 20000, 250000, 90000); /* 262144 and 94372: above 2^16 */
	run_sequence(&cfg, 2u, 40000);
}

static void test_accel_term_value(void **state)
{
	struct control_config cfg;
	struct control c;
	struct orders_axis d = {0, 0, 1000000}, a = {0, 0, 0};

	(void)state;
	config(&cfg, 20000, 3000, 2000);
	assert_int_equal(control_init(&c, &cfg, 1000), 0);
	/* 1 m/s^2: round(10^6 3146 / 2^20) = round(3000.3) = 3000 on both motors */
	control_update(&c, &d, &a, 0, 0);
	assert_int_equal(c.duty_q15[0], 3000);
	assert_int_equal(c.duty_q15[1], 3000);
	/* The acceleration held, then gone: the term follows. */
	control_update(&c, &d, &a, 0, 0);
	assert_int_equal(c.duty_q15[0], 3000);
	d.acc_um_s2 = 0;
	control_update(&c, &d, &a, 0, 0);
	assert_int_equal(c.duty_q15[0], 0);
	/* 1 m/s^2 of arc: -2000 on the left motor, +2000 on the right */
	a.acc_um_s2 = 1000000;
	control_update(&c, &d, &a, 0, 0);
	assert_int_equal(c.duty_q15[0], -2000);
	assert_int_equal(c.duty_q15[1], 2000);
}

int main(void)
{
	const struct CMUnitTest tests[] = {
		cmocka_unit_test(test_accel_term_kept_narrow),
		cmocka_unit_test(test_accel_term_kept_wide),
		cmocka_unit_test(test_accel_term_value),
	};

	return cmocka_run_group_tests(tests, NULL, NULL);
}
