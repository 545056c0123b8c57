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
	assert_int_equal(faults_init(&f, &bc.faults, zero), 0);
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

static void test_encoder_lost(void **state)
{
	uint32_t n;

	(void)state;
	setup();
	for (n = 1; n < 2000; n++) {
		in.motor_count[0] = (uint16_t)(in.motor_count[0] + 100);
		in.motor_count[1] = (uint16_t)(in.motor_count[1] + 100);
		in.free_step_q16[0] = 490 << 16;
		in.free_step_q16[1] = 0; /* right wire cut */
		if (faults_check(&f, &in) == FAULTS_GRAVE)
			break;
	}
	assert_int_equal(f.cause, FAULTS_CAUSE_ENCODER_LOST);
	/* 100 counts are 492 um of drive wheel: 5 mm after 11 ticks. */
	assert_int_equal(n, 11);
	/* PB_GRAVE latches. */
	memset(&in.free_step_q16, 0, sizeof(in.free_step_q16));
	assert_int_equal(faults_check(&f, &in), FAULTS_GRAVE);
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
	in.motor_count[0] = 0x7FFF; /* both motor counters jump half their range in one tick */
	in.motor_count[1] = 0x7FFF;
	in.free_step_q16[0] = INT32_MIN;
	in.free_step_q16[1] = INT32_MAX;
	assert_int_equal(faults_check(&f, &in), FAULTS_MOTOR);
	assert_int_equal(f.cause, FAULTS_CAUSE_SLIP);
	setup();
	in.dist_err_um = INT32_MIN;
	assert_int_equal(ticks_to(FAULTS_MOTOR, 1000), 100);
	assert_int_equal(f.cause, FAULTS_CAUSE_FOLLOWING);
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
		cmocka_unit_test(test_idle_is_not_a_motor_problem),
		cmocka_unit_test(test_extreme_inputs_saturate),
		cmocka_unit_test(test_repeated_motor_faults_are_grave),
		cmocka_unit_test(test_shocks_roles_and_gating),
	};
	return cmocka_run_group_tests(tests, NULL, NULL);
}
