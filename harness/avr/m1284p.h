/* The ATmega1284P's register addresses and vector numbers the harness needs, taken from
 * avr-libc's <avr/iom1284p.h> by m1284p.c (data-space addresses, as simavr's avr->data[]). */
#ifndef ASSERV_HARNESS_M1284P_H
#define ASSERV_HARNESS_M1284P_H

#include <stdint.h>

struct m1284p_regs {
	uint16_t pina, pinb, pinc, pind, porta, portb, portc, portd, ddrd;
	uint16_t ocr1a, ocr1b;                 /* low bytes; the high byte follows */
	uint16_t timsk3, tccr3b, tcnt3, ocr3a; /* tcnt3, ocr3a: low bytes */
	uint8_t ocie3a;
	uint16_t twcr, twsr, twdr, twar;
	uint8_t twint, twea, twsta, twsto, twen, twie;
	uint8_t vec_twi, vec_timer3_compa, vec_pcint[4]; /* vec_pcint[n]: PCINTn_vect */
	uint16_t mcusr;                                  /* the reset flags */
	uint8_t porf, extrf, borf, wdrf, jtrf;
	uint16_t ramstart, ramend;
	uint32_t flashend;
};

extern const struct m1284p_regs m1284p;

#endif
