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

#endif
