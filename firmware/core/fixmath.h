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

/* v / 2^n rounded to nearest (ties away from zero), n in 0..31. */
int32_t fx_shr_round(int32_t v, uint8_t n);

/* v / 2^n rounded to nearest (ties away from zero), n in 0..63. */
int64_t fx_shr_round64(int64_t v, uint8_t n);

/* a * b / 2^n rounded to nearest, computed in 64 bits, saturated to int32. */
int32_t fx_mul_shr(int32_t a, int32_t b, uint8_t n);

/* num / den rounded to nearest (ties away from zero); den != 0. */
int32_t fx_div_round(int32_t num, int32_t den);

/* num / den rounded to nearest (ties away from zero), 64-bit; den != 0. */
int64_t fx_div_round64(int64_t num, int64_t den);

/* Saturate to the type's range. */
int32_t fx_sat32(int64_t v);
int16_t fx_sat16(int32_t v);

/* floor(sqrt(v)). */
uint32_t fx_isqrt64(uint64_t v);

/* sin and cos of a heading, [2^-30], absolute error at most 4 units (about 4e-9). */
void fx_sincos(uint32_t angle_turn32, int32_t *sin_q30, int32_t *cos_q30);

/* The heading of the vector (x, y), [turn * 2^32]; any common unit for x and y; (0, 0) gives 0.
 * Error at most 2^-20 turn (6e-6 rad). */
uint32_t fx_atan2(int32_t y, int32_t x);

/* Conversions at the edges of the core (protocol units); rounded to nearest. */
uint32_t fx_deg_to_turn32(int32_t deg);           /* any int32 degrees, wrapped */
int32_t fx_turn32_to_cdeg(uint32_t angle_turn32); /* -18000..18000 [0.01 degree] */

/* A relative angle between two headings, b - a, in -1/2..+1/2 turn. */
int32_t fx_angle_diff(uint32_t b_turn32, uint32_t a_turn32);

#endif
