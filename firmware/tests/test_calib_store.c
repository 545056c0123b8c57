/* The calibration record (ports/common/calib_store.c): what is encoded decodes to itself, a
 * blank storage is told apart, and a record with a wrong magic, version or CRC is never
 * accepted: every 1- and 2-bit error of a valid record, and random bytes (fuzz-style, from a
 * fixed seed). */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <string.h>

#include <cmocka.h>

#include "calib_store.h"

#define N_OF(a) (sizeof(a) / sizeof((a)[0]))

static uint64_t rng_state = 0x9e3779b97f4a7c15u;

/* xorshift64: deterministic test inputs. */
static uint64_t rng_next(void)
{
	rng_state ^= rng_state << 13;
	rng_state ^= rng_state >> 7;
	rng_state ^= rng_state << 17;
	return rng_state;
}

static struct board_calibration random_cal(void)
{
	struct board_calibration c;

	c.ratio_ppm = (int32_t)(rng_next() % 60001u) - 30000;
	c.scale_ppm = (int32_t)(rng_next() % 60001u) - 30000;
	c.track_10um = (uint16_t)rng_next();
	return c;
}

static void assert_cal_equal(const struct board_calibration *a, const struct board_calibration *b)
{
	assert_int_equal(a->ratio_ppm, b->ratio_ppm);
	assert_int_equal(a->scale_ppm, b->scale_ppm);
	assert_int_equal(a->track_10um, b->track_10um);
}

static void test_crc16_check_value(void **state)
{
	(void)state;
	assert_int_equal(calib_store_crc16((const uint8_t *)"123456789", 9), 0x29B1);
	assert_int_equal(calib_store_crc16(NULL, 0), 0xFFFF);
}

/* The layout calib_store.h documents, byte for byte. */
static void test_layout(void **state)
{
	const struct board_calibration c = {-2, 0x01020304, 28012};
	uint8_t r[CALIB_STORE_SIZE];
	uint16_t crc;

	(void)state;
	calib_store_encode(&c, 0xA7, r);
	assert_int_equal(r[0], 'a');
	assert_int_equal(r[1], 'c');
	assert_int_equal(r[2], CALIB_STORE_VERSION);
	assert_int_equal(r[3], 0xA7);
	assert_int_equal(calib_store_generation(r), 0xA7);
	assert_memory_equal(&r[4], ((const uint8_t[]){0xff, 0xff, 0xff, 0xfe}), 4);
	assert_memory_equal(&r[8], ((const uint8_t[]){1, 2, 3, 4}), 4);
	assert_int_equal(r[12] << 8 | r[13], 28012);
	crc = calib_store_crc16(r, 14);
	assert_int_equal(r[14], crc >> 8);
	assert_int_equal(r[15], crc & 0xff);
}

static void test_round_trip(void **state)
{
	const struct board_calibration edges[] = {
		{0, 0, 0},
		{30000, -30000, 65535},
		{-30000, 30000, 1},
		{0, 0, 28000},
	};
	struct board_calibration c, d;
	uint8_t r[CALIB_STORE_SIZE];

	(void)state;
	for (size_t i = 0; i < N_OF(edges); i++) {
		calib_store_encode(&edges[i], (uint8_t)i, r);
		assert_int_equal(calib_store_decode(r, &d), 0);
		assert_cal_equal(&d, &edges[i]);
	}
	for (int i = 0; i < 100000; i++) {
		uint8_t gen = (uint8_t)rng_next();

		c = random_cal();
		calib_store_encode(&c, gen, r);
		assert_int_equal(calib_store_decode(r, &d), 0);
		assert_cal_equal(&d, &c);
		assert_int_equal(calib_store_generation(r), gen);
	}
}

