; The current-sense ADC's interrupt (motor.c explains the two conversions per period and the
; filter). In assembly: 55 to 61 cycles with the interrupt's response, against 95 for the C
; version, whose prologue saves ten registers.
#include <avr/io.h>

#include "avr_isr.inc"
#include "pinmap.h"

#if PIN_I_LEFT_ADC != 0 || PIN_I_RIGHT_ADC != 1
#error "ADC_vect tells the channels apart by ADMUX bit 0"
#endif

; FILTER sum: sum += reading - sum / 4, the reading in r25:r24.
.macro filter sum
	lds	r30, \sum
	lds	r31, \sum + 1
	add	r24, r30
	adc	r25, r31
	lsr	r31
	ror	r30
	lsr	r31
	ror	r30
	sub	r24, r30
	sbc	r25, r31
	sts	\sum + 1, r25
	sts	\sum, r24
.endm

	.section .text.ADC_vect, "ax", @progbits
	.global	ADC_vect
	.type	ADC_vect, @function
ADC_vect:
	isr_save_r24_sreg
	out	_SFR_IO_ADDR(GPIOR2), r25
	push	r30
	push	r31
	lds	r24, ADCL ; ADCL first: reading it holds ADCH for this conversion
	lds	r25, ADCH
	lds	r30, ADMUX
	sbrc	r30, 0
	rjmp	1f
	; The left channel's reading: the right one's conversion starts now.
	ldi	r30, _BV(REFS0) | PIN_I_RIGHT_ADC
	sts	ADMUX, r30
	lds	r30, ADCSRA
	ori	r30, _BV(ADSC)
	sts	ADCSRA, r30
	filter	avr_adc_sum
	rjmp	2f
	; The right channel's reading: the left one's conversion waits for the next period.
1:	ldi	r30, _BV(REFS0) | PIN_I_LEFT_ADC
	sts	ADMUX, r30
	filter	avr_adc_sum + 2
2:	pop	r31
	pop	r30
	in	r25, _SFR_IO_ADDR(GPIOR2)
	isr_restore_r24_sreg
	reti
	isr_end	ADC_vect
