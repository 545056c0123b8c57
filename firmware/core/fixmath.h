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

static inline int16_t fx_sat16(int32_t v)
{
	if (v > INT16_MAX)
		return INT16_MAX;
	if (v < INT16_MIN)
		return INT16_MIN;
	return (int16_t)v;
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

/* floor(sqrt(v)). */
uint32_t fx_isqrt64(uint64_t v);

/* sin and cos of a heading, [2^-30], absolute error at most 4 units (about 4e-9). */
void fx_sincos(uint32_t angle_turn32, int32_t *sin_q30, int32_t *cos_q30);

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

/* A heading as -18000..18000 [0.01 degree], rounded to nearest. */
static inline int32_t fx_turn32_to_cdeg(uint32_t angle_turn32)
{
	int32_t a = fx_angle_diff(angle_turn32, 0);

	return (int32_t)fx_shr_round64((int64_t)a * 36000, 32);
}

#endif
