/* The PID (pid.c): each term against hand-computed duties in the protocol's gain units,
 * saturation, anti-windup recovery, and a closed-loop step response on a motor-like plant. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>

#include <cmocka.h>

#include "pid.h"

static void setup(struct pid *c, uint16_t p, uint16_t i, uint16_t d, int16_t lim, uint16_t hz)
{
	struct pid_config cfg = {.p = p, .i = i, .d = d, .out_limit_q15 = lim, .tick_hz = hz};

	assert_int_equal(pid_init(c, &cfg), 0);
}

/* P: duty_q15 = 32768 p 2^-12 e_mm = p e_um / 125. */
static void test_p_term(void **state)
{
	struct pid c;

	(void)state;
	/* p = 4096: one full duty per mm. 250 um -> 0.25 full duty = 8192. */
	setup(&c, 4096, 0, 0, 32767, 1000);
	assert_int_equal(pid_update(&c, 250), 8192);
	/* -1 um -> -4096 / 125 = -32.768 -> -33 (rounded to nearest). */
	assert_int_equal(pid_update(&c, -1), -33);
	/* p = 1000, 3 um -> 3000 / 125 = 24 exactly. */
	setup(&c, 1000, 0, 0, 32767, 1000);
	assert_int_equal(pid_update(&c, 3), 24);
	/* p = 1, 1 mm -> 1000 / 125 = 8. */
	setup(&c, 1, 0, 0, 32767, 500);
	assert_int_equal(pid_update(&c, 1000), 8);
	assert_int_equal(pid_update(&c, 0), 0);
}

/* I: duty_q15 = 32768 i 2^-12 (sum e_um / hz) / 1000 = i sum_e_um / (125 hz). */
static void test_i_term(void **state)
{
	struct pid c;
	int16_t out = 0;

	(void)state;
	/* i = 4096 (one full duty per mm*s), 1 mm of error, 1 kHz: 32.768 per tick. */
	setup(&c, 0, 4096, 0, 32767, 1000);
	assert_int_equal(pid_update(&c, 1000), 33); /* 32.768 */
	for (int k = 2; k <= 10; k++)
		out = pid_update(&c, 1000);
	assert_int_equal(out, 328); /* 327.68 */
	for (int k = 11; k <= 100; k++)
		out = pid_update(&c, 1000);
	assert_int_equal(out, 3277); /* 3276.8 */
	/* Back to 0 error: the integral holds. */
	assert_int_equal(pid_update(&c, 0), 3277);
	/* -100 mm*s * ... : 50 ticks of -2 mm remove 50 * 65.536 = 3276.8: back to 0. */
	for (int k = 0; k < 50; k++)
		out = pid_update(&c, -2000);
	assert_int_equal(out, 0);
	/* 100 Hz: one tick of 1 mm is 10 ms: i = 1000 gives 1000 * 1000 / 12500 = 80. */
	setup(&c, 0, 1000, 0, 32767, 100);
	assert_int_equal(pid_update(&c, 1000), 80);
}

/* D: duty_q15 = 32768 d 2^-16 (de_um hz / 1000) = d de_um hz / 2000, on the error difference. */
static void test_d_term(void **state)
{
	struct pid c;

	(void)state;
	/* d = 100, 1 kHz: 0 -> 100 um in one tick is 100 mm/s: 100 * 100 / 65536 full duty
	 * = 0.152587890625 = 5000 / 32768. */
	setup(&c, 0, 0, 100, 32767, 1000);
	assert_int_equal(pid_update(&c, 0), 0);
	assert_int_equal(pid_update(&c, 100), 5000);
	assert_int_equal(pid_update(&c, 100), 0);
	assert_int_equal(pid_update(&c, 99), -50);
	/* The first tick after a reset has no previous error: no derivative kick. */
	pid_reset(&c);
	assert_int_equal(pid_update(&c, 100000), 0);
	/* 2 kHz, d = 7: 3 um per tick -> 7 * 3 * 2000 / 2000 = 21. */
	setup(&c, 0, 0, 7, 32767, 2000);
	assert_int_equal(pid_update(&c, 0), 0);
	assert_int_equal(pid_update(&c, 3), 21);
}

/* All three together add up; the output is clipped to the limit, both ways. */
static void test_sum_and_saturation(void **state)
{
	struct pid c;

	(void)state;
	/* p 1000 * 500 / 125 = 4000; i 4096 * 500 / 125000 = 16.384; d 100 * 500 * 1000 / 2000
	 * = 25000: 29016.384 -> 29016. */
	setup(&c, 1000, 4096, 100, 32767, 1000);
	assert_int_equal(pid_update(&c, 0), 0);
	assert_int_equal(pid_update(&c, 500), 29016);
	/* Limit 20000. */
	setup(&c, 4096, 0, 0, 20000, 1000);
	assert_int_equal(pid_update(&c, 1000000), 20000);
	assert_int_equal(pid_update(&c, -1000000), -20000);
	assert_int_equal(pid_update(&c, INT32_MIN), -20000);
	assert_int_equal(pid_update(&c, INT32_MAX), 20000);
	/* The largest gains on the largest error stay clipped (no overflow: UBSan checks). */
	setup(&c, 65535, 65535, 65535, 32767, 2000);
	assert_int_equal(pid_update(&c, INT32_MAX), 32767);
	assert_int_equal(pid_update(&c, INT32_MIN), -32767);
	/* Out-of-range settings are refused. */
	{
		struct pid_config bad = {1, 1, 1, 0, 1000};

		assert_int_equal(pid_init(&c, &bad), -1);
		bad.out_limit_q15 = 100;
		bad.tick_hz = 99;
		assert_int_equal(pid_init(&c, &bad), -1);
	}
}

