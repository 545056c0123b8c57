/* The AVR port's conversions between the core's units and its hardware's: PWM compare counts
 * and current-sense ADC readings. Plain C with no register access, so that the simavr harness
 * (harness/avr) applies the very same quantisation to the native reference run. */
#ifndef ASSERV_AVR_UNITS_H
#define ASSERV_AVR_UNITS_H

#include <stdint.h>

/* Timer1 in phase-correct PWM with TOP = ICR1 = 400: 16 MHz / (2 * 400) = 20 kHz, above hearing,
 * and a compare value of 0 or TOP gives a steady low or high output (no glitch at 0 %). */
#define AVR_PWM_TOP 400u

/* |duty_q15| [2^-15] -> compare counts 0..AVR_PWM_TOP, rounded to nearest: round(mag * 400 /
 * 2^15) = (mag * 400 + 2^14) >> 15, the sign going to the direction pin; -32768 is taken as
 * -32767. Computed as (mag * 25 + 1024) >> 11 from the bytes of mag, whose products with 25 fit
 * 16 bits: on the AVR two 8 x 8-bit multiplies, where the 32-bit form cost a libgcc call and a
 * 15-step shift loop (test_avr_units checks every duty against the formula). */
static inline uint16_t avr_pwm_counts(int16_t duty_q15)
{
	uint16_t mag = duty_q15 < 0 ? (uint16_t)(0u - (uint16_t)duty_q15) : (uint16_t)duty_q15;
	uint8_t hi, lo;

	if (mag > 32767u)
		mag = 32767u;
	hi = (uint8_t)(mag >> 8);
	lo = (uint8_t)mag;
	return (uint16_t)((uint16_t)(hi * 25u) + ((uint16_t)(lo * 25u + 1024u) >> 8)) >> 3;
}

/* Current sense: a bidirectional Hall sensor (ACS712-20A class: 100 mV/A, 2.5 V at 0 A) read by
 * the 10-bit ADC against AVCC = 5 V. The port keeps, per channel, a low-pass filtered sum worth
 * 4 readings (0..4092, 2048 at 0 A); one unit of it is 5000 mV / 1024 / 4 / (100 mV/A)
 * = 12.207 mA = 3125/256 mA. */
#define AVR_CURRENT_ZERO_MV 2500u
#define AVR_CURRENT_MV_PER_A 100u
#define AVR_ADC_VREF_MV 5000u
#define AVR_CURRENT_SAMPLES 4u

/* That sum (0..4095, the filter's range) -> mA, rounded to nearest, signed like the duty:
 * round(|sum - 2048| * 3125 / 256). With 3125 = 12 * 256 + 53, from the bytes of the magnitude
 * m = 256 h + l (at most 2048): m * 12 + h * 53 + ((l * 53 + 128) >> 8), 16-bit products only
 * (test_avr_units checks every sum against the formula). */
static inline int16_t avr_current_ma(uint16_t sum)
{
	uint16_t mag = sum < 2048u ? (uint16_t)(2048u - sum) : (uint16_t)(sum - 2048u);
	uint8_t hi = (uint8_t)(mag >> 8), lo = (uint8_t)mag;
	int16_t ma = (int16_t)(mag * 12u + hi * 53u + ((uint16_t)(lo * 53u + 128u) >> 8));

	return sum < 2048u ? (int16_t)-ma : ma;
}

#endif
