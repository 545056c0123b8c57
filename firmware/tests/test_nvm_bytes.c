/* The calibration kept in byte storage (hal_nvm.h as ports/common/nvm_bytes.c does it: the AVR's
 * EEPROM, the host's RAM) against a model of an EEPROM that the test powers off at any byte
 * write: thousands of calibrations, each cut at a random write or not at all, and after each
 * power-on the board installs the last calibration whose record was complete, or the new one;
 * never none once one was kept, never a mix. A version-1 record (before the generation) is
 * still installed. The real nvm_bytes.c and calib_store.c, with its lower layer
 * (nvm_bytes_dev_*()) implemented here on the model. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <string.h>

#include <cmocka.h>

#include "calib_store.h"
#include "nvm_bytes.h"
#include "uncertainty.h"

#define EE_SIZE 64u

/* The EEPROM: a write is busy until the test lets it end (one per poll, as the AVR's 3.4 ms
 * against its main loop); the cut_at-th write is the one the power-off interrupts: it leaves
 * that byte anything (nvm_bytes.h), and nothing is written after it. nvm_bytes.c is given it as
 * its storage, and reaches it only through dev. */
static struct nvm_bytes_dev {
	uint8_t mem[EE_SIZE];
	uint8_t busy;
	uint8_t off;      /* the power is off: writes do nothing */
	uint32_t writes;  /* since the last power-on */
	uint32_t cut_at;  /* the write the power-off interrupts (UINT32_MAX: none) */
	uint8_t cut_byte; /* what that write leaves */
} ee;

static uint64_t rng_state = 0x2545f4914f6cdd1du;

static uint64_t rng_next(void)
{
	rng_state ^= rng_state << 13;
	rng_state ^= rng_state >> 7;
	rng_state ^= rng_state << 17;
	return rng_state;
}

uint16_t nvm_bytes_dev_size(struct nvm_bytes_dev *dev)
{
	assert_ptr_equal(dev, &ee);
	return EE_SIZE;
}

int nvm_bytes_dev_read(struct nvm_bytes_dev *dev, uint16_t offset, uint8_t *buf, uint16_t n)
{
	if ((uint32_t)offset + n > EE_SIZE)
		return -1;
	memcpy(buf, &dev->mem[offset], n);
	return 0;
}

uint8_t nvm_bytes_dev_busy(struct nvm_bytes_dev *dev)
{
	return dev->busy;
}

int nvm_bytes_dev_write(struct nvm_bytes_dev *dev, uint16_t offset, uint8_t value)
{
	if (offset >= EE_SIZE)
		return -1;
	if (dev->busy)
		return -2;
	if (dev->off)
		return 0;
	if (dev->writes++ == dev->cut_at) {
		dev->mem[offset] = dev->cut_byte;
		dev->off = 1;
		return 0;
	}
	dev->mem[offset] = value;
	dev->busy = 1;
	return 0;
}

/* A board as nvm_bytes.c needs it: the configuration board_set_calibration() reads. The rest of
 * the board (the control) plays no part here. */
static struct board board;

static void power_on_board(void)
{
	const struct uncertainty_config ucfg = {6554u, 6554u, 627u, 10u};
	const struct uncertainty_model model = {280000u, 7000u, 2000u, 3500u};

	memset(&board, 0, sizeof(board));
	board.cfg.odometry.left_um_per_count_q16 = 20u << 16;
	board.cfg.odometry.right_um_per_count_q16 = 20u << 16;
	board.cfg.odometry.track_um = 280000u;
	board.cfg.orders.drive_track_um = 280000u;
	board.cfg.calibrated.ratio_error_ppm = 500u;
	board.cfg.calibrated.track_error_um = 100u;
	board.cfg.calibrated.scale_error_ppm = 500u;
	assert_int_equal(uncertainty_init(&board.planner.uncertainty, &ucfg, 1000u, &model), 0);
}

static struct board_calibration random_cal(void)
{
	struct board_calibration c;

	c.ratio_ppm = (int32_t)(rng_next() % 60001u) - 30000;
	c.scale_ppm = (int32_t)(rng_next() % 60001u) - 30000;
	c.track_10um = (uint16_t)(20000u + rng_next() % 20000u);
	return c;
}

/* Power on: a new board loads the storage, as a port's start-up does. Returns 1 and *cal when a
 * calibration is installed. */
