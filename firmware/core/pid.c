/* PID on a following error (see pid.h and docs/control.md "PID").
 *
 * P and D are summed in [2^-12 duty_q15], each clipped to 8 times the full duty, and the integral
 * in [2^-24 duty_q15] as an exact 48-bit sum. The common case, errors below 32 mm, takes a fast
 * path of 16-bit products (an 8-bit AVR multiplies 16 x 16 bits in about 25 cycles, and calls a
 * library routine of 200 for anything on int64_t); larger errors take the general path, out of
 * line, which gives the same result on any error. */
#include "pid.h"

#include <stddef.h>

#include "fixmath.h"

#define TERM_MAX ((int32_t)1 << 30) /* [2^-12 duty_q15]: 8 times 32768 */
/* The fast path's bound on P and D, so that their sum needs no clip. */
#define FAST_TERM_MAX ((int32_t)1 << 29)

static int config_valid(const struct pid_config *cfg)
{
	if (cfg->out_limit_q15 < 1)
		return 0;
	if (cfg->tick_hz < PID_TICK_HZ_MIN || cfg->tick_hz > PID_TICK_HZ_MAX)
		return 0;
	return 1;
}

/* n / d rounded to nearest, for the positive values of the gain conversion (plan time). */
static int64_t div_round_pos(int64_t n, int64_t d)
{
	return (n + d / 2) / d;
}

static int32_t err_max(int32_t k)
{
	return k == 0 ? PID_ERR_MAX_UM : (int32_t)((TERM_MAX - 1) / k);
}

/* The largest error that the fast path multiplies by k: it fits 16 bits, and k e < 2^29. */
static int16_t err_fast(int32_t k)
{
	int32_t m = k == 0 ? INT16_MAX : (FAST_TERM_MAX - 1) / k;

	return (int16_t)(m < INT16_MAX ? m : INT16_MAX);
}

/* duty_q15 = 32768 p 2^-12 e_mm = p e_um / 125;
 * duty_q15 = 32768 i 2^-12 (sum e_um / hz) / 1000 = i sum_e_um / (125 hz);
 * duty_q15 = 32768 d 2^-16 (de_um hz) / 1000 = d de_um hz / 2000.
 * The divisions are done once here. */
static void compute_gains(struct pid *c)
{
	int64_t hz = c->cfg.tick_hz;

	c->kp_q12 = (int32_t)div_round_pos((int64_t)c->cfg.p << 12, 125);
	c->kd_q12 = (int32_t)div_round_pos((int64_t)c->cfg.d * hz << 12, 2000);
	/* At most 65535 2^24 / 12500 < 2^27 (tick_hz >= 100). */
	c->ki_q24 = (uint32_t)div_round_pos((int64_t)c->cfg.i << 24, 125 * hz);
	c->p_err_max_um = err_max(c->kp_q12);
	c->d_err_max_um = err_max(c->kd_q12);
	c->p_err_fast_um = err_fast(c->kp_q12);
	c->d_err_fast_um = err_fast(c->kd_q12);
	c->i_max_q8 = (int32_t)c->cfg.out_limit_q15 << 8;
}

/* The integral clipped to the output limit: |hi| <= lim [2^-8 duty_q15]. */
FX_INLINE struct fx48 clip_i8(struct fx48 v, int32_t lim)
{
	if (v.hi >= lim)
		return fx48_make(lim, 0);
	if (v.hi < -lim)
		return fx48_make(-lim, 0);
	return v;
}

int pid_init(struct pid *c, const struct pid_config *cfg)
{
	if (!config_valid(cfg))
		return -1;
	c->cfg = *cfg;
	compute_gains(c);
	pid_reset(c);
	return 0;
}

int pid_set_config(struct pid *c, const struct pid_config *cfg)
{
	if (!config_valid(cfg))
		return -1;
	c->cfg = *cfg;
	compute_gains(c);
	c->i_acc_q24 = clip_i8(c->i_acc_q24, c->i_max_q8);
	return 0;
}