static void test_blank(void **state)
{
	uint8_t r[CALIB_STORE_SIZE];
	struct board_calibration d = {7, 8, 9};

	(void)state;
	memset(r, 0xFF, sizeof(r));
	assert_int_equal(calib_store_decode(r, &d), CALIB_STORE_BLANK);
	memset(r, 0x00, sizeof(r));
	assert_int_equal(calib_store_decode(r, &d), CALIB_STORE_BLANK);
	assert_int_equal(d.ratio_ppm, 7); /* untouched */
	assert_int_equal(d.scale_ppm, 8);
	assert_int_equal(d.track_10um, 9);
}

/* A valid record with its values outside board_set_calibration()'s range. */
static void test_range(void **state)
{
	const struct board_calibration bad[] = {
		{30001, 0, 28000},
		{-30001, 0, 28000},
		{0, 30001, 28000},
		{0, -30001, 28000},
		{INT32_MIN, INT32_MAX, 28000},
	};
	uint8_t r[CALIB_STORE_SIZE];
	struct board_calibration d;

	(void)state;
	for (size_t i = 0; i < N_OF(bad); i++) {
		calib_store_encode(&bad[i], 3, r);
		assert_int_equal(calib_store_decode(r, &d), CALIB_STORE_RANGE);
	}
}

/* CRC-16/CCITT has a Hamming distance of 4 at this length: every 1- and 2-bit error of the 128
 * bits is refused (the magic, version and generation bytes are covered by the CRC too). */
static void test_bit_errors_refused(void **state)
{
	uint8_t r[CALIB_STORE_SIZE], e[CALIB_STORE_SIZE];
	struct board_calibration d;

	(void)state;
	for (int n = 0; n < 20; n++) {
		struct board_calibration c = random_cal();

		calib_store_encode(&c, (uint8_t)rng_next(), r);
		for (unsigned i = 0; i < 8 * CALIB_STORE_SIZE; i++) {
			memcpy(e, r, sizeof(e));
			e[i / 8] ^= (uint8_t)(1u << (i % 8));
			assert_int_equal(calib_store_decode(e, &d), CALIB_STORE_CORRUPT);
			for (unsigned j = i + 1; j < 8 * CALIB_STORE_SIZE; j++) {
				e[j / 8] ^= (uint8_t)(1u << (j % 8));
				assert_int_equal(calib_store_decode(e, &d), CALIB_STORE_CORRUPT);
				e[j / 8] ^= (uint8_t)(1u << (j % 8));
			}
		}
	}
}

/* Fuzz-style: random bytes, then random bytes behind a valid header, with a CRC forced wrong:
 * never accepted. With the CRC right, accepted exactly when in range, and then the record is
 * the encoding of what it decoded to. */
static void test_random_bytes(void **state)
{
	uint8_t r[CALIB_STORE_SIZE], back[CALIB_STORE_SIZE];
	struct board_calibration d;
	long accepted = 0;

	(void)state;
	for (long n = 0; n < 1000000; n++) {
		uint16_t crc;
		int err;

		for (unsigned i = 0; i < CALIB_STORE_SIZE; i++)
			r[i] = (uint8_t)rng_next();
		if (n & 1) { /* a valid header: only the CRC can refuse it */
			r[0] = 'a';
			r[1] = 'c';
			r[2] = CALIB_STORE_VERSION;
			r[3] = (uint8_t)n;
		}
		if ((n & 3) == 3) { /* and values in range */
			struct board_calibration c = random_cal();
			uint8_t full[CALIB_STORE_SIZE];

			calib_store_encode(&c, 0, full);
			memcpy(&r[4], &full[4], 10);
		}
		crc = calib_store_crc16(r, 14);
		/* The CRC wrong, by any non-zero difference. */
		{
			uint16_t x = (uint16_t)rng_next();

			x = x ? x : 1u;
			r[14] = (uint8_t)((crc ^ x) >> 8);
			r[15] = (uint8_t)(crc ^ x);
		}
		err = calib_store_decode(r, &d);
		assert_true(err == CALIB_STORE_CORRUPT || err == CALIB_STORE_BLANK);
		if (!(n & 1))
			continue;
		/* The CRC right. */
		r[14] = (uint8_t)(crc >> 8);
		r[15] = (uint8_t)crc;
		err = calib_store_decode(r, &d);
		if (err == 0) {
			accepted++;
			calib_store_encode(&d, calib_store_generation(r), back);
			assert_memory_equal(back, r, CALIB_STORE_SIZE);
		} else {
			int32_t ratio = (int32_t)((uint32_t)r[4] << 24 | (uint32_t)r[5] << 16 |
						  (uint32_t)r[6] << 8 | r[7]);
			int32_t scale = (int32_t)((uint32_t)r[8] << 24 | (uint32_t)r[9] << 16 |
						  (uint32_t)r[10] << 8 | r[11]);

			assert_int_equal(err, CALIB_STORE_RANGE);
			assert_true(ratio < -30000 || ratio > 30000 || scale < -30000 ||
				    scale > 30000);
		}
	}
	assert_true(accepted >= 250000 - 1000); /* the in-range quarter, at least */
}

