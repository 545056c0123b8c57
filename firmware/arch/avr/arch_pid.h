/* The PID's small-error kernel for an AVR with MUL (see firmware/arch/generic/arch_pid.h for
 * the contract, and for the kernel's domain, struct arch_pid_fast, which is the reference's). It
 * reads and writes struct pid's fields at their offsets: a change of struct pid (pid.h) is a
 * change here, and test_avr_control and test_avr_annex, which compare it with the host's C tick
 * by tick, catch a mismatch. Included twice by pid.h, as the reference. */
#ifndef PID_ARCH_KERNEL
#include "../generic/arch_pid.h"
#elif !defined(ASSERV_ARCH_PID_H)
#define ASSERV_ARCH_PID_H

#include <stddef.h>
#include <stdint.h>

/* pid_update for small errors, with its bounds and the previous error's update, in AVR
 * assembly: avr-gcc 5.4 keeps few of the C version's 32-bit values in registers and calls a library
 * routine for each 16 x 16 product, 750 cycles a call where this takes 300. The same arithmetic,
 * byte by byte: P + D = kp e + kd de, mod 2^32 (each below 2^29): a MUL per byte of the gain and of
 * e (a MULSU for e's signed upper byte), skipped for a zero byte of the gain (at 1 kHz, kd = d 2^11
 *   has two);
 *   pdh = floor((P + D) / 16) by 4 arithmetic shifts, pdl = ((P + D) mod 16) 2^12;
 *   i' = i + ki e in 48 bits, the same way, clipped to +-out_limit 2^24;
 *   u = pdh 2^16 + pdl + i'; if it winds up, u = pdh 2^16 + pdl + i and i is kept;
 *   duty = round(u / 2^24), ties away from zero, clipped to +-out_limit_q15.
 * Returns 1 with out_q15 set, or 0 having changed nothing (pid_update_c then does the whole tick)
 * when e or de is out of the fast path's bounds, or the previous error out of 16 bits (struct
 * arch_pid_fast).
 * test_avr_annex checks it against the host's C every tick of its session. */

/* Registers: Z the pid; e in r22..r25 (left as it was when declining), then its lower half x in
 * r22:r23; r18 a byte of a gain; r19 zero; de in r20:r21; P + D, then pdh, then u's upper part in
 * r24..r27; pdl's upper byte (u's second) in r20; the integral, lo then hi, in r12..r17;
 * out_limit_q15 in r22:r23. MULSU sets C to the sign of its product, which SBC extends upwards. */

/* r24..r27 += r18 (byte J of a gain, J = 0..3) x (X0, X1 signed) 2^(8 J), mod 2^32. */
#define PD_MAC0(X0, X1)                                                                            \
	"mul r18," X0 "\n\tadd r24,r0\n\tadc r25,r1\n\tadc r26,r19\n\tadc r27,r19\n\t"             \
	"mulsu " X1 ",r18\n\tsbc r27,r19\n\tadd r25,r0\n\tadc r26,r1\n\tadc r27,r19\n"
#define PD_MAC1(X0, X1)                                                                            \
	"mul r18," X0 "\n\tadd r25,r0\n\tadc r26,r1\n\tadc r27,r19\n\t"                            \
	"mulsu " X1 ",r18\n\tadd r26,r0\n\tadc r27,r1\n"
#define PD_MAC2(X0, X1)                                                                            \
	"mul r18," X0 "\n\tadd r26,r0\n\tadc r27,r1\n\tmul r18," X1 "\n\tadd r27,r0\n"
#define PD_MAC3(X0, X1) "mul r18," X0 "\n\tadd r27,r0\n"
/* The same for the gain at OFF: byte J loaded, skipped if zero. */
#define PD_BYTE(OFF, J, X0, X1)                                                                    \
	"ldd r18,Z+" OFF "+" #J "\n\ttst r18\n\tbreq 1f\n\t" PD_MAC##J(X0, X1) "1:\n\t"
#define PD_TERM(OFF, X0, X1)                                                                       \
	PD_BYTE(OFF, 0, X0, X1)                                                                    \
	PD_BYTE(OFF, 1, X0, X1) PD_BYTE(OFF, 2, X0, X1) PD_BYTE(OFF, 3, X0, X1)

