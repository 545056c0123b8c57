/* Fixed-point arithmetic for the control core: integers only, rounding to nearest, and no
 * implementation-defined behaviour (no right shift of a negative value, no signed overflow), so
 * that an 8-bit AVR and a PC compute the same bits.
 *
 * Conventions used across the core:
 *   lengths     int32_t [um]
 *   headings    uint32_t [turn * 2^32] (binary angle: wraps by itself), suffix _turn32;
 *               relative angles int32_t in the same unit (-1/2..+1/2 turn)
 *   sin, cos    int32_t [2^-30]
 *   duties      int16_t [2^-15 of full scale], suffix _q15
 * All functions are pure, bounded in time and safe to call from an interrupt.
 */
#ifndef ASSERV_FIXMATH_H
#define ASSERV_FIXMATH_H

#include <stdint.h>

#define FX_ONE_Q30 ((int32_t)1 << 30)
#define FX_HALF_TURN32 ((uint32_t)1 << 31)

/* The small helpers below are defined in this header so that every module can inline them:
 * with a constant shift they reduce to a few instructions, and a call costs more than that. */

/* Saturate to the type's range. */
static inline int32_t fx_sat32(int64_t v)
{
	if (v > INT32_MAX)
		return INT32_MAX;
	if (v < INT32_MIN)
		return INT32_MIN;
	return (int32_t)v;
}

/* |v| as a signed value, |INT32_MIN| saturated to INT32_MAX (no undefined negation). */
static inline int32_t fx_abs32(int32_t v)
{
	if (v == INT32_MIN)
		return INT32_MAX;
	return v < 0 ? -v : v;
}

/* |v| exactly, as an unsigned value. */
static inline uint32_t fx_mag32(int32_t v)
{
	return v >= 0 ? (uint32_t)v : (uint32_t)0 - (uint32_t)v;
}

/* a + b saturated to 32 bits (sums that must not wrap, however long they run). */
static inline int32_t fx_add_sat32(int32_t a, int32_t b)
{
	if (b > 0 && a > INT32_MAX - b)
		return INT32_MAX;
	if (b < 0 && a < INT32_MIN - b)
		return INT32_MIN;
	return a + b;
}

static inline int16_t fx_sat16(int32_t v)
{
	if (v > INT16_MAX)
		return INT16_MAX;
	if (v < INT16_MIN)
		return INT16_MIN;
	return (int16_t)v;
}

/* Products for the tick's arithmetic. An 8-bit AVR multiplies 8 x 8 bits in hardware: avr-gcc's
 * 16 x 16 -> 32 routine takes about 25 cycles, its 32 x 32 -> 32 one 70, and anything on
 * int64_t goes through library routines of 100 to 650 cycles (docs/avr.md). So the code that
 * runs every tick multiplies 16-bit halves with these, and keeps wide values as 32-bit words.
 *
 * The primitives below give the same exact results on any machine. Where the words are narrower
 * than 32 bits (FX_NARROW: the AVR) they are built from 16-bit pieces and byte moves, the *_n
 * functions; on a 32- or 64-bit machine from its own 64-bit arithmetic, a few instructions where
 * the pieces would take tens. test_fixmath checks that both agree. With GCC on an AVR the hot
 * ones are in assembly instead (FX_AVR_MUL, FX_AVR_ASM below); test_avr_fixmath runs them in
 * simavr and checks that they give the host's bits.
 *
 * FX_HIDE is an empty GNU asm statement: it keeps GCC from seeing that a 16-bit operand is the
 * narrowed half of a 32-bit value, which it would otherwise fold into the multiplication and
 * turn back into the 32 x 32 routine. It generates no instruction on any target; compilers
 * without GNU asm, and wide machines (where it is not needed), skip it. */
#if UINTPTR_MAX <= 0xffffu
#define FX_NARROW 1
#else
#define FX_NARROW 0
#endif

#if defined(__GNUC__) && FX_NARROW
#define FX_HIDE(v) __asm__("" : "+r"(v))
#else
#define FX_HIDE(v) ((void)0)
#endif

/* For the small helpers whose shift counts must be constants where they are used: GCC may
 * otherwise keep one out-of-line copy, and shift by a variable count in a loop. */
#ifdef __GNUC__
#define FX_INLINE __attribute__((always_inline)) static inline
#else
#define FX_INLINE static inline
#endif

