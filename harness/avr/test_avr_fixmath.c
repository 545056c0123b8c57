/* The primitives of fixmath.h as the AVR runs them (firmware/arch/avr's kernels) against the
 * host's portable C, bit for bit: fixmath_avr.elf in simavr computes each primitive on operands
 * sent through a mailbox in its RAM (fixmath_avr/fixmath_avr.h), on edge cases and on
 * pseudo-random operands within each function's documented domain. test_fixmath checks the
 * portable C itself; this checks that the AVR gives the same bits. Also prints each primitive's
 * cycles on the AVR (the mailbox's own cycles taken off, within a few cycles). */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <string.h>

#include <cmocka.h>

#include "fixmath.h"
#include "mailbox.h"
#include "fixmath_avr/fixmath_avr.h"

#define RANDOM_PER_OP 10000u
#define MAX_CYCLES_PER_OP 200000u

static const char *elf_path;

static const char *const op_name[FXA_OPS] = {
	[FXA_NOP] = "(mailbox)",
	[FXA_MUL_U16] = "fx_mul_u16",
	[FXA_MUL_S16] = "fx_mul_s16",
	[FXA_MUL_U32_WIDE] = "fx_mul_u32_wide",
	[FXA_MUL_U32_SHR] = "fx_mul_u32_shr, n variable",
	[FXA_MUL_U32_SHR16] = "fx_mul_u32_shr, n = 16",
	[FXA_MUL_U32_SHR32] = "fx_mul_u32_shr, n = 32",
	[FXA_MUL_U32_SHR40] = "fx_mul_u32_shr, n = 40",
	[FXA_MUL_Q] = "fx_mul_q, n variable",
	[FXA_MUL_Q15] = "fx_mul_q, n = 15",
	[FXA_MUL_Q16] = "fx_mul_q, n = 16",
	[FXA_MUL_Q30C] = "fx_mul_q, n = 30",
	[FXA_MUL_QC] = "fx_mul_q, each n constant",
	[FXA_MUL_U32_SHRC] = "fx_mul_u32_shr, each n constant",
	[FXA_MUL_SHR32] = "fx_mul_shr32",
	[FXA_MUL_Q30] = "fx_mul_q30",
	[FXA_UDIV_SMALL] = "fx_udiv_small",
	[FXA_UDIV_SHL16] = "fx_udiv_shl16",
	[FXA_SINCOS] = "fx_sincos",
	[FXA_SINCOS_Q14] = "fx_sincos_q14",
	[FXA_ATAN2] = "fx_atan2",
	[FXA_ISQRT64] = "fx_isqrt64",
	[FXA_ISQRT32] = "fx_isqrt32",
	[FXA_TURN32_TO_CDEG] = "fx_turn32_to_cdeg",
	[FXA_SHR_U32] = "fx_shr_u32 and fx_shl_u32",
	[FXA_FLOOR_SHR] = "fx_floor_shr and fx_shr_round",
	[FXA_MUL_Q20_U16] = "fx_mul_q20_u16",
	[FXA_UDIV1000] = "fx_udiv1000",
	[FXA_UDIV_FRAC20] = "fx_udiv_frac20",
	[FXA_ADD_SUB_U64] = "fx_add_u64 and fx_sub_u64",
	[FXA_ISQRT32_REM] = "fx_isqrt32_rem",
	[FXA_MUL_Q31_APPROX] = "fx_mul_q31_approx",
};

struct target {
	struct mailbox mb;
	uint64_t n[FXA_OPS], cycles[FXA_OPS], max[FXA_OPS];
};

static void poke32(struct target *t, uint8_t off, uint32_t v)
{
	for (int i = 0; i < 4; i++)
		t->mb.avr->data[t->mb.box + off + i] = (uint8_t)(v >> (8 * i));
}

