/* Stop conditions, check by check, on synthetic inputs: what fires, after how many ticks, and
 * what is gated off (pushing, idle, a sensor already pressed). */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <string.h>

#include <cmocka.h>

#include "board.h"

static struct faults f;
static struct faults_inputs in;

static void setup(void)
{
	struct board_config bc;
	const uint16_t zero[2] = {0, 0};

	board_default_config(&bc);
	bc.faults.shock_basket_mask = 0x01;
	assert_int_equal(faults_init(&f, &bc.faults, 1000, zero), 0);
	memset(&in, 0, sizeof(in));
	in.free_ratio_q16 = 37449; /* 160 / 280 */
	in.moving = 1;
}

/* Ticks until the check fires, at most max; 0 when it never does. */
static uint32_t ticks_to(uint8_t event, uint32_t max)
{
	for (uint32_t n = 1; n <= max; n++)
		if (faults_check(&f, &in) == event)
			return n;
	return 0;
}

static void test_overcurrent_after_its_duration(void **state)
{
	(void)state;
	setup();
	in.current_ma[1] = -6001;
	assert_int_equal(ticks_to(FAULTS_MOTOR, 1000), 50);
	assert_int_equal(f.cause, FAULTS_CAUSE_OVERCURRENT);
	setup();
	in.current_ma[0] = 6000; /* at the limit: not over it */
	assert_int_equal(ticks_to(FAULTS_MOTOR, 1000), 0);
}

static void test_following_error_gated(void **state)
{
	(void)state;
	setup();
	in.dist_err_um = 20001;
	assert_int_equal(ticks_to(FAULTS_MOTOR, 1000), 100);
	assert_int_equal(f.cause, FAULTS_CAUSE_FOLLOWING);
	setup();
	in.angle_err_um = -25000;
	in.pushing = 1; /* a deliberate push is not a fault */
	assert_int_equal(ticks_to(FAULTS_MOTOR, 1000), 0);
	setup();
	in.angle_err_um = -25000;
	in.moving = 0; /* nor is being pushed while idle */
	assert_int_equal(ticks_to(FAULTS_MOTOR, 1000), 0);
	setup();
	in.dist_err_um = 25000; /* a blip shorter than the duration */
	for (int i = 0; i < 99; i++)
		assert_int_equal(faults_check(&f, &in), FAULTS_NONE);
	in.dist_err_um = 0;
	assert_int_equal(ticks_to(FAULTS_MOTOR, 1000), 0);
}

static void test_slip(void **state)
{
	(void)state;
	setup();
	/* The drive wheels advance 1 mm per tick, the free wheels 0.9 mm: 0.1 mm/tick of slip
	 * sums (leaky, 128 ticks) to past 10 mm. */
	for (uint32_t n = 1; n < 2000; n++) {
		in.motor_count[0] = (uint16_t)(in.motor_count[0] + 203);
		in.motor_count[1] = (uint16_t)(in.motor_count[1] + 203);
		in.free_step_q16[0] = in.free_step_q16[1] = 900 << 16;
		if (faults_check(&f, &in) == FAULTS_MOTOR)
			break;
	}
	assert_int_equal(f.cause, FAULTS_CAUSE_SLIP);
}

/* Both motors turn n counts and the free wheels travel the given um this tick. */
static uint8_t step(uint16_t left_counts, uint16_t right_counts, int32_t free_l_um,
		    int32_t free_r_um)
{
	in.motor_count[0] = (uint16_t)(in.motor_count[0] + left_counts);
	in.motor_count[1] = (uint16_t)(in.motor_count[1] + right_counts);
	in.free_step_q16[0] = free_l_um * 65536;
	in.free_step_q16[1] = free_r_um * 65536;
	return faults_check(&f, &in);
}

/* A cut wire: the first time, the order is abandoned on suspicion (PB_MOTEUR, cause
 * ENCODER_LOST); the wheel never counts again, and the next order that turns its motor 5 mm is
 * PB_GRAVE. */
