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
 *
 * The kernels (the products, shifts and divisions that the tick's arithmetic is made of) are
 * declared here once, with what each computes; each architecture defines them in its arch_fx.h,
 * picked by the build's include path: firmware/arch/generic (plain C99, the reference) or
 * firmware/arch/avr. Everything else in this header is built on them, in plain C.
 */
#ifndef ASSERV_FIXMATH_H
#define ASSERV_FIXMATH_H

#include <stdint.h>

#define FX_ONE_Q30 ((int32_t)1 << 30)
#define FX_HALF_TURN32 ((uint32_t)1 << 31)

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

/* The upper 16 bits of a uint32_t, and the lower. */
static inline uint16_t fx_hi16(uint32_t v)
{
	return (uint16_t)(v >> 16);
}

static inline uint16_t fx_lo16(uint32_t v)
{
	return (uint16_t)v;
}

/* A uint32_t that holds an int32_t modulo 2^32, back to int32_t without the
 * implementation-defined conversion of an out-of-range value. */
static inline int32_t fx_int32_of(uint32_t v)
{
	if (v < 0x80000000u)
		return (int32_t)v;
	return (int32_t)(v - 0x80000000u) - INT32_MAX - 1;
}

/* The kernels. Exact (bit for bit the reference's) on their domain; outside it, undefined. */

/* a b, exactly. */
static inline uint32_t fx_mul_u16(uint16_t a, uint16_t b);
static inline int32_t fx_mul_s16(int16_t a, int16_t b);

/* x >> n and x << n (bits shifted out lost), n in 0..31. */
static inline uint32_t fx_shr_u32(uint32_t x, uint8_t n);
static inline uint32_t fx_shl_u32(uint32_t x, uint8_t n);

/* The number of bits of v (0 for 0). */
static inline uint8_t fx_bit_length32(uint32_t v);

/* a b as two 32-bit words: returns the upper one, *lo the lower. */
static inline uint32_t fx_mul_u32_wide(uint32_t a, uint32_t b, uint32_t *lo);

/* round(a b / 2^n) with ties away from zero, for n in 1..47 and |b| <= 65535; the caller knows
 * the result fits in 32 bits. */
static inline int32_t fx_mul_q(int32_t a, int32_t b, uint8_t n);

/* fx_mul_q(v, k, 20): a feed-forward term (control.c). */
static inline int32_t fx_mul_q20_u16(int32_t v, uint16_t k);

/* floor(num / den), den >= 1, for a quotient known to be below 2^qbits (qbits 1..32). */
static inline uint32_t fx_udiv_small(uint32_t num, uint32_t den, uint8_t qbits);

/* floor(u / 1000) for u < 2^25 (micrometres to millimetres). */
static inline uint16_t fx_udiv1000(uint32_t u);

/* floor(v 2^16 / den), den 1..2^31 - 1, for a quotient below 2^32. */
static inline uint32_t fx_udiv_shl16(uint32_t v, uint32_t den);

/* q 2^20 + floor(rem 2^20 / den), for q 0 or 1 and rem < den <= 2^31. */
static inline uint32_t fx_udiv_frac20(uint32_t q, uint32_t rem, uint32_t den);

/* floor(sqrt(v)) for v = *rem; *rem becomes v less the root's square. */
static inline uint32_t fx_isqrt32_rem(uint32_t *rem);

/* round(d m / 2^31) within 0.52, for d < 2^32 and m <= 2^22: 2 (d_hi m_hi) +
 * round((d_hi m_lo / 2 + d_lo m_hi / 2 + (d_lo >> 8)(m_lo >> 8) / 2) / 2^14), each quotient
 * floored, d_hi d_lo and m_hi m_lo the 16-bit halves (fx_sincos's first-order terms). */
static inline uint32_t fx_mul_q31_approx(uint32_t d, uint32_t m);

/* (*lo, *hi) += (d[0], d[1]) and -= it, modulo 2^64 (two 32-bit words, lower first). */
static inline void fx_add_u64(uint32_t *lo, uint32_t *hi, const uint32_t d[2]);
static inline void fx_sub_u64(uint32_t *lo, uint32_t *hi, const uint32_t d[2]);

#include "arch_fx.h"

/* round(a * b / 2^n), halves rounded up, for n in 1..63; the caller knows the result fits in
 * 32 bits. */
static inline uint32_t fx_mul_u32_shr(uint32_t a, uint32_t b, uint8_t n)
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
 * micrometres (floored) in hi, its fraction in lo: six bytes of state where an int64_t takes
 * eight, and 32-bit operations on a machine without 64-bit ones. hi wraps modulo 2^32 (the
 * callers stay within +-2^31 um). */
struct fx48 {
	int32_t hi;
	uint16_t lo;
};

static inline struct fx48 fx48_make(int32_t hi, uint16_t lo)
{
	struct fx48 r;

	r.hi = hi;
	r.lo = lo;
	return r;
}

/* v [2^-16 of the unit] as a 48-bit value (hi = floor(v / 2^16)). */
static inline struct fx48 fx48_of32(int32_t v)
{
	uint16_t h = fx_hi16((uint32_t)v);

	return fx48_make(h < 0x8000u ? (int32_t)h : (int32_t)h - 65536, fx_lo16((uint32_t)v));
}

static inline struct fx48 fx48_add(struct fx48 a, struct fx48 b)
{
	uint32_t lo = (uint32_t)a.lo + b.lo;

	return fx48_make(fx_int32_of((uint32_t)a.hi + (uint32_t)b.hi + fx_hi16(lo)), fx_lo16(lo));
}

static inline struct fx48 fx48_sub(struct fx48 a, struct fx48 b)
{
	uint32_t lo = 0x10000u + a.lo - b.lo;

	return fx48_make(fx_int32_of((uint32_t)a.hi - (uint32_t)b.hi - 1u + fx_hi16(lo)),
			 fx_lo16(lo));
}

static inline struct fx48 fx48_add32(struct fx48 a, int32_t d)
{
	return fx48_add(a, fx48_of32(d));
}

static inline struct fx48 fx48_neg(struct fx48 a)
{
	return fx48_sub(fx48_make(0, 0), a);
}

static inline int fx48_lt(struct fx48 a, struct fx48 b)
{
	return a.hi < b.hi || (a.hi == b.hi && a.lo < b.lo);
}

static inline int fx48_eq(struct fx48 a, struct fx48 b)
{
	return a.hi == b.hi && a.lo == b.lo;
}

static inline int fx48_is_neg(struct fx48 a)
{
	return a.hi < 0;
}

static inline int32_t fx48_to32(struct fx48 a)
{
	return fx_int32_of(((uint32_t)a.hi << 16) | a.lo);
}

/* round(v / 2^16), ties away from zero (saturated). */
static inline int32_t fx48_round(struct fx48 a)
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

/* A duration [ms] as a count of periods at rate_hz, rounded up, at least 1 (configuration time:
 * the modules' durations are given in ms, whatever the rate they run at). */
static inline uint16_t fx_ticks_of_ms(uint16_t ms, uint16_t rate_hz)
{
	uint32_t n = ((uint32_t)ms * rate_hz + 999u) / 1000u;

	return (uint16_t)(n == 0 ? 1u : n > 0xffffu ? 0xffffu : n);
}

/* floor(v / 2^n), n in 0..31, without shifting a negative value (implementation-defined). */
static inline int32_t fx_floor_shr(int32_t v, uint8_t n)
{
	uint32_t u = fx_shr_u32((uint32_t)v, n);

	return fx_int32_of(v < 0 ? u | ~fx_shr_u32(UINT32_MAX, n) : u);
}

/* v / 2^n rounded to nearest (ties away from zero), n in 0..31; the same in 32 bits:
 * (|v| + 2^(n-1)) / 2^n is (|v| / 2^(n-1) + 1) / 2 (both floored), which never overflows. */
static inline int32_t fx_shr_round(int32_t v, uint8_t n)
{
	uint32_t mag;

	if (n == 0)
		return v;
	mag = (fx_shr_u32(fx_mag32(v), (uint8_t)(n - 1u)) + 1u) >> 1;
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
