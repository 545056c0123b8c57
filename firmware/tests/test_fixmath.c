/* The fixed-point helpers (fixmath.c) against exact integer references, libm's double sin, cos
 * and atan2, and a long double Taylor series on an exactly reduced argument (about 1e-19
 * accurate) used for the dense sweeps. */
#include <math.h>
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>

#include <cmocka.h>

#include "fixmath.h"

#define N_OF(a) (sizeof(a) / sizeof((a)[0]))
#define PI_L 3.14159265358979323846264338327950288L

static uint64_t rng_state = 0x243f6a8885a308d3u;

/* xorshift64: deterministic test inputs. */
static uint64_t rng_next(void)
{
	rng_state ^= rng_state << 13;
	rng_state ^= rng_state >> 7;
	rng_state ^= rng_state << 17;
	return rng_state;
}

static int32_t rng_i32(void)
{
	uint32_t u = (uint32_t)rng_next();

	return u < 0x80000000u ? (int32_t)u : (int32_t)(u - 0x80000000u) - INT32_MAX - 1;
}

/* sin and cos of t rad, |t| <= pi/4, by their Taylor series. */
static void ref_sincos_small(long double t, long double *s, long double *c)
{
	long double term_s = t, term_c = 1.0L, sum_s = 0.0L, sum_c = 0.0L;

	for (int k = 0; k < 20; k++) {
		sum_s += term_s;
		sum_c += term_c;
		term_s *= -t * t / ((2 * k + 2) * (2 * k + 3));
		term_c *= -t * t / ((2 * k + 1) * (2 * k + 2));
	}
	*s = sum_s;
	*c = sum_c;
}

/* sin and cos of a turn32 heading; the reduction to +/- 1/8 turn is done on the integer. */
static void ref_sincos(uint32_t a, long double *s, long double *c)
{
	uint32_t q = (a + (1u << 29)) >> 30;
	int64_t r = (int64_t)a - (int64_t)q * (1ll << 30);
	long double t = (long double)r * 2.0L * PI_L / 4294967296.0L;
	long double s0, c0;

	ref_sincos_small(t, &s0, &c0);
	switch (q & 3) {
	case 0:
		*s = s0;
		*c = c0;
		break;
	case 1:
		*s = c0;
		*c = -s0;
		break;
	case 2:
		*s = -s0;
		*c = -c0;
		break;
	default:
		*s = -c0;
		*c = s0;
		break;
	}
}

static long double absl(long double v)
{
	return v < 0 ? -v : v;
}

/* v / 2^n rounded half away from zero, from C's truncating division (exact in int64). */
/* floor(v / 2^n), by division (C99 rounds towards zero). */
static int32_t ref_floor_shr(int32_t v, unsigned n)
{
	int64_t d = (int64_t)1 << n, q = (int64_t)v / d;

	return (int32_t)(q * d > v ? q - 1 : q);
}

static int64_t ref_shr_round(int64_t v, unsigned n)
{
	int64_t p, q, r;

	if (n == 63)
		return v >= (1ll << 62) ? 1 : (v <= -(1ll << 62) ? -1 : 0);
	p = (int64_t)1 << n;
	q = v / p;
	r = v % p;
	if (r >= 0 && r >= p - r)
		q++;
	if (r < 0 && -r >= p + r)
		q--;
	return q;
}

