/* The fixed-point kernels of fixmath.h in plain C99: the reference implementation, and the one
 * every target without an arch folder of its own compiles (the host, the simulator, the
 * Cortex-M4). Each kernel computes exactly what fixmath.h's list says, with the machine's own
 * 64-bit arithmetic where it needs more than 32 bits. Another architecture's kernels must give the
 * same bits: firmware/arch/avr's are checked against these in simavr (test_avr_fixmath). */
#ifndef ASSERV_ARCH_FX_H
#define ASSERV_ARCH_FX_H

#include <stdint.h>

static inline uint32_t fx_mul_u16(uint16_t a, uint16_t b)
{
	return (uint32_t)a * b;
}

static inline int32_t fx_mul_s16(int16_t a, int16_t b)
{
	return (int32_t)a * b;
}

static inline uint32_t fx_shr_u32(uint32_t x, uint8_t n)
{
	return x >> n;
}

static inline uint32_t fx_shl_u32(uint32_t x, uint8_t n)
{
	return x << n;
}

static inline uint8_t fx_bit_length32(uint32_t v)
{
	uint8_t n = 0;

	while (v != 0) {
		v >>= 1;
		n++;
	}
	return n;
}

static inline uint32_t fx_mul_u32_wide(uint32_t a, uint32_t b, uint32_t *lo)
{
	uint64_t p = (uint64_t)a * b;

	*lo = (uint32_t)p;
	return (uint32_t)(p >> 32);
}

static inline int32_t fx_mul_q(int32_t a, int32_t b, uint8_t n)
{
	uint64_t m = (uint64_t)(a >= 0 ? (uint32_t)a : (uint32_t)0 - (uint32_t)a) *
		     (uint32_t)(b >= 0 ? b : -b);
	uint32_t r = (uint32_t)((m + ((uint64_t)1 << (n - 1))) >> n);

	return (a < 0) != (b < 0) ? -(int32_t)r : (int32_t)r;
}

static inline int32_t fx_mul_q20_u16(int32_t v, uint16_t k)
{
	return fx_mul_q(v, k, 20);
}

static inline uint32_t fx_udiv_small(uint32_t num, uint32_t den, uint8_t qbits)
{
	(void)qbits; /* the bound only lets narrower machines stop early */
	return num / den;
}

static inline uint16_t fx_udiv1000(uint32_t u)
{
	return (uint16_t)(u / 1000u);
}

static inline uint32_t fx_udiv_shl16(uint32_t v, uint32_t den)
{
	return (uint32_t)(((uint64_t)v << 16) / den);
}

static inline uint32_t fx_udiv_frac20(uint32_t q, uint32_t rem, uint32_t den)
{
	for (uint8_t i = 0; i < 20; i++) {
		rem <<= 1; /* rem < den <= 2^31: no overflow */
		q <<= 1;
		if (rem >= den) {
			rem -= den;
			q |= 1u;
		}
	}
	return q;
}

#ifdef ARCH_FX_ISQRT32_REM
/* An arch folder's kernel (firmware/arch/armv7m), with the same bits. */
static inline uint32_t fx_isqrt32_rem(uint32_t *rem)
{
	return ARCH_FX_ISQRT32_REM(rem);
}
#else
/* Digit by digit, one step per bit of the root; each step's choice applied through a mask (all
 * ones when the bit belongs to the root) rather than a branch: the choices are as good as random,
 * and a mispredicted branch costs a PC more than the two extra operations. */
static inline uint32_t fx_isqrt32_rem(uint32_t *rem)
{
	uint32_t v = *rem, res = 0;
	uint32_t bit = v < ((uint32_t)1 << 16) ? (uint32_t)1 << 14 : (uint32_t)1 << 30;

	while (bit > v)
		bit >>= 2;
	while (bit != 0) {
		uint32_t t = res + bit;
		uint32_t m = (uint32_t)0 - (uint32_t)(v >= t);

		v -= t & m;
		res = (res >> 1) + (bit & m);
		bit >>= 2;
	}
	*rem = v;
	return res;
}
#endif

static inline uint32_t fx_mul_q31_approx(uint32_t d, uint32_t m)
{
	uint16_t dl = (uint16_t)d, ml = (uint16_t)m;
	uint16_t ll = (uint16_t)((uint16_t)(uint8_t)(dl >> 8) * (uint8_t)(ml >> 8));
	uint32_t mid =
		(((uint32_t)(d >> 16) * ml) >> 1) + (((uint32_t)dl * (m >> 16)) >> 1) + (ll >> 1);

	return (((d >> 16) * (m >> 16)) << 1) + ((mid + 0x2000u) >> 14);
}

static inline void fx_add_u64(uint32_t *lo, uint32_t *hi, const uint32_t d[2])
{
	uint32_t l = *lo;

	*lo = l + d[0];
	*hi += d[1] + (*lo < l);
}

static inline void fx_sub_u64(uint32_t *lo, uint32_t *hi, const uint32_t d[2])
{
	uint32_t l = *lo;

	*lo = l - d[0];
	*hi -= d[1] + (l < d[0]);
}

#endif
