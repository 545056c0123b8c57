; The control timer's interrupt (tick.c), by execution model (CONFIG_AVR_SLOW_SHIFT, tick.c;
; undefined reads as 0, robot.c's default):
;   one rate (0): counts the period for the main loop, at most 255. 23 cycles with the
;     interrupt's response, against 44 in C.
;   two rates (> 0): runs the servo (avr_servo_tick) with interrupts enabled, so that the
;     encoder and TWI interrupts nest in it; a compare match that finds the servo still
;     running is counted in avr_tick_overruns and dropped.
#include <avr/io.h>

#include "avr_isr.inc"

	.section .text.TIMER3_COMPA_vect, "ax", @progbits
	.global	TIMER3_COMPA_vect
	.type	TIMER3_COMPA_vect, @function
TIMER3_COMPA_vect:
	isr_save_r24_sreg
#if !defined(CONFIG_AVR_SLOW_SHIFT) || CONFIG_AVR_SLOW_SHIFT == 0
	lds	r24, avr_tick_periods
	inc	r24
	breq	1f ; 255 already
	sts	avr_tick_periods, r24
1:	isr_restore_r24_sreg
	reti
#else
	lds	r24, avr_servo_busy
	tst	r24
	brne	2f
	ldi	r24, 1
	sts	avr_servo_busy, r24
	; r24 and SREG from GPIOR0..1 to the stack before sei: the interrupts that nest from now on
	; keep their own registers in GPIOR0..2 (avr_isr.inc).
	in	r24, _SFR_IO_ADDR(GPIOR0)
	push	r24
	in	r24, _SFR_IO_ADDR(GPIOR1)
	push	r24
	sei
	; What a C function may change: r0, r1, r18..r27, r30, r31 (r24 saved above), and RAMPZ,
	; which libgcc's __tablejump2__ sets (the code preempted may be between its out and elpm).
	push	r0
	push	r1
	in	r0, _SFR_IO_ADDR(RAMPZ)
	push	r0
	push	r18
	push	r19
	push	r20
	push	r21
	push	r22
	push	r23
	push	r25
	push	r26
	push	r27
	push	r30
	push	r31
	clr	r1
	call	avr_servo_tick
	pop	r31
	pop	r30
	pop	r27
	pop	r26
	pop	r25
	pop	r23
	pop	r22
	pop	r21
	pop	r20
	pop	r19
	pop	r18
	pop	r0
	out	_SFR_IO_ADDR(RAMPZ), r0
	; Interrupts off from the flag's release to reti: a compare match cannot find the flag
	; clear while this one still holds its stack.
	cli
	sts	avr_servo_busy, r1 ; r1 is 0 after the C function
	pop	r1
	pop	r0
	pop	r24
	out	_SFR_IO_ADDR(SREG), r24 ; I clear as at entry: reti sets it
	pop	r24
	reti
	; The servo is still running (this interrupt nests in it): count the period it loses.
2:	lds	r24, avr_tick_overruns
	subi	r24, 0xFF
	sts	avr_tick_overruns, r24
	lds	r24, avr_tick_overruns + 1
	sbci	r24, 0xFF
	sts	avr_tick_overruns + 1, r24
	isr_restore_r24_sreg
	reti
#endif
	isr_end	TIMER3_COMPA_vect