static void test_shr_round_ties_and_signs(void **state)
{
	(void)state;
	assert_int_equal(fx_shr_round(5, 1), 3);
	assert_int_equal(fx_shr_round(-5, 1), -3);
	assert_int_equal(fx_shr_round(3, 1), 2);
	assert_int_equal(fx_shr_round(-3, 1), -2);
	assert_int_equal(fx_shr_round(6, 2), 2);
	assert_int_equal(fx_shr_round(-6, 2), -2);
	assert_int_equal(fx_shr_round(5, 2), 1);
	assert_int_equal(fx_shr_round(-5, 2), -1);
	assert_int_equal(fx_shr_round(7, 0), 7);
	assert_int_equal(fx_shr_round(INT32_MIN, 0), INT32_MIN);
	assert_int_equal(fx_shr_round(INT32_MIN, 31), -1);
	assert_int_equal(fx_shr_round(INT32_MAX, 31), 1);
	assert_int_equal(fx_shr_round(INT32_MIN, 1), INT32_MIN / 2);
	assert_int_equal(fx_shr_round(INT32_MAX, 1), 1 << 30);
	assert_true(fx_shr_round64(INT64_MIN, 63) == -1);
	assert_true(fx_shr_round64(INT64_MAX, 63) == 1);
	assert_true(fx_shr_round64(INT64_MIN, 1) == INT64_MIN / 2);
	assert_true(fx_shr_round64(INT64_MAX, 1) == ((int64_t)1 << 62));
	assert_true(fx_shr_round64(-(3ll << 40), 41) == -2);
	for (int i = 0; i < 100000; i++) {
		int64_t v = (int64_t)(rng_next() >> (rng_next() & 63));
		unsigned n = (unsigned)(rng_next() % 64);
		int32_t v32 = rng_i32();
		unsigned n32 = (unsigned)(rng_next() % 32);

		if (rng_next() & 1)
			v = -v;
		assert_true(fx_shr_round64(v, (uint8_t)n) == ref_shr_round(v, n));
		assert_true(fx_shr_round(v32, (uint8_t)n32) == ref_shr_round(v32, n32));
		assert_true(fx_floor_shr(v32, (uint8_t)n32) == ref_floor_shr(v32, n32));
	}
	for (uint8_t n = 0; n < 32; n++) {
		static const int32_t edges[] = {INT32_MIN, INT32_MIN + 1, -3,       -2, -1, 0, 1, 2,
						3,         INT32_MAX - 1, INT32_MAX};

		for (size_t i = 0; i < N_OF(edges); i++)
			assert_true(fx_shr_round(edges[i], n) == ref_shr_round(edges[i], n) &&
				    fx_floor_shr(edges[i], n) == ref_floor_shr(edges[i], n));
	}
}

static void test_mul_shr_rounds_and_saturates(void **state)
{
	(void)state;
	assert_int_equal(fx_mul_shr(3, 5, 1), 8);
	assert_int_equal(fx_mul_shr(-3, 5, 1), -8);
	assert_int_equal(fx_mul_shr(3, -5, 2), -4);
	assert_int_equal(fx_mul_shr(1 << 30, 1 << 30, 30), 1 << 30);
	assert_int_equal(fx_mul_shr(INT32_MAX, INT32_MAX, 0), INT32_MAX);
	assert_int_equal(fx_mul_shr(INT32_MIN, INT32_MAX, 0), INT32_MIN);
	assert_int_equal(fx_mul_shr(INT32_MIN, INT32_MIN, 62), 1);
	assert_int_equal(fx_mul_shr(INT32_MIN, INT32_MIN, 32), 1 << 30);
	assert_int_equal(fx_sat32((int64_t)INT32_MAX + 1), INT32_MAX);
	assert_int_equal(fx_sat32((int64_t)INT32_MIN - 1), INT32_MIN);
	assert_int_equal(fx_sat32(-12345), -12345);
	assert_int_equal(fx_sat16(40000), INT16_MAX);
	assert_int_equal(fx_sat16(-40000), INT16_MIN);
	assert_int_equal(fx_sat16(-32768), -32768);
}

static void test_div_round(void **state)
{
	(void)state;
	assert_int_equal(fx_div_round(7, 2), 4);
	assert_int_equal(fx_div_round(-7, 2), -4);
	assert_int_equal(fx_div_round(7, -2), -4);
	assert_int_equal(fx_div_round(-7, -2), 4);
	assert_int_equal(fx_div_round(5, 3), 2);
	assert_int_equal(fx_div_round(4, 3), 1);
	assert_int_equal(fx_div_round(-5, 3), -2);
	assert_int_equal(fx_div_round(-4, 3), -1);
	assert_int_equal(fx_div_round(0, -3), 0);
	assert_int_equal(fx_div_round(INT32_MIN, -1), INT32_MAX);
	assert_int_equal(fx_div_round(INT32_MIN, 1), INT32_MIN);
	assert_int_equal(fx_div_round(INT32_MAX, INT32_MIN), -1);
	assert_true(fx_div_round64(INT64_MIN, -1) == INT64_MAX);
	assert_true(fx_div_round64(INT64_MIN, 1) == INT64_MIN);
	assert_true(fx_div_round64(INT64_MIN, 2) == INT64_MIN / 2);
	assert_true(fx_div_round64(INT64_MAX, INT64_MIN) == -1);
	assert_true(fx_div_round64(-15, 10) == -2);
	assert_true(fx_div_round64(-14, 10) == -1);
	for (int i = 0; i < 100000; i++) {
		int32_t num = rng_i32() / ((int32_t)1 << (rng_next() % 31));
		int32_t den = rng_i32() / ((int32_t)1 << (rng_next() % 31));
		int64_t q, twice_r;

		if (den == 0)
			continue;
		q = fx_div_round(num, den);
		/* |num - q den| <= |den| / 2, ties away from zero. */
		twice_r = 2 * ((int64_t)num - q * den);
		if (twice_r < 0)
			twice_r = -twice_r;
		assert_true(twice_r <= (den < 0 ? -(int64_t)den : den));
	}
}

