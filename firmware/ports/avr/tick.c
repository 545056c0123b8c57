/* The control period: Timer3 in CTC mode wakes the main loop, which runs the tick (main.c).
 * Running the tick in the main loop rather than in the timer's interrupt lets the TWI and
 * encoder interrupts preempt it with no nesting, and the tick can never re-enter itself. */
#include <avr/interrupt.h>
#include <avr/io.h>
#include <avr/sleep.h>

#include "avr_port.h"
#include "hal.h"

/* Compare matches not yet taken by avr_tick_wait(), at most 255: counted by the timer's
 * interrupt (tick_isr.S), which also starts the period's current-sense conversions. */
volatile uint8_t avr_tick_periods;

void hal_tick_start(uint16_t rate_hz)
{
	/* Prescaler 8: 2 MHz, exact for every rate dividing 2 000 000 (1 kHz: 2000 counts). */
	uint32_t top = ((F_CPU / 8u) + rate_hz / 2u) / rate_hz - 1u;

	TCCR3A = 0;
	TCCR3B = 0;
	TCNT3 = 0;
	OCR3A = (uint16_t)top;
	TIFR3 = _BV(OCF3A);
	TIMSK3 = _BV(OCIE3A);
	TCCR3B = _BV(WGM32) | _BV(CS31);
}

uint8_t avr_tick_wait(void)
{
	uint8_t n;

	set_sleep_mode(SLEEP_MODE_IDLE);
	cli();
	while (avr_tick_periods == 0) {
		sleep_enable();
		sei(); /* the instruction after sei runs first: no wake-up lost */
		sleep_cpu();
		sleep_disable();
		cli();
	}
	n = avr_tick_periods;
	avr_tick_periods = 0;
	sei();
	return n;
}
