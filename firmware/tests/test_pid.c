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

/* The derivative's low-pass (pid_config.d_shift, docs/control.md "PID"): d = 125 at 1 kHz makes
 * the D duty 62.5 per um/tick, kd_q12 exact for every d_shift up to 6. */
static void setup_lp(struct pid *c, uint16_t d, uint8_t k, int32_t lag_um)
{
	struct pid_config cfg = {.d = d,
				 .out_limit_q15 = 32767,
				 .tick_hz = 1000,
				 .d_shift = k,
				 .d_lag_max_um = lag_um};

	assert_int_equal(pid_init(c, &cfg), 0);
}

/* d_shift 0 is the difference of two ticks, whatever the lag cap; out-of-range settings are
 * refused. */
static void test_lowpass_off_and_bounds(void **state)
{
	struct pid a, b;
	struct pid_config bad = {
		.d = 1, .out_limit_q15 = 100, .tick_hz = 1000, .d_shift = 7, .d_lag_max_um = 100};
	uint32_t x = 12345;

	(void)state;
	assert_int_equal(pid_init(&a, &bad), -1); /* d_shift past PID_D_SHIFT_MAX */
	bad.d_shift = 4;
	bad.d_lag_max_um = 0;
	assert_int_equal(pid_init(&a, &bad), -1); /* a low-pass needs a lag cap */
	bad.d_lag_max_um = PID_ERR_MAX_UM + 1;
	assert_int_equal(pid_init(&a, &bad), -1);
	/* d_shift 0 ignores the cap, bit for bit (test_d_term's figures). */
	setup_lp(&a, 100, 0, 0);
	setup_lp(&b, 100, 0, 5000);
	for (int t = 0; t < 2000; t++) {
		int32_t e;

		x = x * 1103515245u + 12345u;
		e = (int32_t)(x >> 8) % 3000 - 1500;
		assert_int_equal(pid_update(&a, e), pid_update(&b, e));
	}
	setup_lp(&a, 100, 0, 1);
	assert_int_equal(pid_update(&a, 0), 0);
	assert_int_equal(pid_update(&a, 100), 5000);
	assert_int_equal(pid_update(&a, 100), 0);
	assert_int_equal(pid_update(&a, 99), -50);
	/* The extremes at the largest gain, time constant and cap stay within the limit (and
	 * within int32: the sanitizers run this). */
	for (uint8_t k = 1; k <= PID_D_SHIFT_MAX; k++) {
		struct pid_config cfg = {.p = 65535,
					 .i = 65535,
					 .d = 65535,
					 .out_limit_q15 = 32767,
					 .tick_hz = 2000,
					 .d_shift = k,
					 .d_lag_max_um = PID_ERR_MAX_UM};

		assert_int_equal(pid_init(&a, &cfg), 0);
		for (int t = 0; t < 300; t++) {
			int16_t u = pid_update(&a, (t / 3) % 2 ? INT32_MAX : INT32_MIN);

			assert_true(u >= -32767);
		}
		pid_reset(&a);
		assert_true(pid_update(&a, 0) >= -32767);
	}
}

/* A steady speed reads as that speed; a count's staircase is smoothed; the cap passes a fast
 * change at once. */
