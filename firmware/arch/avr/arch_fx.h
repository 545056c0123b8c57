/* The fixed-point kernels of fixmath.h for an AVR with a hardware multiplier (ATmega1284P), with
 * avr-gcc: picked by the AVR builds (firmware/ports/avr, harness/avr) in place of
 * firmware/arch/generic/arch_fx.h, the plain C reference whose bits these must give
 * (test_avr_fixmath and test_avr_control run them in simavr against the host's).
 *
 * Why: an 8-bit AVR multiplies 8 x 8 bits in hardware. avr-gcc's 16 x 16 -> 32 routine takes
 * about 25 cycles, its 32 x 32 -> 32 one 70, and anything on int64_t goes through library
 * routines of 100 to 650 cycles; it shifts a uint32_t by most constant counts in a loop, one bit
 * per turn. So the kernels below are built from 16-bit pieces and byte moves, and the hot ones
 * are in assembly. The cycle counts quoted are avr-gcc 5.4's at -O2 (docs/avr.md).
 *
 * In line, the four MUL (8 x 8 bits into r1:r0) of a 16 x 16 product and their sums take 18
 * cycles, in whatever registers the operands already are, where avr-gcc's library call (operands
 * moved into its fixed registers, the call and the return) takes about 30. r1 is avr-gcc's zero
 * register: it is cleared again before each carry that needs a zero and at the end. A signed
 * product is the unsigned one of the same bits less 2^16 b for a negative a (and 2^16 a for a
 * negative b), modulo 2^32: two subtractions, where the MULS/MULSU forms would tie the operands
 * to r16..r23. Constant operands keep the C, which GCC folds.
 *
 * FX_HIDE is an empty asm statement: it keeps GCC from seeing that a 16-bit operand is the
 * narrowed half of a 32-bit value, which it would otherwise fold into the multiplication and turn
 * back into the 32 x 32 routine. It generates no instruction. */
#ifndef ASSERV_ARCH_FX_H
#define ASSERV_ARCH_FX_H

#include <stdint.h>

#if !defined(__AVR__) || !defined(__GNUC__) || !defined(__AVR_HAVE_MUL__)
#error "firmware/arch/avr: avr-gcc for an AVR with MUL; other targets use firmware/arch/generic"
#endif

#define FX_HIDE(v) __asm__("" : "+r"(v))
/* The kernels whose shift counts must be constants where they are used: GCC may otherwise keep
 * one out-of-line copy, and shift by a variable count in a loop. */
#define AVR_INLINE __attribute__((always_inline)) static inline

/* p = a b (unsigned), as a 32-bit word of the operand's type; a and b 16-bit registers. */
#define FX_AVR_MUL_U16(p, a, b)                                                                    \
	__asm__("mul  %A1, %A2\n\t"                                                                \
		"movw %A0, r0\n\t"                                                                 \
		"mul  %B1, %B2\n\t"                                                                \
		"movw %C0, r0\n\t"                                                                 \
		"mul  %A1, %B2\n\t"                                                                \
		"add  %B0, r0\n\t"                                                                 \
		"adc  %C0, r1\n\t"                                                                 \
		"clr  __zero_reg__\n\t"                                                            \
		"adc  %D0, __zero_reg__\n\t"                                                       \
		"mul  %B1, %A2\n\t"                                                                \
		"add  %B0, r0\n\t"                                                                 \
		"adc  %C0, r1\n\t"                                                                 \
		"clr  __zero_reg__\n\t"                                                            \
		"adc  %D0, __zero_reg__"                                                           \
		: "=&r"(p)                                                                         \
		: "r"(a), "r"(b)                                                                   \
		: "r0")

/* p -= 2^16 b if a is negative: a and b 16-bit registers. */
#define FX_AVR_FIX_SIGN(p, a, b)                                                                   \
	__asm__("sbrs %B1, 7\n\t"                                                                  \
		"rjmp 1f\n\t"                                                                      \
		"sub  %C0, %A2\n\t"                                                                \
		"sbc  %D0, %B2\n"                                                                  \
		"1:"                                                                               \
		: "+r"(p)                                                                          \
		: "r"(a), "r"(b))

AVR_INLINE uint32_t fx_mul_u16(uint16_t a, uint16_t b)
{
	if (!__builtin_constant_p(a) || !__builtin_constant_p(b)) {
		uint32_t p;

		FX_AVR_MUL_U16(p, a, b);
		return p;
	}
	FX_HIDE(a);
	FX_HIDE(b);
	return (uint32_t)a * b;
}

AVR_INLINE int32_t fx_mul_s16(int16_t a, int16_t b)
{
	if (!__builtin_constant_p(a) || !__builtin_constant_p(b)) {
		int32_t p;

		FX_AVR_MUL_U16(p, a, b);
		FX_AVR_FIX_SIGN(p, a, b);
		FX_AVR_FIX_SIGN(p, b, a);
		return p;
	}
	FX_HIDE(a);
	FX_HIDE(b);
	return (int32_t)a * b;
}

/* x >> n and x << n for a constant n in 0..31, written as 16-bit shifts and byte moves: avr-gcc
 * shifts a uint32_t by any other count than 1, 2, 8, 16, 24 or 31 in a loop, one bit per turn,
 * up to 180 cycles; its 16-bit shifts are straight code. The halves are hidden from the
 * compiler so that it does not fold them back into one 32-bit shift. */
AVR_INLINE uint32_t fx_shr_u32_n(uint32_t x, uint8_t n)
{
	uint16_t hi = fx_hi16(x), lo = fx_lo16(x);

	if (n == 0)
		return x;
	if (n >= 16)
		return (uint16_t)(hi >> (n - 16));
	FX_HIDE(hi);
	FX_HIDE(lo);
	return ((uint32_t)(uint16_t)(hi >> n) << 16) |
	       (uint16_t)((uint16_t)(hi << (16 - n)) | (uint16_t)(lo >> n));
}

