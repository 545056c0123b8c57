/* The A/B rule (ports/common/calib_log.c) on the STM32's scheme, on the host: two flash logs,
 * programmed a 32-bit word at a time from 1 to 0 only, erased by whole areas. A model of the
 * writer follows docs/stm32.md ("Switching logs"): each record into the next free slot of the
 * active log, words 1, 2, 3 then 0; a full log compacted into the other area, erased first,
 * one generation on. Thousands of calibrations, the power cut at random moments of a word's
 * program (part of its bits done) and of an erase (part of the area's bits set back to 1); after
 * each cut the rule finds the newest whole record, never another. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <string.h>

#include <cmocka.h>

#include "calib_log.h"

#define SLOTS 16u /* per log: small, so that the soak switches logs often */
#define WORDS (CALIB_STORE_SIZE / 4u)

static uint8_t flash[CALIB_LOG_AREAS][SLOTS * CALIB_STORE_SIZE];

static uint64_t rng_state = 0x9e3779b97f4a7c15u;

static uint64_t rng_next(void)
{
	rng_state ^= rng_state << 13;
	rng_state ^= rng_state >> 7;
	rng_state ^= rng_state << 17;
	return rng_state;
}

static const uint8_t *read_flash(void *ctx, uint8_t area, uint16_t i, uint8_t buf[CALIB_STORE_SIZE])
{
	(void)ctx;
	(void)buf;
	return &flash[area][i * CALIB_STORE_SIZE];
}

static struct board_calibration random_cal(void)
{
	struct board_calibration c;

	c.ratio_ppm = (int32_t)(rng_next() % 60001u) - 30000;
	c.scale_ppm = (int32_t)(rng_next() % 60001u) - 30000;
	c.track_10um = (uint16_t)(20000u + rng_next() % 20000u);
	return c;
}

/* The writer, as the board restarts it from what the rule found. */
struct writer {
	uint8_t area, gen;
	uint16_t next;
};

static void restart(struct writer *w, struct calib_log_area l[CALIB_LOG_AREAS])
{
	calib_log_scan(read_flash, NULL, 0, SLOTS, &l[0]);
	calib_log_scan(read_flash, NULL, 1, SLOTS, &l[1]);
	w->area = calib_log_pick(l);
	w->gen = l[w->area].gen;
	w->next = l[w->area].next;
}

/* One word programmed, 1 to 0 only; cut: only a random part of its bits done. */
static void program(uint8_t *at, const uint8_t *word, int cut)
{
	for (uint8_t i = 0; i < 4; i++) {
		uint8_t done = cut ? (uint8_t)rng_next() : 0xFFu;

		at[i] &= (uint8_t)(word[i] | (uint8_t)~done);
	}
}

/* Returns 1 when the power was cut (the flash left as the cut leaves it). */
static int write_record(struct writer *w, const struct board_calibration *c, uint32_t cut_at)
{
	uint8_t rec[CALIB_STORE_SIZE];
	uint32_t op = 0;

	if (w->next >= SLOTS) {
		uint8_t other = (uint8_t)(w->area ^ 1u);

		if (op++ == cut_at) { /* the erase cut: part of the bits back to 1 */
			for (size_t i = 0; i < sizeof(flash[other]); i++)
				flash[other][i] |= (uint8_t)rng_next();
			return 1;
		}
		memset(flash[other], 0xFF, sizeof(flash[other]));
		w->area = other;
		w->gen++;
		w->next = 0;
	}
	calib_store_encode(c, w->gen, rec);
	for (uint8_t k = 0; k < WORDS; k++) {
		uint8_t word = (uint8_t)((k + 1u) & 3u);
		uint8_t *at = &flash[w->area][w->next * CALIB_STORE_SIZE + 4u * word];
		int cut = op++ == cut_at;

		program(at, &rec[4u * word], cut);
		if (cut)
			return 1;
	}
	w->next++;
	return 0;
}

static void assert_cal_equal(const struct board_calibration *a, const struct board_calibration *b)
{
	assert_int_equal(a->ratio_ppm, b->ratio_ppm);
	assert_int_equal(a->scale_ppm, b->scale_ppm);
	assert_int_equal(a->track_10um, b->track_10um);
}

static void test_cuts_across_log_switches_keep_the_newest_whole_record(void **state)
{
	struct calib_log_area l[CALIB_LOG_AREAS];
	struct board_calibration good = {0, 0, 0}, now;
	struct writer w;
	int have = 0;
	uint32_t cuts = 0, erase_cuts = 0, switches = 0;

	(void)state;
	memset(flash, 0xFF, sizeof(flash));
	restart(&w, l);
	for (uint32_t n = 0; n < 200000; n++) {
		uint8_t area = w.area;
		uint32_t cut_at = rng_next() % 4u == 0 ? (uint32_t)(rng_next() % 6u) : UINT32_MAX;
		uint8_t rec[CALIB_STORE_SIZE];
		int cut, whole;

		now = random_cal();
		cut = write_record(&w, &now, cut_at);
		switches += w.area != area;
		if (!cut) {
			good = now;
			have = 1;
			continue;
		}
		cuts++;
		erase_cuts += cut_at == 0 && w.next >= SLOTS;
		/* Did the cut happen to complete the record (word 0's bits all done)? */
		whole = 0;
		if (w.next < SLOTS) {
			calib_store_encode(&now, w.gen, rec);
			whole = !memcmp(&flash[w.area][w.next * CALIB_STORE_SIZE], rec,
					sizeof(rec));
		}
		restart(&w, l);
		if (whole) {
			assert_true(l[w.area].found);
			assert_cal_equal(&l[w.area].cal, &now); /* whole: the new one */
			good = now;
			have = 1;
			continue;
		}
		if (!have) {
			assert_false(l[0].found || l[1].found);
			continue;
		}
		assert_true(l[w.area].found); /* never nothing once one was kept */
		assert_cal_equal(&l[w.area].cal, &good);
	}
	print_message("%u cuts (%u in an erase), %u log switches\n", cuts, erase_cuts, switches);
	assert_true(erase_cuts > 100 && switches > 1000);
}

/* The rule's order on its own: the newer generation whichever area, across the wrap. */
static void test_pick_by_generation_across_the_wrap(void **state)
{
	struct calib_log_area l[CALIB_LOG_AREAS];

	(void)state;
	for (unsigned g = 0; g < 256; g++) {
		memset(l, 0, sizeof(l));
		l[0].found = l[1].found = 1;
		l[0].gen = (uint8_t)g;
		l[1].gen = (uint8_t)(g + 1u);
		assert_int_equal(calib_log_pick(l), 1);
		l[0].gen = (uint8_t)(g + 2u);
		assert_int_equal(calib_log_pick(l), 0);
	}
	memset(l, 0, sizeof(l));
	l[0].next = 5; /* none valid: the emptier */
	assert_int_equal(calib_log_pick(l), 1);
	l[1].next = 5;
	assert_int_equal(calib_log_pick(l), 0);
	l[1].found = 1;
	assert_int_equal(calib_log_pick(l), 1);
}

int main(void)
{
	const struct CMUnitTest tests[] = {
		cmocka_unit_test(test_cuts_across_log_switches_keep_the_newest_whole_record),
		cmocka_unit_test(test_pick_by_generation_across_the_wrap),
	};

	return cmocka_run_group_tests(tests, NULL, NULL);
}