static void test_encoder_lost(void **state)
{
	uint32_t n;

	(void)state;
	setup();
	for (n = 1; n < 2000; n++)
		if (step(100, 100, 490, 0) != FAULTS_NONE) /* right wire cut */
			break;
	/* 100 counts are 492 um of drive wheel: 5 mm after 11 ticks. */
	assert_int_equal(n, 11);
	assert_int_equal(f.cause, FAULTS_CAUSE_ENCODER_LOST);
	assert_int_equal(f.n_motor_faults, 1);
	in.moving = 0; /* the order is abandoned, the robot coasts: still not a count */
	assert_int_equal(step(20, 20, 100, 0), FAULTS_NONE);
	in.moving = 1; /* the next order: steering on the wrong heading, whatever it does */
	for (n = 1; n < 2000; n++)
		if (step(20, 150, 100, 0) != FAULTS_NONE)
			break;
	/* 150 counts are 738 um: 5 mm after 7 ticks. */
	assert_int_equal(n, 7);
	assert_int_equal(f.cause, FAULTS_CAUSE_ENCODER_LOST);
	assert_true(f.grave);
	/* PB_GRAVE latches. */
	assert_int_equal(step(0, 0, 0, 0), FAULTS_GRAVE);
}

/* The wheel's next count clears the suspicion: a robot that pivoted on a contact once and then
 * rolled away is not a cut wire. */
static void test_encoder_suspicion_cleared_by_a_count(void **state)
{
	uint32_t n;

	(void)state;
	setup();
	for (n = 1; n < 2000; n++)
		if (step(100, 100, 490, 0) != FAULTS_NONE)
			break;
	assert_int_equal(f.cause, FAULTS_CAUSE_ENCODER_LOST);
	assert_int_equal(step(100, 100, 490, 79), FAULTS_NONE); /* one count */
	for (n = 1; n < 2000; n++)
		if (step(100, 100, 490, 0) != FAULTS_NONE)
			break;
	assert_int_equal(n, 11);
	assert_int_equal(f.cause, FAULTS_CAUSE_ENCODER_LOST);
	assert_false(f.grave); /* a suspicion again, not a verdict */
}

/* The known false PB_GRAVE: a robot blocked head-on, drive wheels spinning 1 mm per tick, the
 * right free wheel still and the left one twitching back and forth. It is a slip. */
static void test_blocked_with_a_twitching_wheel_is_a_slip(void **state)
{
	uint8_t ev = FAULTS_NONE;
	uint32_t n;

	(void)state;
	setup();
	for (n = 1; n < 2000 && ev == FAULTS_NONE; n++)
		ev = step(203, 203, (n % 2) ? 79 : -79, 0);
	assert_int_equal(ev, FAULTS_MOTOR);
	assert_int_equal(f.cause, FAULTS_CAUSE_SLIP);
}

/* A corner against a border: the robot pivots on the contact near its right side, the right
 * free wheel still, the right drive wheel spinning 1.3 mm per tick, the left side rolling 0.35
 * mm per tick. It is a slip (measured on the simulator, python/tests/test_faults_sim.py). */
static void test_pivot_on_a_contact_is_a_slip(void **state)
{
	uint8_t ev = FAULTS_NONE;

	(void)state;
	setup();
	for (uint32_t n = 1; n < 2000 && ev == FAULTS_NONE; n++)
		ev = step(60, 262, 353, 0);
	assert_int_equal(ev, FAULTS_MOTOR);
	assert_int_equal(f.cause, FAULTS_CAUSE_SLIP);
}

/* With no order running there is no trajectory to abandon: a robot pushed while it holds its
 * position slips without a PB_MOTEUR, and an overcurrent only makes it let go (FAULTS_YIELD),
 * never counted towards PB_GRAVE. Before, the rocking after one abandoned order gave two more
 * PB_MOTEUR and a PB_GRAVE within 40 ms. */
static void test_idle_is_not_a_motor_problem(void **state)
{
	(void)state;
	setup();
	in.moving = 0;
	for (uint32_t n = 1; n < 2000; n++) {
		in.motor_count[0] = (uint16_t)(in.motor_count[0] + 203); /* 1 mm per tick */
		in.motor_count[1] = (uint16_t)(in.motor_count[1] + 203);
		in.free_step_q16[0] = in.free_step_q16[1] = 500 << 16; /* the robot: 0.5 mm */
		assert_int_equal(faults_check(&f, &in), FAULTS_NONE);
	}
	in.free_step_q16[0] = in.free_step_q16[1] = 0;
	in.motor_count[0] = in.motor_count[1] = 0;
	(void)faults_check(&f, &in);
	in.current_ma[0] = 7000;
	for (int k = 0; k < 10; k++)
		assert_int_equal(ticks_to(FAULTS_YIELD, 1000), 50);
	assert_int_equal(f.n_motor_faults, 0);
	/* The same while an order runs is PB_MOTEUR, and the third within the window PB_GRAVE. */
	in.moving = 1;
	assert_int_equal(ticks_to(FAULTS_MOTOR, 1000), 50);
	assert_int_equal(f.cause, FAULTS_CAUSE_OVERCURRENT);
}

