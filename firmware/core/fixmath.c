/* Fixed-point arithmetic for the control core (see fixmath.h): integer-only, rounded to nearest,
 * free of implementation-defined behaviour so that an AVR and a PC give the same bits. */
#include "fixmath.h"

/* A quarter wave in 128 steps, i = 0..128: sin(i pi / 256) [2^-30], and 2 pi cos(i pi / 256)
 * [2^-29], the derivative per turn, so that a residual angle in turns needs no conversion to
 * radians (a wide product less). 1032 bytes. */
static const int32_t sin_table_q30[129] = {
	0,          13176464,   26350943,   39521455,   52686014,   65842639,   78989349,
	92124163,   105245103,  118350194,  131437462,  144504935,  157550647,  170572633,
	183568930,  196537583,  209476638,  222384147,  235258165,  248096755,  260897982,
	273659918,  286380643,  299058239,  311690799,  324276419,  336813204,  349299266,
	361732726,  374111709,  386434353,  398698801,  410903207,  423045732,  435124548,
	447137835,  459083786,  470960600,  482766489,  494499676,  506158392,  517740883,
	529245404,  540670223,  552013618,  563273883,  574449320,  585538248,  596538995,
	607449906,  618269338,  628995660,  639627258,  650162530,  660599890,  670937767,
	681174602,  691308855,  701339000,  711263525,  721080937,  730789757,  740388522,
	749875788,  759250125,  768510122,  777654384,  786681534,  795590213,  804379079,
	813046808,  821592095,  830013654,  838310216,  846480531,  854523370,  862437520,
	870221790,  877875009,  885396022,  892783698,  900036924,  907154608,  914135678,
	920979082,  927683790,  934248793,  940673101,  946955747,  953095785,  959092290,
	964944360,  970651112,  976211688,  981625251,  986890984,  992008094,  996975812,
	1001793390, 1006460100, 1010975242, 1015338134, 1019548121, 1023604567, 1027506862,
	1031254418, 1034846671, 1038283080, 1041563127, 1044686319, 1047652185, 1050460278,
	1053110176, 1055601479, 1057933813, 1060106826, 1062120190, 1063973603, 1065666786,
	1067199483, 1068571464, 1069782521, 1070832474, 1071721163, 1072448455, 1073014240,
	1073418433, 1073660973, 1073741824,
};