/* Anti-windup. A long saturation must not leave an integral that delays the recovery. */
static void test_anti_windup(void **state)
{
	struct pid c;
	int16_t out = 0;
	int k;

	(void)state;
	/* 10 s saturated by P (5 mm * p 400 = 16000 > 10000): the integral does not grow at all
	 * (without anti-windup it would hold 10 s * 5 mm = 50 full duties). An error of the other
	 * sign gives a negative duty on its first tick: -0.1 mm * 400 / 125 - 0.1 * 32.768. */
	setup(&c, 400, 4096, 0, 10000, 1000);
	for (k = 0; k < 10000; k++)
		assert_int_equal(pid_update(&c, 5000), 10000);
	assert_int_equal(pid_update(&c, -100), -323); /* -320 - 3.2768 */

	/* Integral alone: it climbs 32.768 per tick to the limit, then stays clipped there. */
	setup(&c, 0, 4096, 0, 10000, 1000);
	for (k = 0; k < 10000; k++)
		out = pid_update(&c, 1000);
	assert_int_equal(out, 10000);
	/* The integral holds one full output at most: 10000 [2^-24 duty_q15 * 2^24]. */
	assert_true(c.i_acc_q24.hi <= (int32_t)10000 << 8);
	/* The error reverses: the duty leaves saturation at once and crosses zero after
	 * 10000 / 32.768 = 305.2 ticks, not after the ~9700 that a free integral would take. */
	for (k = 1; k < 1000; k++) {
		out = pid_update(&c, -1000);
		if (out < 0)
			break;
		if (k == 1)
			assert_true(out < 10000);
	}
	assert_int_equal(k, 306);

	/* A new i gain keeps the integral's duty (bumpless); a lower limit clips it. */
	{
		struct pid_config cfg = {0, 100, 0, 5000, 1000};

		setup(&c, 0, 4096, 0, 10000, 1000);
		for (k = 0; k < 100; k++)
			out = pid_update(&c, 1000);
		assert_int_equal(out, 3277);
		cfg.out_limit_q15 = 10000;
		assert_int_equal(pid_set_config(&c, &cfg), 0);
		assert_int_equal(pid_update(&c, 0), 3277);
		cfg.out_limit_q15 = 2000;
		assert_int_equal(pid_set_config(&c, &cfg), 0);
		assert_int_equal(pid_update(&c, 0), 2000);
	}
}

/* A motor and robot as one first-order velocity lag (docs physics figures: 2 m/s at full duty,
 * mechanical time constant 0.11 s), integrated exactly over each tick with the duty held. */
struct plant1 {
	double x_um;
	double v_um_s;
};

/* exp(-dt / tau) for dt = 1 ms, tau = 0.11 s (no libm in the tests): 0.99095133 */
#define PLANT_DECAY 0.9909513340
#define PLANT_TAU_S 0.11
#define PLANT_FULL_UM_S 2000000.0

static void plant1_step(struct plant1 *pl, int16_t duty_q15)
{
	double v_ss = PLANT_FULL_UM_S * duty_q15 / 32768.0;
	double v0 = pl->v_um_s;

	pl->v_um_s = v_ss + (v0 - v_ss) * PLANT_DECAY;
	pl->x_um += v_ss * 0.001 + (v0 - v_ss) * PLANT_TAU_S * (1.0 - PLANT_DECAY);
}

/* Step of 20 mm at 1 kHz. Gains placing the three closed-loop poles at -30 rad/s:
 * tau s^3 + (1 + K kd) s^2 + K kp s + K ki = tau (s + 30)^3 with K = 2000 mm/s per duty, so
 * kp = 0.1485 duty/mm (p 608), ki = 1.485 duty/(mm*s) (i 6083), kd = 0.00445 duty/(mm/s)
 * (d 292). The step saturates the duty for about 20 ms; the zeros of the PID give a 16 %
 * overshoot. Measured: peak 23158 um, within +/-0.1 mm from 326 ms on. */
#define SETTLE_MAX_MS 350
#define OVERSHOOT_MAX_UM 3300

static void test_closed_loop_step(void **state)
{
	struct pid c;
	struct plant1 pl = {0.0, 0.0};
	const double target_um = 20000.0;
	double peak_um = 0.0;
	int settle_tick = -1;

	(void)state;
	setup(&c, 608, 6083, 292, 32767, 1000);
	for (int k = 0; k < 3000; k++) {
		double e = target_um - pl.x_um;
		int16_t duty = pid_update(&c, (int32_t)(e >= 0 ? e + 0.5 : e - 0.5));

		plant1_step(&pl, duty);
		if (pl.x_um > peak_um)
			peak_um = pl.x_um;
		if (pl.x_um < target_um - 100.0 || pl.x_um > target_um + 100.0)
			settle_tick = -1;
		else if (settle_tick < 0)
			settle_tick = k + 1;
	}
	print_message("peak %.1f um, settled at %d ms, end %.2f um\n", peak_um, settle_tick,
		      pl.x_um);
	assert_true(settle_tick > 0);
	assert_true(settle_tick <= SETTLE_MAX_MS);
	assert_true(peak_um - target_um <= OVERSHOOT_MAX_UM);
	assert_true(pl.x_um > target_um - 5.0 && pl.x_um < target_um + 5.0);
}

int main(void)
{
	const struct CMUnitTest tests[] = {
		cmocka_unit_test(test_p_term),      cmocka_unit_test(test_i_term),
		cmocka_unit_test(test_d_term),      cmocka_unit_test(test_sum_and_saturation),
		cmocka_unit_test(test_anti_windup), cmocka_unit_test(test_closed_loop_step),
	};
	return cmocka_run_group_tests(tests, NULL, NULL);
}