static uint32_t peek32(const struct target *t, uint8_t off)
{
	const uint8_t *p = t->mb.avr->data + t->mb.box + off;

	return (uint32_t)p[0] | (uint32_t)p[1] << 8 | (uint32_t)p[2] << 16 | (uint32_t)p[3] << 24;
}

static int target_open(struct target *t)
{
	memset(t, 0, sizeof(*t));
	return mailbox_open(&t->mb, elf_path);
}

/* The operation on the AVR: results in r[0], r[1]. */
static void on_avr(struct target *t, uint8_t op, uint8_t n, const uint32_t in[3], uint32_t r[2])
{
	uint64_t start;

	t->mb.avr->data[t->mb.box + FXA_OFF_N] = n;
	poke32(t, FXA_OFF_A, in[0]);
	poke32(t, FXA_OFF_B, in[1]);
	poke32(t, FXA_OFF_C, in[2]);
	poke32(t, FXA_OFF_R0, 0xdeadbeefu);
	poke32(t, FXA_OFF_R1, 0xdeadbeefu);
	start = t->mb.avr->cycle;
	t->mb.avr->data[t->mb.box + FXA_OFF_OP] = op;
	if (mailbox_run_until(&t->mb, (uint16_t)(t->mb.box + FXA_OFF_OP), 0, MAX_CYCLES_PER_OP))
		fail_msg("%s: the AVR did not finish", op_name[op]);
	t->n[op]++;
	t->cycles[op] += t->mb.avr->cycle - start;
	if (t->mb.avr->cycle - start > t->max[op])
		t->max[op] = t->mb.avr->cycle - start;
	r[0] = peek32(t, FXA_OFF_R0);
	r[1] = peek32(t, FXA_OFF_R1);
}

/* The same operation on the host. */
static void on_host(uint8_t op, uint8_t n, const uint32_t in[3], uint32_t r[2])
{
	uint32_t a = in[0], b = in[1], c = in[2];
	int32_t s0, s1;
	int16_t h0, h1;

	r[0] = r[1] = 0;
	switch (op) {
	case FXA_MUL_U16:
		r[0] = fx_mul_u16((uint16_t)a, (uint16_t)b);
		break;
	case FXA_MUL_S16:
		r[0] = (uint32_t)fx_mul_s16((int16_t)a, (int16_t)b);
		break;
	case FXA_MUL_U32_WIDE:
		r[0] = fx_mul_u32_wide(a, b, &r[1]);
		break;
	case FXA_MUL_U32_SHR:
	case FXA_MUL_U32_SHRC:
		r[0] = fx_mul_u32_shr(a, b, n);
		break;
	case FXA_MUL_U32_SHR16:
		r[0] = fx_mul_u32_shr(a, b, 16);
		break;
	case FXA_MUL_U32_SHR32:
		r[0] = fx_mul_u32_shr(a, b, 32);
		break;
	case FXA_MUL_U32_SHR40:
		r[0] = fx_mul_u32_shr(a, b, 40);
		break;
	case FXA_MUL_Q:
	case FXA_MUL_QC:
	case FXA_MUL_Q15:
	case FXA_MUL_Q16:
	case FXA_MUL_Q30C:
		r[0] = (uint32_t)fx_mul_q((int32_t)a, (int32_t)b, n);
		break;
	case FXA_MUL_SHR32:
		r[0] = (uint32_t)fx_mul_shr32((int32_t)a, b);
		break;
	case FXA_MUL_Q30:
		r[0] = (uint32_t)fx_mul_q30((int32_t)a, (int32_t)b);
		break;
	case FXA_UDIV_SMALL:
		r[0] = fx_udiv_small(a, b, n);
		break;
	case FXA_UDIV_SHL16:
		r[0] = fx_udiv_shl16(a, b);
		break;
	case FXA_SINCOS:
		fx_sincos(a, &s0, &s1);
		r[0] = (uint32_t)s0;
		r[1] = (uint32_t)s1;
		break;
	case FXA_SINCOS_Q14:
		fx_sincos_q14(a, &h0, &h1);
		r[0] = (uint32_t)(int32_t)h0;
		r[1] = (uint32_t)(int32_t)h1;
		break;
	case FXA_ATAN2:
		r[0] = fx_atan2((int32_t)a, (int32_t)b);
		break;
	case FXA_ISQRT64:
		r[0] = fx_isqrt64((uint64_t)c << 32 | a);
		break;
	case FXA_ISQRT32:
		r[0] = fx_isqrt32(a);
		break;
	case FXA_SHR_U32:
		r[0] = fx_shr_u32(a, n);
		r[1] = fx_shl_u32(a, n);
		break;
	case FXA_FLOOR_SHR:
		r[0] = (uint32_t)fx_floor_shr((int32_t)a, n);
		r[1] = (uint32_t)fx_shr_round((int32_t)a, n);
		break;
	case FXA_MUL_Q20_U16:
		r[0] = (uint32_t)fx_mul_q20_u16((int32_t)a, (uint16_t)b);
		break;
	case FXA_UDIV1000:
		r[0] = fx_udiv1000(a);
		break;
	case FXA_UDIV_FRAC20:
		r[0] = fx_udiv_frac20(n, a, b);
		break;
	case FXA_ADD_SUB_U64: {
		uint32_t d[2] = {c, a ^ b}, e[2] = {c, b};

		r[0] = a;
		r[1] = b;
		fx_add_u64(&r[0], &r[1], d);
		if (n)
			fx_sub_u64(&r[0], &r[1], e);
		break;
	}
	case FXA_ISQRT32_REM: {
		uint32_t v = a;

		r[0] = fx_isqrt32_rem(&v);
		r[1] = v;
		break;
	}
	case FXA_MUL_Q31_APPROX:
		r[0] = fx_mul_q31_approx(a, b);
		break;
	case FXA_TURN32_TO_CDEG:
		r[0] = (uint32_t)fx_turn32_to_cdeg(a);
		break;
	default:
		break;
	}
}