AVR_INLINE uint32_t fx_shl_u32_n(uint32_t x, uint8_t n)
{
	uint16_t hi = fx_hi16(x), lo = fx_lo16(x);

	if (n == 0)
		return x;
	if (n >= 16)
		return (uint32_t)(uint16_t)(lo << (n - 16)) << 16;
	FX_HIDE(hi);
	FX_HIDE(lo);
	return ((uint32_t)(uint16_t)((uint16_t)(hi << n) | (uint16_t)(lo >> (16 - n))) << 16) |
	       (uint16_t)(lo << n);
}

/* Constant counts that avr-gcc shifts a uint32_t by in a few instructions (1, 2, 31): the
 * pieces would only hide that from it (the shift by 1 in fx_mul_u32_shr(..., 31) took 40). */
#define FX_PLAIN_SHIFT(n) (__builtin_constant_p(n) && ((n) <= 2 || (n) == 31))

/* x >> n and x << n for a count n in 0..31 known only at run time: avr-gcc shifts a uint32_t by
 * a variable count one bit per turn of a loop, 8 cycles a bit; here 16 and 8 bits at once are
 * byte moves, and only the last 0..7 bits take turns. */
static inline uint32_t fx_shr_u32_var(uint32_t x, uint8_t n)
{
	if (n >= 16) {
		x = fx_hi16(x);
		n = (uint8_t)(n - 16u);
	}
	if (n >= 8) {
		x >>= 8;
		n = (uint8_t)(n - 8u);
	}
	while (n-- != 0)
		x >>= 1;
	return x;
}

static inline uint32_t fx_shl_u32_var(uint32_t x, uint8_t n)
{
	if (n >= 16) {
		x = (uint32_t)fx_lo16(x) << 16;
		n = (uint8_t)(n - 16u);
	}
	if (n >= 8) {
		x <<= 8;
		n = (uint8_t)(n - 8u);
	}
	while (n-- != 0)
		x <<= 1;
	return x;
}

/* Constant counts by pieces (or plainly, FX_PLAIN_SHIFT), counts known at run time by bytes. */
AVR_INLINE uint32_t fx_shr_u32(uint32_t x, uint8_t n)
{
	if (!__builtin_constant_p(n))
		return fx_shr_u32_var(x, n);
	return FX_PLAIN_SHIFT(n) ? x >> n : fx_shr_u32_n(x, n);
}

AVR_INLINE uint32_t fx_shl_u32(uint32_t x, uint8_t n)
{
	if (!__builtin_constant_p(n))
		return fx_shl_u32_var(x, n);
	return FX_PLAIN_SHIFT(n) ? x << n : fx_shl_u32_n(x, n);
}

/* The number of bits of v (0 for 0): the top non-zero byte found by comparisons, then at most 8
 * turns of an 8-bit loop (a 32-bit one costs an AVR 12 cycles a turn). */
static inline uint8_t fx_bit_length32(uint32_t v)
{
	uint8_t n, top;

	if (fx_hi16(v) != 0) {
		n = v >= ((uint32_t)1 << 24) ? 24 : 16;
		top = (uint8_t)(n == 24 ? v >> 24 : v >> 16);
	} else {
		n = fx_lo16(v) >= 0x100u ? 8 : 0;
		top = (uint8_t)(n == 8 ? fx_lo16(v) >> 8 : fx_lo16(v));
	}
	while (top != 0) {
		top >>= 1;
		n++;
	}
	return n;
}
/* a * b as two 32-bit words: returns the upper one, *lo the lower. Four 16 x 16 products. */
static inline uint32_t fx_mul_u32_wide_n(uint32_t a, uint32_t b, uint32_t *lo)
{
	uint32_t p0 = fx_mul_u16(fx_lo16(a), fx_lo16(b));
	uint32_t p1 = fx_mul_u16(fx_lo16(a), fx_hi16(b));
	uint32_t p2 = fx_mul_u16(fx_hi16(a), fx_lo16(b));
	uint32_t t = (p0 >> 16) + fx_lo16(p1) + fx_lo16(p2); /* below 3 * 2^16 */

	*lo = fx_lo16(p0) | (t << 16);
	return fx_mul_u16(fx_hi16(a), fx_hi16(b)) + (p1 >> 16) + (p2 >> 16) + (t >> 16);
}

/* On the AVR, in assembly: the 16 byte products summed column by column (all a_i b_j with
 * i + j = k into result bytes k and k + 1, the carry into byte k + 2), 83 cycles where the C
 * above takes over 200 with its spills. The sum of the columns up to k is below
 * 2^18 256^k, so a carry never goes past byte k + 2, which is still zero (cleared first) when
 * column k starts. The zero that the carries add comes from byte 7, untouched until the last
 * two columns: column 6 goes before column 5 (no carry out of byte 7 either way, the product
 * being below 2^64), and column 5's carries clear r1 (EOR leaves the carry flag alone). */
