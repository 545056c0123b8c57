/* m1284p.h from avr-libc's device header, read with its register macros turned into plain
 * data-space addresses (I/O register n is at data address n + 0x20). Kept in its own file so
 * that avr-libc's short register names stay out of the rest of the harness. */
#include "m1284p.h"

#define _SFR_IO8(v) ((v) + 0x20)
#define _SFR_MEM8(v) (v)
#define _SFR_IO16(v) ((v) + 0x20)
#define _SFR_MEM16(v) (v)
#define _VECTOR(n) (n)
#define _AVR_IO_H_ 1
#include <avr/iom1284p.h>

const struct m1284p_regs m1284p = {
	.pina = PINA,
	.pinb = PINB,
	.pinc = PINC,
	.pind = PIND,
	.porta = PORTA,
	.portb = PORTB,
	.portc = PORTC,
	.portd = PORTD,
	.ddrd = DDRD,
	.ocr1a = OCR1AL,
	.ocr1b = OCR1BL,
	.timsk3 = TIMSK3,
	.tccr3b = TCCR3B,
	.tcnt3 = TCNT3L,
	.ocr3a = OCR3AL,
	.ocie3a = OCIE3A,
	.twcr = TWCR,
	.twsr = TWSR,
	.twdr = TWDR,
	.twar = TWAR,
	.twint = TWINT,
	.twea = TWEA,
	.twsta = TWSTA,
	.twsto = TWSTO,
	.twen = TWEN,
	.twie = TWIE,
	.vec_twi = TWI_vect,
	.vec_timer3_compa = TIMER3_COMPA_vect,
	.vec_pcint = {PCINT0_vect, PCINT1_vect, PCINT2_vect, PCINT3_vect},
	.mcusr = MCUSR,
	.porf = PORF,
	.extrf = EXTRF,
	.borf = BORF,
	.wdrf = WDRF,
	.jtrf = JTRF,
	.ramstart = RAMSTART,
	.ramend = RAMEND,
	.flashend = FLASHEND,
};