static void check(struct target *t, uint8_t op, uint8_t n, uint32_t a, uint32_t b, uint32_t c)
{
	const uint32_t in[3] = {a, b, c};
	uint32_t got[2], want[2];

	on_avr(t, op, n, in, got);
	on_host(op, n, in, want);
	if (got[0] != want[0] || got[1] != want[1])
		fail_msg("%s (n %u, a 0x%08x, b 0x%08x, c 0x%08x): AVR 0x%08x 0x%08x, host 0x%08x "
			 "0x%08x",
			 op_name[op], n, a, b, c, got[0], got[1], want[0], want[1]);
}

/* xorshift64*: the same operands on every run. */
static uint64_t rng_state = 0x9e3779b97f4a7c15u;

static uint64_t rnd64(void)
{
	rng_state ^= rng_state >> 12;
	rng_state ^= rng_state << 25;
	rng_state ^= rng_state >> 27;
	return rng_state * 2685821657736338717u;
}

/* A random value of a random bit length (0..bits), so that small operands are tried as often as
 * large ones. */
static uint64_t rnd_bits(unsigned bits)
{
	unsigned len = (unsigned)(rnd64() % (bits + 1u));

	return len == 0 ? 0 : rnd64() >> (64u - len);
}

static uint32_t rnd_s32(void)
{
	uint32_t m = (uint32_t)rnd_bits(31);

	return rnd64() & 1 ? (uint32_t)0 - m : m;
}

static const uint32_t edges32[] = {
	0,          1,          2,          0x7f,       0x80,       0xff,       0x100,
	0x7fff,     0x8000,     0x8001,     0xfffe,     0xffff,     0x10000,    0x10001,
	0x7fffff,   0x800000,   0xffffff,   0x1000000,  0x3fffffff, 0x40000000, 0x40000001,
	0x7ffffffe, 0x7fffffff, 0x80000000, 0x80000001, 0xbfffffff, 0xc0000000, 0xfeffffff,
	0xff000000, 0xfffeffff, 0xffff0000, 0xffff0001, 0xffff7fff, 0xffff8000, 0xffffff00,
	0xfffffffe, 0xffffffff, 0x12345678, 0x87654321, 0xa5a5a5a5, 0x5a5a5a5a,
};
#define N_EDGES (sizeof(edges32) / sizeof(edges32[0]))