/* r12..r17 += r18 (byte J of ki) x (r22, r23 signed) 2^(8 J), skipped if zero. */
#define I_MAC0                                                                                     \
	"mul r18,r22\n\tadd r12,r0\n\tadc r13,r1\n\tadc r14,r19\n\tadc r15,r19\n\tadc r16,r19\n\t" \
	"adc r17,r19\n\tmulsu r23,r18\n\tsbc r15,r19\n\tsbc r16,r19\n\tsbc r17,r19\n\t"            \
	"add r13,r0\n\tadc r14,r1\n\tadc r15,r19\n\tadc r16,r19\n\tadc r17,r19\n"
#define I_MAC1                                                                                     \
	"mul r18,r22\n\tadd r13,r0\n\tadc r14,r1\n\tadc r15,r19\n\tadc r16,r19\n\tadc r17,r19\n\t" \
	"mulsu r23,r18\n\tsbc r16,r19\n\tsbc r17,r19\n\t"                                          \
	"add r14,r0\n\tadc r15,r1\n\tadc r16,r19\n\tadc r17,r19\n"
#define I_MAC2                                                                                     \
	"mul r18,r22\n\tadd r14,r0\n\tadc r15,r1\n\tadc r16,r19\n\tadc r17,r19\n\t"                \
	"mulsu r23,r18\n\tsbc r17,r19\n\tadd r15,r0\n\tadc r16,r1\n\tadc r17,r19\n"
#define I_MAC3                                                                                     \
	"mul r18,r22\n\tadd r15,r0\n\tadc r16,r1\n\tadc r17,r19\n\t"                               \
	"mulsu r23,r18\n\tadd r16,r0\n\tadc r17,r1\n"
#define I_BYTE(J) "ldd r18,Z+%[ki]+" #J "\n\ttst r18\n\tbreq 1f\n\t" I_MAC##J "1:\n\t"

/* (r22:r23 and r20:r21 are e and de) |X| <= the int16_t at OFF: (X + lim) mod 2^16 <= 2 lim. */
#define WITHIN(X0, X1, OFF)                                                                        \
	"ldd r26,Z+" OFF "\n\tldd r27,Z+" OFF "+1\n\tmovw r18,r26\n\tadd r18," X0 "\n\t"           \
	"adc r19," X1 "\n\tlsl r26\n\trol r27\n\tcp r26,r18\n\tcpc r27,r19\n\tbrlo 8f\n\t"

