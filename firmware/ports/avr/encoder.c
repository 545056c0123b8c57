/* Quadrature decoding of the four encoders by pin-change interrupts (encoder_isr.S), each alone
 * on its port: the motor shafts on PA2, PA3 (PCINT0) and PB2, PB3 (PCINT1), the free wheels on
 * PC2, PC3 (PCINT2) and PD6, PD7 (PCINT3). Each interrupt reads its port once and steps its
 * counter from the tables below. */
#include <avr/interrupt.h>
#include <avr/io.h>
#include <avr/pgmspace.h>
#include <util/atomic.h>

#include "avr_layout.h"
#include "avr_port.h"
#include "hal.h"
#include "pinmap.h"

/* A channel's state is A | B << 1; forward (A leads B) runs 0 -> 1 -> 3 -> 2 -> 0. The step from
 * state p to state n is +1 one way round, -1 the other, 0 when nothing changed, and 0 when both
 * pins changed at once (an edge missed: the direction is unknown). */
#define FWD(s) ((s) == 0 ? 1 : (s) == 1 ? 3 : (s) == 3 ? 2 : 0)
#define STEP(p, n) ((n) == FWD(p) ? 1 : (p) == FWD(n) ? -1 : 0)

/* An interrupt's table index i is swap(previous levels) | current levels, the levels being its
 * port's encoder bits; the swap moves the previous ones beside the current ones. Each table is
 * aligned to 256 bytes, so that the interrupt puts the index in ZL and a constant in ZH.
 * quad_step[0]: a channel on bits 2, 3 (both motors, the left free wheel), previous levels in
 * bits 6, 7. quad_step[1]: a channel on bits 6, 7 (the right free wheel), previous levels in
 * bits 2, 3. */
#define BITS23(i) STEP(3 & ((i) >> 6), 3 & ((i) >> 2))
#define BITS67(i) STEP(3 & ((i) >> 2), 3 & ((i) >> 6))
#define ROW(f, i) f(i), f((i) + 1), f((i) + 2), f((i) + 3)
#define ROW16(f, i) ROW(f, i), ROW(f, (i) + 4), ROW(f, (i) + 8), ROW(f, (i) + 12)
#define ROW64(f, i) ROW16(f, i), ROW16(f, (i) + 16), ROW16(f, (i) + 32), ROW16(f, (i) + 48)
#define TABLE(f)                                                                                   \
	{                                                                                          \
		ROW64(f, 0), ROW64(f, 64), ROW64(f, 128), ROW64(f, 192)                            \
	}

const int8_t quad_step[2][256] PROGMEM
	__attribute__((aligned(256))) = {TABLE(BITS23), TABLE(BITS67)};

/* Written by encoder_isr.S. A counter is kept as count ^ 0x80: its low byte moves by the step
 * and its high byte by the same step when the low byte overflows as a signed byte (0x7F <-> 0x80,
 * which is count's 0xFF <-> 0x00), so the interrupt needs no 16-bit addition. A state is its
 * port's last levels of the encoder pins, swapped (see quad_step): the motors' in RAM, the free
 * wheels' (the most frequent edges) in Timer0's compare registers, OCR0A the left, OCR0B the
 * right, which in and out reach in a cycle where lds and sts take two. Timer0 is never started
 * (no clock, normal mode, no output, no interrupt): its compare registers are then plain bytes,
 * written at once (buffered only in the PWM modes) and never compared. They used to be EEARL and
 * EEDR, which the calibration's EEPROM writes now need (nvm.c). */
volatile uint16_t avr_free_count[2];
volatile uint16_t avr_motor_count[2];
uint8_t avr_motor_state[2];

#if PIN_MOTOR_LEFT_MASK != 0x0Cu || PIN_MOTOR_RIGHT_MASK != 0x0Cu ||                               \
	PIN_FREE_LEFT_MASK != 0x0Cu || PIN_FREE_RIGHT_MASK != 0xC0u
#error "encoder_isr.S and quad_step expect the encoder pins of pinmap.h"
#endif

static uint8_t swapped_levels(uint8_t pins, uint8_t mask)
{
	uint8_t v = pins & mask;

	return (uint8_t)(v << 4 | v >> 4);
}

void avr_encoder_init(void)
{
	/* Timer0 as at reset, written all the same: no clock, normal mode, no output, no
	 * interrupt, so that OCR0A and OCR0B hold the states as plain bytes. */
	TCCR0B = 0;
	TCCR0A = 0;
	TIMSK0 = 0;
	OCR0A = swapped_levels(PIN_FREE_LEFT_PORT, PIN_FREE_LEFT_MASK);
	OCR0B = swapped_levels(PIN_FREE_RIGHT_PORT, PIN_FREE_RIGHT_MASK);
	avr_motor_state[0] = swapped_levels(PIN_MOTOR_LEFT_PORT, PIN_MOTOR_LEFT_MASK);
	avr_motor_state[1] = swapped_levels(PIN_MOTOR_RIGHT_PORT, PIN_MOTOR_RIGHT_MASK);
	for (uint8_t s = 0; s < 2; s++)
		avr_free_count[s] = avr_motor_count[s] = AVR_COUNT_BIAS;
	PCMSK0 = PIN_MOTOR_LEFT_MASK;
	PCMSK1 = PIN_MOTOR_RIGHT_MASK;
	PCMSK2 = PIN_FREE_LEFT_MASK;
	PCMSK3 = PIN_FREE_RIGHT_MASK;
	PCIFR = _BV(PCIF3) | _BV(PCIF2) | _BV(PCIF1) | _BV(PCIF0);
	PCICR = _BV(PCIE3) | _BV(PCIE2) | _BV(PCIE1) | _BV(PCIE0);
}

uint16_t hal_encoder_free(enum hal_side side)
{
	uint16_t c;

	ATOMIC_BLOCK(ATOMIC_RESTORESTATE)
	{
		c = avr_free_count[side];
	}
	return c ^ AVR_COUNT_BIAS;
}

uint16_t hal_encoder_motor(enum hal_side side)
{
	uint16_t c;

	ATOMIC_BLOCK(ATOMIC_RESTORESTATE)
	{
		c = avr_motor_count[side];
	}
	return c ^ AVR_COUNT_BIAS;
}
