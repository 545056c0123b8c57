/* Fixed-point arithmetic for the control core (see fixmath.h): integer-only, rounded to nearest,
 * free of implementation-defined behaviour so that an AVR and a PC give the same bits. */
#include "fixmath.h"

/* sin(i * pi / 64) [2^-30], i = 0..32: a quarter wave in 32 steps (132 bytes). The residual
 * angle after picking the nearest entry is at most pi/128 rad, so a Taylor correction up to d^4
 * is enough for the documented 4 units (d^5/120 is below 0.1 unit). */
static const int32_t sin_table_q30[33] = {
	0,          52686014,   105245103,  157550647,  209476638,  260897982,  311690799,
	361732726,  410903207,  459083786,  506158392,  552013618,  596538995,  639627258,
	681174602,  721080937,  759250125,  795590213,  830013654,  862437520,  892783698,
	920979082,  946955747,  970651112,  992008094,  1010975242, 1027506862, 1041563127,
	1053110176, 1062120190, 1068571464, 1072448455, 1073741824,
};

/* atan(2^-i) [turn * 2^32], the CORDIC rotation angles. */
#define FX_CORDIC_STEPS 22
static const uint32_t cordic_atan_turn32[FX_CORDIC_STEPS] = {
	536870912, 316933406, 167458907, 85004756, 42667331, 21354465, 10679838, 5340245,
	2670163,   1335087,   667544,    333772,   166886,   83443,    41722,    20861,
	10430,     5215,      2608,      1304,     652,      326,
};

int32_t fx_shr_round(int32_t v, uint8_t n)
{
	return (int32_t)fx_shr_round64(v, n);
}

int64_t fx_shr_round64(int64_t v, uint8_t n)
{
	uint64_t mag;

	if (n == 0)
		return v;
	/* Work on the magnitude in unsigned arithmetic: shifting a negative value right is
	 * implementation-defined, and -INT64_MIN overflows. */
	if (v >= 0) {
		mag = (uint64_t)v;
		return (int64_t)((mag + ((uint64_t)1 << (n - 1))) >> n);
	}
	mag = (uint64_t)0 - (uint64_t)v;
	mag = (mag + ((uint64_t)1 << (n - 1))) >> n;
	/* mag <= 2^62 + 1 here since n >= 1, so the negation stays in range. */
	return -(int64_t)mag;
}

int32_t fx_mul_shr(int32_t a, int32_t b, uint8_t n)
{
	return fx_sat32(fx_shr_round64((int64_t)a * b, n));
}

int32_t fx_div_round(int32_t num, int32_t den)
{
	/* In 64 bits, INT32_MIN / -1 is representable; the result is then saturated. */
	return fx_sat32(fx_div_round64(num, den));
}

int64_t fx_div_round64(int64_t num, int64_t den)
{
	uint64_t un = num >= 0 ? (uint64_t)num : (uint64_t)0 - (uint64_t)num;
	uint64_t ud = den >= 0 ? (uint64_t)den : (uint64_t)0 - (uint64_t)den;
	uint64_t q = un / ud;
	uint64_t r = un % ud;

	if (r >= ud - r)
		q++;
	if ((num < 0) != (den < 0)) {
		if (q > (uint64_t)INT64_MAX)
			return INT64_MIN;
		return -(int64_t)q;
	}
	if (q > (uint64_t)INT64_MAX)
		return INT64_MAX;
	return (int64_t)q;
}

int32_t fx_sat32(int64_t v)
{
	if (v > INT32_MAX)
		return INT32_MAX;
	if (v < INT32_MIN)
		return INT32_MIN;
	return (int32_t)v;
}

int16_t fx_sat16(int32_t v)
{
	if (v > INT16_MAX)
		return INT16_MAX;
	if (v < INT16_MIN)
		return INT16_MIN;
	return (int16_t)v;
}

uint32_t fx_isqrt64(uint64_t v)
{
	/* Digit-by-digit method: shifts and adds only, 32 fixed iterations (no multiply, which
	 * is slow on the AVR). */
	uint64_t res = 0;
	uint64_t bit = (uint64_t)1 << 62;

	while (bit > v)
		bit >>= 2;
	while (bit != 0) {
		if (v >= res + bit) {
			v -= res + bit;
			res = (res >> 1) + bit;
		} else {
			res >>= 1;
		}
		bit >>= 2;
	}
	return (uint32_t)res;
}