AVR_INLINE uint32_t fx_mul_u32_wide(uint32_t a, uint32_t b, uint32_t *lo)
{
	if (!__builtin_constant_p(a) || !__builtin_constant_p(b)) {
		uint32_t l, h;

		__asm__("clr  %C0\n\t"
			"clr  %D0\n\t"
			"movw %A1, %C0\n\t"
			"movw %C1, %C0\n\t"
			/* column 0 */
			"mul  %A2, %A3\n\t"
			"movw %A0, r0\n\t"
			/* column 1 */
			"mul  %A2, %B3\n\t"
			"add  %B0, r0\n\t"
			"adc  %C0, r1\n\t"
			"adc  %D0, %D1\n\t"
			"mul  %B2, %A3\n\t"
			"add  %B0, r0\n\t"
			"adc  %C0, r1\n\t"
			"adc  %D0, %D1\n\t"
			/* column 2 */
			"mul  %A2, %C3\n\t"
			"add  %C0, r0\n\t"
			"adc  %D0, r1\n\t"
			"adc  %A1, %D1\n\t"
			"mul  %B2, %B3\n\t"
			"add  %C0, r0\n\t"
			"adc  %D0, r1\n\t"
			"adc  %A1, %D1\n\t"
			"mul  %C2, %A3\n\t"
			"add  %C0, r0\n\t"
			"adc  %D0, r1\n\t"
			"adc  %A1, %D1\n\t"
			/* column 3 */
			"mul  %A2, %D3\n\t"
			"add  %D0, r0\n\t"
			"adc  %A1, r1\n\t"
			"adc  %B1, %D1\n\t"
			"mul  %B2, %C3\n\t"
			"add  %D0, r0\n\t"
			"adc  %A1, r1\n\t"
			"adc  %B1, %D1\n\t"
			"mul  %C2, %B3\n\t"
			"add  %D0, r0\n\t"
			"adc  %A1, r1\n\t"
			"adc  %B1, %D1\n\t"
			"mul  %D2, %A3\n\t"
			"add  %D0, r0\n\t"
			"adc  %A1, r1\n\t"
			"adc  %B1, %D1\n\t"
			/* column 4 */
			"mul  %B2, %D3\n\t"
			"add  %A1, r0\n\t"
			"adc  %B1, r1\n\t"
			"adc  %C1, %D1\n\t"
			"mul  %C2, %C3\n\t"
			"add  %A1, r0\n\t"
			"adc  %B1, r1\n\t"
			"adc  %C1, %D1\n\t"
			"mul  %D2, %B3\n\t"
			"add  %A1, r0\n\t"
			"adc  %B1, r1\n\t"
			"adc  %C1, %D1\n\t"
			/* column 6 */
			"mul  %D2, %D3\n\t"
			"add  %C1, r0\n\t"
			"adc  %D1, r1\n\t"
			/* column 5 */
			"mul  %C2, %D3\n\t"
			"add  %B1, r0\n\t"
			"adc  %C1, r1\n\t"
			"clr  __zero_reg__\n\t"
			"adc  %D1, __zero_reg__\n\t"
			"mul  %D2, %C3\n\t"
			"add  %B1, r0\n\t"
			"adc  %C1, r1\n\t"
			"clr  __zero_reg__\n\t"
			"adc  %D1, __zero_reg__"
			: "=&r"(l), "=&r"(h)
			: "r"(a), "r"(b)
			: "r0");
		*lo = l;
		return h;
	}
	return fx_mul_u32_wide_n(a, b, lo);
}
/* round(a b / 2^n) with ties away from zero, for n in 8..47 and |b| <= 65535: two 16 x 16
 * products (|a| < 2^31); the caller knows the result fits in 32 bits. */
AVR_INLINE int32_t fx_mul_q_n(int32_t a, int32_t b, uint8_t n)
{
	uint32_t ua = a >= 0 ? (uint32_t)a : (uint32_t)0 - (uint32_t)a;
	uint16_t ub = (uint16_t)(b >= 0 ? b : -b);
	uint32_t lo = fx_mul_u16(fx_lo16(ua), ub);
	uint32_t hi = fx_mul_u16(fx_hi16(ua), ub) + fx_hi16(lo); /* floor(|a b| / 2^16) */
	uint32_t r;

	if (n < 16)
		r = fx_shl_u32(hi, (uint8_t)(16 - n)) +
		    fx_shr_u32(fx_lo16(lo) + ((uint32_t)1 << (n - 1)), n);
	else if (n == 16)
		r = hi + (fx_lo16(lo) >> 15);
	else
		r = fx_shr_u32(hi + ((uint32_t)1 << (n - 17)), (uint8_t)(n - 16));
	return (a < 0) != (b < 0) ? -(int32_t)r : (int32_t)r;
}

/* round(ua ub / 2^n), halves up, for a constant n in 1..47, the result fitting 32 bits, in AVR
 * assembly: the 48-bit product column by column (as fx_mul_u32_wide), then, for n <= 16,
 * shifted left by 16 - n (the result is its upper four bytes) or, for n > 16, its upper four
 * bytes moved down by whole bytes and shifted right by the rest; the rounding adds the last bit
 * below the result (bit n - 1 of the product: shifted out to the carry, or by LSL when no bit
 * is). 60 cycles for n = 15 where the C's shifts of the 48-bit value took 120. n reaches the
 * assembler as a constant (.if, .rept). */
