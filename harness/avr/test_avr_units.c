/* The AVR port's unit conversions (avr_units.h), computed there from bytes so that the AVR needs
 * no 32-bit product: every input gives the value of the plain 32-bit formula. Host only. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>

#include <cmocka.h>

#include "avr_units.h"

static void test_pwm_counts_every_duty(void **state)
{
	(void)state;
	for (int32_t d = -32768; d <= 32767; d++) {
		uint32_t mag = (uint32_t)(d < 0 ? -d : d);
		uint32_t want = ((mag > 32767u ? 32767u : mag) * AVR_PWM_TOP + 16384u) >> 15;

		if (avr_pwm_counts((int16_t)d) != want)
			fail_msg("duty %d: %u counts, want %u", (int)d,
				 (unsigned)avr_pwm_counts((int16_t)d), (unsigned)want);
	}
	assert_int_equal(avr_pwm_counts(32767), AVR_PWM_TOP);
	assert_int_equal(avr_pwm_counts(-32768), AVR_PWM_TOP);
}

static void test_current_every_sum(void **state)
{
	(void)state;
	/* The filter (motor.c) keeps the sum within 0..4095: sum - sum / 4 + reading, reading
	 * 0..1023. */
	for (uint32_t sum = 0; sum < 4096u; sum++) {
		int32_t d = (int32_t)sum - 2048;
		int32_t ma = (int32_t)(((uint32_t)(d < 0 ? -d : d) * 3125u + 128u) >> 8);
		int32_t want = d < 0 ? -ma : ma;

		if (avr_current_ma((uint16_t)sum) != want)
			fail_msg("sum %u: %d mA, want %d", (unsigned)sum,
				 (int)avr_current_ma((uint16_t)sum), (int)want);
	}
	assert_int_equal(avr_current_ma(2048), 0);
	assert_int_equal(avr_current_ma(0), -25000);
}

int main(void)
{
	const struct CMUnitTest tests[] = {
		cmocka_unit_test(test_pwm_counts_every_duty),
		cmocka_unit_test(test_current_every_sum),
	};

	return cmocka_run_group_tests(tests, NULL, NULL);
}