/* For the work a tick does only now and then: kept out of line, so that the tick's common path
 * does not pay for its registers (an AVR saves up to 18 of them on entry). */
#ifdef __GNUC__
#define FX_NOINLINE __attribute__((noinline))
#else
#define FX_NOINLINE
#endif

/* On an AVR with a hardware multiplier (FX_AVR_MUL) the 16 x 16-bit products are written in
 * assembly. avr-gcc 5.4 calls a library routine for each (__umulhisi3 and its signed variants):
 * operands moved into its fixed registers, the call and the return, about 30 cycles, and the
 * caller keeps fewer values in registers across it. In line, the four MUL (8 x 8 bits into
 * r1:r0) and their sums take 18 cycles, in whatever registers the operands already are. r1 is
 * avr-gcc's zero register: it is cleared again before each carry that needs a zero and at the
 * end. A signed product is the unsigned one of the same bits less 2^16 b for a negative a (and
 * 2^16 a for a negative b), modulo 2^32: two subtractions, where the MULS/MULSU forms would
 * tie the operands to r16..r23. Constant operands keep the C, which GCC folds. */
#if defined(__GNUC__) && defined(__AVR__)
#define FX_AVR_ASM 1
#else
#define FX_AVR_ASM 0
#endif
#if FX_AVR_ASM && defined(__AVR_HAVE_MUL__)
#define FX_AVR_MUL 1
#else
#define FX_AVR_MUL 0
#endif

#if FX_AVR_MUL
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
#endif

FX_INLINE uint32_t fx_mul_u16(uint16_t a, uint16_t b)
{
#if FX_AVR_MUL
	if (!__builtin_constant_p(a) || !__builtin_constant_p(b)) {
		uint32_t p;

		FX_AVR_MUL_U16(p, a, b);
		return p;
	}
#endif
	FX_HIDE(a);
	FX_HIDE(b);
	return (uint32_t)a * b;
}

FX_INLINE int32_t fx_mul_s16(int16_t a, int16_t b)
{
#if FX_AVR_MUL
	if (!__builtin_constant_p(a) || !__builtin_constant_p(b)) {
		int32_t p;

		FX_AVR_MUL_U16(p, a, b);
		FX_AVR_FIX_SIGN(p, a, b);
		FX_AVR_FIX_SIGN(p, b, a);
		return p;
	}
#endif
	FX_HIDE(a);
	FX_HIDE(b);
	return (int32_t)a * b;
}

FX_INLINE int32_t fx_mul_s16_u16(int16_t a, uint16_t b)
{
#if FX_AVR_MUL
	if (!__builtin_constant_p(a) || !__builtin_constant_p(b)) {
		int32_t p;

		FX_AVR_MUL_U16(p, a, b);
		FX_AVR_FIX_SIGN(p, a, b);
		return p;
	}
#endif
	FX_HIDE(a);
	FX_HIDE(b);
	return (int32_t)a * (int32_t)b;
}

/* The upper 16 bits of a uint32_t, and the lower. */
static inline uint16_t fx_hi16(uint32_t v)
{
	return (uint16_t)(v >> 16);
}

static inline uint16_t fx_lo16(uint32_t v)
{
	return (uint16_t)v;
}

/* x >> n and x << n for a constant n in 0..31, written as 16-bit shifts and byte moves: avr-gcc
 * shifts a uint32_t by any other count than 1, 2, 8, 16, 24 or 31 in a loop, one bit per turn,
 * up to 180 cycles; its 16-bit shifts are straight code. The halves are hidden from the
 * compiler so that it does not fold them back into one 32-bit shift. */
FX_INLINE uint32_t fx_shr_u32_n(uint32_t x, uint8_t n)
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

FX_INLINE uint32_t fx_shl_u32_n(uint32_t x, uint8_t n)
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
#ifdef __GNUC__
#define FX_PLAIN_SHIFT(n) (__builtin_constant_p(n) && ((n) <= 2 || (n) == 31))
#else
#define FX_PLAIN_SHIFT(n) 0
#endif

FX_INLINE uint32_t fx_shr_u32(uint32_t x, uint8_t n)
{
	return FX_NARROW && !FX_PLAIN_SHIFT(n) ? fx_shr_u32_n(x, n) : x >> n;
}