AVR_INLINE uint32_t fx_avr_mul_u32_u16_round(uint32_t ua, uint16_t ub, uint8_t n)
{
	uint32_t r;
	uint16_t lo;

	__asm__("clr  %A0\n\t"
		"clr  %B0\n\t"
		"movw %C0, %A0\n\t"
		/* column 0 into lo */
		"mul  %A2, %A3\n\t"
		"movw %A1, r0\n\t"
		/* column 1: carry into byte 3, the zero from byte 5 */
		"mul  %B2, %A3\n\t"
		"add  %B1, r0\n\t"
		"adc  %A0, r1\n\t"
		"adc  %B0, %D0\n\t"
		"mul  %A2, %B3\n\t"
		"add  %B1, r0\n\t"
		"adc  %A0, r1\n\t"
		"adc  %B0, %D0\n\t"
		/* column 2 */
		"mul  %C2, %A3\n\t"
		"add  %A0, r0\n\t"
		"adc  %B0, r1\n\t"
		"adc  %C0, %D0\n\t"
		"mul  %B2, %B3\n\t"
		"add  %A0, r0\n\t"
		"adc  %B0, r1\n\t"
		"adc  %C0, %D0\n\t"
		/* column 3: carry into byte 5 itself */
		"mul  %D2, %A3\n\t"
		"add  %B0, r0\n\t"
		"adc  %C0, r1\n\t"
		"clr  __zero_reg__\n\t"
		"adc  %D0, __zero_reg__\n\t"
		"mul  %C2, %B3\n\t"
		"add  %B0, r0\n\t"
		"adc  %C0, r1\n\t"
		"clr  __zero_reg__\n\t"
		"adc  %D0, __zero_reg__\n\t"
		/* column 4 */
		"mul  %D2, %B3\n\t"
		"add  %C0, r0\n\t"
		"adc  %D0, r1\n\t"
		"clr  __zero_reg__\n\t"
		".if %4 <= 16\n\t"
		".rept 16 - %4\n\t"
		"lsl  %A1\n\t"
		"rol  %B1\n\t"
		"rol  %A0\n\t"
		"rol  %B0\n\t"
		"rol  %C0\n\t"
		"rol  %D0\n\t"
		".endr\n\t"
		"lsl  %B1\n\t"
		".elseif %4 < 24\n\t"
		".rept %4 - 16\n\t"
		"lsr  %D0\n\t"
		"ror  %C0\n\t"
		"ror  %B0\n\t"
		"ror  %A0\n\t"
		".endr\n\t"
		".elseif %4 < 32\n\t"
		".if %4 == 24\n\t"
		"lsl  %A0\n\t"
		".endif\n\t"
		"mov  %A0, %B0\n\t"
		"mov  %B0, %C0\n\t"
		"mov  %C0, %D0\n\t"
		"clr  %D0\n\t"
		".rept %4 - 24\n\t"
		"lsr  %C0\n\t"
		"ror  %B0\n\t"
		"ror  %A0\n\t"
		".endr\n\t"
		".elseif %4 < 40\n\t"
		".if %4 == 32\n\t"
		"lsl  %B0\n\t"
		".endif\n\t"
		"movw %A0, %C0\n\t"
		"clr  %C0\n\t"
		"clr  %D0\n\t"
		".rept %4 - 32\n\t"
		"lsr  %B0\n\t"
		"ror  %A0\n\t"
		".endr\n\t"
		".else\n\t"
		".if %4 == 40\n\t"
		"lsl  %C0\n\t"
		".endif\n\t"
		"mov  %A0, %D0\n\t"
		"clr  %B0\n\t"
		"clr  %C0\n\t"
		"clr  %D0\n\t"
		".rept %4 - 40\n\t"
		"lsr  %A0\n\t"
		".endr\n\t"
		".endif\n\t"
		"adc  %A0, __zero_reg__\n\t"
		"adc  %B0, __zero_reg__\n\t"
		"adc  %C0, __zero_reg__\n\t"
		"adc  %D0, __zero_reg__"
		: "=&r"(r), "=&r"(lo)
		: "r"(ua), "r"(ub), "n"(n));
	return r;
}

AVR_INLINE int32_t fx_mul_q(int32_t a, int32_t b, uint8_t n)
{
	uint32_t r;

	if (__builtin_constant_p(n) && n >= 1 && n <= 47 &&
	    !(__builtin_constant_p(a) && __builtin_constant_p(b))) {
		r = fx_avr_mul_u32_u16_round(a >= 0 ? (uint32_t)a : (uint32_t)0 - (uint32_t)a,
					     (uint16_t)(b >= 0 ? b : -b), n);
		return (a < 0) != (b < 0) ? -(int32_t)r : (int32_t)r;
	}
	return fx_mul_q_n(a, b, n);
}
/* floor(num / den), den >= 1, for a quotient known to be below 2^qbits (1..32): a restoring
 * division over the quotient's bits only (avr-gcc's 32-bit division always takes 32 steps of a
 * slower loop). */
static inline uint32_t fx_udiv_small_n(uint32_t num, uint32_t den, uint8_t qbits)
{
	uint32_t rem = qbits >= 32 ? 0 : num >> qbits;
	uint32_t q = 0;

	num = qbits >= 32 ? num : num << (32 - qbits);
	while (qbits-- != 0) {
		rem = (rem << 1) | (num >> 31);
		num <<= 1;
		q <<= 1;
		if (rem >= den) {
			rem -= den;
			q |= 1u;
		}
	}
	return q;
}

/* The steps of that division in AVR assembly, 17 to 20 cycles each where avr-gcc's loop takes
 * 40: the remainder (rem, from 0) first takes the upper shift bits of num (whole bytes, then
 * bits), then each of the steps moves num's top bit into the remainder, compares, subtracts,
 * and puts the quotient bit in num's lowest bit, freed by the shift. After shift + steps = 32
 * (or with num's upper 32 - steps bits zero) num is the quotient: every bit of the dividend has
 * gone to the remainder, and the quotient bits, no more than the steps, never reach bit 31 before
 * the last step. The remainder's top bit is shifted out as the C's does (it is lost only outside
 * the domain, den > 2^31). steps >= 1; *rem is the remainder in, and out. */
AVR_INLINE uint32_t fx_avr_div_steps(uint32_t *rem, uint32_t num, uint32_t den, uint8_t shift,
				     uint8_t steps)
{
	uint32_t r = *rem;

	__asm__("rjmp 2f\n"
		"1:\n\t"
		"mov  %D0, %C0\n\t"
		"mov  %C0, %B0\n\t"
		"mov  %B0, %A0\n\t"
		"mov  %A0, %D1\n\t"
		"mov  %D1, %C1\n\t"
		"mov  %C1, %B1\n\t"
		"mov  %B1, %A1\n\t"
		"clr  %A1\n\t"
		"subi %2, 8\n"
		"2:\n\t"
		"cpi  %2, 8\n\t"
		"brsh 1b\n\t"
		"tst  %2\n\t"
		"breq 4f\n"
		"3:\n\t"
		"lsl  %A1\n\t"
		"rol  %B1\n\t"
		"rol  %C1\n\t"
		"rol  %D1\n\t"
		"rol  %A0\n\t"
		"rol  %B0\n\t"
		"rol  %C0\n\t"
		"rol  %D0\n\t"
		"dec  %2\n\t"
		"brne 3b\n"
		"4:\n\t"
		"lsl  %A1\n\t"
		"rol  %B1\n\t"
		"rol  %C1\n\t"
		"rol  %D1\n\t"
		"rol  %A0\n\t"
		"rol  %B0\n\t"
		"rol  %C0\n\t"
		"rol  %D0\n\t"
		"cp   %A0, %A4\n\t"
		"cpc  %B0, %B4\n\t"
		"cpc  %C0, %C4\n\t"
		"cpc  %D0, %D4\n\t"
		"brcs 5f\n\t"
		"sub  %A0, %A4\n\t"
		"sbc  %B0, %B4\n\t"
		"sbc  %C0, %C4\n\t"
		"sbc  %D0, %D4\n\t"
		"inc  %A1\n"
		"5:\n\t"
		"dec  %3\n\t"
		"brne 4b"
		: "+r"(r), "+r"(num), "+d"(shift), "+r"(steps)
		: "r"(den));
	*rem = r;
	return num;
}