void pid_reset(struct pid *c)
{
	c->i_acc_q24 = fx48_make(0, 0);
	c->prev_err_um = 0;
	c->has_prev = 0;
	c->out_q15 = 0;
}

FX_INLINE int32_t clip32(int32_t v, int32_t lim)
{
	if (v > lim)
		return lim;
	if (v < -lim)
		return -lim;
	return v;
}

/* |v| <= lim for a lim in 0..32767, as one unsigned comparison. */
FX_INLINE int within16(int32_t v, int16_t lim)
{
	return (uint32_t)v + (uint16_t)lim <= (uint32_t)(uint16_t)lim * 2u;
}

/* k x exactly, for k e_fast < 2^29 and |x| <= e_fast (err_fast(k)): the product fits, so the
 * upper half of k only contributes its product's low 16 bits. */
FX_INLINE int32_t mul_fast(int32_t k, int16_t x)
{
	uint32_t p = (uint32_t)fx_mul_s16_u16(x, fx_lo16((uint32_t)k));
	unsigned kh = fx_hi16((uint32_t)k);

	if (kh != 0)
		p += (uint32_t)(uint16_t)(kh * (unsigned)(uint16_t)x) << 16;
	return fx_int32_of(p);
}

/* floor(v / 16), without shifting a negative value (implementation-defined). */
FX_INLINE int32_t floor_div16(int32_t v)
{
	uint32_t u = fx_shr_u32((uint32_t)v, 4);

	return fx_int32_of(v < 0 ? u | 0xf0000000u : u);
}

/* The upper part of u = pd 2^12 + i [2^-24 duty_q15], pd = pdh 16 + pdl / 2^12; *ul the lower. */
FX_INLINE int32_t sum_hi(int32_t pdh, uint16_t pdl, struct fx48 i, uint16_t *ul)
{
	uint32_t t = (uint32_t)pdl + i.lo;

	*ul = fx_lo16(t);
	return pdh + i.hi + (int32_t)fx_hi16(t);
}

/* Conditional integration: while the output is saturated in the direction in which the error
 * pushes it, integrating would only wind up. Whether u = uh 2^16 + ul is such an output. */
FX_INLINE int winds_up(int32_t e, int32_t uh, uint16_t ul, int32_t lim)
{
	return e > 0 ? uh > lim || (uh == lim && ul != 0) : uh < -lim;
}

/* round(u / 2^24) with ties away from zero, clipped to +-out_limit, for u = uh 2^16 + ul
 * [2^-24 duty_q15]: the ties fall on multiples of 2^23, so ul only matters below zero. */
FX_INLINE int16_t duty_of(const struct pid *c, int32_t uh, uint16_t ul)
{
	int32_t lim = c->i_max_q8;
	uint32_t m;

	if (uh >= lim)
		return c->cfg.out_limit_q15;
	if (uh <= -lim)
		return (int16_t)-c->cfg.out_limit_q15;
	if (uh >= 0)
		return (int16_t)(((uint32_t)uh + 128) >> 8);
	m = (uint32_t)0 - (uint32_t)uh - (ul != 0);
	return (int16_t)(0 - (int32_t)((m + 128) >> 8));
}

/* The duty from P + D (pd [2^-12 duty_q15]) and the integral i moved by this tick's error e
 * (the stored one when e is 0): i is clipped and kept unless it winds up, in which case the
 * stored integral gives the duty. */
FX_INLINE int16_t duty_with(struct pid *c, int32_t e, int32_t pd, struct fx48 i)
{
	int32_t pdh = floor_div16(pd); /* pd [2^-12] in [2^-24] as pdh 2^16 + pdl */
	uint16_t pdl = (uint16_t)((uint16_t)fx_lo16((uint32_t)pd) << 12);
	int32_t uh;
	uint16_t ul;

	if (e != 0) {
		i = clip_i8(i, c->i_max_q8);
		uh = sum_hi(pdh, pdl, i, &ul);
		if (!winds_up(e, uh, ul, c->i_max_q8)) {
			c->i_acc_q24 = i;
			return duty_of(c, uh, ul);
		}
	}
	uh = sum_hi(pdh, pdl, c->i_acc_q24, &ul);
	return duty_of(c, uh, ul);
}