static int power_on(struct hal_nvm *s, struct board_calibration *cal)
{
	ee.busy = 0;
	ee.off = 0;
	ee.writes = 0;
	ee.cut_at = UINT32_MAX;
	power_on_board();
	nvm_bytes_init(s, &ee);
	if (hal_nvm_load(s, &board) != 0) {
		assert_false(board.planner.calibrated);
		return 0;
	}
	assert_true(board.planner.calibrated);
	*cal = board.planner.calibration;
	return 1;
}

/* The main loop until the record is written or the power is off; each pass ends the write in
 * progress first. */
static void run_main_loop(struct hal_nvm *s)
{
	for (int pass = 0; pass < 100 && !ee.off; pass++) {
		hal_nvm_poll(s, &board);
		if (!hal_nvm_pending(s))
			return;
		ee.busy = 0;
	}
}

static void assert_cal_equal(const struct board_calibration *a, const struct board_calibration *b)
{
	assert_int_equal(a->ratio_ppm, b->ratio_ppm);
	assert_int_equal(a->scale_ppm, b->scale_ppm);
	assert_int_equal(a->track_10um, b->track_10um);
}

/* The property. Each round: power on (the installed calibration must be the last good one),
 * then SET_ODOMETRIE with a random calibration, sometimes a second one while the first is half
 * written, and a power-off at a random write of the record (or none, or once it is written).
 * After it the next power-on installs the old calibration or the one the master sent; the new
 * one whenever its record was complete. Never nothing once a calibration was kept. */
static void soak(uint32_t rounds)
{
	struct hal_nvm s;
	struct board_calibration good, now, got;
	int have_good = power_on(&s, &good);
	uint32_t kept_new = 0, kept_old = 0;

	for (uint32_t r = 0; r < rounds; r++) {
		uint32_t left = NVM_BYTES_STEPS; /* the writes of the record to come */
		uint32_t cut;                    /* the one the cut interrupts; left and on: none */
		int ok;

		now = random_cal();
		assert_int_equal(board_set_calibration(&board, &now), 0);
		ee.cut_byte = (uint8_t)rng_next();
		if (rng_next() % 4u == 0)
			ee.cut_byte = 'a'; /* the cut left the byte whole */
		if (rng_next() % 8u == 0) {
			/* A second calibration after a few writes of the first: the write restarts
			 * with its record, in the same slot; the cut falls in the second. */
			uint8_t n = (uint8_t)(rng_next() % (NVM_BYTES_STEPS - 1u));

			for (uint8_t i = 0; i < n; i++) {
				hal_nvm_poll(&s, &board);
				ee.busy = 0;
			}
			now = random_cal();
			assert_int_equal(board_set_calibration(&board, &now), 0);
		}
		/* Byte 0 is spoilt first only when it reads 'a'. */
		if (ee.mem[(hal_nvm_pending(&s) ? s.slot : s.slot ^ 1u) * CALIB_STORE_SIZE] != 'a')
			left--;
		cut = (uint32_t)(rng_next() % (left + 4u));
		ee.cut_at = ee.writes + cut;
		run_main_loop(&s);
		assert_int_equal(ee.off, cut < left);

		ok = power_on(&s, &got);
		if (cut >= left || (cut == left - 1u && ee.cut_byte == 'a')) {
			/* Complete: the last write, byte 0, whole. */
			assert_true(ok);
			assert_cal_equal(&got, &now);
			kept_new += cut < left;
		} else if (have_good) {
			assert_true(ok); /* never nothing, never a mix */
			assert_cal_equal(&got, &good);
			kept_old++;
		} else {
			assert_false(ok); /* nothing was kept yet */
		}
		good = got;
		have_good = ok;
	}
	assert_true(kept_old > rounds / 2u); /* the soak did cut records half written */
	assert_true(kept_new > 0u);
}

static void test_power_cuts_keep_the_last_good_calibration_or_the_new_one(void **state)
{
	(void)state;
	memset(ee.mem, 0xFF, sizeof(ee.mem)); /* a new chip */
	soak(20000);
}

/* The first calibration of a new chip: before it is whole, nothing to keep (uncalibrated); the
 * record goes into slot 0, generation 0. */
