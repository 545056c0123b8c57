; The pin-change interrupts of the four quadrature encoders (encoder.c explains the decoding).
; In assembly because they run up to 35 000 times a second at 1 m/s: about 70 cycles each,
; against 140 for the C version, whose prologue saves twelve registers.
;
; Each interrupt reads its port once. The previous levels of the port's four encoder pins are
; kept shifted to bits 4..7, so that (previous | current >> 2) indexes quad_pair[], whose entry
; is the step of each channel (-1, 0, +1), and the matching 16-bit counter moves by that step.
#include <avr/io.h>

#define PINS_MASK 0x3C ; bits 2..5 of the port: left A, left B, right A, right B

; COUNT counter, register: counter += (int8_t)register, for a step of -1, 0 or +1.
.macro count counter, step
	tst	\step
	breq	1f
	lds	r30, \counter
	lds	r31, \counter + 1
	adiw	r30, 1
	sbrc	\step, 7
	sbiw	r30, 2
	sts	\counter + 1, r31
	sts	\counter, r30
1:
.endm

; ISR vector, pin register, state byte, counters.
.macro quad_isr vector, pins, state, counts
	.section .text.\vector, "ax", @progbits
	.global	\vector
\vector:
	push	r24
	in	r24, _SFR_IO_ADDR(SREG)
	push	r24
	push	r25
	push	r30
	push	r31
	in	r24, _SFR_IO_ADDR(\pins)
	andi	r24, PINS_MASK
	lds	r30, \state
	mov	r25, r24
	lsl	r25
	lsl	r25
	sts	\state, r25
	lsr	r24
	lsr	r24
	or	r30, r24
	ldi	r31, 0
	lsl	r30
	rol	r31
	subi	r30, lo8(-(quad_pair))
	sbci	r31, hi8(-(quad_pair))
	lpm	r24, Z+
	lpm	r25, Z
	count	\counts, r24
	count	\counts + 2, r25
	pop	r31
	pop	r30
	pop	r25
	pop	r24
	out	_SFR_IO_ADDR(SREG), r24
	pop	r24
	reti
.endm

	quad_isr PCINT2_vect, PINC, avr_free_state, avr_free_count
	quad_isr PCINT0_vect, PINA, avr_motor_state, avr_motor_count