/* The same division for a divisor of 16 bits, in AVR assembly: the remainder, below den, stays
 * a 16-bit word (17 bits after the shift, whose carry says it is above den), and the dividend is
 * taken a byte at a time: its top byte shifts out into the remainder and takes the quotient bits
 * in, one register where the steps above shift all four. 8 to 10 cycles a step, over the
 * quotient's whole bytes (ceil(qbits / 8)): the dividend's bytes above them first go to the
 * remainder whole (they are below den, as the quotient is below 2^qbits), and each byte done
 * rotates to the bottom, so that the last leaves the quotient in place. */
AVR_INLINE uint32_t fx_avr_div_u16(uint32_t num, uint16_t den, uint8_t qbits)
{
	uint16_t rem = 0;
	uint8_t bytes = (uint8_t)((qbits + 7u) >> 3); /* 1..4 */
	uint8_t skip = (uint8_t)(4u - bytes);

	__asm__("tst  %[skip]\n\t"
		"breq 2f\n"
		"1:\n\t"
		"mov  %B[rem], %A[rem]\n\t"
		"mov  %A[rem], %D[num]\n\t"
		"mov  %D[num], %C[num]\n\t"
		"mov  %C[num], %B[num]\n\t"
		"mov  %B[num], %A[num]\n\t"
		"clr  %A[num]\n\t"
		"dec  %[skip]\n\t"
		"brne 1b\n"
		"2:\n\t"
		".rept 8\n\t"
		"lsl  %D[num]\n\t"
		"rol  %A[rem]\n\t"
		"rol  %B[rem]\n\t"
		"brcs 3f\n\t"
		"cp   %A[rem], %A[den]\n\t"
		"cpc  %B[rem], %B[den]\n\t"
		"brcs 4f\n"
		"3:\n\t"
		"sub  %A[rem], %A[den]\n\t"
		"sbc  %B[rem], %B[den]\n\t"
		"inc  %D[num]\n"
		"4:\n\t"
		".endr\n\t"
		"mov  __tmp_reg__, %D[num]\n\t"
		"mov  %D[num], %C[num]\n\t"
		"mov  %C[num], %B[num]\n\t"
		"mov  %B[num], %A[num]\n\t"
		"mov  %A[num], __tmp_reg__\n\t"
		"dec  %[bytes]\n\t"
		"breq 5f\n\t"
		"rjmp 2b\n" /* beyond a branch's reach */
		"5:"
		: [num] "+r"(num), [rem] "+r"(rem), [skip] "+r"(skip), [bytes] "+r"(bytes)
		: [den] "r"(den));
	return num;
}

static inline uint32_t fx_udiv_small(uint32_t num, uint32_t den, uint8_t qbits)
{
	if ((uint8_t)(qbits - 1u) < 32u && den <= 0xffffu)
		return fx_avr_div_u16(num, (uint16_t)den, qbits);
	if ((uint8_t)(qbits - 1u) < 32u) {
		uint32_t rem = 0;

		return fx_avr_div_steps(&rem, num, den, (uint8_t)(32u - qbits), qbits);
	}
	return fx_udiv_small_n(num, den, qbits);
}

/* floor(u / 1000) for u < 2^25: q = floor(u 33555 / 2^25) (33555 = ceil(2^25 / 1000)) is the
 * quotient or one more (the excess u 0.568 / 2^25 stays below 1), which the remainder settles.
 * Three 16 x 16-bit products, where a division takes 600 cycles. x = u 33555 / 2^16 is below
 * 2^25, q = x / 2^9 below 2^16: a byte move, then one bit (hidden from avr-gcc, which would
 * shift by 9 in a loop of 9 turns). */
static inline uint16_t fx_udiv1000(uint32_t u)
{
	uint32_t x =
		(fx_mul_u16(fx_hi16(u), 33555u) + fx_hi16(fx_mul_u16(fx_lo16(u), 33555u))) >> 8;
	uint16_t q;

	FX_HIDE(x);
	q = (uint16_t)(x >> 1);
	if (fx_mul_u16(q, 1000u) > u)
		q--;
	return q;
}

/* floor(v 2^16 / den), den 1..2^31 - 1, by the division steps of fx_avr_div_steps(): the quotient's
 * integer bits (as many as v and den's lengths allow), then 16 steps on the remainder alone. About
 * 20 cycles a step, where avr-gcc's 32-bit division took some 600 cycles and its remainder's 16
 * steps in C as many again. */
static inline uint32_t fx_udiv_shl16(uint32_t v, uint32_t den)
{
	uint8_t vb = fx_bit_length32(v), db = fx_bit_length32(den);
	uint32_t rem = 0, q = 0;

	if (vb >= db) {
		uint8_t qbits = (uint8_t)(vb - db + 1u); /* v / den < 2^qbits */

		q = fx_avr_div_steps(&rem, v, den, (uint8_t)(32u - qbits), qbits);
	} else {
		rem = v;
	}
	return fx_shl_u32(q, 16) | fx_avr_div_steps(&rem, 0, den, 0, 16);
}

/* floor(sqrt(v)) for a 32-bit v, and *rem = v less its square: digit-by-digit, shifts and adds
 * only, one step per bit of the root (no multiply, which is slow on the AVR); what the steps
 * leave of v is that remainder. Each step's choice is applied through a mask
 * (all ones when the bit belongs to the root) rather than a branch: the choices are as good as
 * random, and a mispredicted branch costs a PC more than the two extra operations.
 * On the AVR the same steps in assembly, 280 cycles where avr-gcc's 32-bit shifts and masks took
 * 870: the bit tried moves through the bytes of the word, four steps per byte; res has no bit
 * below bit + 1 (it is (res >> 1) + bit after a step, and bit moves by two), so res + bit is
 * res | bit, and the bytes below bit's are zero in res + bit: the comparison, the subtraction
 * and res's shift only touch the bytes from bit's up. */
