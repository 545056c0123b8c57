/* The integer square root for a 32-bit core with a count-leading-zeros instruction and a
 * hardware divide (ARMv7-M: CLZ, UDIV in 2 to 12 cycles): Newton's method from above, where the
 * reference (firmware/arch/generic/arch_fx.h) takes one bit per turn, 16 turns.
 *
 * x0 = 2^ceil(n / 2), n the bit length of v, is at least sqrt(v). From any x at least
 * floor(sqrt(v)), the step (x + floor(v / x)) / 2, floored, is at least floor(sqrt(v)) (the mean
 * of x and v / x is at least sqrt(v), and flooring keeps it at least floor(sqrt(v))), and it is
 * below x while x is above floor(sqrt(v)); so the steps go down and stop at floor(sqrt(v)), the
 * first x whose step does not go lower. From x0 within a factor sqrt(2), 3 to 5 steps.
 * x + v / x stays below 2^18 for every v: x <= 2^16 and v / x <= 2^17.
 *
 * Plain GNU C (__builtin_clz): test_arch_armv7m runs it on the host against the reference, over
 * every v below 2^20, the squares and their neighbours up to 2^32, and random values. */
#ifndef ASSERV_ARCH_ARMV7M_ISQRT_H
#define ASSERV_ARCH_ARMV7M_ISQRT_H

#include <stdint.h>

static inline uint32_t fx_isqrt32_rem_newton(uint32_t *rem)
{
	uint32_t v = *rem, x, y;

	if (v == 0)
		return 0;
	x = (uint32_t)1 << ((33u - (uint32_t)__builtin_clz(v)) >> 1);
	for (;;) {
		y = (x + v / x) >> 1;
		if (y >= x)
			break;
		x = y;
	}
	*rem = v - x * x;
	return x;
}

/* floor(sqrt(v)) of a 64-bit value, where the reference (fixmath.c's fx_isqrt64()) takes a 64-bit
 * division (a library call, dozens of instructions) and 64-bit shifts by variable amounts:
 * - below 2^32, the 32-bit kernel above;
 * - else v shifted left by an even s until its top two bits are not both zero, V = v 4^(s/2):
 *   its top word t in [2^30, 2^32) has the root r1 = floor(sqrt(t)) in [2^15, 2^16), and
 *   R = r1 2^16 is at most sqrt(V), above it by less than 2^16. One Newton step from R,
 *   y = R + floor((V - R^2) / (2 R)), is at least floor(sqrt(V)) (the step's mean is at least
 *   the root, and flooring keeps it at least the floor) and above sqrt(V) by less than
 *   (2^16)^2 / (2 R) <= 1: floor(sqrt(V)) or one more, which the square tells. V - R^2 is
 *   (t - r1^2) 2^32 + V's low word, t - r1^2 <= 2 r1 < 2^17: (V - R^2) / (2 R) is
 *   floor(floor((V - R^2) / 2^17) / r1), a 32-bit division of a 32-bit numerator;
 * - the root of v is then floor(sqrt(V)) / 2^(s/2), floored (the floor of a floor).
 * test_arch_armv7m runs it on the host against the reference: the squares and their
 * neighbours of every bit length, the extremes, random values. */
static inline uint32_t fx_isqrt64_newton(uint64_t v)
{
	uint32_t hi = (uint32_t)(v >> 32), t, r1, rem, s, num, y;
	uint64_t big;

	if (hi == 0) {
		uint32_t lo = (uint32_t)v;

		return fx_isqrt32_rem_newton(&lo);
	}
	s = (uint32_t)__builtin_clz(hi) & ~1u;
	big = v << s;
	t = (uint32_t)(big >> 32);
	rem = t;
	r1 = fx_isqrt32_rem_newton(&rem); /* rem = t - r1^2 */
	num = (rem << 15) | ((uint32_t)big >> 17);
	y = (r1 << 16) + num / r1; /* at most 2^32 - 1 + 1: wraps only there */
	if (y < (r1 << 16) || (uint64_t)y * y > big)
		y--;
	return y >> (s >> 1);
}

#endif