static int64_t mag(uint32_t v)
{
	int64_t s = fx_int32_of(v);

	return s < 0 ? -s : s;
}

/* round(|a| |b| / 2^n) fits an int32_t: fx_mul_q's domain (|b| <= 65535). */
static int mul_q_ok(uint32_t a, uint32_t b, uint8_t n)
{
	uint64_t m = (uint64_t)mag(a) * (uint64_t)mag(b);

	return a != 0x80000000u && mag(b) <= 65535 &&
	       (m + ((uint64_t)1 << (n - 1))) >> n <= (uint64_t)INT32_MAX;
}

/* round(a b / 2^n) fits a uint32_t, the bias not overflowing: fx_mul_u32_shr's domain. */
static int mul_shr_ok(uint32_t a, uint32_t b, uint8_t n)
{
	uint64_t p = (uint64_t)a * b, bias = (uint64_t)1 << (n - 1);

	return p <= UINT64_MAX - bias && (p + bias) >> n <= UINT32_MAX;
}

static void test_products(void **state)
{
	struct target *t = *state;

	for (size_t i = 0; i < N_EDGES; i++)
		for (size_t j = 0; j < N_EDGES; j++) {
			uint32_t a = edges32[i], b = edges32[j];

			check(t, FXA_MUL_U16, 0, a, b, 0);
			check(t, FXA_MUL_S16, 0, a, b, 0);
			check(t, FXA_MUL_U32_WIDE, 0, a, b, 0);
			if (a != 0x80000000u)
				check(t, FXA_MUL_SHR32, 0, a, b, 0);
			if (a != 0x80000000u && mag(b) <= FX_ONE_Q30)
				check(t, FXA_MUL_Q30, 0, a, b, 0);
		}
	for (uint32_t k = 0; k < RANDOM_PER_OP; k++) {
		uint32_t a = (uint32_t)rnd_bits(32), b = (uint32_t)rnd_bits(32);
		uint32_t s = rnd_s32(), c = (uint32_t)rnd_bits(30);

		check(t, FXA_MUL_U16, 0, a, b, 0);
		check(t, FXA_MUL_S16, 0, s, b, 0);
		check(t, FXA_MUL_U32_WIDE, 0, a, b, 0);
		check(t, FXA_MUL_SHR32, 0, s, b, 0);
		check(t, FXA_MUL_Q30, 0, s, rnd64() & 1 ? (uint32_t)0 - c : c, 0);
	}
}

/* The kernels that the core's own functions above reach only on part of their domain. */
static void test_kernels(void **state)
{
	struct target *t = *state;

	for (uint32_t k = 0; k < RANDOM_PER_OP; k++) {
		uint32_t a = (uint32_t)rnd_bits(32), b = (uint32_t)rnd_bits(32);
		uint32_t c = (uint32_t)rnd_bits(32), den = (uint32_t)rnd_bits(31) + 1u;
		uint8_t n = (uint8_t)(rnd64() % 32);

		check(t, FXA_SHR_U32, n, a, 0, 0);
		check(t, FXA_FLOOR_SHR, n, a, 0, 0);
		/* |v| below 2^24 (the profiles' limits), k below 2^16 */
		check(t, FXA_MUL_Q20_U16, 0, (uint32_t)((int32_t)(a >> 8) - (1 << 23)), b & 0xffffu,
		      0);
		check(t, FXA_UDIV1000, 0, a >> 7, 0, 0);
		check(t, FXA_UDIV_FRAC20, (uint8_t)(b & 1u), a % den, den, 0);
		check(t, FXA_UDIV_FRAC20, (uint8_t)(b & 1u), (a >> 8) % (den >> 8 | 1u),
		      den >> 8 | 1u, 0);
		check(t, FXA_ADD_SUB_U64, (uint8_t)(c & 1u), a, b, c);
		check(t, FXA_ISQRT32_REM, 0, a, 0, 0);
		check(t, FXA_MUL_Q31_APPROX, 0, a, b >> 10, 0);
	}
	for (size_t i = 0; i < N_EDGES; i++)
		for (uint8_t n = 0; n < 32; n++) {
			check(t, FXA_SHR_U32, n, edges32[i], 0, 0);
			check(t, FXA_FLOOR_SHR, n, edges32[i], 0, 0);
			check(t, FXA_ISQRT32_REM, 0, edges32[i], 0, 0);
		}
}