AVR_INLINE uint32_t fx_isqrt32_rem(uint32_t *rem)
{
	uint32_t v = *rem;
	uint32_t res, t;
	uint8_t bit;

	__asm__("clr  %A0\n\t"
		"clr  %B0\n\t"
		"movw %C0, %A0\n\t"
		/* bit in byte 3 */
		"ldi  %3, 0x40\n"
		"1:\n\t"
		"mov  %D2, %D0\n\t"
		"or   %D2, %3\n\t"
		"lsr  %D0\n\t"
		"cp   %D1, %D2\n\t"
		"brlo 2f\n\t"
		"sub  %D1, %D2\n\t"
		"or   %D0, %3\n"
		"2:\n\t"
		"lsr  %3\n\t"
		"lsr  %3\n\t"
		"brne 1b\n\t"
		/* bit in byte 2 */
		"ldi  %3, 0x40\n"
		"1:\n\t"
		"movw %C2, %C0\n\t"
		"or   %C2, %3\n\t"
		"lsr  %D0\n\t"
		"ror  %C0\n\t"
		"cp   %C1, %C2\n\t"
		"cpc  %D1, %D2\n\t"
		"brlo 2f\n\t"
		"sub  %C1, %C2\n\t"
		"sbc  %D1, %D2\n\t"
		"or   %C0, %3\n"
		"2:\n\t"
		"lsr  %3\n\t"
		"lsr  %3\n\t"
		"brne 1b\n\t"
		/* bit in byte 1 */
		"ldi  %3, 0x40\n"
		"1:\n\t"
		"mov  %B2, %B0\n\t"
		"movw %C2, %C0\n\t"
		"or   %B2, %3\n\t"
		"lsr  %D0\n\t"
		"ror  %C0\n\t"
		"ror  %B0\n\t"
		"cp   %B1, %B2\n\t"
		"cpc  %C1, %C2\n\t"
		"cpc  %D1, %D2\n\t"
		"brlo 2f\n\t"
		"sub  %B1, %B2\n\t"
		"sbc  %C1, %C2\n\t"
		"sbc  %D1, %D2\n\t"
		"or   %B0, %3\n"
		"2:\n\t"
		"lsr  %3\n\t"
		"lsr  %3\n\t"
		"brne 1b\n\t"
		/* bit in byte 0 */
		"ldi  %3, 0x40\n"
		"1:\n\t"
		"movw %A2, %A0\n\t"
		"movw %C2, %C0\n\t"
		"or   %A2, %3\n\t"
		"lsr  %D0\n\t"
		"ror  %C0\n\t"
		"ror  %B0\n\t"
		"ror  %A0\n\t"
		"cp   %A1, %A2\n\t"
		"cpc  %B1, %B2\n\t"
		"cpc  %C1, %C2\n\t"
		"cpc  %D1, %D2\n\t"
		"brlo 2f\n\t"
		"sub  %A1, %A2\n\t"
		"sbc  %B1, %B2\n\t"
		"sbc  %C1, %C2\n\t"
		"sbc  %D1, %D2\n\t"
		"or   %A0, %3\n"
		"2:\n\t"
		"lsr  %3\n\t"
		"lsr  %3\n\t"
		"brne 1b"
		: "=&r"(res), "+r"(v), "=&r"(t), "=&d"(bit));
	*rem = v;
	return res;
}

/* round(d m / 2^31) for d < 2^32, m <= 2^22, within 0.52: the product of the low halves is
 * taken from their upper bytes (8 x 8 bits, one instruction on an AVR).
 * On the AVR the same steps in assembly (m's top byte is zero, the upper half of m one byte):
 * avr-gcc kept the three 16 x 16 products in the stack and saved 16 registers, 200 cycles for
 * 60. The additions of 0x2000 and the shift by 14 bits work on the upper three bytes of mid,
 * which needs them in r16..r31 (SUBI, SBCI: the "d" constraint). */
AVR_INLINE uint32_t fx_mul_q31_approx(uint32_t d, uint32_t m)
{
	uint32_t r, mid;

	__asm__(/* mid = (d >> 16) (m & 0xffff) / 2 */
		"mul  %C2, %A3\n\t"
		"movw %A1, r0\n\t"
		"mul  %D2, %B3\n\t"
		"movw %C1, r0\n\t"
		"mul  %C2, %B3\n\t"
		"add  %B1, r0\n\t"
		"adc  %C1, r1\n\t"
		"clr  __zero_reg__\n\t"
		"adc  %D1, __zero_reg__\n\t"
		"mul  %D2, %A3\n\t"
		"add  %B1, r0\n\t"
		"adc  %C1, r1\n\t"
		"clr  __zero_reg__\n\t"
		"adc  %D1, __zero_reg__\n\t"
		"lsr  %D1\n\t"
		"ror  %C1\n\t"
		"ror  %B1\n\t"
		"ror  %A1\n\t"
		/* + floor((d & 0xffff) (m >> 16) / 2), in r's lower three bytes */
		"mul  %A2, %C3\n\t"
		"movw %A0, r0\n\t"
		"mul  %B2, %C3\n\t"
		"clr  %C0\n\t"
		"add  %B0, r0\n\t"
		"adc  %C0, r1\n\t"
		"lsr  %C0\n\t"
		"ror  %B0\n\t"
		"ror  %A0\n\t"
		"add  %A1, %A0\n\t"
		"adc  %B1, %B0\n\t"
		"adc  %C1, %C0\n\t"
		"clr  __zero_reg__\n\t"
		"adc  %D1, __zero_reg__\n\t"
		/* + floor(d's byte 1 m's byte 1 / 2) */
		"mul  %B2, %B3\n\t"
		"lsr  r1\n\t"
		"ror  r0\n\t"
		"add  %A1, r0\n\t"
		"adc  %B1, r1\n\t"
		"clr  __zero_reg__\n\t"
		"adc  %C1, __zero_reg__\n\t"
		"adc  %D1, __zero_reg__\n\t"
		/* (mid + 0x2000) >> 14 into r's byte 3 : mid's bytes 3, 2 */
		"subi %B1, 0xe0\n\t"
		"sbci %C1, 0xff\n\t"
		"sbci %D1, 0xff\n\t"
		"clr  %D0\n\t"
		"lsl  %B1\n\t"
		"rol  %C1\n\t"
		"rol  %D1\n\t"
		"rol  %D0\n\t"
		"lsl  %B1\n\t"
		"rol  %C1\n\t"
		"rol  %D1\n\t"
		"rol  %D0\n\t"
		/* + 2 (d >> 16) (m >> 16), below 2^23 */
		"mul  %C2, %C3\n\t"
		"movw %A0, r0\n\t"
		"mul  %D2, %C3\n\t"
		"clr  %C0\n\t"
		"add  %B0, r0\n\t"
		"adc  %C0, r1\n\t"
		"clr  __zero_reg__\n\t"
		"lsl  %A0\n\t"
		"rol  %B0\n\t"
		"rol  %C0\n\t"
		"add  %A0, %C1\n\t"
		"adc  %B0, %D1\n\t"
		"adc  %C0, %D0\n\t"
		"clr  %D0\n\t"
		"rol  %D0"
		: "=&r"(r), "=&d"(mid)
		: "r"(d), "r"(m)
		: "r0");
	return r;
}