static void check_isqrt(uint64_t v)
{
	uint64_t r = fx_isqrt64(v);

	assert_true(r * r <= v);
	if (r < 0xffffffffu)
		assert_true((r + 1) * (r + 1) > v);
}

/* round(a b / 2^n), ties away from zero, from the definition in 64 bits. */
static int32_t ref_mul_q(int32_t a, int32_t b, unsigned n)
{
	int64_t p = (int64_t)a * b;
	uint64_t m = p >= 0 ? (uint64_t)p : (uint64_t)0 - (uint64_t)p;
	int64_t r = (int64_t)((m + ((uint64_t)1 << (n - 1))) >> n);

	return (int32_t)(p >= 0 ? r : -r);
}

/* The kernels (fixmath.h's list, arch_fx.h of the build) against their definitions, computed
 * here in 64 bits, on random operands and on the edges. test_avr_fixmath checks that the AVR's
 * kernels give these same bits. */
static void test_kernels_match_their_definitions(void **state)
{
	static const uint32_t edges[] = {0,           1,           2,          0x7fff,
					 0x8000,      0xffff,      0x10000,    0x7fffffff,
					 0x80000000u, 0xfffffffeu, 0xffffffffu};

	(void)state;
	for (int i = 0; i < 400000; i++) {
		uint32_t a = i < 121 ? edges[i / 11] : (uint32_t)rng_next() >> (rng_next() & 31);
		uint32_t b = i < 121 ? edges[i % 11] : (uint32_t)rng_next() >> (rng_next() & 31);
		uint8_t n = (uint8_t)(rng_next() % 32);
		uint32_t lo;
		uint64_t p = (uint64_t)a * b;

		assert_true(fx_mul_u32_wide(a, b, &lo) == (uint32_t)(p >> 32) && lo == (uint32_t)p);
		assert_true(fx_mul_u16((uint16_t)a, (uint16_t)b) ==
			    (uint32_t)(uint16_t)a * (uint16_t)b);
		assert_true(fx_mul_s16((int16_t)(uint16_t)a, (int16_t)(uint16_t)b) ==
			    (int32_t)(int16_t)(uint16_t)a * (int16_t)(uint16_t)b);
		assert_true(fx_shr_u32(a, n) == a >> n);
		assert_true(fx_shl_u32(a, n) == (uint32_t)(a << n));
		{
			uint8_t len = 0;

			while (len < 32 && (a >> len) != 0)
				len++;
			assert_int_equal(fx_bit_length32(a), len);
		}
		{
			/* fx_mul_q: |b| <= 65535, n in 1..47, the result fitting 32 bits. */
			int32_t sa = (int32_t)(a >> 1) * (rng_next() & 1 ? 1 : -1);
			int32_t sb = (int32_t)(b & 0xffff) * (rng_next() & 1 ? 1 : -1);
			uint8_t q = (uint8_t)(16 + rng_next() % 32);

			assert_true(fx_mul_q(sa, sb, q) == ref_mul_q(sa, sb, q));
			assert_true(fx_mul_q20_u16(sa, (uint16_t)(b & 0xffff)) ==
				    ref_mul_q(sa, (int32_t)(b & 0xffff), 20));
			q = (uint8_t)(1 + rng_next() % 15);
			sa /= 65536;
			assert_true(fx_mul_q(sa, sb, q) == ref_mul_q(sa, sb, q));
		}
		if (b != 0) {
			uint32_t quot = a / b;
			uint8_t bits = 0;

			while (bits < 32 && (quot >> bits) != 0)
				bits++;
			bits = (uint8_t)(bits + rng_next() % (33 - bits));
			if (bits == 0)
				bits = 1;
			assert_true(fx_udiv_small(a, b, bits) == quot);
		}
		assert_true(fx_udiv1000(a >> 7) == (a >> 7) / 1000u);
		if (b != 0 && b <= 0x80000000u) {
			uint32_t rem = a % b, q1 = rng_next() & 1;

			assert_true(fx_udiv_frac20(q1, rem, b) ==
				    (q1 << 20) + (uint32_t)(((uint64_t)rem << 20) / b));
		}
		{
			uint32_t h[2] = {a, b}, d[2] = {(uint32_t)rng_next(), (uint32_t)rng_next()};
			uint64_t hv = (uint64_t)b << 32 | a, dv = (uint64_t)d[1] << 32 | d[0];

			fx_add_u64(&h[0], &h[1], d);
			assert_true(((uint64_t)h[1] << 32 | h[0]) == hv + dv);
			fx_sub_u64(&h[0], &h[1], d);
			fx_sub_u64(&h[0], &h[1], d);
			assert_true(((uint64_t)h[1] << 32 | h[0]) == hv - dv);
		}
		{
			/* within 0.52 of d m / 2^31, for m <= 2^22 */
			uint32_t m = b >> 10;
			double exact = (double)a * m / 2147483648.0;
			double got = fx_mul_q31_approx(a, m);

			assert_true(got - exact <= 0.52 && exact - got <= 0.52);
		}
		{
			uint32_t v = a, r = fx_isqrt32_rem(&v);

			assert_true((uint64_t)r * r <= a && ((uint64_t)r + 1) * (r + 1) > a);
			assert_true(v == a - r * r);
		}
	}
}