/* The common case: |e| <= p_err_fast_um, |de| <= d_err_fast_um. */
static int16_t update_fast(struct pid *c, int16_t e, int16_t de)
{
	int32_t pd = mul_fast(c->kp_q12, e) + mul_fast(c->kd_q12, de);
	struct fx48 i = c->i_acc_q24;

	/* The integral is kept as its contribution to the output, so that it can be clipped to
	 * the limit directly and stays bumpless when the i gain changes. Integer products: exact,
	 * no rounding to accumulate. ki e < 2^42. */
	if (e != 0) {
		unsigned kh = fx_hi16(c->ki_q24);

		i = fx48_add32(i, fx_mul_s16_u16(e, fx_lo16(c->ki_q24)));
		if (kh != 0)
			i.hi += fx_mul_s16_u16(e, (uint16_t)kh);
	}
	return duty_with(c, e, pd, i);
}

/* k e [2^-12 duty_q15], clipped to +-TERM_MAX (|e| <= e_max keeps the product below it). */
static int32_t term(int32_t k, int32_t e, int32_t e_max)
{
	uint32_t m = fx_mag32(e);
	uint32_t t;

	if (m > (uint32_t)e_max)
		t = (uint32_t)TERM_MAX - 1;
	else if (k <= 0xffff && m <= 0xffffu)
		t = fx_mul_u16((uint16_t)k, (uint16_t)m);
	else
		t = (uint32_t)k * m; /* below 2^30 */
	return e >= 0 ? (int32_t)t : -(int32_t)t;
}

/* The same on any error (out of line: it is rare, and its registers would burden the fast
 * path). ki e exactly (ki < 2^27, |e| <= 2^22), its upper part saturated at 2^30 (the integral
 * is clipped to the output limit, below 2^23 there, anyway). */
static FX_NOINLINE int16_t update_general(struct pid *c, int32_t e, int32_t de)
{
	int32_t pd = term(c->kp_q12, e, c->p_err_max_um) + term(c->kd_q12, de, c->d_err_max_um);
	struct fx48 i = c->i_acc_q24;

	if (e != 0) {
		uint32_t lo, hi = fx_mul_u32_wide(c->ki_q24, fx_mag32(e), &lo);
		uint32_t t;

		if (hi >= (uint32_t)1 << 14) {
			hi = (uint32_t)1 << 30;
			lo = 0;
		} else {
			hi = (hi << 16) | fx_hi16(lo);
		}
		if (e > 0) {
			t = (uint32_t)i.lo + fx_lo16(lo);
			i.hi += (int32_t)hi + (int32_t)fx_hi16(t);
		} else {
			t = 0x10000u + i.lo - fx_lo16(lo);
			i.hi -= (int32_t)hi + 1 - (int32_t)fx_hi16(t);
		}
		i.lo = fx_lo16(t);
	}
	return duty_with(c, e, pd, i);
}

/* pid_update on any error, in portable C. */
static FX_NOINLINE int16_t update_any(struct pid *c, int32_t err_um)
{
	int32_t e = clip32(err_um, PID_ERR_MAX_UM);
	/* Clipped like the error. */
	int32_t de = c->has_prev ? clip32(e - c->prev_err_um, PID_ERR_MAX_UM) : 0;

	c->prev_err_um = e;
	c->has_prev = e >= INT16_MIN && e <= INT16_MAX ? 2 : 1;
	if (within16(e, c->p_err_fast_um) && within16(de, c->d_err_fast_um))
		c->out_q15 = update_fast(c, (int16_t)e, (int16_t)de);
	else
		c->out_q15 = update_general(c, e, de);
	return c->out_q15;
}

