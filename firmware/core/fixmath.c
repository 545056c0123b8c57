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

/* floor(sqrt(v)) for a 32-bit v: digit-by-digit, shifts and adds only, one step per bit of the
 * root (no multiply, which is slow on the AVR). Each step's choice is applied through a mask
 * (all ones when the bit belongs to the root) rather than a branch: the choices are as good as
 * random, and a mispredicted branch costs a PC more than the two extra operations. */
static uint32_t isqrt32(uint32_t v)
{
	uint32_t res = 0;
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
	return res;
}

uint32_t fx_isqrt64(uint64_t v)
{
	uint64_t r, q;
	uint8_t m = 0;

	if ((v >> 32) == 0)
		return isqrt32((uint32_t)v);
	/* The root of the top bits, then one Newton step: with v / 4^m in [2^30, 2^32), m in
	 * 1..16, r0 = isqrt32(v / 4^m) 2^m is below sqrt(v) by less than 2^m, and the step
	 * (r0 + v / r0) / 2, at least sqrt(v) (the mean of r0 and v / r0), is above it by less
	 * than (2^m)^2 / (2 r0) <= 2^m / 2^16 <= 1: floor(sqrt(v)) or one more. One 64-bit
	 * division instead of 16 more steps of 64-bit shifts. */
	if ((v >> 48) != 0)
		m = 8;
	if ((v >> (2 * m + 40)) != 0)
		m += 4;
	if ((v >> (2 * m + 36)) != 0)
		m += 2;
	if ((v >> (2 * m + 34)) != 0)
		m += 1;
	if ((v >> (2 * m + 32)) != 0)
		m += 1;
	r = (uint64_t)isqrt32((uint32_t)(v >> (2 * m))) << m;
	q = v / r;
	r = (r + q) >> 1;
	if (r > 0xffffffffu)
		r = 0xffffffffu;
	if (r * r > v)
		r--;
	return (uint32_t)r;
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

/* atan(2^-i) [turn * 2^32], the CORDIC rotation angles. */
#define FX_CORDIC_STEPS 10
static const uint32_t cordic_atan_turn32[FX_CORDIC_STEPS] = {
	536870912, 316933406, 167458907, 85004756, 42667331,
	21354465,  10679838,  5340245,   2670163,  1335087,
};

/* 2^32 / (2 pi), turn * 2^32 per rad. */
#define FX_TURN32_PER_RAD 683565276u

/* The angle of (x, y) with x >= y >= 0, x > 0, in 0..1/8 turn [turn * 2^32].
 * CORDIC vectoring in 32 bits (an AVR has no 64-bit registers, and a 64-bit shift by a variable
 * count is a loop over eight bytes there), ten steps, then the residual angle phi from one
 * division, phi = atan(y / x) ~ y / x.
 * Bounds: the larger component is scaled to [2^28, 2^29), so |(x, y)| < 2^29.5; the CORDIC gain
 * (1.647) keeps both components of the rotated vector below 2^30.3, in int32_t.
 * Error: after ten steps |phi| <= atan(2^-9) rad, so |y| <= 2^30.3 * 2^-9 = 2^21.3, and
 * atan(y / x) - y / x is below phi^3 / 3 = 2^-27 / 3 rad, 2 units. The ratio is taken as
 * (|y| 2^10) / (x / 2^12), both in 32 bits (|y| 2^10 < 2^31.3, x / 2^12 >= 2^16), rounded: a
 * ratio in units of 2^-22, within half a unit, 81 units of angle; x / 2^12 drops below 2^-16 of
 * x, which moves phi by under 2^-16 phi, 2 units. Rounding the shifts (half a unit on a vector
 * longer than 2^28) turns it by at most 2^-28 rad per step, under 30 units over ten steps; the
 * table adds 5. In all well within the documented 4096 units (2^-20 turn). */
static uint32_t atan_octant(uint32_t x, uint32_t y)
{
	uint32_t cx, z, my, d, q;
	int32_t cy;
	uint8_t i;

	if (y == 0)
		return 0;
	/* x <= 2^31: at most three halvings; rounding both keeps y <= x. */
	while (x >= ((uint32_t)1 << 29)) {
		x = (x + 1) >> 1;
		y = (y + 1) >> 1;
	}
	/* The left shift that brings x into [2^28, 2^29), found by halves (16, 8, 4, 2, 1). */
	if (x < ((uint32_t)1 << 13)) {
		x <<= 16;
		y <<= 16;
	}
	if (x < ((uint32_t)1 << 21)) {
		x <<= 8;
		y <<= 8;
	}
	if (x < ((uint32_t)1 << 25)) {
		x <<= 4;
		y <<= 4;
	}
	if (x < ((uint32_t)1 << 27)) {
		x <<= 2;
		y <<= 2;
	}
	if (x < ((uint32_t)1 << 28)) {
		x <<= 1;
		y <<= 1;
	}
	/* Step 0 rotates by 1/8 turn; then step i shifts by i. x stays positive (it only grows),
	 * so its shift rounds with a bias; y is shifted as a magnitude (rounded half away from
	 * zero like fx_shr_round) and, whatever its sign, the magnitude is added to x. */
	cx = x + y;
	cy = (int32_t)y - (int32_t)x;
	z = cordic_atan_turn32[0];
	for (i = 1; i < FX_CORDIC_STEPS; i++) {
		uint32_t half = (uint32_t)1 << (i - 1);
		uint32_t sx = (cx + half) >> i;

		my = cy >= 0 ? (uint32_t)cy : (uint32_t)0 - (uint32_t)cy;
		cx += (my + half) >> i;
		if (cy >= 0) {
			cy -= (int32_t)sx;
			z += cordic_atan_turn32[i];
		} else {
			cy += (int32_t)sx;
			z -= cordic_atan_turn32[i];
		}
	}
	/* The residual: phi [2^-22 rad] = round(|y| 2^10 / (x / 2^12)), then to turn * 2^32. */
	my = cy >= 0 ? (uint32_t)cy : (uint32_t)0 - (uint32_t)cy;
	d = (cx + ((uint32_t)1 << 11)) >> 12;
	q = ((my << 10) + (d >> 1)) / d;
	q = (uint32_t)(((uint64_t)q * FX_TURN32_PER_RAD + ((uint64_t)1 << 21)) >> 22);
	return cy >= 0 ? z + q : z - q;
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