/* floor(v 2^16 / den) for den below 2^31 and a quotient below 2^32, against the 64-bit
 * division. */
static void test_udiv_shl16(void **state)
{
	static const uint32_t edges[] = {1,         2,          3,          999,       1000,
					 65535,     65536,      65537,      4000000,   0xffffff,
					 0x1000000, 0x7ffffffe, 0x7fffffff, 0xffffffff};

	(void)state;
	for (int i = 0; i < 400000; i++) {
		uint32_t v = i < 196 ? edges[i / 14] : (uint32_t)rng_next() >> (rng_next() & 31);
		uint32_t den =
			i < 196 ? edges[i % 14] : (uint32_t)rng_next() >> (1 + rng_next() % 31);
		uint64_t want;

		if (den == 0 || den > 0x7fffffffu || (v >> 16) >= den)
			continue; /* outside the domain: den 1..2^31 - 1, v / den below 2^16 */
		want = ((uint64_t)v << 16) / den;
		assert_true(fx_udiv_shl16(v, den) == want);
	}
}

/* A duration in ms as periods at a rate: ceil(ms rate / 1000), at least 1, at most 65535, on
 * random durations and rates and on the edges. */
static void test_ticks_of_ms(void **state)
{
	(void)state;
	for (int i = 0; i < 100000; i++) {
		uint16_t ms = (uint16_t)(i < 4 ? (uint32_t[]){0, 1, 999, 65535}[i] : rng_next());
		uint16_t hz = (uint16_t)(i < 4 ? 1000u : 1u + rng_next() % 65535u);
		uint64_t want = ((uint64_t)ms * hz + 999u) / 1000u;

		want = want == 0 ? 1 : want > 0xffffu ? 0xffffu : want;
		assert_int_equal(fx_ticks_of_ms(ms, hz), want);
	}
	assert_int_equal(fx_ticks_of_ms(20, 125), 3); /* the settle time at the AVR's 125 Hz */
	assert_int_equal(fx_ticks_of_ms(128, 125), 16);
}