#if FX_AVR_MUL
/* update_fast, with its bounds and the previous error's update, in AVR assembly: avr-gcc 5.4
 * keeps few of the C version's 32-bit values in registers and calls a library routine for each
 * 16 x 16 product, 750 cycles a call where this takes 300. The same arithmetic, byte by byte:
 *   P + D = kp e + kd de, mod 2^32 (each below 2^29): a MUL per byte of the gain and of e (a
 *   MULSU for e's signed upper byte), skipped for a zero byte of the gain (at 1 kHz, kd = d 2^11
 *   has two);
 *   pdh = floor((P + D) / 16) by 4 arithmetic shifts, pdl = ((P + D) mod 16) 2^12;
 *   i' = i + ki e in 48 bits, the same way, clipped to +-out_limit 2^24;
 *   u = pdh 2^16 + pdl + i'; if it winds up, u = pdh 2^16 + pdl + i and i is kept;
 *   duty = round(u / 2^24), ties away from zero, clipped to +-out_limit_q15.
 * Returns 1 with out_q15 set, or 0 having changed nothing (update_any then does the whole tick)
 * when e or de is out of the fast path's bounds, or the previous error out of 16 bits.
 * test_avr_annex checks it against the host's C every tick of its session. */

/* Registers: Z the pid; e in r22..r25 (left as it was when declining), then its lower half x in
 * r22:r23; r18 a byte of a gain; r19 zero; de in r20:r21; P + D, then pdh, then u's upper part in
 * r24..r27; pdl's upper byte (u's second) in r20; the integral, lo then hi, in r12..r17;
 * out_limit_q15 in r22:r23. MULSU sets C to the sign of its product, which SBC extends upwards. */

/* r24..r27 += r18 (byte J of a gain, J = 0..3) x (X0, X1 signed) 2^(8 J), mod 2^32. */
#define PD_MAC0(X0, X1)                                                                            \
	"mul r18," X0 "\n\tadd r24,r0\n\tadc r25,r1\n\tadc r26,r19\n\tadc r27,r19\n\t"             \
	"mulsu " X1 ",r18\n\tsbc r27,r19\n\tadd r25,r0\n\tadc r26,r1\n\tadc r27,r19\n"
#define PD_MAC1(X0, X1)                                                                            \
	"mul r18," X0 "\n\tadd r25,r0\n\tadc r26,r1\n\tadc r27,r19\n\t"                            \
	"mulsu " X1 ",r18\n\tadd r26,r0\n\tadc r27,r1\n"
#define PD_MAC2(X0, X1)                                                                            \
	"mul r18," X0 "\n\tadd r26,r0\n\tadc r27,r1\n\tmul r18," X1 "\n\tadd r27,r0\n"
#define PD_MAC3(X0, X1) "mul r18," X0 "\n\tadd r27,r0\n"
/* The same for the gain at OFF: byte J loaded, skipped if zero. */
#define PD_BYTE(OFF, J, X0, X1)                                                                    \
	"ldd r18,Z+" OFF "+" #J "\n\ttst r18\n\tbreq 1f\n\t" PD_MAC##J(X0, X1) "1:\n\t"
#define PD_TERM(OFF, X0, X1)                                                                       \
	PD_BYTE(OFF, 0, X0, X1)                                                                    \
	PD_BYTE(OFF, 1, X0, X1) PD_BYTE(OFF, 2, X0, X1) PD_BYTE(OFF, 3, X0, X1)

/* r12..r17 += r18 (byte J of ki) x (r22, r23 signed) 2^(8 J), skipped if zero. */
#define I_MAC0                                                                                     \
	"mul r18,r22\n\tadd r12,r0\n\tadc r13,r1\n\tadc r14,r19\n\tadc r15,r19\n\tadc r16,r19\n\t" \
	"adc r17,r19\n\tmulsu r23,r18\n\tsbc r15,r19\n\tsbc r16,r19\n\tsbc r17,r19\n\t"            \
	"add r13,r0\n\tadc r14,r1\n\tadc r15,r19\n\tadc r16,r19\n\tadc r17,r19\n"