static void test_scaled_products(void **state)
{
	struct target *t = *state;
	static const uint8_t const_n[] = {16, 32, 40};
	static const uint8_t const_q[] = {15, 16, 30};

	for (uint32_t k = 0; k < RANDOM_PER_OP;) {
		uint32_t a = (uint32_t)rnd_bits(32), b = (uint32_t)rnd_bits(32);
		uint32_t s = rnd_s32(), m = (uint32_t)rnd_bits(16);
		uint8_t n = (uint8_t)(1 + rnd64() % 63), q = (uint8_t)(8 + rnd64() % 40);
		uint8_t i = (uint8_t)(rnd64() % 3);

		m = rnd64() & 1 ? (uint32_t)0 - m : m;
		if (mul_shr_ok(a, b, n))
			check(t, FXA_MUL_U32_SHR, n, a, b, 0);
		if (mul_shr_ok(a, b, const_n[i]))
			check(t, (uint8_t)(FXA_MUL_U32_SHR16 + i), const_n[i], a, b, 0);
		if (mul_q_ok(s, m, q))
			check(t, FXA_MUL_Q, q, s, m, 0);
		if (mul_shr_ok(a, b, (uint8_t)(1 + k % 63)))
			check(t, FXA_MUL_U32_SHRC, (uint8_t)(1 + k % 63), a, b, 0);
		if (mul_q_ok(s, m, (uint8_t)(1 + k % 47)))
			check(t, FXA_MUL_QC, (uint8_t)(1 + k % 47), s, m, 0);
		if (mul_q_ok(s, m, const_q[i])) {
			check(t, (uint8_t)(FXA_MUL_Q15 + i), const_q[i], s, m, 0);
			k++;
		}
	}
}

static void test_divisions(void **state)
{
	struct target *t = *state;

	for (uint32_t k = 0; k < RANDOM_PER_OP;) {
		uint8_t bits = (uint8_t)(1 + rnd64() % 32);
		uint64_t den = rnd_bits(32), q = rnd64() >> (64 - bits), num;

		if (den == 0)
			continue;
		num = q * den + rnd64() % den;
		if (num > UINT32_MAX)
			continue;
		check(t, FXA_UDIV_SMALL, bits, (uint32_t)num, (uint32_t)den, 0);
		/* floor(v 2^16 / d): d 1..2^31 - 1, v / d below 2^16 */
		{
			uint32_t v = (uint32_t)rnd_bits(32), d = (uint32_t)rnd_bits(31);

			if (d != 0 && (v >> 16) < d)
				check(t, FXA_UDIV_SHL16, 0, v, d, 0);
		}
		k++;
	}
	for (size_t i = 0; i < N_EDGES; i++)
		for (size_t j = 0; j < N_EDGES; j++)
			if (edges32[j] != 0 && edges32[j] <= INT32_MAX &&
			    (edges32[i] >> 16) < edges32[j])
				check(t, FXA_UDIV_SHL16, 0, edges32[i], edges32[j], 0);
}