static void test_isqrt_edges(void **state)
{
	(void)state;
	assert_int_equal(fx_isqrt64(0), 0);
	assert_int_equal(fx_isqrt64(1), 1);
	assert_int_equal(fx_isqrt64(2), 1);
	assert_int_equal(fx_isqrt64(3), 1);
	assert_int_equal(fx_isqrt64(4), 2);
	assert_int_equal(fx_isqrt64(UINT64_MAX), 0xffffffffu);
	assert_int_equal(fx_isqrt64(0xfffffffe00000001u), 0xffffffffu);
	assert_int_equal(fx_isqrt64(0xfffffffe00000000u), 0xfffffffeu);
	assert_int_equal(fx_isqrt64((uint64_t)1 << 62), 1u << 31);
	for (uint64_t k = 1; k < 0x100000000u; k = k * 3 + 1) {
		assert_true(fx_isqrt64(k * k) == k);
		assert_true(fx_isqrt64(k * k - 1) == k - 1);
		if (k < 0xffffffffu)
			assert_true(fx_isqrt64(k * k + 2 * k) == k);
	}
	for (int i = 0; i < 100000; i++)
		check_isqrt(rng_next() >> (rng_next() & 63));
	/* The 32-bit root on its own (the AVR's is in assembly: test_avr_fixmath). */
	assert_int_equal(fx_isqrt32(0), 0);
	assert_int_equal(fx_isqrt32(0xffffffffu), 0xffffu);
	for (uint32_t k = 1; k < 0x10000u; k++) {
		assert_true(fx_isqrt32(k * k) == k);
		assert_true(fx_isqrt32(k * k - 1) == k - 1);
		assert_true(fx_isqrt32(k * k + 2 * k) == k);
	}
	/* Rounded up: the root of a square, one more for anything else. */
	assert_int_equal(fx_isqrt32_up(0), 0);
	assert_int_equal(fx_isqrt32_up(0xffffffffu), 0x10000u);
	for (uint32_t k = 1; k < 0x10000u; k++) {
		assert_true(fx_isqrt32_up(k * k) == k);
		assert_true(k == 1 || fx_isqrt32_up(k * k - 1) == k);
		assert_true(fx_isqrt32_up(k * k + 1) == k + 1);
		assert_true(fx_isqrt32_up(k * k + 2 * k) == k + 1);
	}
	for (int i = 0; i < 100000; i++) {
		uint32_t v = (uint32_t)rng_next() >> (rng_next() & 31);
		uint64_t r = fx_isqrt32_up(v);

		assert_true(r * r >= v && (r == 0 || (r - 1) * (r - 1) < v));
	}
}

static int64_t sincos_max_error;

static void check_sincos(uint32_t a)
{
	int32_t s, c;
	long double rs, rc, es, ec;

	fx_sincos(a, &s, &c);
	ref_sincos(a, &rs, &rc);
	es = absl((long double)s - rs * 1073741824.0L);
	ec = absl((long double)c - rc * 1073741824.0L);
	if (es > sincos_max_error)
		sincos_max_error = (int64_t)es + 1;
	if (ec > sincos_max_error)
		sincos_max_error = (int64_t)ec + 1;
	assert_true(es <= 4.0L);
	assert_true(ec <= 4.0L);
	assert_true(s >= -FX_ONE_Q30 && s <= FX_ONE_Q30);
	assert_true(c >= -FX_ONE_Q30 && c <= FX_ONE_Q30);
}

static void test_sincos_against_reference(void **state)
{
	int32_t s, c;

	(void)state;
	fx_sincos(0, &s, &c);
	assert_int_equal(s, 0);
	assert_int_equal(c, FX_ONE_Q30);
	fx_sincos(1u << 30, &s, &c);
	assert_int_equal(s, FX_ONE_Q30);
	assert_int_equal(c, 0);
	fx_sincos(FX_HALF_TURN32, &s, &c);
	assert_int_equal(s, 0);
	assert_int_equal(c, -FX_ONE_Q30);
	fx_sincos(3u << 30, &s, &c);
	assert_int_equal(s, -FX_ONE_Q30);
	assert_int_equal(c, 0);
	/* Every table entry, its neighbours and the midpoints between entries (largest
	 * residual), in all four quadrants. */
	for (uint32_t k = 0; k < 128; k++) {
		uint32_t base = k << 25;

		for (int32_t off = -3; off <= 3; off++)
			check_sincos(base + (uint32_t)off);
		check_sincos(base + (1u << 24));
		check_sincos(base + (1u << 24) - 1);
		check_sincos(base - (1u << 24));
	}
	/* A dense sweep (step prime to the table step) and random angles. */
	for (uint32_t a = 7; a < 0xffff0000u; a += 4093u * 1021u)
		check_sincos(a);
	for (int i = 0; i < 200000; i++)
		check_sincos((uint32_t)rng_next());
	print_message("sincos max error %lld units of 2^-30\n", (long long)sincos_max_error);
}