void fx_sincos(uint32_t angle_turn32, int32_t *sin_q30, int32_t *cos_q30)
{
	uint32_t quadrant = angle_turn32 >> 30;
	uint32_t u = angle_turn32 & 0x3fffffffu;
	/* Nearest table entry: step 2^25 turn32, so the residual is within +/-2^24. */
	uint32_t i = (u + ((uint32_t)1 << 24)) >> 25;
	int32_t r = (int32_t)u - (int32_t)(i << 25);
	int64_t d, d2, d3, d4, sin_d, cos_d_m1, s_corr, c_corr;
	int32_t sa = sin_table_q30[i];
	int32_t ca = sin_table_q30[32 - i];
	int32_t s, c;

	/* d = r * 2 pi / 2^32 [rad * 2^36]: |d| <= pi/128 * 2^36 < 2^31. 6746518852 is
	 * 2 pi * 2^30, so r * it / 2^26 gives the Q36 angle. */
	d = fx_shr_round64((int64_t)r * 6746518852LL, 26);
	d2 = fx_shr_round64(d * d, 36);
	d3 = fx_shr_round64(d2 * d, 36);
	d4 = fx_shr_round64(d2 * d2, 36);
	/* sin d = d - d^3/6, cos d - 1 = -d^2/2 + d^4/24 [2^-36]; 715827883 = 2^32/6 and
	 * 178956971 = 2^32/24, multiplying rather than dividing. */
	sin_d = d - fx_shr_round64(d3 * 715827883LL, 32);
	cos_d_m1 = fx_shr_round64(d4 * 178956971LL, 32) - fx_shr_round64(d2, 1);
	/* sin(a + d) = sin a + sin a (cos d - 1) + cos a sin d, the small terms summed in
	 * [2^-66] and rounded once. */
	s_corr = fx_shr_round64((int64_t)sa * cos_d_m1 + (int64_t)ca * sin_d, 36);
	c_corr = fx_shr_round64((int64_t)ca * cos_d_m1 - (int64_t)sa * sin_d, 36);
	s = fx_sat32(sa + s_corr);
	c = fx_sat32(ca + c_corr);
	if (s > FX_ONE_Q30)
		s = FX_ONE_Q30;
	if (c > FX_ONE_Q30)
		c = FX_ONE_Q30;

	switch (quadrant) {
	case 0:
		*sin_q30 = s;
		*cos_q30 = c;
		break;
	case 1:
		*sin_q30 = c;
		*cos_q30 = -s;
		break;
	case 2:
		*sin_q30 = -s;
		*cos_q30 = -c;
		break;
	default:
		*sin_q30 = -c;
		*cos_q30 = s;
		break;
	}
}

/* The angle of (x, y) with x >= y >= 0, x > 0, in 0..1/8 turn [turn * 2^32]. */
static uint32_t atan_octant(uint32_t x, uint32_t y)
{
	uint8_t len = 0;
	int64_t cx, cy;
	uint32_t z = 0;
	uint8_t i;

	if (y == 0)
		return 0;
	/* Scale the larger component to [2^40, 2^41) so that the shifts below lose nothing that
	 * matters whatever the size of the inputs. */
	while ((x >> len) > 1)
		len++;
	cx = (int64_t)x * ((int64_t)1 << (40 - len));
	cy = (int64_t)y * ((int64_t)1 << (40 - len));
	/* CORDIC vectoring: after 22 steps the residual angle is below atan(2^-21) rad, 326
	 * units, well within the documented 4096 units (2^-20 turn). */
	for (i = 0; i < FX_CORDIC_STEPS; i++) {
		int64_t sx = fx_shr_round64(cx, i);
		int64_t sy = fx_shr_round64(cy, i);

		if (cy >= 0) {
			cx += sy;
			cy -= sx;
			z += cordic_atan_turn32[i];
		} else {
			cx -= sy;
			cy += sx;
			z -= cordic_atan_turn32[i];
		}
	}
	return z;
}

uint32_t fx_atan2(int32_t y, int32_t x)
{
	uint32_t ax = x >= 0 ? (uint32_t)x : (uint32_t)0 - (uint32_t)x;
	uint32_t ay = y >= 0 ? (uint32_t)y : (uint32_t)0 - (uint32_t)y;
	uint32_t a;

	if (ax == 0 && ay == 0)
		return 0;
	if (ay > ax)
		a = ((uint32_t)1 << 30) - atan_octant(ay, ax);
	else
		a = atan_octant(ax, ay);
	if (x < 0)
		a = FX_HALF_TURN32 - a;
	if (y < 0)
		a = (uint32_t)0 - a;
	return a;
}

uint32_t fx_deg_to_turn32(int32_t deg)
{
	int32_t r = deg % 360;

	if (r < 0)
		r += 360;
	/* r * 2^32 / 360 = r * 2^29 / 45, rounded; 45 is odd so there is never a tie. */
	return (uint32_t)((((uint64_t)r << 29) + 22) / 45);
}

int32_t fx_turn32_to_cdeg(uint32_t angle_turn32)
{
	int32_t a = fx_angle_diff(angle_turn32, 0);

	return (int32_t)fx_shr_round64((int64_t)a * 36000, 32);
}

int32_t fx_angle_diff(uint32_t b_turn32, uint32_t a_turn32)
{
	uint32_t d = b_turn32 - a_turn32;

	/* Converting an out-of-range unsigned value to int32_t is implementation-defined, so
	 * the upper half is mapped by hand. */
	if (d < FX_HALF_TURN32)
		return (int32_t)d;
	return (int32_t)(d - FX_HALF_TURN32) - INT32_MAX - 1;
}