static const uint32_t dsin_table_q29[129] = {
	3373259426, 3373005426, 3372243463, 3370973654, 3369196187, 3366911333, 3364119434,
	3360820910, 3357016260, 3352706055, 3347890945, 3342571655, 3336748986, 3330423815,
	3323597095, 3316269852, 3308443192, 3300118293, 3291296407, 3281978865, 3272167068,
	3261862496, 3251066699, 3239781303, 3228008008, 3215748587, 3203004886, 3189778824,
	3176072393, 3161887657, 3147226753, 3132091888, 3116485342, 3100409464, 3083866676,
	3066859469, 3049390404, 3031462112, 3013077294, 2994238717, 2974949218, 2955211703,
	2935029144, 2914404581, 2893341119, 2871841930, 2849910253, 2827549389, 2804762707,
	2781553638, 2757925678, 2733882383, 2709427377, 2684564340, 2659297018, 2633629216,
	2607564798, 2581107691, 2554261879, 2527031404, 2499420368, 2471432928, 2443073299,
	2414345753, 2385254615, 2355804266, 2325999142, 2295843731, 2265342575, 2234500266,
	2203321449, 2171810821, 2139973126, 2107813158, 2075335762, 2042545828, 2009448294,
	1976048144, 1942350409, 1908360163, 1874082525, 1839522657, 1804685764, 1769577092,
	1734201928, 1698565599, 1662673473, 1626530954, 1590143486, 1553516548, 1516655656,
	1479566361, 1442254249, 1404724939, 1366984082, 1329037363, 1290890495, 1252549225,
	1214019324, 1175306597, 1136416874, 1097356009, 1058129888, 1018744415, 979205524,
	939519168,  899691323,  859727989,  819635182,  779418942,  739085324,  698640402,
	658090268,  617441027,  576698803,  535869729,  494959956,  453975644,  412922964,
	371808100,  330637243,  289416593,  248152358,  206850752,  165517995,  124160312,
	82783930,   41395082,   0,
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

uint32_t fx_isqrt32(uint32_t v)
{
	return fx_isqrt32_rem(&v);
}

uint32_t fx_isqrt32_up(uint32_t v)
{
	uint32_t r = fx_isqrt32_rem(&v);

	return v != 0 ? r + 1u : r;
}

uint32_t fx_isqrt64(uint64_t v)
{
#ifdef ARCH_FX_ISQRT64 /* an arch folder's kernel (firmware/arch/armv7m), with the same bits */
	return ARCH_FX_ISQRT64(v);
#else
	uint64_t r, q;
	uint8_t m = 0;

	if ((v >> 32) == 0)
		return fx_isqrt32((uint32_t)v);
	/* The root of the top bits, then one Newton step: with v / 4^m in [2^30, 2^32), m in
	 * 1..16, r0 = fx_isqrt32(v / 4^m) 2^m is below sqrt(v) by less than 2^m, and the step
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
	r = (uint64_t)fx_isqrt32((uint32_t)(v >> (2 * m))) << m;
	q = v / r;
	r = (r + q) >> 1;
	if (r > 0xffffffffu)
		r = 0xffffffffu;
	if (r * r > v)
		r--;
	return (uint32_t)r;
#endif
}

/* The sine and cosine (s, c) of an angle in the first quadrant, moved on by q quarter turns. */
static inline void to_quadrant(uint8_t q, int32_t s, int32_t c, int32_t *sin_out, int32_t *cos_out)
{
	switch (q) {
	case 0:
		*sin_out = s;
		*cos_out = c;
		break;
	case 1:
		*sin_out = c;
		*cos_out = -s;
		break;
	case 2:
		*sin_out = -s;
		*cos_out = -c;
		break;
	default:
		*sin_out = -c;
		*cos_out = s;
		break;
	}
}

/* sin(a + d) = sin a + cos a d - sin a d^2/2 - cos a d^3/6 (+ sin a d^4/24, below 0.06 unit),
 * cos(a + d) = cos a - sin a d - cos a d^2/2 + sin a d^3/6, a the nearest table entry,
 * |d| <= pi/512. The first-order terms come from the derivative table at full precision; each
 * higher one is the previous times d/2 or d/3, which need only 16 bits. Error budget [units of
 * 2^-30]: table 0.5, first order 1, second 0.7, third 0.2, fourth 0.06: test_fixmath measures. */
void fx_sincos(uint32_t angle_turn32, int32_t *sin_q30, int32_t *cos_q30)
{
	uint8_t quadrant = (uint8_t)(angle_turn32 >> 24) >> 6;
	uint32_t u = angle_turn32 & 0x3fffffffu;
	/* Nearest entry: step 2^23, residual r in [-2^22, 2^22). */
	uint8_t i = (uint8_t)(fx_hi16(u + ((uint32_t)1 << 22)) >> 7);
	uint32_t base = (uint32_t)(uint16_t)((uint16_t)i << 7) << 16;
	uint8_t neg = u < base;
	uint32_t m = neg ? base - u : u - base; /* |r| <= 2^22 */
	/* |cos a d|, |sin a d| [2^-30], below 2^22.7. */
	uint32_t tc = fx_mul_q31_approx(dsin_table_q29[i], m);
	uint32_t ts = fx_mul_q31_approx(dsin_table_q29[128 - i], m);
	/* |d|/2 = pi m / 2^32 rad, as hq [2^-24 rad] <= 51472 (m / 2^6 is clamped to 16 bits at
	 * m = 2^22, an error of 2^-16 of it). */
	uint32_t m6 = ((m + 32) << 2) >> 8;
	uint16_t hq = fx_hi16(fx_mul_u16(m6 > 0xffffu ? 0xffffu : (uint16_t)m6, 51472u) + 0x8000u);
	/* Second order: |cos a| d^2/2 = tc |d|/2 and |sin a| d^2/2 = ts |d|/2, below 2^14.3
	 * [2^-30]: tc / 2^7 to 16 bits times hq, / 2^17. */
	uint16_t t2c = fx_hi16(fx_mul_u16((uint16_t)(((tc + 64) << 1) >> 8), hq) + 0x10000u) >> 1;
	uint16_t t2s = fx_hi16(fx_mul_u16((uint16_t)(((ts + 64) << 1) >> 8), hq) + 0x10000u) >> 1;
	/* Third order: d^3/6 = (d^2/2) (|d|/2) 2/3; h23 = hq 2/3 [2^-24 rad]. */
	uint16_t h23 = fx_hi16(fx_mul_u16(hq, 43691u) + 0x8000u);
	uint16_t t3c = fx_hi16(fx_mul_u16(t2c, h23) + 0x800000u) >> 8;
	uint16_t t3s = fx_hi16(fx_mul_u16(t2s, h23) + 0x800000u) >> 8;
	int32_t sa = sin_table_q30[i];
	int32_t ca = sin_table_q30[128 - i];
	int32_t s, c;

	if (neg) {
		s = sa - (int32_t)tc - t2s + t3c;
		c = ca + (int32_t)ts - t2c - t3s;
	} else {
		s = sa + (int32_t)tc - t2s - t3c;
		c = ca - (int32_t)ts - t2c + t3s;
	}
	if (s > FX_ONE_Q30)
		s = FX_ONE_Q30;
	if (c > FX_ONE_Q30)
		c = FX_ONE_Q30;
	if (s < 0)
		s = 0;
	if (c < 0)
		c = 0;

	to_quadrant(quadrant, s, c, sin_q30, cos_q30);
}

/* sin(i pi / 128) [2^-14], i = 0..64: 1 is exact. */
static const int16_t sin_table_q14[65] = {
	0,     402,   804,   1205,  1606,  2006,  2404,  2801,  3196,  3590,  3981,  4370,  4756,
	5139,  5520,  5897,  6270,  6639,  7005,  7366,  7723,  8076,  8423,  8765,  9102,  9434,
	9760,  10080, 10394, 10702, 11003, 11297, 11585, 11866, 12140, 12406, 12665, 12916, 13160,
	13395, 13623, 13842, 14053, 14256, 14449, 14635, 14811, 14978, 15137, 15286, 15426, 15557,
	15679, 15791, 15893, 15986, 16069, 16143, 16207, 16261, 16305, 16340, 16364, 16379, 16384,
};

/* Linear interpolation between entries 2^-8 turn apart: the error of the chord is at most
 * (pi/128)^2 / 8 = 7.5e-5, 1.2 units, plus the rounding. */
void fx_sincos_q14(uint32_t angle_turn32, int16_t *sin_q14, int16_t *cos_q14)
{
	uint8_t quadrant = (uint8_t)(angle_turn32 >> 24) >> 6;
	uint8_t i = (uint8_t)(angle_turn32 >> 24) & 63u;
	uint16_t f = (uint16_t)(angle_turn32 >> 8);
	/* The quarter wave rises: both differences are positive. */
	int16_t s =
		(int16_t)(sin_table_q14[i] +
			  fx_hi16(fx_mul_u16((uint16_t)(sin_table_q14[i + 1] - sin_table_q14[i]),
					     f) +
				  0x8000u));
	int16_t c = (int16_t)(sin_table_q14[64 - i] -
			      fx_hi16(fx_mul_u16((uint16_t)(sin_table_q14[64 - i] -
							    sin_table_q14[63 - i]),
						 f) +
				      0x8000u));
	int32_t so, co;

	to_quadrant(quadrant, s, c, &so, &co);
	*sin_q14 = (int16_t)so;
	*cos_q14 = (int16_t)co;
}

/* atan(t) on t = k / 32, k = 0..32 [turn * 2^32]; its derivative 1 / (1 + t^2) [turn * 2^32 / 2^16
 * per unit of t]; and t / (1 + t^2)^2, half the second derivative's magnitude [turn * 2^32 / 2^12].
 * 264 bytes. */
static const uint32_t atan_table[33] = {
	0,         21354465,  42667331,  63897482,  85004756,  105950391, 126697423,
	147211045, 167458907, 187411349, 207041579, 226325781, 245243172, 263775993,
	281909457, 299631651, 316933406, 333808132, 350251643, 366261957, 381839095,
	396984877, 411702716, 425997422, 439875013, 453342536, 466407904, 479079736,
	491367227, 503280012, 514828063, 526021581, 536870912,
};

static const uint16_t atan_slope[33] = {
	10430, 10420, 10390, 10340, 10270, 10182, 10076, 9954, 9817, 9666, 9502,
	9328,  9144,  8953,  8755,  8551,  8344,  8135,  7923, 7712, 7500, 7291,
	7083,  6877,  6675,  6477,  6283,  6093,  5907,  5727, 5551, 5381, 5215,
};

static const uint16_t atan_curve[33] = {
	0,     5205,  10349, 15374, 20224, 24848, 29202, 33248, 36957, 40308, 43285,
	45883, 48102, 49950, 51437, 52582, 53404, 53925, 54170, 54166, 53936, 53507,
	52904, 52150, 51267, 50277, 49198, 48047, 46842, 45594, 44318, 43024, 41722,
};

/* The angle of (x, y) with x >= y >= 0, x > 0, in 0..1/8 turn [turn * 2^32]: t = y / x to 20
 * bits by long division (20 steps of compare and subtract), then atan from the nearest of 33
 * entries with a second-order correction, d = t - t_k <= 2^-6:
 *   atan(t_k + d) = atan(t_k) + d / (1 + t_k^2) - d^2 t_k / (1 + t_k^2)^2 + O(d^3).
 * Error: t's floor 2^-20 (652 units of 2^-32 turn), the d^3 term left out (850), the roundings
 * (under 200): within the 4096 documented. */
static uint32_t atan_octant(uint32_t x, uint32_t y)
{
	uint32_t rem = y, q = 0, p;
	uint8_t k;
	int16_t d;
	int32_t a;
	uint16_t d2;

	if (y == 0)
		return 0;
	if (rem >= x) {
		rem -= x;
		q = 1;
	}
	q = fx_udiv_frac20(q, rem, x);
	/* q = t 2^20 <= 2^20; the nearest entry, 2^15 apart. */
	k = (uint8_t)fx_shr_u32(q + 0x4000u, 15);
	d = (int16_t)((int32_t)q - ((int32_t)k << 15)); /* |d| <= 2^14 */
	/* round(d slope / 16), ties away from zero (fx_mul_q(d, slope, 4)): one 16 x 16 product */
	p = fx_shr_u32(fx_mul_u16(d >= 0 ? (uint16_t)d : (uint16_t)-d, atan_slope[k]) + 8u, 4);
	a = (int32_t)atan_table[k] + (d >= 0 ? (int32_t)p : -(int32_t)p);
	d2 = (uint16_t)fx_shr_u32((uint32_t)fx_mul_s16(d, d), 13); /* d^2 [2^-27], <= 2^15 */
	return (uint32_t)(a - (int32_t)fx_shr_u32(fx_mul_u16(d2, atan_curve[k]), 15));
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
