/* The AVR port's conversions between the core's units and its hardware's: PWM compare counts
 * and current-sense ADC readings. Plain C with no register access, so that the simavr harness
 * (harness/avr) applies the very same quantisation to the native reference run. */
#ifndef ASSERV_AVR_UNITS_H
#define ASSERV_AVR_UNITS_H

#include <stdint.h>

/* Timer1 in phase-correct PWM with TOP = ICR1 = 400: 16 MHz / (2 * 400) = 20 kHz, above hearing,
 * and a compare value of 0 or TOP gives a steady low or high output (no glitch at 0 %). */
#define AVR_PWM_TOP 400u

/* |duty_q15| [2^-15] -> compare counts 0..AVR_PWM_TOP, rounded to nearest; the sign goes to the
 * direction pin. -32768 is taken as -32767. */
static inline uint16_t avr_pwm_counts(int16_t duty_q15)
{
	uint32_t mag = duty_q15 < 0 ? (uint32_t)(-(int32_t)duty_q15) : (uint32_t)duty_q15;

	if (mag > 32767u)
		mag = 32767u;
	return (uint16_t)((mag * AVR_PWM_TOP + 16384u) >> 15);
}

/* Current sense: a bidirectional Hall sensor (ACS712-20A class: 100 mV/A, 2.5 V at 0 A) read by
 * the 10-bit ADC against AVCC = 5 V. The port keeps, per channel, a low-pass filtered sum worth
 * 4 readings (0..4092, 2048 at 0 A); one unit of it is 5000 mV / 1024 / 4 / (100 mV/A)
 * = 12.207 mA = 3125/256 mA. */
#define AVR_CURRENT_ZERO_MV 2500u
#define AVR_CURRENT_MV_PER_A 100u
#define AVR_ADC_VREF_MV 5000u
#define AVR_CURRENT_SAMPLES 4u

/* That sum -> mA, rounded to nearest, signed like the duty. */
static inline int16_t avr_current_ma(uint16_t sum)
{
	int32_t d = (int32_t)sum - 2048;
	uint32_t mag = (uint32_t)(d < 0 ? -d : d);
	int32_t ma = (int32_t)((mag * 3125u + 128u) >> 8);

	return (int16_t)(d < 0 ? -ma : ma);
}

#endif
