/* firmware/arch/armv7m's kernels give the reference's bits (firmware/arch/generic/arch_fx.h):
 * they are plain GNU C, so they run here on the host, against the reference this build
 * compiles. The STM32 binary itself is compared with the host build whole in harness/stm32. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>

#include <cmocka.h>

#include "fixmath.h"

#include "../arch/armv7m/arch_isqrt.h"

static uint64_t rng_state = 0x9e3779b97f4a7c15u;

static uint32_t rng_u32(void)
{
	rng_state ^= rng_state << 13;
	rng_state ^= rng_state >> 7;
	rng_state ^= rng_state << 17;
	return (uint32_t)(rng_state >> 16);
}

/* The root and the remainder of v, both ways; 1 when they agree. */
static int same_isqrt(uint32_t v)
{
	uint32_t ref_rem = v, new_rem = v;
	uint32_t ref = fx_isqrt32_rem(&ref_rem);
	uint32_t got = fx_isqrt32_rem_newton(&new_rem);

	if (ref == got && ref_rem == new_rem)
		return 1;
	print_error("v %lu: reference %lu rem %lu, armv7m %lu rem %lu\n", (unsigned long)v,
		    (unsigned long)ref, (unsigned long)ref_rem, (unsigned long)got,
		    (unsigned long)new_rem);
	return 0;
}

static void test_isqrt_small_values(void **state)
{
	(void)state;
	for (uint32_t v = 0; v < ((uint32_t)1 << 20); v++)
		assert_true(same_isqrt(v));
}

/* Where a root changes: k^2 - 1, k^2 and k^2 + 1 for every k, and the top of the range. */
static void test_isqrt_squares(void **state)
{
	(void)state;
	for (uint32_t k = 1; k <= 0xFFFFu; k++) {
		uint32_t sq = k * k;

		assert_true(same_isqrt(sq - 1u));
		assert_true(same_isqrt(sq));
		assert_true(same_isqrt(sq + 1u));
	}
	assert_true(same_isqrt(UINT32_MAX));
	assert_true(same_isqrt(UINT32_MAX - 1u));
}

static void test_isqrt_random(void **state)
{
	(void)state;
	for (uint32_t i = 0; i < 4000000u; i++) {
		uint32_t v = rng_u32();

		assert_true(same_isqrt(v >> (i % 32u))); /* every bit length */
	}
}

/* The 64-bit root both ways (the reference: fixmath.c's fx_isqrt64 of this build); 1 when they
 * agree. */
static int same_isqrt64(uint64_t v)
{
	uint32_t ref = fx_isqrt64(v), got = fx_isqrt64_newton(v);

	if (ref == got)
		return 1;
	print_error("v %llu: reference %lu, armv7m %lu\n", (unsigned long long)v,
		    (unsigned long)ref, (unsigned long)got);
	return 0;
}

/* Squares and their neighbours for roots of every bit length, the extremes, and the values
 * where the kernel's shift and its Newton step change (v's top word 0, 1, 2^30, 2^32 - 1). */
static void test_isqrt64_edges(void **state)
{
	(void)state;
	for (uint32_t bits = 1; bits <= 32; bits++)
		for (int64_t d = -300; d <= 300; d++) {
			uint64_t r = (uint64_t)((bits == 32 ? 0xffffffffu : (1u << bits) - 1u)) +
				     (uint64_t)d;
			uint64_t sq;

			if (r > 0xffffffffu)
				continue;
			sq = r * r;
			assert_true(same_isqrt64(sq));
			assert_true(same_isqrt64(sq + 1u));
			assert_true(same_isqrt64(sq - 1u));
			assert_true(same_isqrt64(sq + 2u * r)); /* the next square less one */
		}
	assert_true(same_isqrt64(0));
	assert_true(same_isqrt64(UINT64_MAX));
	assert_true(same_isqrt64(UINT64_MAX - 1u));
	assert_true(same_isqrt64((uint64_t)1 << 32));
	assert_true(same_isqrt64(((uint64_t)1 << 32) - 1u));
	assert_true(same_isqrt64((uint64_t)1 << 62));
	assert_true(same_isqrt64(((uint64_t)1 << 62) - 1u));
	assert_true(same_isqrt64((uint64_t)1 << 63));
}

static void test_isqrt64_random(void **state)
{
	(void)state;
	for (uint32_t i = 0; i < 3000000u; i++) {
		uint64_t v = ((uint64_t)rng_u32() << 32) | rng_u32();
		uint64_t r = v >> 32;

		assert_true(same_isqrt64(v >> (i % 64u)));              /* every bit length */
		assert_true(same_isqrt64(r * r + (v & 0xffu) - 0x80u)); /* near a square */
	}
}

int main(void)
{
	const struct CMUnitTest tests[] = {
		cmocka_unit_test(test_isqrt_small_values), cmocka_unit_test(test_isqrt_squares),
		cmocka_unit_test(test_isqrt_random),       cmocka_unit_test(test_isqrt64_edges),
		cmocka_unit_test(test_isqrt64_random),
	};

	return cmocka_run_group_tests(tests, NULL, NULL);
}