static void test_angles(void **state)
{
	struct target *t = *state;

	for (size_t i = 0; i < N_EDGES; i++) {
		check(t, FXA_SINCOS, 0, edges32[i], 0, 0);
		check(t, FXA_SINCOS_Q14, 0, edges32[i], 0, 0);
		check(t, FXA_TURN32_TO_CDEG, 0, edges32[i], 0, 0);
		for (size_t j = 0; j < N_EDGES; j++)
			check(t, FXA_ATAN2, 0, edges32[i], edges32[j], 0);
	}
	/* Around each table entry of fx_sincos (2^23 apart), where the residual changes sign. */
	for (uint32_t e = 0; e < 512; e++)
		for (int32_t d = -2; d <= 2; d++) {
			uint32_t a = (e << 23) + ((uint32_t)1 << 22) + (uint32_t)d;

			check(t, FXA_SINCOS, 0, a, 0, 0);
			check(t, FXA_SINCOS, 0, (e << 23) + (uint32_t)d, 0, 0);
		}
	for (uint32_t k = 0; k < RANDOM_PER_OP; k++) {
		uint32_t a = (uint32_t)rnd64();

		check(t, FXA_SINCOS, 0, a, 0, 0);
		check(t, FXA_SINCOS_Q14, 0, a, 0, 0);
		check(t, FXA_TURN32_TO_CDEG, 0, a, 0, 0);
		check(t, FXA_ATAN2, 0, rnd_s32(), rnd_s32(), 0);
	}
}

static void check_isqrt(struct target *t, uint64_t v)
{
	check(t, FXA_ISQRT64, 0, (uint32_t)v, 0, (uint32_t)(v >> 32));
	if ((v >> 32) == 0)
		check(t, FXA_ISQRT32, 0, (uint32_t)v, 0, 0);
}

static void test_square_roots(void **state)
{
	struct target *t = *state;

	for (size_t i = 0; i < N_EDGES; i++)
		for (size_t j = 0; j < N_EDGES; j += 4)
			check_isqrt(t, (uint64_t)edges32[j] << 32 | edges32[i]);
	for (uint32_t k = 0; k < RANDOM_PER_OP; k++) {
		uint64_t r = rnd_bits(32), v = rnd_bits(64);

		check_isqrt(t, v);
		check_isqrt(t, (uint32_t)v);
		/* around a square: r^2 - 1, r^2 */
		check_isqrt(t, r * r);
		check_isqrt(t, r * r - 1);
	}
}

static int setup(void **state)
{
	static struct target t;

	if (target_open(&t)) {
		fprintf(stderr, "cannot run %s in simavr\n", elf_path);
		return -1;
	}
	*state = &t;
	return 0;
}

/* The cycles of each primitive: the mailbox's own (FXA_NOP, which moves operands to results) taken
 * off. */
static int report(void **state)
{
	struct target *t = *state;
	const uint32_t none[3] = {0, 0, 0};
	uint32_t r[2];
	double base;

	on_avr(t, FXA_NOP, 0, none, r);
	base = (double)t->cycles[FXA_NOP];
	printf("cycles on the AVR per call (mean, max), over the operands tried:\n");
	for (int op = FXA_NOP + 1; op < FXA_OPS; op++)
		if (t->n[op] != 0)
			printf("  %-32s %7.1f %7.0f   (%llu calls)\n", op_name[op],
			       (double)t->cycles[op] / (double)t->n[op] - base,
			       (double)t->max[op] - base, (unsigned long long)t->n[op]);
	return 0;
}

int main(int argc, char **argv)
{
	const struct CMUnitTest tests[] = {
		cmocka_unit_test(test_products),     cmocka_unit_test(test_scaled_products),
		cmocka_unit_test(test_divisions),    cmocka_unit_test(test_angles),
		cmocka_unit_test(test_square_roots), cmocka_unit_test(test_kernels),
	};

	if (argc != 2) {
		fprintf(stderr, "usage: %s fixmath_avr.elf\n", argv[0]);
		return 2;
	}
	elf_path = argv[1];
	return cmocka_run_group_tests(tests, setup, report);
}