#define I_MAC1                                                                                     \
	"mul r18,r22\n\tadd r13,r0\n\tadc r14,r1\n\tadc r15,r19\n\tadc r16,r19\n\tadc r17,r19\n\t" \
	"mulsu r23,r18\n\tsbc r16,r19\n\tsbc r17,r19\n\t"                                          \
	"add r14,r0\n\tadc r15,r1\n\tadc r16,r19\n\tadc r17,r19\n"
#define I_MAC2                                                                                     \
	"mul r18,r22\n\tadd r14,r0\n\tadc r15,r1\n\tadc r16,r19\n\tadc r17,r19\n\t"                \
	"mulsu r23,r18\n\tsbc r17,r19\n\tadd r15,r0\n\tadc r16,r1\n\tadc r17,r19\n"
#define I_MAC3                                                                                     \
	"mul r18,r22\n\tadd r15,r0\n\tadc r16,r1\n\tadc r17,r19\n\t"                               \
	"mulsu r23,r18\n\tadd r16,r0\n\tadc r17,r1\n"
#define I_BYTE(J) "ldd r18,Z+%[ki]+" #J "\n\ttst r18\n\tbreq 1f\n\t" I_MAC##J "1:\n\t"

/* (r22:r23 and r20:r21 are e and de) |X| <= the int16_t at OFF: (X + lim) mod 2^16 <= 2 lim. */
#define WITHIN(X0, X1, OFF)                                                                        \
	"ldd r26,Z+" OFF "\n\tldd r27,Z+" OFF "+1\n\tmovw r18,r26\n\tadd r18," X0 "\n\t"           \
	"adc r19," X1 "\n\tlsl r26\n\trol r27\n\tcp r26,r18\n\tcpc r27,r19\n\tbrlo 8f\n\t"

