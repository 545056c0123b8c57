/* The primitives of fixmath.h run on the AVR (their assembly, as the firmware compiles them) on
 * operands the host sends through simavr: test_avr_fixmath compares each result with the host's
 * portable C. Compiled like the firmware (-O2 -flto). */
#include <avr/io.h>
#include <stdint.h>

#include "fixmath.h"
#include "fixmath_avr.h"

static volatile uint8_t box[FXA_SIZE];

static uint32_t get32(uint8_t off)
{
	return (uint32_t)box[off] | (uint32_t)box[off + 1] << 8 | (uint32_t)box[off + 2] << 16 |
	       (uint32_t)box[off + 3] << 24;
}

static void put32(uint8_t off, uint32_t v)
{
	for (uint8_t i = 0; i < 4; i++)
		box[off + i] = (uint8_t)(v >> (8 * i));
}

/* The primitives whose shift is a constant where they are used: one inlined copy per n. */
#define N7(f, base)                                                                                \
	f(base + 1) f(base + 2) f(base + 3) f(base + 4) f(base + 5) f(base + 6) f(base + 7)
#define N8(f, base) f(base) N7(f, base)
#define MUL_Q_CASE(k)                                                                              \
	case k:                                                                                    \
		return (uint32_t)fx_mul_q((int32_t)a, (int32_t)b, k);
#define MUL_SHR_CASE(k)                                                                            \
	case k:                                                                                    \
		return fx_mul_u32_shr(a, b, k);

static uint32_t mul_q_const(uint32_t a, uint32_t b, uint8_t n)
{
	switch (n) {
		N7(MUL_Q_CASE, 0)
		N8(MUL_Q_CASE, 8)
		N8(MUL_Q_CASE, 16)
		N8(MUL_Q_CASE, 24)
		N8(MUL_Q_CASE, 32)
		N8(MUL_Q_CASE, 40)
	default:
		return 0;
	}
}

static uint32_t mul_shr_const(uint32_t a, uint32_t b, uint8_t n)
{
	switch (n) {
		N7(MUL_SHR_CASE, 0)
		N8(MUL_SHR_CASE, 8)
		N8(MUL_SHR_CASE, 16)
		N8(MUL_SHR_CASE, 24)
		N8(MUL_SHR_CASE, 32)
		N8(MUL_SHR_CASE, 40)
		N8(MUL_SHR_CASE, 48)
		N8(MUL_SHR_CASE, 56)
	default:
		return 0;
	}
}

static void run(uint8_t op)
{
	uint8_t n = box[FXA_OFF_N];
	uint32_t a = get32(FXA_OFF_A), b = get32(FXA_OFF_B), c = get32(FXA_OFF_C);
	uint32_t r0 = 0, r1 = 0;
	int32_t s0, s1;
	int16_t h0, h1;

	switch (op) {
	case FXA_NOP:
		r0 = a ^ b;
		r1 = c;
		break;
	case FXA_MUL_U16:
		r0 = fx_mul_u16((uint16_t)a, (uint16_t)b);
		break;
	case FXA_MUL_S16:
		r0 = (uint32_t)fx_mul_s16((int16_t)a, (int16_t)b);
		break;
	case FXA_MUL_U32_WIDE:
		r0 = fx_mul_u32_wide(a, b, &r1);
		break;
	case FXA_MUL_U32_SHR:
		r0 = fx_mul_u32_shr(a, b, n);
		break;
	case FXA_MUL_U32_SHR16:
		r0 = fx_mul_u32_shr(a, b, 16);
		break;
	case FXA_MUL_U32_SHR32:
		r0 = fx_mul_u32_shr(a, b, 32);
		break;
	case FXA_MUL_U32_SHR40:
		r0 = fx_mul_u32_shr(a, b, 40);
		break;
	case FXA_MUL_Q:
		r0 = (uint32_t)fx_mul_q((int32_t)a, (int32_t)b, n);
		break;
	case FXA_MUL_Q15:
		r0 = (uint32_t)fx_mul_q((int32_t)a, (int32_t)b, 15);
		break;
	case FXA_MUL_Q16:
		r0 = (uint32_t)fx_mul_q((int32_t)a, (int32_t)b, 16);
		break;
	case FXA_MUL_Q30C:
		r0 = (uint32_t)fx_mul_q((int32_t)a, (int32_t)b, 30);
		break;
	case FXA_MUL_QC:
		r0 = mul_q_const(a, b, n);
		break;
	case FXA_MUL_U32_SHRC:
		r0 = mul_shr_const(a, b, n);
		break;
	case FXA_MUL_SHR32:
		r0 = (uint32_t)fx_mul_shr32((int32_t)a, b);
		break;
	case FXA_MUL_Q30:
		r0 = (uint32_t)fx_mul_q30((int32_t)a, (int32_t)b);
		break;
	case FXA_UDIV_SMALL:
		r0 = fx_udiv_small(a, b, n);
		break;
	case FXA_UDIV_SHL16:
		r0 = fx_udiv_shl16(a, b);
		break;
	case FXA_SINCOS:
		fx_sincos(a, &s0, &s1);
		r0 = (uint32_t)s0;
		r1 = (uint32_t)s1;
		break;
	case FXA_SINCOS_Q14:
		fx_sincos_q14(a, &h0, &h1);
		r0 = (uint32_t)(int32_t)h0;
		r1 = (uint32_t)(int32_t)h1;
		break;
	case FXA_ATAN2:
		r0 = fx_atan2((int32_t)a, (int32_t)b);
		break;
	case FXA_ISQRT64:
		r0 = fx_isqrt64((uint64_t)c << 32 | a);
		break;
	case FXA_ISQRT32:
		r0 = fx_isqrt32(a);
		break;
	case FXA_TURN32_TO_CDEG:
		r0 = (uint32_t)fx_turn32_to_cdeg(a);
		break;
	case FXA_SHR_U32:
		r0 = fx_shr_u32(a, n);
		r1 = fx_shl_u32(a, n);
		break;
	case FXA_FLOOR_SHR:
		r0 = (uint32_t)fx_floor_shr((int32_t)a, n);
		r1 = (uint32_t)fx_shr_round((int32_t)a, n);
		break;
	case FXA_MUL_Q20_U16:
		r0 = (uint32_t)fx_mul_q20_u16((int32_t)a, (uint16_t)b);
		break;
	case FXA_UDIV1000:
		r0 = fx_udiv1000(a);
		break;
	case FXA_UDIV_FRAC20:
		r0 = fx_udiv_frac20(n, a, b);
		break;
	case FXA_ADD_SUB_U64: {
		uint32_t d[2] = {c, a ^ b}, e[2] = {c, b};

		r0 = a;
		r1 = b;
		fx_add_u64(&r0, &r1, d);
		if (n)
			fx_sub_u64(&r0, &r1, e);
		break;
	}
	case FXA_ISQRT32_REM: {
		uint32_t v = a;

		r0 = fx_isqrt32_rem(&v);
		r1 = v;
		break;
	}
	case FXA_MUL_Q31_APPROX:
		r0 = fx_mul_q31_approx(a, b);
		break;
	default:
		break;
	}
	put32(FXA_OFF_R0, r0);
	put32(FXA_OFF_R1, r1);
}

int main(void)
{
	GPIOR1 = (uint8_t)(uintptr_t)box;
	GPIOR2 = (uint8_t)((uintptr_t)box >> 8);
	GPIOR0 = FXA_READY;
	for (;;) {
		uint8_t op = box[FXA_OFF_OP];

		if (op != 0) {
			run(op);
			box[FXA_OFF_OP] = 0;
		}
	}
}