/* fx_atan2(y, x) is within 2^-20 turn of the true heading: the cross product of (x, y) with the
 * returned direction is at most sin(2^-20 turn) |(x, y)|, and the dot product is positive. */
static void check_atan2(int32_t y, int32_t x)
{
	uint32_t a = fx_atan2(y, x);
	long double s, c, cross, dot, tol;

	ref_sincos(a, &s, &c);
	cross = (long double)y * c - (long double)x * s;
	dot = (long double)x * c + (long double)y * s;
	tol = 2.0L * PI_L / 1048576.0L;
	assert_true(dot > 0);
	assert_true(cross * cross <= tol * tol * ((long double)x * x + (long double)y * y));
}

static void test_atan2_octants_and_edges(void **state)
{
	(void)state;
	assert_int_equal(fx_atan2(0, 0), 0);
	assert_int_equal(fx_atan2(0, 1), 0);
	assert_int_equal(fx_atan2(0, 12345), 0);
	assert_int_equal(fx_atan2(1, 0), 1u << 30);
	assert_int_equal(fx_atan2(0, -1), FX_HALF_TURN32);
	assert_int_equal(fx_atan2(-1, 0), 3u << 30);
	assert_int_equal(fx_atan2(INT32_MIN, 0), 3u << 30);
	assert_int_equal(fx_atan2(0, INT32_MIN), FX_HALF_TURN32);
	assert_true(fx_angle_diff(fx_atan2(1, 1), 1u << 29) <= 4096);
	assert_true(fx_angle_diff(fx_atan2(1, 1), 1u << 29) >= -4096);
	check_atan2(INT32_MIN, INT32_MIN);
	check_atan2(INT32_MAX, INT32_MIN);
	check_atan2(INT32_MIN, INT32_MAX);
	check_atan2(1, INT32_MAX);
	check_atan2(-1, INT32_MIN);
	check_atan2(INT32_MAX, -1);
	for (int32_t y = -20; y <= 20; y++)
		for (int32_t x = -20; x <= 20; x++)
			if (x != 0 || y != 0)
				check_atan2(y, x);
	/* Vectors of every size pointing every way, built from the reference sin/cos. */
	for (int i = 0; i < 200000; i++) {
		uint32_t a = (uint32_t)rng_next();
		long double r = (long double)(rng_next() >> (33 + rng_next() % 31)) + 1.0L;
		long double s, c;
		int32_t x, y;

		ref_sincos(a, &s, &c);
		x = (int32_t)(r * c);
		y = (int32_t)(r * s);
		if (x != 0 || y != 0)
			check_atan2(y, x);
		check_atan2(rng_i32(), rng_i32());
	}
	/* Round trip through fx_sincos at full scale. */
	for (int i = 0; i < 100000; i++) {
		uint32_t a = (uint32_t)rng_next();
		int32_t s, c, d;

		fx_sincos(a, &s, &c);
		d = fx_angle_diff(fx_atan2(s, c), a);
		assert_true(d >= -4096 && d <= 4096);
	}
}

/* The same accuracy claims against libm in double. */
static void test_against_libm(void **state)
{
	(void)state;
	for (int i = 0; i < 200000; i++) {
		uint32_t a = (uint32_t)rng_next();
		double rad = (double)a * (2.0 * (double)PI_L / 4294967296.0);
		int32_t s, c, x = rng_i32(), y = rng_i32();
		double want, err;

		fx_sincos(a, &s, &c);
		assert_true(fabs(s - sin(rad) * 1073741824.0) <= 4.0);
		assert_true(fabs(c - cos(rad) * 1073741824.0) <= 4.0);
		if (x == 0 && y == 0)
			continue;
		want = atan2((double)y, (double)x) / (2.0 * (double)PI_L) * 4294967296.0;
		err = (double)fx_angle_diff(fx_atan2(y, x), 0) - want;
		if (err > 2147483648.0)
			err -= 4294967296.0;
		if (err < -2147483648.0)
			err += 4294967296.0;
		assert_true(fabs(err) <= 4096.0);
	}
}

