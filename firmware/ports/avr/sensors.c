/* Pins, pull-ups, and the switches and line sensors, read once per control period (that sampling
 * is their debouncing: a bounce shorter than a period is seen at most once). */
#include <avr/io.h>

#include "avr_port.h"
#include "hal.h"
#include "pinmap.h"

#if CONFIG_AVR_SLOW_SHIFT > 0
#define SLOW_MASK _BV(PIN_SLOW_BIT)
#else
#define SLOW_MASK 0
#endif

void avr_sensors_init(void)
{
	/* Inputs with pull-ups everywhere but the ADC pins and the TWI pins (the bus has its own
	 * pull-ups); PD3 (TICK) and, with two rates, PD1 (SLOW) outputs, low. Motor pins (PWM,
	 * direction): motor.c, after this. */
	DDRA = 0;
	PORTA = (uint8_t) ~(_BV(PIN_I_LEFT_ADC) | _BV(PIN_I_RIGHT_ADC));
	DDRB = 0;
	PORTB = 0xFFu;
	DDRC = 0;
	PORTC = (uint8_t) ~(_BV(0) | _BV(1));
	DDRD = _BV(PIN_TICK_BIT) | SLOW_MASK;
	PORTD = (uint8_t)((_BV(0) | _BV(1) | _BV(PIN_BASKET_BIT) | PIN_FREE_RIGHT_MASK) &
			  ~SLOW_MASK);
}

uint8_t hal_shock_read(void)
{
	uint8_t a = (uint8_t)((PINA & PIN_SHOCK_A_MASK) >> 2);

	return (uint8_t) ~((PINB & PIN_SHOCK_B_MASK) | a);
}

uint8_t hal_basket_contact(void)
{
	return (PIND & _BV(PIN_BASKET_BIT)) ? 0 : 1;
}

uint8_t hal_line_read(void)
{
	uint8_t a = (uint8_t)~PINA & PIN_LINE_A_MASK;
	uint8_t c = (uint8_t)~PINC & PIN_LINE_C_MASK;

	return (uint8_t)((a >> 6) | (c >> 4));
}
