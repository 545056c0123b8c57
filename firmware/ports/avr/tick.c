/* The control period: Timer3 in CTC mode, one compare match per period, and the two ways this
 * port runs the board's work on it, chosen when building (CONFIG_AVR_SLOW_SHIFT, which robot.c
 * also puts in cfg.slow_shift; docs/avr.md):
 *
 * One rate (0): the timer's interrupt only counts the period (tick_isr.S); the main loop wakes
 * and runs the whole tick (main.c). The TWI and encoder interrupts preempt it with no nesting,
 * and it cannot re-enter itself.
 *
 * Two rates (> 0): the timer's interrupt runs the servo (avr_servo_tick below: sample,
 * board_tick, PWM) with interrupts enabled, so that an encoder edge never waits for a servo
 * tick, only for another interrupt; the main loop runs the slow steps (port_slow) when the
 * servo has handed them a snapshot, and sleeps otherwise. The servo preempts the slow steps;
 * they share only the hand-over, which board_tick() touches when the slow steps are done. */
#include <avr/interrupt.h>
#include <avr/io.h>
#include <avr/sleep.h>

#include "avr_port.h"
#include "hal.h"
#include "pinmap.h"
#include "port.h"

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

#if CONFIG_AVR_SLOW_SHIFT == 0

/* Compare matches not yet taken by avr_tick_wait(), at most 255: counted by the timer's
 * interrupt (tick_isr.S), which also starts the period's current-sense conversions. */
volatile uint8_t avr_tick_periods;

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

#else

/* 1 while avr_servo_tick() runs: the timer's interrupt does not re-enter it (tick_isr.S). */
volatile uint8_t avr_servo_busy;
volatile uint8_t avr_servo_alive;

void avr_servo_tick(void)
{
	PORTD |= _BV(PIN_TICK_BIT);
	avr_motor_sense();
	port_control_tick(&asserv_board);
	PORTD &= (uint8_t)~_BV(PIN_TICK_BIT);
	avr_servo_alive = 1;
}

void avr_slow_wait(void)
{
	/* The sleep enable bit stays set: this is the firmware's only sleep instruction, and each
	 * interrupt (35 000 encoder edges a second at 1 m/s) wakes the loop, whose round trip
	 * is kept to the test and the sleep. */
	set_sleep_mode(SLEEP_MODE_IDLE);
	sleep_enable();
	cli();
	while (!board_slow_due(&asserv_board)) {
		sei(); /* the instruction after sei runs first: no wake-up lost */
		sleep_cpu();
		/* One cycle for simavr, whose cli clears an interrupt it has not yet taken: it
		 * takes one two instructions after sei (the hardware after one), so an interrupt
		 * already pending at the sleep would never be taken in this loop without it. */
		__asm__ __volatile__("nop");
		cli();
	}
	sei();
}

#endif