static void test_first_record_goes_to_slot_0(void **state)
{
	struct hal_nvm s;
	struct board_calibration c = {1500, -700, 28037}, got;
	uint8_t rec[CALIB_STORE_SIZE];

	(void)state;
	memset(ee.mem, 0xFF, sizeof(ee.mem));
	assert_int_equal(power_on(&s, &got), 0);
	assert_int_equal(s.loaded, CALIB_STORE_BLANK);
	assert_int_equal(board_set_calibration(&board, &c), 0);
	run_main_loop(&s);
	calib_store_encode(&c, 0, rec);
	assert_memory_equal(&ee.mem[NVM_BYTES_CALIB_OFFSET], rec, CALIB_STORE_SIZE);
	for (unsigned i = CALIB_STORE_SIZE; i < EE_SIZE; i++)
		assert_int_equal(ee.mem[i], 0xFF);
	assert_int_equal(ee.writes, NVM_BYTES_STEPS - 1u); /* byte 0 blank: not spoilt */
	/* Loaded again: not written again. */
	assert_int_equal(power_on(&s, &got), 1);
	assert_cal_equal(&got, &c);
	run_main_loop(&s);
	assert_int_equal(ee.writes, 0);
}

/* A board updated from version 1 keeps its calibration: the record at offset 0 is installed,
 * and the next one goes into slot 1, generation 1, leaving it as the fallback. */
static void test_a_version_1_record_is_kept(void **state)
{
	struct hal_nvm s;
	struct board_calibration old = {-2000, 400, 27990}, c = {1500, -700, 28037}, got;
	uint8_t rec[CALIB_STORE_SIZE];
	uint16_t crc;

	(void)state;
	memset(ee.mem, 0xFF, sizeof(ee.mem));
	calib_store_encode(&old, 0, ee.mem);
	ee.mem[2] = CALIB_STORE_VERSION_1;
	crc = calib_store_crc16(ee.mem, 14);
	ee.mem[14] = (uint8_t)(crc >> 8);
	ee.mem[15] = (uint8_t)crc;
	memcpy(rec, ee.mem, sizeof(rec));
	assert_int_equal(power_on(&s, &got), 1);
	assert_cal_equal(&got, &old);
	assert_int_equal(board_set_calibration(&board, &c), 0);
	run_main_loop(&s);
	assert_memory_equal(ee.mem, rec, CALIB_STORE_SIZE); /* untouched */
	calib_store_encode(&c, 1, rec);
	assert_memory_equal(&ee.mem[CALIB_STORE_SIZE], rec, CALIB_STORE_SIZE);
	assert_int_equal(power_on(&s, &got), 1);
	assert_cal_equal(&got, &c);
	/* and the soak from there */
	soak(2000);
}

/* Whatever the two slots hold, the board installs the valid record of the newer generation, or
 * the only valid one, or none: random generations across the wrap, random corruption. */
static void test_load_takes_the_newest_valid_slot(void **state)
{
	(void)state;
	for (int n = 0; n < 20000; n++) {
		struct hal_nvm s;
		struct board_calibration c[2], got;
		uint8_t gen[2], valid[2];
		int want = -1;

		for (int i = 0; i < 2; i++) {
			c[i] = random_cal();
			gen[i] = (uint8_t)rng_next();
			calib_store_encode(&c[i], gen[i], &ee.mem[i * CALIB_STORE_SIZE]);
			valid[i] = rng_next() % 4u != 0;
			if (!valid[i]) /* a byte changed: torn, or an EEPROM fault */
				ee.mem[i * CALIB_STORE_SIZE + rng_next() % CALIB_STORE_SIZE] ^=
					(uint8_t)(1u + rng_next() % 255u);
		}
		if (valid[0] && valid[1])
			want = calib_store_newer(gen[1], gen[0]) ? 1 : 0;
		else if (valid[0] || valid[1])
			want = valid[1];
		if (power_on(&s, &got)) {
			assert_true(want >= 0);
			assert_cal_equal(&got, &c[want]);
			assert_int_equal(s.slot, want);
			assert_int_equal(s.gen, gen[want]);
		} else {
			assert_int_equal(want, -1);
		}
	}
}

int main(void)
{
	const struct CMUnitTest tests[] = {
		cmocka_unit_test(test_first_record_goes_to_slot_0),
		cmocka_unit_test(test_power_cuts_keep_the_last_good_calibration_or_the_new_one),
		cmocka_unit_test(test_a_version_1_record_is_kept),
		cmocka_unit_test(test_load_takes_the_newest_valid_slot),
	};

	return cmocka_run_group_tests(tests, NULL, NULL);
}