FX_INLINE uint32_t fx_shl_u32(uint32_t x, uint8_t n)
{
	return FX_NARROW && !FX_PLAIN_SHIFT(n) ? fx_shl_u32_n(x, n) : x << n;
}

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
FX_INLINE uint32_t fx_mul_u32_wide(uint32_t a, uint32_t b, uint32_t *lo)
{
	uint64_t p;

#if FX_AVR_MUL
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
#endif
	if (FX_NARROW)
		return fx_mul_u32_wide_n(a, b, lo);
	p = (uint64_t)a * b;
	*lo = (uint32_t)p;
	return (uint32_t)(p >> 32);
}

/* round(a * b / 2^n), halves rounded up, for n in 1..63; the caller knows the result fits in
 * 32 bits. With a constant n the shift is a few moves. */
FX_INLINE uint32_t fx_mul_u32_shr(uint32_t a, uint32_t b, uint8_t n)
{
	uint32_t lo, hi = fx_mul_u32_wide(a, b, &lo);
	uint32_t bias_lo = n <= 32 ? (uint32_t)1 << (n - 1) : 0;
	uint32_t bias_hi = n > 32 ? (uint32_t)1 << (n - 33) : 0;

	lo += bias_lo;
	hi += bias_hi + (lo < bias_lo);
	if (n >= 32)
		return fx_shr_u32(hi, (uint8_t)(n - 32));
	return fx_shr_u32(lo, n) | fx_shl_u32(hi, (uint8_t)(32 - n));
}

/* A uint32_t that holds an int32_t modulo 2^32, back to int32_t without the
 * implementation-defined conversion of an out-of-range value. */
static inline int32_t fx_int32_of(uint32_t v)
{
	if (v < 0x80000000u)
		return (int32_t)v;
	return (int32_t)(v - 0x80000000u) - INT32_MAX - 1;
}

/* round(a b / 2^n) with ties away from zero, for n in 8..47 and |b| <= 65535: two 16 x 16
 * products (|a| < 2^31); the caller knows the result fits in 32 bits. */
FX_INLINE int32_t fx_mul_q_n(int32_t a, int32_t b, uint8_t n)
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

#if FX_AVR_MUL
/* round(ua ub / 2^n), halves up, for a constant n in 1..47, the result fitting 32 bits, in AVR
 * assembly: the 48-bit product column by column (as fx_mul_u32_wide), then, for n <= 16,
 * shifted left by 16 - n (the result is its upper four bytes) or, for n > 16, its upper four
 * bytes moved down by whole bytes and shifted right by the rest; the rounding adds the last bit
 * below the result (bit n - 1 of the product: shifted out to the carry, or by LSL when no bit
 * is). 60 cycles for n = 15 where the C's shifts of the 48-bit value took 120. n reaches the
 * assembler as a constant (.if, .rept). */
FX_INLINE uint32_t fx_avr_mul_u32_u16_round(uint32_t ua, uint16_t ub, uint8_t n)
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
#endif