FX_INLINE uint8_t update_fast_avr(struct pid *c, int32_t *err_um, int16_t *out)
{
	register int32_t e __asm__("r22") = *err_um;
	register uint8_t done __asm__("r18");
	register int16_t o __asm__("r20");

	__asm__ volatile(
		/* e within 16 bits (its upper half is the sign of its lower), and |e| <= pf. */
		"mov r18,r23\n\t"
		"lsl r18\n\t"
		"sbc r18,r18\n\t"
		"cp r24,r18\n\t"
		"cpc r25,r18\n\t"
		"brne 8f\n\t" WITHIN("r22", "r23", "%[pf]")
		/* de = e - prev: 0 after a reset (has_prev 0); in 16 bits when prev is (has_prev
		 * 2), if it does not overflow. Then |de| <= df. */
		"ldd r19,Z+%[has]\n\t"
		"cpi r19,2\n\t"
		"breq 1f\n\t"
		"tst r19\n\t"
		"brne 8f\n\t"
		"clr r20\n\t"
		"clr r21\n\t"
		"rjmp 2f\n"
		"1:\n\t"
		"ldd r26,Z+%[prev]\n\t"
		"ldd r27,Z+%[prev]+1\n\t"
		"movw r20,r22\n\t"
		"sub r20,r26\n\t"
		"sbc r21,r27\n\t"
		"brvs 8f\n"
		"2:\n\t" WITHIN("r20", "r21", "%[df]") "rjmp 3f\n"
						       "8:\n\t"
						       "clr r18\n\t"
						       "rjmp 9f\n"
						       /* The fast path: prev = e, has_prev = 2. */
						       "3:\n\t"
						       "std Z+%[prev],r22\n\t"
						       "std Z+%[prev]+1,r23\n\t"
						       "std Z+%[prev]+2,r24\n\t"
						       "std Z+%[prev]+3,r25\n\t"
						       "ldi r18,2\n\t"
						       "std Z+%[has],r18\n\t"
						       "clr r19\n\t"
						       /* r24..r27 = kd de + kp e. */
						       "clr r24\n\t"
						       "clr r25\n\t"
						       "movw r26,r24\n\t" PD_TERM("%[kd]", "r20",
										  "r21")
							       PD_TERM("%[kp]", "r22", "r23")
		/* pdl's upper byte, then pdh = (P + D) >> 4, arithmetic. */
		"mov r20,r24\n\t"
		"swap r20\n\t"
		"andi r20,0xf0\n\t"
		"asr r27\n\t"
		"ror r26\n\t"
		"ror r25\n\t"
		"ror r24\n\t"
		"asr r27\n\t"
		"ror r26\n\t"
		"ror r25\n\t"
		"ror r24\n\t"
		"asr r27\n\t"
		"ror r26\n\t"
		"ror r25\n\t"
		"ror r24\n\t"
		"asr r27\n\t"
		"ror r26\n\t"
		"ror r25\n\t"
		"ror r24\n\t"
		/* The integral: T = e < 0; nothing to add when e = 0. */
		"bst r23,7\n\t"
		"mov r18,r22\n\t"
		"or r18,r23\n\t"
		"brne 3f\n\t"
		"rjmp 6f\n"
		"3:\n\t"
		"ldd r12,Z+%[il]\n\t"
		"ldd r13,Z+%[il]+1\n\t"
		"ldd r14,Z+%[ih]\n\t"
		"ldd r15,Z+%[ih]+1\n\t"
		"ldd r16,Z+%[ih]+2\n\t"
		"ldd r17,Z+%[ih]+3\n\t" I_BYTE(0) I_BYTE(1) I_BYTE(2) I_BYTE(3)
		/* Clipped: hi >= lim = out_limit 2^8 gives lim, hi + lim < 0 gives -lim. */
		"ldd r22,Z+%[ol]\n\t"
		"ldd r23,Z+%[ol]+1\n\t"
		"cp r14,r19\n\t"
		"cpc r15,r22\n\t"
		"cpc r16,r23\n\t"
		"cpc r17,r19\n\t"
		"brlt 4f\n\t"
		"clr r12\n\t"
		"clr r13\n\t"
		"clr r14\n\t"
		"mov r15,r22\n\t"
		"mov r16,r23\n\t"
		"clr r17\n\t"
		"rjmp 5f\n"
		"4:\n\t"
		"mov r18,r15\n\t"
		"add r18,r22\n\t"
		"mov r18,r16\n\t"
		"adc r18,r23\n\t"
		"mov r18,r17\n\t"
		"adc r18,r19\n\t"
		"brge 5f\n\t"
		"clr r12\n\t"
		"clr r13\n\t"
		"clr r14\n\t"
		"mov r15,r22\n\t"
		"mov r16,r23\n\t"
		"com r16\n\t"
		"neg r15\n\t"
		"sbci r16,0xff\n\t"
		"ldi r17,0xff\n"
		/* u' = pdh 2^16 + pdl + i' in r12 (i's own), r20, r24..r27. */
		"5:\n\t"
		"add r20,r13\n\t"
		"adc r24,r14\n\t"
		"adc r25,r15\n\t"
		"adc r26,r16\n\t"
		"adc r27,r17\n\t"
		/* Winds up: e > 0 and u' > lim 2^16, or e < 0 and u' < -lim 2^16. */
		"brts 7f\n\t"
		"cp r19,r12\n\t"
		"cpc r19,r20\n\t"
		"cpc r19,r24\n\t"
		"cpc r22,r25\n\t"
		"cpc r23,r26\n\t"
		"cpc r19,r27\n\t"
		"brlt 10f\n\t"
		"rjmp 11f\n"
		"7:\n\t"
		"mov r18,r25\n\t"
		"add r18,r22\n\t"
		"mov r18,r26\n\t"
		"adc r18,r23\n\t"
		"mov r18,r27\n\t"
		"adc r18,r19\n\t"
		"brlt 10f\n"
		"11:\n\t"
		"std Z+%[il],r12\n\t"
		"std Z+%[il]+1,r13\n\t"
		"std Z+%[ih],r14\n\t"
		"std Z+%[ih]+1,r15\n\t"
		"std Z+%[ih]+2,r16\n\t"
		"std Z+%[ih]+3,r17\n\t"
		"rjmp 12f\n"
		/* It winds up: back to pdh 2^16 + pdl, then u with the integral kept. */
		"10:\n\t"
		"sub r20,r13\n\t"
		"sbc r24,r14\n\t"
		"sbc r25,r15\n\t"
		"sbc r26,r16\n\t"
		"sbc r27,r17\n\t"
		"rjmp 13f\n"
		"6:\n\t"
		"ldd r22,Z+%[ol]\n\t"
		"ldd r23,Z+%[ol]+1\n"
		"13:\n\t"
		"ldd r12,Z+%[il]\n\t"
		"ldd r13,Z+%[il]+1\n\t"
		"ldd r14,Z+%[ih]\n\t"
		"ldd r15,Z+%[ih]+1\n\t"
		"ldd r16,Z+%[ih]+2\n\t"
		"ldd r17,Z+%[ih]+3\n\t"
		"add r20,r13\n\t"
		"adc r24,r14\n\t"
		"adc r25,r15\n\t"
		"adc r26,r16\n\t"
		"adc r27,r17\n"
		/* The duty: T = u < 0; m = |u| rounded down to 2^-8 (~uh, + 1 if ul = 0); m >=
		 * lim gives out_limit, else (m + 128) >> 8; then the sign. */
		"12:\n\t"
		"bst r27,7\n\t"
		"brtc 14f\n\t"
		"com r24\n\t"
		"com r25\n\t"
		"com r26\n\t"
		"com r27\n\t"
		"or r12,r20\n\t"
		"brne 14f\n\t"
		"subi r24,0xff\n\t"
		"sbci r25,0xff\n\t"
		"sbci r26,0xff\n\t"
		"sbci r27,0xff\n"
		"14:\n\t"
		"cp r24,r19\n\t"
		"cpc r25,r22\n\t"
		"cpc r26,r23\n\t"
		"cpc r27,r19\n\t"
		"brlo 15f\n\t"
		"movw r20,r22\n\t"
		"rjmp 16f\n"
		"15:\n\t"
		"mov r20,r25\n\t"
		"mov r21,r26\n\t"
		"lsl r24\n\t"
		"adc r20,r19\n\t"
		"adc r21,r19\n"
		"16:\n\t"
		"brtc 17f\n\t"
		"com r21\n\t"
		"neg r20\n\t"
		"sbci r21,0xff\n"
		"17:\n\t"
		"std Z+%[out],r20\n\t"
		"std Z+%[out]+1,r21\n\t"
		"ldi r18,1\n"
		"9:\n\t"
		"clr r1"
		: "+r"(e), "=&r"(done), "=&r"(o)
		: "z"(c), [ol] "n"(offsetof(struct pid, cfg.out_limit_q15)),
		  [kp] "n"(offsetof(struct pid, kp_q12)), [kd] "n"(offsetof(struct pid, kd_q12)),
		  [ki] "n"(offsetof(struct pid, ki_q24)),
		  [pf] "n"(offsetof(struct pid, p_err_fast_um)),
		  [df] "n"(offsetof(struct pid, d_err_fast_um)),
		  [ih] "n"(offsetof(struct pid, i_acc_q24.hi)),
		  [il] "n"(offsetof(struct pid, i_acc_q24.lo)),
		  [prev] "n"(offsetof(struct pid, prev_err_um)),
		  [has] "n"(offsetof(struct pid, has_prev)),
		  [out] "n"(offsetof(struct pid, out_q15))
		: "r0", "r12", "r13", "r14", "r15", "r16", "r17", "r19", "r26", "r27", "memory");
	*err_um = e;
	*out = o;
	return done;
}
#endif

#if FX_AVR_MUL
/* Inlined into the caller (link-time optimisation): the call and its register saves would cost
 * about 40 cycles. */
#define PID_UPDATE_INLINE __attribute__((always_inline)) inline
#else
#define PID_UPDATE_INLINE
#endif

PID_UPDATE_INLINE int16_t pid_update(struct pid *c, int32_t err_um)
{
#if FX_AVR_MUL
	int16_t out;

	if (update_fast_avr(c, &err_um, &out))
		return out;
#endif
	return update_any(c, err_um);
}
