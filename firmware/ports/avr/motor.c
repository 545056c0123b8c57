/* The two drive motors: Timer1 phase-correct PWM at 20 kHz on OC1A (left) and OC1B (right), a
 * direction pin each, and the current-sense ADC, converted once per period and channel and filtered
 * by its interrupt (motor_isr.S). */
#include <avr/interrupt.h>
#include <avr/io.h>
#include <util/atomic.h>

#include "avr_port.h"
#include "avr_units.h"
#include "hal.h"
#include "pinmap.h"

/* Each channel's readings, low-pass filtered: sum += reading - sum / 4, so that sum settles at 4
 * readings (avr_units.h) with a time constant of 4 control periods. The control timer's
 * interrupt starts a conversion of the left channel each period, the ADC interrupt
 * (motor_isr.S, which keeps these sums) then the right one: two conversions of 13 ADC clocks
 * (8 us each at prescaler 128) per period, two short interrupts, where converting all the time
 * would cost 6 % of the CPU. */
volatile uint16_t avr_adc_sum[2];

void avr_motor_init(void)
{
	PORTD &= (uint8_t) ~(_BV(PIN_PWM_LEFT_BIT) | _BV(PIN_PWM_RIGHT_BIT));
	DDRD |= _BV(PIN_PWM_LEFT_BIT) | _BV(PIN_PWM_RIGHT_BIT);
	PIN_DIR_PORT &= (uint8_t) ~(_BV(PIN_DIR_LEFT_BIT) | _BV(PIN_DIR_RIGHT_BIT));
	PIN_DIR_DDR |= _BV(PIN_DIR_LEFT_BIT) | _BV(PIN_DIR_RIGHT_BIT);
	OCR1A = 0;
	OCR1B = 0;
	ICR1 = AVR_PWM_TOP;
	/* Mode 10: phase-correct PWM, TOP = ICR1; non-inverting on both outputs; no prescaler. */
	TCCR1A = _BV(COM1A1) | _BV(COM1B1) | _BV(WGM11);
	TCCR1B = _BV(WGM13) | _BV(CS10);

	avr_adc_sum[0] = avr_adc_sum[1] = 512u * AVR_CURRENT_SAMPLES; /* 0 A */
	DIDR0 = _BV(PIN_I_LEFT_ADC) | _BV(PIN_I_RIGHT_ADC);
	ADMUX = _BV(REFS0) | PIN_I_LEFT_ADC; /* AVCC reference */
	ADCSRA = _BV(ADEN) | _BV(ADIE) | _BV(ADPS2) | _BV(ADPS1) | _BV(ADPS0);
}

/* Inlined into the tick (link-time optimisation), where the side is a constant: the side's pins
 * and registers then need no test, and the call no register shuffling (about 60 cycles a tick for
 * both sides, against 112 called). */
__attribute__((always_inline)) inline void hal_motor_set(enum hal_side side, int16_t duty_q15)
{
	uint16_t counts = avr_pwm_counts(duty_q15);
	uint8_t dir = side == HAL_LEFT ? _BV(PIN_DIR_LEFT_BIT) : _BV(PIN_DIR_RIGHT_BIT);

	/* OCR1x is double-buffered (taken at TOP), and written atomically: the 16-bit timer
	 * registers share one TEMP byte. */
	ATOMIC_BLOCK(ATOMIC_RESTORESTATE)
	{
		if (duty_q15 < 0)
			PIN_DIR_PORT |= dir;
		else
			PIN_DIR_PORT &= (uint8_t)~dir;
		if (side == HAL_LEFT)
			OCR1A = counts;
		else
			OCR1B = counts;
	}
}

/* Inlined into port_sample() for the same reason (38 cycles a tick less). */
__attribute__((always_inline)) inline int16_t hal_motor_current_ma(enum hal_side side)
{
	uint16_t sum;

	ATOMIC_BLOCK(ATOMIC_RESTORESTATE)
	{
		sum = avr_adc_sum[side];
	}
	return avr_current_ma(sum);
}
