/* The two drive motors: Timer1 phase-correct PWM at 20 kHz on OC1A (left) and OC1B (right), a
 * direction pin each, and the current-sense ADC, a conversion each period, the channels in turn,
 * read and filtered by the control tick (avr_motor_sense()). */
#include <avr/interrupt.h>
#include <avr/io.h>
#include <util/atomic.h>

#include "avr_port.h"
#include "avr_units.h"
#include "hal.h"
#include "pinmap.h"

#if PIN_I_LEFT_ADC != 0 || PIN_I_RIGHT_ADC != 1
#error "avr_motor_sense() tells the channels apart by ADMUX bit 0"
#endif

/* Each channel's readings, low-pass filtered: sum += reading - sum / 4, so that sum settles at 4
 * readings (avr_units.h), with a time constant of 4 readings, 8 control periods. The control
 * tick takes a channel's reading and starts the other's conversion (13 ADC clocks, 104 us at
 * prescaler 128, done long before the next tick): one conversion a period and no interrupt,
 * where an interrupt per conversion cost about 60 cycles, and converting all the time 6 % of the
 * CPU. Only the tick touches them (with two rates the servo, and the period's end samples of
 * port_sample_period() in it), so they need no atomic access. */
static uint16_t adc_sum[2];

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

	adc_sum[0] = adc_sum[1] = 512u * AVR_CURRENT_SAMPLES; /* 0 A */
	DIDR0 = _BV(PIN_I_LEFT_ADC) | _BV(PIN_I_RIGHT_ADC);
	ADMUX = _BV(REFS0) | PIN_I_LEFT_ADC; /* AVCC reference */
	/* The first conversion (25 ADC clocks) before the first tick reads it. */
	ADCSRA = _BV(ADEN) | _BV(ADSC) | _BV(ADPS2) | _BV(ADPS1) | _BV(ADPS0);
}

/* The period's current sense: the last conversion's reading into its channel's sum, then the
 * other channel's conversion. Inlined into the tick. A tick that comes while the conversion
 * still runs (one rate, right after an overrun) leaves it be: it would read the last channel's
 * reading again, and the channel change would wait for the conversion's end. */
__attribute__((always_inline)) inline void avr_motor_sense(void)
{
	uint8_t mux = ADMUX;
	uint16_t *sum = &adc_sum[mux & 1u];
	uint16_t reading;

	if (ADCSRA & _BV(ADSC))
		return;
	reading = ADC; /* ADCL first: reading it holds ADCH for this conversion */

	ADMUX = mux ^ 1u;
	ADCSRA |= _BV(ADSC);
	*sum = (uint16_t)(*sum + reading - (*sum >> 2));
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

/* Inlined into port_sample_period() for the same reason. */
__attribute__((always_inline)) inline int16_t hal_motor_current_ma(enum hal_side side)
{
	return avr_current_ma(adc_sum[side]);
}
