/* The mailbox between test_avr_fixmath (the host, through simavr) and fixmath_avr.elf (the AVR):
 * byte offsets in the AVR's RAM, and the operations. The AVR publishes the mailbox's address in
 * GPIOR1 (low byte) and GPIOR2, then sets GPIOR0 to FXA_READY; the host writes the operands,
 * then the operation, and runs the AVR until the operation byte is 0 again. Integers are
 * little-endian, as the AVR stores them. */
#ifndef ASSERV_HARNESS_FIXMATH_AVR_H
#define ASSERV_HARNESS_FIXMATH_AVR_H

#define FXA_READY 0xa5

/* Data-space addresses of GPIOR0..2 on the ATmega1284P (avr-libc's <avr/iom1284p.h>: I/O
 * 0x1E, 0x2A, 0x2B, plus 0x20). */
#define FXA_GPIOR0 0x3eu
#define FXA_GPIOR1 0x4au
#define FXA_GPIOR2 0x4bu

#define FXA_OFF_OP 0 /* uint8_t: the operation, 0 when done */
#define FXA_OFF_N 1  /* uint8_t: a shift or a bit count */
#define FXA_OFF_A 2  /* uint32_t operands */
#define FXA_OFF_B 6
#define FXA_OFF_C 10
#define FXA_OFF_R0 14 /* uint32_t results */
#define FXA_OFF_R1 18
#define FXA_SIZE 22

enum fxa_op {
	FXA_NOP = 1,       /* r0 = a ^ b, r1 = c: the mailbox's own cycles */
	FXA_MUL_U16,       /* r0 = fx_mul_u16(a, b) */
	FXA_MUL_S16,       /* r0 = fx_mul_s16(a, b) */
	FXA_MUL_U32_WIDE,  /* r0 = fx_mul_u32_wide(a, b, &r1) */
	FXA_MUL_U32_SHR,   /* r0 = fx_mul_u32_shr(a, b, n) */
	FXA_MUL_U32_SHR16, /* the same with n a constant: 16, 32, 40 */
	FXA_MUL_U32_SHR32,
	FXA_MUL_U32_SHR40,
	FXA_MUL_Q,   /* r0 = fx_mul_q(a, b, n) */
	FXA_MUL_Q15, /* the same with n a constant: 15, 16, 30 */
	FXA_MUL_Q16,
	FXA_MUL_Q30C,
	FXA_MUL_QC,         /* fx_mul_q(a, b, n) with n a constant, each of 1..47 */
	FXA_MUL_U32_SHRC,   /* fx_mul_u32_shr(a, b, n) with n a constant, each of 1..63 */
	FXA_MUL_SHR32,      /* r0 = fx_mul_shr32(a, b) */
	FXA_MUL_Q30,        /* r0 = fx_mul_q30(a, b) */
	FXA_UDIV_SMALL,     /* r0 = fx_udiv_small(a, b, n) */
	FXA_UDIV_SHL16,     /* r0 = fx_udiv_shl16(a, b) */
	FXA_SINCOS,         /* fx_sincos(a, &r0, &r1) */
	FXA_SINCOS_Q14,     /* fx_sincos_q14(a, &r0, &r1) (16-bit results) */
	FXA_ATAN2,          /* r0 = fx_atan2(a, b) */
	FXA_ISQRT64,        /* r0 = fx_isqrt64(c 2^32 + a) */
	FXA_ISQRT32,        /* r0 = fx_isqrt32(a) */
	FXA_TURN32_TO_CDEG, /* r0 = fx_turn32_to_cdeg(a) */
	FXA_SHR_U32,        /* r0 = fx_shr_u32(a, n), r1 = fx_shl_u32(a, n), n at run time */
	FXA_FLOOR_SHR,      /* r0 = fx_floor_shr(a, n), r1 = fx_shr_round(a, n) */
	FXA_MUL_Q20_U16,    /* r0 = fx_mul_q20_u16(a, b) */
	FXA_UDIV1000,       /* r0 = fx_udiv1000(a) */
	FXA_UDIV_FRAC20,    /* r0 = fx_udiv_frac20(n, a, b) */
	FXA_ADD_SUB_U64,    /* (r0, r1) = (a, b) + (c, a ^ b), then, if n, - (c, b) */
	FXA_ISQRT32_REM,    /* r0 = fx_isqrt32_rem(&a), r1 = a after */
	FXA_MUL_Q31_APPROX, /* r0 = fx_mul_q31_approx(a, b) */
	FXA_OPS
};

#endif
