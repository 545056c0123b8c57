; The pin-change interrupts of the four quadrature encoders (encoder.c explains the decoding and
; the tables). In assembly because they run up to 35 000 times a second at 1 m/s: an edge costs
; 35 cycles with the interrupt's response (a free wheel's, its state in an I/O register) or 37 (a
; motor's), where the C version took 140 (its prologue saves twelve registers).
;
; Each interrupt reads its port once: the index into quad_step[] is the state (the previous
; levels, kept swapped) | the current levels, and the new state is the current levels swapped.
; Each channel's step (-1, 0, +1) is one lpm from its table and is added to its counter's low
; byte, with no branch on the step; the high byte follows only when the low byte overflows
; (encoder.c: the counters are kept as count ^ 0x80), once in 256 counts. Each encoder is alone
; on its port (one channel, one counter: Z is all it needs).
#include <avr/io.h>

#include "avr_isr.inc"

; The rare half of a step: the high byte moves by the step (in r30) too.
.macro carry counter, back
	lds	r31, \counter + 1
	add	r31, r30
	sts	\counter + 1, r31
	rjmp	\back
.endm

; One channel on its port (pins at mask): ISR vector, pin register, mask, table page, state
; byte, counter, and io: 0 for a state in RAM (lds, sts), 1 for one in an I/O register (in, out:
; a cycle each where lds and sts take two), the free wheels', whose edges are the most frequent
; (encoder.c). Only Z is used, kept in GPIOR0 and GPIOR2, SREG in GPIOR1.
.macro quad_isr vector, pins, mask, page, state, counter, io
	.section .text.\vector, "ax", @progbits
	.global	\vector
	.type	\vector, @function
\vector:
	out	_SFR_IO_ADDR(GPIOR0), r30
	in	r30, _SFR_IO_ADDR(SREG)
	out	_SFR_IO_ADDR(GPIOR1), r30
	out	_SFR_IO_ADDR(GPIOR2), r31
	in	r31, _SFR_IO_ADDR(\pins)
	andi	r31, \mask
	.if \io
	in	r30, _SFR_IO_ADDR(\state)
	.else
	lds	r30, \state
	.endif
	or	r30, r31
	swap	r31
	.if \io
	out	_SFR_IO_ADDR(\state), r31
	.else
	sts	\state, r31
	.endif
	ldi	r31, hi8(quad_step + 256 * \page)
	lpm	r30, Z
	lds	r31, \counter
	add	r31, r30
	sts	\counter, r31
	brvs	2f
1:	in	r31, _SFR_IO_ADDR(GPIOR2)
	in	r30, _SFR_IO_ADDR(GPIOR1)
	out	_SFR_IO_ADDR(SREG), r30
	in	r30, _SFR_IO_ADDR(GPIOR0)
	reti
2:	carry	\counter, 1b
	isr_end	\vector
.endm

	quad_isr PCINT0_vect, PINA, 0x0C, 0, avr_motor_state, avr_motor_count, 0
	quad_isr PCINT1_vect, PINB, 0x0C, 0, avr_motor_state + 1, avr_motor_count + 2, 0
	quad_isr PCINT2_vect, PINC, 0x0C, 0, OCR0A, avr_free_count, 1
	quad_isr PCINT3_vect, PIND, 0xC0, 1, OCR0B, avr_free_count + 2, 1