AVR_INLINE uint8_t pid_arch_update_small(struct pid *c, int32_t *err_um, int16_t *out)
{
	register int32_t e __asm__("r22") = *err_um;
	register uint8_t done __asm__("r18");
	register int16_t o __asm__("r20");

	__asm__ volatile(
		/* e within 16 bits (its upper half is the sign of its lower), and |e| <= pf. */
		"mov r18,r23\n\t"
		"lsl r18\n\t"
		"sbc r18,r18\n\t"
		"cp r24,r18\n\t"
		"cpc r25,r18\n\t"
		"brne 8f\n\t" WITHIN("r22", "r23", "%[pf]")
		/* de = e - prev: 0 after a reset (has_prev 0); in 16 bits when prev is (has_prev
		 * 2: pid_arch_fast_mark), if it does not overflow. Then |de| <= df. */
		"ldd r19,Z+%[has]\n\t"
		"cpi r19,2\n\t"
		"breq 1f\n\t"
		"tst r19\n\t"
		"brne 8f\n\t"
		"clr r20\n\t"
		"clr r21\n\t"
		"rjmp 2f\n"
		"1:\n\t"
		"ldd r26,Z+%[prev]\n\t"
		"ldd r27,Z+%[prev]+1\n\t"
		"movw r20,r22\n\t"
		"sub r20,r26\n\t"
		"sbc r21,r27\n\t"
		"brvs 8f\n"
		"2:\n\t" WITHIN("r20", "r21", "%[df]") "rjmp 3f\n"
						       "8:\n\t"
						       "clr r18\n\t"
						       "rjmp 9f\n"
						       /* The fast path: prev = e, has_prev = 2. */
						       "3:\n\t"
						       "std Z+%[prev],r22\n\t"
						       "std Z+%[prev]+1,r23\n\t"
						       "std Z+%[prev]+2,r24\n\t"
						       "std Z+%[prev]+3,r25\n\t"
						       "ldi r18,2\n\t"
						       "std Z+%[has],r18\n\t"
						       "clr r19\n\t"
						       /* r24..r27 = kd de + kp e. */
						       "clr r24\n\t"
						       "clr r25\n\t"
						       "movw r26,r24\n\t" PD_TERM("%[kd]", "r20",
										  "r21")
							       PD_TERM("%[kp]", "r22", "r23")
		/* pdl's upper byte, then pdh = (P + D) >> 4, arithmetic. */
		"mov r20,r24\n\t"
		"swap r20\n\t"
		"andi r20,0xf0\n\t"
		"asr r27\n\t"
		"ror r26\n\t"
		"ror r25\n\t"
		"ror r24\n\t"
		"asr r27\n\t"
		"ror r26\n\t"
		"ror r25\n\t"
		"ror r24\n\t"
		"asr r27\n\t"
		"ror r26\n\t"
		"ror r25\n\t"
		"ror r24\n\t"
		"asr r27\n\t"
		"ror r26\n\t"
		"ror r25\n\t"
		"ror r24\n\t"
		/* The integral: T = e < 0; nothing to add when e = 0. */
		"bst r23,7\n\t"
		"mov r18,r22\n\t"
		"or r18,r23\n\t"
		"brne 3f\n\t"
		"rjmp 6f\n"
		"3:\n\t"
		"ldd r12,Z+%[il]\n\t"
		"ldd r13,Z+%[il]+1\n\t"
		"ldd r14,Z+%[ih]\n\t"
		"ldd r15,Z+%[ih]+1\n\t"
		"ldd r16,Z+%[ih]+2\n\t"
		"ldd r17,Z+%[ih]+3\n\t" I_BYTE(0) I_BYTE(1) I_BYTE(2) I_BYTE(3)
		/* Clipped: hi >= lim = out_limit 2^8 gives lim, hi + lim < 0 gives -lim. */
		"ldd r22,Z+%[ol]\n\t"
		"ldd r23,Z+%[ol]+1\n\t"
		"cp r14,r19\n\t"
		"cpc r15,r22\n\t"
		"cpc r16,r23\n\t"
		"cpc r17,r19\n\t"
		"brlt 4f\n\t"
		"clr r12\n\t"
		"clr r13\n\t"
		"clr r14\n\t"
		"mov r15,r22\n\t"
		"mov r16,r23\n\t"
		"clr r17\n\t"
		"rjmp 5f\n"
		"4:\n\t"
		"mov r18,r15\n\t"
		"add r18,r22\n\t"
		"mov r18,r16\n\t"
		"adc r18,r23\n\t"
		"mov r18,r17\n\t"
		"adc r18,r19\n\t"
		"brge 5f\n\t"
		"clr r12\n\t"
		"clr r13\n\t"
		"clr r14\n\t"
		"mov r15,r22\n\t"
		"mov r16,r23\n\t"
		"com r16\n\t"
		"neg r15\n\t"
		"sbci r16,0xff\n\t"
		"ldi r17,0xff\n"
		/* u' = pdh 2^16 + pdl + i' in r12 (i's own), r20, r24..r27. */
		"5:\n\t"
		"add r20,r13\n\t"
		"adc r24,r14\n\t"
		"adc r25,r15\n\t"
		"adc r26,r16\n\t"
		"adc r27,r17\n\t"
		/* Winds up: e > 0 and u' > lim 2^16, or e < 0 and u' < -lim 2^16. */
		"brts 7f\n\t"
		"cp r19,r12\n\t"
		"cpc r19,r20\n\t"
		"cpc r19,r24\n\t"
		"cpc r22,r25\n\t"
		"cpc r23,r26\n\t"
		"cpc r19,r27\n\t"
		"brlt 10f\n\t"
		"rjmp 11f\n"
		"7:\n\t"
		"mov r18,r25\n\t"
		"add r18,r22\n\t"
		"mov r18,r26\n\t"
		"adc r18,r23\n\t"
		"mov r18,r27\n\t"
		"adc r18,r19\n\t"
		"brlt 10f\n"
		"11:\n\t"
		"std Z+%[il],r12\n\t"
		"std Z+%[il]+1,r13\n\t"
		"std Z+%[ih],r14\n\t"
		"std Z+%[ih]+1,r15\n\t"
		"std Z+%[ih]+2,r16\n\t"
		"std Z+%[ih]+3,r17\n\t"
		"rjmp 12f\n"
		/* It winds up: back to pdh 2^16 + pdl, then u with the integral kept. */
		"10:\n\t"
		"sub r20,r13\n\t"
		"sbc r24,r14\n\t"
		"sbc r25,r15\n\t"
		"sbc r26,r16\n\t"
		"sbc r27,r17\n\t"
		"rjmp 13f\n"
		"6:\n\t"
		"ldd r22,Z+%[ol]\n\t"
		"ldd r23,Z+%[ol]+1\n"
		"13:\n\t"
		"ldd r12,Z+%[il]\n\t"
		"ldd r13,Z+%[il]+1\n\t"
		"ldd r14,Z+%[ih]\n\t"
		"ldd r15,Z+%[ih]+1\n\t"
		"ldd r16,Z+%[ih]+2\n\t"
		"ldd r17,Z+%[ih]+3\n\t"
		"add r20,r13\n\t"
		"adc r24,r14\n\t"
		"adc r25,r15\n\t"
		"adc r26,r16\n\t"
		"adc r27,r17\n"
		/* The duty: T = u < 0; m = |u| rounded down to 2^-8 (~uh, + 1 if ul = 0); m >=
		 * lim gives out_limit, else (m + 128) >> 8; then the sign. */
		"12:\n\t"
		"bst r27,7\n\t"
		"brtc 14f\n\t"
		"com r24\n\t"
		"com r25\n\t"
		"com r26\n\t"
		"com r27\n\t"
		"or r12,r20\n\t"
		"brne 14f\n\t"
		"subi r24,0xff\n\t"
		"sbci r25,0xff\n\t"
		"sbci r26,0xff\n\t"
		"sbci r27,0xff\n"
		"14:\n\t"
		"cp r24,r19\n\t"
		"cpc r25,r22\n\t"
		"cpc r26,r23\n\t"
		"cpc r27,r19\n\t"
		"brlo 15f\n\t"
		"movw r20,r22\n\t"
		"rjmp 16f\n"
		"15:\n\t"
		"mov r20,r25\n\t"
		"mov r21,r26\n\t"
		"lsl r24\n\t"
		"adc r20,r19\n\t"
		"adc r21,r19\n"
		"16:\n\t"
		"brtc 17f\n\t"
		"com r21\n\t"
		"neg r20\n\t"
		"sbci r21,0xff\n"
		"17:\n\t"
		"std Z+%[out],r20\n\t"
		"std Z+%[out]+1,r21\n\t"
		"ldi r18,1\n"
		"9:\n\t"
		"clr r1"
		: "+r"(e), "=&r"(done), "=&r"(o)
		: "z"(c), [ol] "n"(offsetof(struct pid, cfg.out_limit_q15)),
		  [kp] "n"(offsetof(struct pid, kp_q12)), [kd] "n"(offsetof(struct pid, kd_q12)),
		  [ki] "n"(offsetof(struct pid, ki_q24)),
		  [pf] "n"(offsetof(struct pid, fast.p_err_um)),
		  [df] "n"(offsetof(struct pid, fast.d_err_um)),
		  [ih] "n"(offsetof(struct pid, i_acc_q24.hi)),
		  [il] "n"(offsetof(struct pid, i_acc_q24.lo)),
		  [prev] "n"(offsetof(struct pid, prev_err_um)),
		  [has] "n"(offsetof(struct pid, has_prev)),
		  [out] "n"(offsetof(struct pid, out_q15))
		: "r0", "r12", "r13", "r14", "r15", "r16", "r17", "r19", "r26", "r27", "memory");
	*err_um = e;
	*out = o;
	return done;
}

#endif