/* Extreme inputs (a counter glitch, a wild following error) saturate instead of overflowing:
 * the build of the tests stops on any signed overflow (UBSan). Found by fuzz/fuzz_board. */
static void test_extreme_inputs_saturate(void **state)
{
	(void)state;
	setup();
	in.free_step_q16[0] = INT32_MIN; /* the free wheels at the ends of their range */
	in.free_step_q16[1] = INT32_MAX;
	/* Both motor counters jump half their range, tick after tick: slip within 3 ticks (2 since
	 * each wheel's own slip is checked, issue 18). */
	for (int i = 1; i <= 3; i++) {
		in.motor_count[0] = (uint16_t)(in.motor_count[0] + 0x7FFF);
		in.motor_count[1] = (uint16_t)(in.motor_count[1] + 0x7FFF);
		if (faults_check(&f, &in) == FAULTS_MOTOR)
			break;
		assert_true(i < 3);
	}
	assert_int_equal(f.cause, FAULTS_CAUSE_SLIP);
	setup();
	in.dist_err_um = INT32_MIN;
	assert_int_equal(ticks_to(FAULTS_MOTOR, 1000), 100);
	assert_int_equal(f.cause, FAULTS_CAUSE_FOLLOWING);
	/* A huge track ratio with the free wheels turning apart at full range. */
	setup();
	in.free_ratio_q16 = INT32_MAX;
	in.free_step_q16[0] = INT32_MAX;
	in.free_step_q16[1] = INT32_MIN;
	assert_true(ticks_to(FAULTS_MOTOR, 10) > 0);
	assert_int_equal(f.cause, FAULTS_CAUSE_SLIP);
}

static void test_repeated_motor_faults_are_grave(void **state)
{
	(void)state;
	setup();
	in.current_ma[0] = 7000;
	assert_int_equal(ticks_to(FAULTS_MOTOR, 1000), 50);
	assert_int_equal(ticks_to(FAULTS_MOTOR, 1000), 50);
	assert_int_equal(ticks_to(FAULTS_GRAVE, 1000), 50);
	assert_int_equal(f.cause, FAULTS_CAUSE_REPEATED);
	/* Spread out over more than the window, they stay PB_MOTEUR. */
	setup();
	in.current_ma[0] = 7000;
	for (int k = 0; k < 5; k++) {
		assert_int_equal(ticks_to(FAULTS_MOTOR, 1000), 50);
		in.current_ma[0] = 0;
		assert_int_equal(ticks_to(FAULTS_MOTOR, 6000), 0);
		in.current_ma[0] = 7000;
	}
}

static void test_shocks_roles_and_gating(void **state)
{
	(void)state;
	setup();
	in.shocks = 0x01;
	assert_int_equal(faults_check(&f, &in), FAULTS_SHOCK_PANIER);
	in.shocks = 0x81;
	assert_int_equal(faults_check(&f, &in), FAULTS_SHOCK_BORD);
	in.pushing = 1;
	in.shocks = 0x01; /* the basket-side sensor is the expected contact of a push */
	assert_int_equal(faults_check(&f, &in), FAULTS_NONE);
	in.pushing = 0;
	in.moving = 0; /* idle: nothing to stop */
	assert_int_equal(faults_check(&f, &in), FAULTS_NONE);
	/* Pressed when the order started: ignored until released once. */
	in.moving = 1;
	in.shocks = 0x10;
	faults_order_started(&f, 0x10);
	assert_int_equal(faults_check(&f, &in), FAULTS_NONE);
	in.shocks = 0;
	assert_int_equal(faults_check(&f, &in), FAULTS_NONE);
	in.shocks = 0x10;
	assert_int_equal(faults_check(&f, &in), FAULTS_SHOCK_BORD);
}

int main(void)
{
	const struct CMUnitTest tests[] = {
		cmocka_unit_test(test_overcurrent_after_its_duration),
		cmocka_unit_test(test_following_error_gated),
		cmocka_unit_test(test_slip),
		cmocka_unit_test(test_encoder_lost),
		cmocka_unit_test(test_encoder_suspicion_cleared_by_a_count),
		cmocka_unit_test(test_blocked_with_a_twitching_wheel_is_a_slip),
		cmocka_unit_test(test_pivot_on_a_contact_is_a_slip),
		cmocka_unit_test(test_idle_is_not_a_motor_problem),
		cmocka_unit_test(test_extreme_inputs_saturate),
		cmocka_unit_test(test_repeated_motor_faults_are_grave),
		cmocka_unit_test(test_shocks_roles_and_gating),
	};
	return cmocka_run_group_tests(tests, NULL, NULL);
}