/* One step of frac20_avr(): the remainder doubled (its carry out says it passed 2^24, so den),
 * compared with den and reduced, the quotient bit shifted into the byte qb. 10 to 13 cycles. */
#define FRAC_STEP(qb)                                                                              \
	"lsl  " qb "\n\t"                                                                          \
	"lsl  %A1\n\t"                                                                             \
	"rol  %B1\n\t"                                                                             \
	"rol  %C1\n\t"                                                                             \
	"brcs 1f\n\t"                                                                              \
	"cp   %A1, %A2\n\t"                                                                        \
	"cpc  %B1, %B2\n\t"                                                                        \
	"cpc  %C1, %C2\n\t"                                                                        \
	"brcs 2f\n"                                                                                \
	"1:\n\t"                                                                                   \
	"sub  %A1, %A2\n\t"                                                                        \
	"sbc  %B1, %B2\n\t"                                                                        \
	"sbc  %C1, %C2\n\t"                                                                        \
	"inc  " qb "\n"                                                                            \
	"2:\n\t"

/* q 2^20 + floor(rem 2^20 / den) for rem < den < 2^24, q 0 or 1: fx_avr_div_steps()'s 20 steps
 * with a remainder of three bytes, and the quotient's bits shifted into one byte at a time
 * (4 into byte 2, above q, then 8 into byte 1 and 8 into byte 0), where the steps shift eight
 * registers: 11 cycles a step for 20. */
static inline uint32_t frac20_avr(uint32_t q, uint32_t rem, uint32_t den)
{
	q <<= 16;
	__asm__(".rept 4\n\t" FRAC_STEP("%C0") ".endr\n\t"
					       ".rept 8\n\t" FRAC_STEP(
						       "%B0") ".endr\n\t"
							      ".rept 8\n\t" FRAC_STEP("%A0") ".endr"
		: "+r"(q), "+r"(rem)
		: "r"(den));
	return q;
}
#undef FRAC_STEP

AVR_INLINE uint32_t fx_udiv_frac20(uint32_t q, uint32_t rem, uint32_t den)
{
	if (den < ((uint32_t)1 << 24)) /* a field's lengths [um]: the steps on three bytes */
		return frac20_avr(q, rem, den);
	else
		return fx_avr_div_steps(&rem, q, den, 0, 20); /* q's upper bits are zero */
}

/* One term of the feed-forward, round(v k / 2^20) into P2..P5 (r16 is zero): r18..r21 = v; 0 if v
 * is; else v k in 48 bits (r26, r27, P2..P5) from eight MULs, v taken as unsigned and then
 * corrected by -k 2^32 when negative; + 2^19, less 1 below zero (ties away from zero); >> 20,
 * arithmetic. */