FX_INLINE int32_t fx_mul_q(int32_t a, int32_t b, uint8_t n)
{
	uint64_t m;
	uint32_t r;

#if FX_AVR_MUL
	if (__builtin_constant_p(n) && n >= 1 && n <= 47 &&
	    !(__builtin_constant_p(a) && __builtin_constant_p(b))) {
		r = fx_avr_mul_u32_u16_round(a >= 0 ? (uint32_t)a : (uint32_t)0 - (uint32_t)a,
					     (uint16_t)(b >= 0 ? b : -b), n);
		return (a < 0) != (b < 0) ? -(int32_t)r : (int32_t)r;
	}
#endif
	if (FX_NARROW)
		return fx_mul_q_n(a, b, n);
	m = (uint64_t)(a >= 0 ? (uint32_t)a : (uint32_t)0 - (uint32_t)a) *
	    (uint32_t)(b >= 0 ? b : -b);
	r = (uint32_t)((m + ((uint64_t)1 << (n - 1))) >> n);
	return (a < 0) != (b < 0) ? -(int32_t)r : (int32_t)r;
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

#if FX_AVR_ASM
/* The steps of that division in AVR assembly, 17 to 20 cycles each where avr-gcc's loop takes
 * 40: the remainder (rem, from 0) first takes the upper shift bits of num (whole bytes, then
 * bits), then each of the steps moves num's top bit into the remainder, compares, subtracts,
 * and puts the quotient bit in num's lowest bit, freed by the shift. After shift + steps = 32
 * (or with num's upper 32 - steps bits zero) num is the quotient: every bit of the dividend has
 * gone to the remainder, and the quotient bits, no more than the steps, never reach bit 31 before
 * the last step. The remainder's top bit is shifted out as the C's does (it is lost only outside
 * the domain, den > 2^31). steps >= 1; *rem is the remainder in, and out. */
FX_INLINE uint32_t fx_avr_div_steps(uint32_t *rem, uint32_t num, uint32_t den, uint8_t shift,
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
FX_INLINE uint32_t fx_avr_div_u16(uint32_t num, uint16_t den, uint8_t qbits)
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
#endif

static inline uint32_t fx_udiv_small(uint32_t num, uint32_t den, uint8_t qbits)
{
#if FX_AVR_ASM
	if ((uint8_t)(qbits - 1u) < 32u && den <= 0xffffu)
		return fx_avr_div_u16(num, (uint16_t)den, qbits);
	if ((uint8_t)(qbits - 1u) < 32u) {
		uint32_t rem = 0;

		return fx_avr_div_steps(&rem, num, den, (uint8_t)(32u - qbits), qbits);
	}
#endif
	return FX_NARROW ? fx_udiv_small_n(num, den, qbits) : num / den;
}

/* floor(v 2^16 / den), den 1..2^31 - 1, for a quotient below 2^32 (v / den below 2^16): v / den,
 * then the 16 bits below it one step each, the remainder kept below den (2 r >= den is tested as
 * r >= den - r, so that no den overflows it). */
static inline uint32_t fx_udiv_shl16_n(uint32_t v, uint32_t den)
{
	uint32_t q = v / den, r = v - q * den;

	for (uint8_t i = 0; i < 16; i++) {
		q <<= 1;
		if (r >= den - r) {
			r -= den - r;
			q |= 1u;
		} else {
			r <<= 1;
		}
	}
	return q;
}

/* The same by the division steps of fx_avr_div_steps() on an AVR: the quotient's integer bits
 * (as many as v and den's lengths allow), then 16 steps on the remainder alone. About 20 cycles
 * a step, where avr-gcc's 32-bit division took some 600 cycles and its remainder's 16 steps in C
 * as many again. */
static inline uint32_t fx_udiv_shl16(uint32_t v, uint32_t den)
{
#if FX_AVR_ASM
	uint8_t vb = fx_bit_length32(v), db = fx_bit_length32(den);
	uint32_t rem = 0, q = 0;

	if (vb >= db) {
		uint8_t qbits = (uint8_t)(vb - db + 1u); /* v / den < 2^qbits */

		q = fx_avr_div_steps(&rem, v, den, (uint8_t)(32u - qbits), qbits);
	} else {
		rem = v;
	}
	return fx_shl_u32(q, 16) | fx_avr_div_steps(&rem, 0, den, 0, 16);
#else
	return FX_NARROW ? fx_udiv_shl16_n(v, den) : (uint32_t)(((uint64_t)v << 16) / den);
#endif
}

/* round(num / den) with ties away from zero, den >= 1, for |num| / den + 1 below 2^qbits. */
static inline int32_t fx_div_round_small(int32_t num, uint32_t den, uint8_t qbits)
{
	uint32_t m = num >= 0 ? (uint32_t)num : (uint32_t)0 - (uint32_t)num;
	int32_t q = (int32_t)fx_udiv_small(m + den / 2, den, qbits);

	return num >= 0 ? q : -q;
}

/* round(a b / 2^32) with ties away from zero, for any int32_t a and uint32_t b whose product
 * over 2^32 fits: four 16 x 16 products. */
static inline int32_t fx_mul_shr32(int32_t a, uint32_t b)
{
	uint32_t m = a >= 0 ? (uint32_t)a : (uint32_t)0 - (uint32_t)a;
	uint32_t lo, hi = fx_mul_u32_wide(m, b, &lo);
	int32_t r = (int32_t)(hi + (lo >> 31));

	return a >= 0 ? r : -r;
}

/* round(a c / 2^30) with ties away from zero, for a sine or cosine c [2^-30] (|c| <= 2^30) and
 * |a| below 2^31: four 16 x 16 products. */
static inline int32_t fx_mul_q30(int32_t a, int32_t c)
{
	uint32_t m = c >= 0 ? (uint32_t)c : (uint32_t)0 - (uint32_t)c;
	int32_t r = m >= ((uint32_t)1 << 30) ? a : fx_mul_shr32(a, m << 2);

	return c >= 0 ? r : -r;
}

/* A signed 48-bit value, hi 2^16 + lo with lo unsigned: a length [um * 2^16] keeps its whole
 * micrometres (floored) in hi. avr-gcc's int64_t arithmetic calls library routines (40 to 130
 * cycles an operation); these are a few instructions. hi wraps modulo 2^32 (the callers stay
 * within +-2^31 um). */
struct fx48 {
	int32_t hi;
	uint16_t lo;
};

FX_INLINE struct fx48 fx48_make(int32_t hi, uint16_t lo)
{
	struct fx48 r;

	r.hi = hi;
	r.lo = lo;
	return r;
}

/* v [2^-16 of the unit] as a 48-bit value (hi = floor(v / 2^16)). */
FX_INLINE struct fx48 fx48_of32(int32_t v)
{
	uint16_t h = fx_hi16((uint32_t)v);

	return fx48_make(h < 0x8000u ? (int32_t)h : (int32_t)h - 65536, fx_lo16((uint32_t)v));
}

FX_INLINE struct fx48 fx48_add(struct fx48 a, struct fx48 b)
{
	uint32_t lo = (uint32_t)a.lo + b.lo;

	return fx48_make(fx_int32_of((uint32_t)a.hi + (uint32_t)b.hi + fx_hi16(lo)), fx_lo16(lo));
}

FX_INLINE struct fx48 fx48_sub(struct fx48 a, struct fx48 b)
{
	uint32_t lo = 0x10000u + a.lo - b.lo;

	return fx48_make(fx_int32_of((uint32_t)a.hi - (uint32_t)b.hi - 1u + fx_hi16(lo)),
			 fx_lo16(lo));
}

FX_INLINE struct fx48 fx48_add32(struct fx48 a, int32_t d)
{
	return fx48_add(a, fx48_of32(d));
}

FX_INLINE struct fx48 fx48_neg(struct fx48 a)
{
	return fx48_sub(fx48_make(0, 0), a);
}

FX_INLINE int fx48_lt(struct fx48 a, struct fx48 b)
{
	return a.hi < b.hi || (a.hi == b.hi && a.lo < b.lo);
}

FX_INLINE int fx48_eq(struct fx48 a, struct fx48 b)
{
	return a.hi == b.hi && a.lo == b.lo;
}

FX_INLINE int fx48_is_neg(struct fx48 a)
{
	return a.hi < 0;
}

/* The value as an int32_t, when it fits (hi in -32768..32767). */
FX_INLINE int fx48_fits32(struct fx48 a)
{
	return a.hi >= -32768 && a.hi <= 32767;
}

FX_INLINE int32_t fx48_to32(struct fx48 a)
{
	return fx_int32_of(((uint32_t)a.hi << 16) | a.lo);
}

/* round(v / 2^16), ties away from zero (saturated). */
FX_INLINE int32_t fx48_round(struct fx48 a)
{
	if (a.hi >= 0 ? a.lo >= 0x8000u : a.lo > 0x8000u)
		return a.hi == INT32_MAX ? a.hi : a.hi + 1;
	return a.hi;
}

/* v / 2^n rounded to nearest (ties away from zero), n in 0..63. On the magnitude, in unsigned
 * arithmetic: shifting a negative value right is implementation-defined, and -INT64_MIN
 * overflows. */
static inline int64_t fx_shr_round64(int64_t v, uint8_t n)
{
	uint64_t mag;

	if (n == 0)
		return v;
	if (v >= 0)
		return (int64_t)(((uint64_t)v + ((uint64_t)1 << (n - 1))) >> n);
	mag = (uint64_t)0 - (uint64_t)v;
	mag = (mag + ((uint64_t)1 << (n - 1))) >> n;
	/* mag <= 2^62 + 1 here since n >= 1, so the negation stays in range. */
	return -(int64_t)mag;
}

/* v / 2^n rounded to nearest (ties away from zero), n in 0..31; the same in 32 bits. */
static inline int32_t fx_shr_round(int32_t v, uint8_t n)
{
	uint32_t mag;

	if (n == 0)
		return v;
	if (v >= 0)
		return (int32_t)(((uint32_t)v + ((uint32_t)1 << (n - 1))) >> n);
	mag = (uint32_t)0 - (uint32_t)v;
	mag = (mag + ((uint32_t)1 << (n - 1))) >> n;
	/* mag < 2^31 here since n >= 1. */
	return -(int32_t)mag;
}

/* The same for a count known only at run time: (|v| + 2^(n-1)) / 2^n is (|v| / 2^(n-1) + 1) / 2
 * (both floored), which spares the shift that makes 2^(n-1), and the shift by n - 1 moves whole
 * bytes (fx_shr_u32_var). */
static inline int32_t fx_shr_round_var(int32_t v, uint8_t n)
{
	uint32_t mag;

	if (n == 0)
		return v;
	mag = (fx_shr_u32_var(fx_mag32(v), (uint8_t)(n - 1u)) + 1u) >> 1;
	return v >= 0 ? (int32_t)mag : -(int32_t)mag;
}

/* a * b / 2^n rounded to nearest, computed in 64 bits, saturated to int32. */
static inline int32_t fx_mul_shr(int32_t a, int32_t b, uint8_t n)
{
	return fx_sat32(fx_shr_round64((int64_t)a * b, n));
}

/* num / den rounded to nearest (ties away from zero); den != 0; INT32_MIN / -1 saturates to
 * INT32_MAX. In 32 bits: the magnitudes fit in uint32_t, and the rounding increment only
 * happens for |den| >= 2, where the quotient is at most 2^30. */
static inline int32_t fx_div_round(int32_t num, int32_t den)
{
	uint32_t un = num >= 0 ? (uint32_t)num : (uint32_t)0 - (uint32_t)num;
	uint32_t ud = den >= 0 ? (uint32_t)den : (uint32_t)0 - (uint32_t)den;
	uint32_t q = un / ud;
	uint32_t r = un % ud;

	if (r >= ud - r)
		q++;
	if ((num < 0) != (den < 0))
		return q > (uint32_t)INT32_MAX ? INT32_MIN : -(int32_t)q;
	return q > (uint32_t)INT32_MAX ? INT32_MAX : (int32_t)q;
}

/* num / den rounded to nearest (ties away from zero), 64-bit; den != 0. */
int64_t fx_div_round64(int64_t num, int64_t den);

/* floor(sqrt(v)), of a 64-bit and of a 32-bit value. */
uint32_t fx_isqrt64(uint64_t v);
uint32_t fx_isqrt32(uint32_t v);

/* ceil(sqrt(v)): the floor, one more unless v is a square (the root's remainder is not 0). */
uint32_t fx_isqrt32_up(uint32_t v);

/* sin and cos of a heading, [2^-30], absolute error at most 4 units (about 4e-9). */
void fx_sincos(uint32_t angle_turn32, int32_t *sin_q30, int32_t *cos_q30);

/* sin and cos of a heading to 16 bits [2^-14], error at most 2 units (1.2e-4), exact at the four
 * cardinal headings: a 65-entry table and linear interpolation, for the error model. */
void fx_sincos_q14(uint32_t angle_turn32, int16_t *sin_q14, int16_t *cos_q14);

/* The heading of the vector (x, y), [turn * 2^32]; any common unit for x and y; (0, 0) gives 0.
 * Error at most 2^-20 turn (6e-6 rad). */
uint32_t fx_atan2(int32_t y, int32_t x);

/* Conversions at the edges of the core (protocol units); rounded to nearest. */
uint32_t fx_deg_to_turn32(int32_t deg); /* any int32 degrees, wrapped */

/* A relative angle between two headings, b - a, in -1/2..+1/2 turn. Converting an
 * out-of-range unsigned value to int32_t is implementation-defined, so the upper half is mapped
 * by hand. */
static inline int32_t fx_angle_diff(uint32_t b_turn32, uint32_t a_turn32)
{
	uint32_t d = b_turn32 - a_turn32;

	if (d < FX_HALF_TURN32)
		return (int32_t)d;
	return (int32_t)(d - FX_HALF_TURN32) - INT32_MAX - 1;
}

/* The size of the angle between two headings, |b - a|, in 0..1/2 turn (1/2 turn is 2^31: no
 * negation of INT32_MIN). */
static inline uint32_t fx_angle_dist(uint32_t b_turn32, uint32_t a_turn32)
{
	uint32_t d = b_turn32 - a_turn32;

	return d <= FX_HALF_TURN32 ? d : 0u - d;
}

/* A heading as -18000..18000 [0.01 degree], rounded to nearest. */
static inline int32_t fx_turn32_to_cdeg(uint32_t angle_turn32)
{
	return fx_mul_q(fx_angle_diff(angle_turn32, 0), 36000, 32);
}

#endif