static void test_angle_conversions(void **state)
{
	(void)state;
	assert_int_equal(fx_deg_to_turn32(0), 0);
	assert_int_equal(fx_deg_to_turn32(90), 1u << 30);
	assert_int_equal(fx_deg_to_turn32(180), FX_HALF_TURN32);
	assert_int_equal(fx_deg_to_turn32(-90), 3u << 30);
	assert_int_equal(fx_deg_to_turn32(360), 0);
	assert_int_equal(fx_deg_to_turn32(450), 1u << 30);
	assert_int_equal(fx_deg_to_turn32(-720), 0);
	/* 2^32 / 360 = 11930464.71 */
	assert_int_equal(fx_deg_to_turn32(1), 11930465u);
	assert_int_equal(fx_deg_to_turn32(-1), 4294967296u - 11930465u);
	/* INT32_MIN = -5965232 * 360 - 128, i.e. 232 degrees; 232 * 2^32 / 360 = 2767867812.98 */
	assert_int_equal(fx_deg_to_turn32(INT32_MIN), 2767867813u);
	/* INT32_MAX = 5965232 * 360 + 127; 127 * 2^32 / 360 = 1515169018.31 */
	assert_int_equal(fx_deg_to_turn32(INT32_MAX), 1515169018u);

	assert_int_equal(fx_turn32_to_cdeg(0), 0);
	assert_int_equal(fx_turn32_to_cdeg(1u << 30), 9000);
	assert_int_equal(fx_turn32_to_cdeg(3u << 30), -9000);
	assert_int_equal(fx_turn32_to_cdeg(FX_HALF_TURN32), -18000);
	assert_int_equal(fx_turn32_to_cdeg(FX_HALF_TURN32 - 1), 18000);
	assert_int_equal(fx_turn32_to_cdeg(11930465u), 100);
	/* 0.005 degree is 59652.3 units: just below the tie at 0.5 cdeg, then just above. */
	assert_int_equal(fx_turn32_to_cdeg(59652u), 0);
	assert_int_equal(fx_turn32_to_cdeg(59653u), 1);
	assert_int_equal(fx_turn32_to_cdeg((uint32_t)0 - 59653u), -1);
	/* 36000 * 2^26 / 2^32 = 562.5 exactly: ties go away from zero. */
	assert_int_equal(fx_turn32_to_cdeg(1u << 26), 563);
	assert_int_equal(fx_turn32_to_cdeg((uint32_t)0 - (1u << 26)), -563);
	for (int32_t deg = -179; deg <= 179; deg++)
		assert_int_equal(fx_turn32_to_cdeg(fx_deg_to_turn32(deg)), deg * 100);
	assert_int_equal(fx_turn32_to_cdeg(fx_deg_to_turn32(180)), -18000);

	assert_int_equal(fx_angle_diff(0, 1), -1);
	assert_int_equal(fx_angle_diff(1, 0), 1);
	assert_int_equal(fx_angle_diff(0, FX_HALF_TURN32), INT32_MIN);
	assert_int_equal(fx_angle_diff(FX_HALF_TURN32, 0), INT32_MIN);
	assert_int_equal(fx_angle_diff(10, 0xfffffff6u), 20);
	assert_int_equal(fx_angle_diff(0xfffffff6u, 10), -20);
	assert_int_equal(fx_angle_diff(FX_HALF_TURN32 - 1, 0), INT32_MAX);
}

int main(void)
{
	const struct CMUnitTest tests[] = {
		cmocka_unit_test(test_shr_round_ties_and_signs),
		cmocka_unit_test(test_mul_shr_rounds_and_saturates),
		cmocka_unit_test(test_div_round),
		cmocka_unit_test(test_kernels_match_their_definitions),
		cmocka_unit_test(test_udiv_shl16),
		cmocka_unit_test(test_ticks_of_ms),
		cmocka_unit_test(test_isqrt_edges),
		cmocka_unit_test(test_sincos_against_reference),
		cmocka_unit_test(test_atan2_octants_and_edges),
		cmocka_unit_test(test_against_libm),
		cmocka_unit_test(test_angle_conversions),
	};

	return cmocka_run_group_tests(tests, NULL, NULL);
}