#define FF_TERM(K0, K1, P2, P3, P4, P5)                                                            \
	"mov r26,r18\n\t"                                                                          \
	"or r26,r19\n\t"                                                                           \
	"or r26,r20\n\t"                                                                           \
	"or r26,r21\n\t"                                                                           \
	"brne 3f\n\t"                                                                              \
	"clr " P2 "\n\t"                                                                           \
	"clr " P3 "\n\t"                                                                           \
	"movw " P4 "," P2 "\n\t"                                                                   \
	"rjmp 4f\n"                                                                                \
	"3:\n\t"                                                                                   \
	"mul r18," K0 "\n\t"                                                                       \
	"movw r26,r0\n\t"                                                                          \
	"mul r19," K1 "\n\t"                                                                       \
	"movw " P2 ",r0\n\t"                                                                       \
	"mul r21," K1 "\n\t"                                                                       \
	"movw " P4 ",r0\n\t"                                                                       \
	"mul r18," K1 "\n\t"                                                                       \
	"add r27,r0\n\t"                                                                           \
	"adc " P2 ",r1\n\t"                                                                        \
	"adc " P3 ",r16\n\t"                                                                       \
	"adc " P4 ",r16\n\t"                                                                       \
	"adc " P5 ",r16\n\t"                                                                       \
	"mul r19," K0 "\n\t"                                                                       \
	"add r27,r0\n\t"                                                                           \
	"adc " P2 ",r1\n\t"                                                                        \
	"adc " P3 ",r16\n\t"                                                                       \
	"adc " P4 ",r16\n\t"                                                                       \
	"adc " P5 ",r16\n\t"                                                                       \
	"mul r20," K0 "\n\t"                                                                       \
	"add " P2 ",r0\n\t"                                                                        \
	"adc " P3 ",r1\n\t"                                                                        \
	"adc " P4 ",r16\n\t"                                                                       \
	"adc " P5 ",r16\n\t"                                                                       \
	"mul r20," K1 "\n\t"                                                                       \
	"add " P3 ",r0\n\t"                                                                        \
	"adc " P4 ",r1\n\t"                                                                        \
	"adc " P5 ",r16\n\t"                                                                       \
	"mul r21," K0 "\n\t"                                                                       \
	"add " P3 ",r0\n\t"                                                                        \
	"adc " P4 ",r1\n\t"                                                                        \
	"adc " P5 ",r16\n\t"                                                                       \
	"sbrs r21,7\n\t"                                                                           \
	"rjmp 1f\n\t"                                                                              \
	"sub " P4 "," K0 "\n\t"                                                                    \
	"sbc " P5 "," K1 "\n\t"                                                                    \
	"or r26,r27\n\t"                                                                           \
	"ldi r27,7\n\t"                                                                            \
	"breq 2f\n"                                                                                \
	"1:\n\t"                                                                                   \
	"ldi r27,8\n"                                                                              \
	"2:\n\t"                                                                                   \
	"add " P2 ",r27\n\t"                                                                       \
	"adc " P3 ",r16\n\t"                                                                       \
	"adc " P4 ",r16\n\t"                                                                       \
	"adc " P5 ",r16\n\t"                                                                       \
	"asr " P5 "\n\t"                                                                           \
	"ror " P4 "\n\t"                                                                           \
	"ror " P3 "\n\t"                                                                           \
	"ror " P2 "\n\t"                                                                           \
	"asr " P5 "\n\t"                                                                           \
	"ror " P4 "\n\t"                                                                           \
	"ror " P3 "\n\t"                                                                           \
	"ror " P2 "\n\t"                                                                           \
	"asr " P5 "\n\t"                                                                           \
	"ror " P4 "\n\t"                                                                           \
	"ror " P3 "\n\t"                                                                           \
	"ror " P2 "\n\t"                                                                           \
	"asr " P5 "\n\t"                                                                           \
	"ror " P4 "\n\t"                                                                           \
	"ror " P3 "\n\t"                                                                           \
	"ror " P2 "\n"                                                                             \
	"4:\n\t"

/* round(v k / 2^20) for a coefficient below 2^16, in AVR assembly: avr-gcc calls a library
 * routine for each of the C version's 16 x 16 products and keeps few of its 32-bit values in
 * registers: about 200 cycles a term where this takes 70, and 10 for a zero v. round(v k / 2^20)
 * with ties away from zero is floor((v k + 2^19 - [v < 0]) / 2^20) on the signed product, for
 * any v. */
AVR_INLINE int32_t fx_mul_q20_u16(int32_t v, uint16_t k)
{
	register int32_t r __asm__("r22");
	register int32_t x __asm__("r18") = v;

	__asm__("clr r16\n\t" FF_TERM("%A[k]", "%B[k]", "r22", "r23", "r24", "r25") "clr r1"
		: "=&r"(r)
		: "r"(x), [k] "r"(k)
		: "r0", "r16", "r26", "r27");
	return r;
}

/* (lo, hi) += d and -= d modulo 2^64: eight loads and additions with carry (loads leave the carry
 * alone); C has no carry, and avr-gcc's compare for it costs as much again. */
AVR_INLINE void fx_add_u64(uint32_t *lo, uint32_t *hi, const uint32_t d[2])
{
	uint32_t l = *lo, h = *hi;
	const uint32_t *p = d;

	__asm__("ld __tmp_reg__,%a[p]+\n\tadd %A[lo],__tmp_reg__\n\t"
		"ld __tmp_reg__,%a[p]+\n\tadc %B[lo],__tmp_reg__\n\t"
		"ld __tmp_reg__,%a[p]+\n\tadc %C[lo],__tmp_reg__\n\t"
		"ld __tmp_reg__,%a[p]+\n\tadc %D[lo],__tmp_reg__\n\t"
		"ld __tmp_reg__,%a[p]+\n\tadc %A[hi],__tmp_reg__\n\t"
		"ld __tmp_reg__,%a[p]+\n\tadc %B[hi],__tmp_reg__\n\t"
		"ld __tmp_reg__,%a[p]+\n\tadc %C[hi],__tmp_reg__\n\t"
		"ld __tmp_reg__,%a[p]+\n\tadc %D[hi],__tmp_reg__"
		: [lo] "+r"(l), [hi] "+r"(h), [p] "+e"(p)
		: "m"(*(const uint32_t(*)[2])d));
	*lo = l;
	*hi = h;
}

AVR_INLINE void fx_sub_u64(uint32_t *lo, uint32_t *hi, const uint32_t d[2])
{
	uint32_t l = *lo, h = *hi;
	const uint32_t *p = d;

	__asm__("ld __tmp_reg__,%a[p]+\n\tsub %A[lo],__tmp_reg__\n\t"
		"ld __tmp_reg__,%a[p]+\n\tsbc %B[lo],__tmp_reg__\n\t"
		"ld __tmp_reg__,%a[p]+\n\tsbc %C[lo],__tmp_reg__\n\t"
		"ld __tmp_reg__,%a[p]+\n\tsbc %D[lo],__tmp_reg__\n\t"
		"ld __tmp_reg__,%a[p]+\n\tsbc %A[hi],__tmp_reg__\n\t"
		"ld __tmp_reg__,%a[p]+\n\tsbc %B[hi],__tmp_reg__\n\t"
		"ld __tmp_reg__,%a[p]+\n\tsbc %C[hi],__tmp_reg__\n\t"
		"ld __tmp_reg__,%a[p]+\n\tsbc %D[hi],__tmp_reg__"
		: [lo] "+r"(l), [hi] "+r"(h), [p] "+e"(p)
		: "m"(*(const uint32_t(*)[2])d));
	*lo = l;
	*hi = h;
}

#endif