/* A version-1 record (the boards of before the generation: byte 3 reserved, 0) decodes as
 * generation 0, to the same calibration; with byte 3 not 0 (and its CRC right) it is refused. */
static void test_version_1_still_decodes(void **state)
{
	uint8_t r[CALIB_STORE_SIZE];
	struct board_calibration d;
	uint16_t crc;

	(void)state;
	for (int i = 0; i < 10000; i++) {
		struct board_calibration c = random_cal();

		calib_store_encode(&c, 0, r);
		r[2] = CALIB_STORE_VERSION_1;
		r[3] = (uint8_t)(i & 1 ? 0 : 1 + rng_next() % 255u);
		crc = calib_store_crc16(r, 14);
		r[14] = (uint8_t)(crc >> 8);
		r[15] = (uint8_t)crc;
		if (r[3] != 0) {
			assert_int_equal(calib_store_decode(r, &d), CALIB_STORE_CORRUPT);
			continue;
		}
		assert_int_equal(calib_store_decode(r, &d), 0);
		assert_cal_equal(&d, &c);
		assert_int_equal(calib_store_generation(r), 0);
	}
	/* Other versions: refused, with the CRC right. */
	for (unsigned v = 0; v < 256; v++) {
		if (v == CALIB_STORE_VERSION || v == CALIB_STORE_VERSION_1)
			continue;
		calib_store_encode(&(struct board_calibration){0, 0, 28000}, 0, r);
		r[2] = (uint8_t)v;
		crc = calib_store_crc16(r, 14);
		r[14] = (uint8_t)(crc >> 8);
		r[15] = (uint8_t)crc;
		assert_int_equal(calib_store_decode(r, &d), CALIB_STORE_CORRUPT);
	}
}

/* Serial-number order: a generation is newer than the 127 before it, older than the 128 after,
 * never newer than itself; the order is antisymmetric. */
static void test_generation_order(void **state)
{
	(void)state;
	for (unsigned a = 0; a < 256; a++) {
		assert_false(calib_store_newer((uint8_t)a, (uint8_t)a));
		for (unsigned d = 1; d < 256; d++) {
			uint8_t b = (uint8_t)(a - d);

			assert_int_equal(calib_store_newer((uint8_t)a, b), d < 128);
			if (d != 128)
				assert_int_equal(calib_store_newer(b, (uint8_t)a),
						 !calib_store_newer((uint8_t)a, b));
		}
	}
	assert_true(calib_store_newer(0, 255)); /* the wrap */
}

int main(void)
{
	const struct CMUnitTest tests[] = {
		cmocka_unit_test(test_crc16_check_value),
		cmocka_unit_test(test_layout),
		cmocka_unit_test(test_round_trip),
		cmocka_unit_test(test_blank),
		cmocka_unit_test(test_range),
		cmocka_unit_test(test_bit_errors_refused),
		cmocka_unit_test(test_random_bytes),
		cmocka_unit_test(test_version_1_still_decodes),
		cmocka_unit_test(test_generation_order),
	};

	return cmocka_run_group_tests(tests, NULL, NULL);
}