static void test_lowpass_response(void **state)
{
	struct pid c, raw;
	int16_t u = 0, lo = 32767, hi = -32767, rlo = 32767, rhi = -32767;

	(void)state;
	/* 10 um a tick: 625, reached as 1 - (15/16)^n within a count of duty. */
	setup_lp(&c, 125, 4, 100000);
	for (int t = 0; t <= 200; t++) {
		int16_t v = pid_update(&c, 10 * t);

		if (t > 0)
			assert_true(v >= u); /* monotonic */
		u = v;
	}
	assert_true(u >= 624 && u <= 625);
	/* 39 um a tick as whole counts of 78 um (every other tick): the raw difference swings
	 * 0..4875, the low-pass within a tenth of it around 2437. */
	setup_lp(&c, 125, 4, 100000);
	setup_lp(&raw, 125, 0, 1);
	for (int t = 0; t < 400; t++) {
		int32_t e = 78 * (t / 2);
		int16_t v = pid_update(&c, e), r = pid_update(&raw, e);

		if (t >= 200) {
			lo = v < lo ? v : lo;
			hi = v > hi ? v : hi;
			rlo = r < rlo ? r : rlo;
			rhi = r > rhi ? r : rhi;
		}
	}
	assert_int_equal(rlo, 0);
	assert_int_equal(rhi, 4875);
	assert_true(hi - lo <= 4875 / 10);
	assert_true(lo <= 2438 && hi >= 2437);
	/* The cap: 64 ticks, 100 um. 50 um a tick passes raw from the third tick: 3125. Stopped,
	 * it reads what is left of the lag: 100 um over 64 ticks, 97. */
	setup_lp(&c, 125, 6, 100);
	for (int t = 0; t <= 10; t++)
		u = pid_update(&c, 50 * t);
	assert_true(u >= 3124 && u <= 3125);
	u = pid_update(&c, 500);
	assert_true(u >= 96 && u <= 98);
}

/* A reset keeps the speed read (a set point's jump is not a speed); pid_forget and the raw mode
 * do not. */
static void test_lowpass_reset_and_raw(void **state)
{
	struct pid c, ref;
	int16_t u = 0;
	uint32_t x = 99;

	(void)state;
	setup_lp(&c, 125, 4, 100000);
	for (int t = 0; t <= 200; t++)
		u = pid_update(&c, 10 * t);
	assert_int_equal(u, 625);
	pid_reset(&c);
	/* no kick from the jump: the speed read, less the low-pass's last move (15/16) */
	assert_int_equal(pid_update(&c, 10 * 201 + 50000), 586);
	for (int t = 202; t <= 400; t++) {
		int16_t v = pid_update(&c, 10 * t + 50000);

		assert_true(v >= u - 40 && v <= 625); /* back to the speed read */
		u = v;
	}
	assert_true(u >= 624);
	pid_forget(&c);
	assert_int_equal(pid_update(&c, 7000), 0);
	/* Raw: the difference of two ticks with the same gain, bit for bit with d_shift 0 (kd
	 * exact); then the low-pass goes on from rest. */
	setup_lp(&c, 125, 4, 320);
	setup_lp(&ref, 125, 0, 1);
	pid_set_raw_d(&c, 1);
	for (int t = 0; t < 1000; t++) {
		int32_t e;

		x = x * 1103515245u + 12345u;
		e = (int32_t)(x >> 8) % 20000 - 10000;
		assert_int_equal(pid_update(&c, e), pid_update(&ref, e));
	}
	pid_reset(&c);
	pid_reset(&ref);
	assert_int_equal(pid_update(&c, 4242), 0);
	assert_int_equal(pid_update(&ref, 4242), 0);
	pid_set_raw_d(&c, 0);
	assert_int_equal(pid_update(&c, 4242), 0);  /* at rest */
	assert_int_equal(pid_update(&c, 4258), 63); /* 16 um over 16 ticks: 62.5 */
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
		struct pid_config bad = {1, 1, 1, 0, 1000, 0, 0};

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
		struct pid_config cfg = {0, 100, 0, 5000, 1000, 0, 0};

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
		cmocka_unit_test(test_p_term),
		cmocka_unit_test(test_i_term),
		cmocka_unit_test(test_d_term),
		cmocka_unit_test(test_sum_and_saturation),
		cmocka_unit_test(test_anti_windup),
		cmocka_unit_test(test_closed_loop_step),
		cmocka_unit_test(test_lowpass_off_and_bounds),
		cmocka_unit_test(test_lowpass_response),
		cmocka_unit_test(test_lowpass_reset_and_raw),
	};
	return cmocka_run_group_tests(tests, NULL, NULL);
}
