/* Quadrature decoding of the four encoders by pin-change interrupts (encoder_isr.S): the free
 * wheels on PC2..PC5 (PCINT2), the motor shafts on PA2..PA5 (PCINT0). Each interrupt reads its
 * port once and steps both channels on it from the table below. */
#include <avr/interrupt.h>
#include <avr/io.h>
#include <avr/pgmspace.h>
#include <util/atomic.h>

#include "avr_port.h"
#include "hal.h"
#include "pinmap.h"

/* A channel's state is A | B << 1; forward (A leads B) runs 0 -> 1 -> 3 -> 2 -> 0. The step from
 * state p to state n is +1 one way round, -1 the other, 0 when nothing changed, and 0 when both
 * pins changed at once (an edge missed: the direction is unknown). */
#define FWD(s) ((s) == 0 ? 1 : (s) == 1 ? 3 : (s) == 3 ? 2 : 0)
#define STEP(p, n) ((n) == FWD(p) ? 1 : (p) == FWD(n) ? -1 : 0)

/* quad_pair[2 i], quad_pair[2 i + 1]: the left and right steps for i = previous levels << 4 |
 * current levels, the levels being left A, left B, right A, right B in bits 0..3. */
#define PAIR(i) STEP(3 & ((i) >> 4), 3 & (i)), STEP(3 & ((i) >> 6), 3 & ((i) >> 2))
#define PAIR4(i) PAIR(i), PAIR((i) + 1), PAIR((i) + 2), PAIR((i) + 3)
#define PAIR16(i) PAIR4(i), PAIR4((i) + 4), PAIR4((i) + 8), PAIR4((i) + 12)
#define PAIR64(i) PAIR16(i), PAIR16((i) + 16), PAIR16((i) + 32), PAIR16((i) + 48)

const int8_t quad_pair[512] PROGMEM = {PAIR64(0), PAIR64(64), PAIR64(128), PAIR64(192)};

/* Written by encoder_isr.S: counts, and the port's last levels of the four pins, in bits 4..7. */
volatile uint16_t avr_free_count[2];
volatile uint16_t avr_motor_count[2];
uint8_t avr_free_state;
uint8_t avr_motor_state;

void avr_encoder_init(void)
{
	avr_free_state = (uint8_t)((PIN_FREE_ENC_PORT & PIN_FREE_ENC_MASK) << 2);
	avr_motor_state = (uint8_t)((PIN_MOTOR_ENC_PORT & PIN_MOTOR_ENC_MASK) << 2);
	PCMSK2 = PIN_FREE_ENC_MASK;
	PCMSK0 = PIN_MOTOR_ENC_MASK;
	PCIFR = _BV(PCIF2) | _BV(PCIF0);
	PCICR = _BV(PCIE2) | _BV(PCIE0);
}

uint16_t hal_encoder_free(enum hal_side side)
{
	uint16_t c;

	ATOMIC_BLOCK(ATOMIC_RESTORESTATE)
	{
		c = avr_free_count[side];
	}
	return c;
}

uint16_t hal_encoder_motor(enum hal_side side)
{
	uint16_t c;

	ATOMIC_BLOCK(ATOMIC_RESTORESTATE)
	{
		c = avr_motor_count[side];
	}
	return c;
}
