/* The odometry calibration across a power cycle on the AVR binary in simavr, against the host
 * port (firmware/ports/host) doing the same: SET_ODOMETRIE, then the EEPROM holds the record the
 * host port's storage holds, byte for byte; after a power cycle (a new chip, the same EEPROM:
 * avrsim_power_cycle()) VERSION says CALIBRATED and the odometry's factors in the AVR's RAM are
 * the host's after its own power cycle, bit for bit, and those SET_ODOMETRIE had installed. A
 * corrupt record leaves the board uncalibrated, on the nominal factors, answering. A power cut
 * at any tick of a record's write leaves the previous calibration or the new one installed; so
 * does a watchdog reset or a brown-out there (issue 28, item 4), the RAM kept or scrambled,
 * reported at the master's next poll with the pose refused. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <string.h>

#include <cmocka.h>

#include "avrsim.h"
#include "calib_store.h"
#include "host.h"
#include "protocol.h"
#include "robot.h"

/* The AVR's capabilities: position fixes, match play and the quiet servo are compiled out
 * (docs/avr.md); it reports its resets (RESET_INFO) but does not keep the pose across them (no
 * KEEP_POSE). */
#define AVR_CAPS                                                                                   \
	((CAP_ALL &                                                                                \
	  ~(CAP_FIX | CAP_PAUSE | CAP_SPEED_SCALE | CAP_QUEUE | CAP_CORNERS | CAP_QUIET_SERVO)) |  \
	 CAP_RESET_INFO)

static const char *elf_path;

/* SET_ODOMETRIE ratio 1500 ppm, track 280.37 mm, scale -700 ppm (big-endian s16, u16, s16). */
static const uint8_t set_odometrie[] = {PROTO_SET_ODOMETRIE, 0x05, 0xdc, 0x6d, 0x85, 0xfd, 0x44};
static const struct board_calibration cal = {1500, -700, 28037};

struct factors {
	uint32_t left, right, track;
};

static void run_ticks(struct avrsim *h, unsigned n)
{
	for (unsigned t = 0; t < n; t++)
		assert_int_equal(avrsim_run_to_tick_end(h), 0);
}

static uint16_t version_caps(struct avrsim *h)
{
	uint8_t d = PROTO_VERSION, r[4];

	assert_int_equal(avrsim_i2c_write(h, &d, 1, 0), 0);
	assert_int_equal(avrsim_i2c_read(h, r, sizeof(r)), 0);
	assert_int_equal(r[0], PROTO_VERSION_MAJOR);
	return (uint16_t)(r[2] << 8 | r[3]);
}

static uint32_t peek32(const struct avrsim *h, uint16_t offset)
{
	uint32_t v;

	avrsim_peek(h, (uint16_t)(avrsim_board(h) + offset), &v, sizeof(v));
	return v;
}

static struct factors avr_factors(const struct avrsim *h)
{
	const struct avr_layout *l = avrsim_layout(h);
	struct factors f = {peek32(h, l->odo_left_factor), peek32(h, l->odo_right_factor),
			    peek32(h, l->odo_track)};

	return f;
}

static uint8_t avr_calibrated(const struct avrsim *h, struct board_calibration *c)
{
	const struct avr_layout *l = avrsim_layout(h);
	uint8_t on;
	uint16_t track;

	avrsim_peek(h, (uint16_t)(avrsim_board(h) + l->calibrated), &on, 1);
	c->ratio_ppm = (int32_t)peek32(h, l->calibration);
	c->scale_ppm = (int32_t)peek32(h, (uint16_t)(l->calibration + 4u));
	avrsim_peek(h, (uint16_t)(avrsim_board(h) + l->calibration + 8u), &track, 2);
	c->track_10um = track;
	return on;
}

static struct factors host_factors(const struct host *h)
{
	const struct odometry_config *c = &h->board.servo.counter.cfg;
	struct factors f = {c->left_um_per_count_q16, c->right_um_per_count_q16, c->track_um};

	return f;
}

static void assert_factors_equal(struct factors a, struct factors b)
{
	assert_int_equal(a.left, b.left);
	assert_int_equal(a.right, b.right);
	assert_int_equal(a.track, b.track);
}

/* The host port on the AVR build's configuration (robot.c), the robot at rest. */
static void host_start(struct host *h)
{
	struct board_config bc;
	struct sim_config sc;
	struct sim_field f;

	avr_robot_config(&bc);
	sim_config_defaults(&sc);
	sim_field_defaults(&f);
	assert_int_equal(host_init(h, &bc, &sc, &f), 0);
}

static void test_calibration_survives_power_cycle(void **state)
{
	static struct host host;
	struct avrsim *h = avrsim_open(elf_path, 100000);
	uint8_t ee[CALIB_STORE_SIZE], blank[CALIB_STORE_SIZE];
	struct factors nominal, installed;
	struct board_calibration c;

	(void)state;
	assert_non_null(h);
	host_start(&host);
	memset(blank, 0xFF, sizeof(blank));

	/* A new chip: blank EEPROM, uncalibrated. */
	run_ticks(h, 20);
	assert_int_equal(avrsim_eeprom_read(h, 0, ee, sizeof(ee)), 0);
	assert_memory_equal(ee, blank, sizeof(ee));
	assert_int_equal(version_caps(h), AVR_CAPS);
	assert_int_equal(avr_calibrated(h, &c), 0);
	nominal = avr_factors(h);
	assert_factors_equal(nominal, host_factors(&host));

	/* SET_ODOMETRIE on both; the record is written within 16 slow periods (one byte a pass of
	 * the main loop at most). */
	assert_int_equal(avrsim_i2c_write(h, set_odometrie, sizeof(set_odometrie), 1), 0);
	host_i2c_write(&host, set_odometrie, sizeof(set_odometrie), 1);
	run_ticks(h, 200);
	for (int t = 0; t < 200; t++)
		host_tick(&host);
	assert_int_equal(version_caps(h), AVR_CAPS | CAP_CALIBRATED);
	installed = avr_factors(h);
	assert_factors_equal(installed, host_factors(&host));
	assert_true(installed.left != nominal.left && installed.track != nominal.track);
	assert_int_equal(avrsim_eeprom_read(h, 0, ee, sizeof(ee)), 0);
	assert_memory_equal(ee, host.storage.mem, sizeof(ee));
	assert_int_equal(calib_store_decode(ee, &c), 0);
	assert_int_equal(c.ratio_ppm, cal.ratio_ppm);
	assert_int_equal(c.scale_ppm, cal.scale_ppm);
	assert_int_equal(c.track_10um, cal.track_10um);

	/* Power cycle both: calibrated again, on the same factors, bit for bit. */
	h = avrsim_power_cycle(h);
	assert_non_null(h);
	assert_int_equal(host_power_cycle(&host), 0);
	run_ticks(h, 20);
	for (int t = 0; t < 20; t++)
		host_tick(&host);
	assert_int_equal(version_caps(h), AVR_CAPS | CAP_CALIBRATED);
	assert_int_equal(avr_calibrated(h, &c), 1);
	assert_int_equal(c.ratio_ppm, cal.ratio_ppm);
	assert_int_equal(c.scale_ppm, cal.scale_ppm);
	assert_int_equal(c.track_10um, cal.track_10um);
	assert_int_equal(host.board.planner.calibrated, 1);
	assert_factors_equal(avr_factors(h), installed);
	assert_factors_equal(avr_factors(h), host_factors(&host));
	/* Nothing written again: the record is the one loaded. */
	assert_int_equal(avrsim_eeprom_read(h, 0, ee, sizeof(ee)), 0);
	assert_memory_equal(ee, host.storage.mem, sizeof(ee));
	avrsim_close(h);
}

static void test_corrupt_record_uncalibrated(void **state)
{
	struct avrsim *h = avrsim_open(elf_path, 100000);
	uint8_t rec[CALIB_STORE_SIZE];
	struct factors nominal;
	struct board_calibration c;

	(void)state;
	assert_non_null(h);
	run_ticks(h, 20);
	nominal = avr_factors(h);
	for (unsigned bit = 0; bit < 8 * CALIB_STORE_SIZE; bit += 37) {
		calib_store_encode(&cal, 0, rec);
		rec[bit / 8] ^= (uint8_t)(1u << (bit % 8));
		assert_int_equal(avrsim_eeprom_write(h, 0, rec, sizeof(rec)), 0);
		h = avrsim_power_cycle(h);
		assert_non_null(h);
		run_ticks(h, 20);
		assert_int_equal(version_caps(h), AVR_CAPS);
		assert_int_equal(avr_calibrated(h, &c), 0);
		assert_factors_equal(avr_factors(h), nominal);
	}
	/* The same record intact: installed. */
	calib_store_encode(&cal, 0, rec);
	assert_int_equal(avrsim_eeprom_write(h, 0, rec, sizeof(rec)), 0);
	h = avrsim_power_cycle(h);
	assert_non_null(h);
	run_ticks(h, 20);
	assert_int_equal(version_caps(h), AVR_CAPS | CAP_CALIBRATED);
	avrsim_close(h);
}

static uint8_t same_cal(const struct board_calibration *a, const struct board_calibration *b)
{
	return a->ratio_ppm == b->ratio_ppm && a->scale_ppm == b->scale_ppm &&
	       a->track_10um == b->track_10um;
}

/* A board with an older calibration in slot 0 gets SET_ODOMETRIE, and the power goes ticks
 * and cycles later. Returns what the cut left in slot 1 (the new record's) in slot1, and the
 * calibration the board installs at the next start in *c (which must be one). */
static struct avrsim *cut_after(struct avrsim *h, unsigned ticks, uint64_t cycles,
				uint8_t slot1[CALIB_STORE_SIZE], struct board_calibration *c)
{
	static const struct board_calibration older = {-2000, 400, 27990};
	uint8_t rec[2 * CALIB_STORE_SIZE];

	memset(rec, 0xFF, sizeof(rec));
	calib_store_encode(&older, 0, rec);
	assert_int_equal(avrsim_eeprom_write(h, 0, rec, sizeof(rec)), 0);
	h = avrsim_power_cycle(h);
	assert_non_null(h);
	run_ticks(h, 20);
	assert_int_equal(avr_calibrated(h, c), 1);
	assert_true(same_cal(c, &older));
	assert_int_equal(avrsim_i2c_write(h, set_odometrie, sizeof(set_odometrie), 1), 0);
	run_ticks(h, ticks);
	if (cycles)
		assert_int_equal(avrsim_run_cycles(h, cycles), 0);
	h = avrsim_power_cycle(h); /* the cut */
	assert_non_null(h);
	assert_int_equal(avrsim_eeprom_read(h, CALIB_STORE_SIZE, slot1, CALIB_STORE_SIZE), 0);
	run_ticks(h, 20);
	assert_int_equal(avr_calibrated(h, c), 1); /* never nothing */
	assert_int_equal(version_caps(h), AVR_CAPS | CAP_CALIBRATED);
	assert_true(same_cal(c, &older) || same_cal(c, &cal)); /* never a mix */
	return h;
}

/* Cuts before, inside and after the record's write into slot 1: the tick it is written in
 * found first, then the cycles of that tick, coarse then by 10 cycles across the write. The
 * board comes back with the older calibration until the record is whole, the new one once it
 * is (simavr writes an EEPROM byte at once: the cut of a byte half written is the host test's,
 * firmware/tests/test_nvm_bytes.c). */
static void test_power_cut_during_the_write(void **state)
{
	struct avrsim *h = avrsim_open(elf_path, 100000);
	uint8_t want[CALIB_STORE_SIZE], blank[CALIB_STORE_SIZE], slot1[CALIB_STORE_SIZE];
	struct board_calibration c;
	unsigned tick = 0;
	uint64_t from = 0;
	int torn = 0, cuts = 0;

	(void)state;
	assert_non_null(h);
	calib_store_encode(&cal, 1, want);
	memset(blank, 0xFF, sizeof(blank));
	for (; tick <= 40; tick++) { /* the tick after which slot 1 is written */
		h = cut_after(h, tick, 0, slot1, &c);
		if (memcmp(slot1, blank, sizeof(slot1)) != 0)
			break;
	}
	assert_true(tick > 0 && tick <= 40);
	for (from = 0; from < 16000; from += 500) { /* the 500 cycles of the write's start */
		h = cut_after(h, tick - 1u, from + 500u, slot1, &c);
		if (memcmp(slot1, blank, sizeof(slot1)) != 0)
			break;
	}
	for (uint64_t at = from; at <= from + 2000u; at += 10u) {
		h = cut_after(h, tick - 1u, at, slot1, &c);
		cuts++;
		if (memcmp(slot1, want, sizeof(slot1)) == 0) {
			assert_true(same_cal(&c, &cal)); /* whole: the new one */
		} else {
			assert_false(same_cal(&c, &cal)); /* not whole: the older one */
			torn += memcmp(slot1, blank, sizeof(slot1)) != 0;
		}
	}
	print_message("%d cuts across the write of the record, %d of them left it torn\n", cuts,
		      torn);
	assert_true(torn > 0); /* some cuts fell inside the write */
	avrsim_close(h);
}

/* ---------------------------------------------------------------------------------------------
 * A reset that is not a power-on during the write (issue 28, item 4): a watchdog reset or a
 * brown-out, the RAM kept or scrambled (avrsim_reset()), at a random moment of the record's
 * write. simavr writes an EEPROM byte at once, where the chip takes 3.4 ms with the main loop
 * going on: a reset between two of the firmware's byte writes is, on the chip, one during the
 * last of them. After a watchdog reset the chip finishes that byte (the datasheet's 8.3.1: a
 * reset during a write completes it, the supply sufficient); a brown-out may leave it anything
 * (nvm_bytes.h), and the test tears it so, drawn at random. */

#define RESET_CASES 10

static uint32_t draw(uint32_t *rng, uint32_t n)
{
	*rng = *rng * 1664525u + 1013904223u; /* Numerical Recipes' LCG */
	return (*rng >> 8) % n;
}

static void query(struct avrsim *h, uint8_t designation, uint8_t *out, uint8_t n)
{
	assert_int_equal(avrsim_i2c_write(h, &designation, 1, 0), 0);
	assert_int_equal(avrsim_i2c_read(h, out, n), 0);
}

static void put16(uint8_t *b, int v)
{
	b[0] = (uint8_t)((unsigned)v >> 8);
	b[1] = (uint8_t)v;
}

static uint8_t check_busy(struct avrsim *h)
{
	uint8_t s;

	query(h, PROTO_CHECK_BUSY, &s, 1);
	return s;
}

static void send_calibration(struct avrsim *h, const struct board_calibration *c)
{
	uint8_t f[7] = {PROTO_SET_ODOMETRIE};

	put16(&f[1], (int)c->ratio_ppm);
	put16(&f[3], c->track_10um);
	put16(&f[5], (int)c->scale_ppm);
	assert_int_equal(avrsim_i2c_write(h, f, sizeof(f), 1), 0);
}

/* The calibration the board must load from the two slots: the valid record of the newer
 * generation (calib_store_newer(), docs/calibration.md); 0 when none is valid. */
static uint8_t eeprom_newest(const struct avrsim *h, struct board_calibration *c)
{
	uint8_t rec[2][CALIB_STORE_SIZE];
	struct board_calibration s[2];
	int ok[2];

	assert_int_equal(avrsim_eeprom_read(h, 0, &rec[0][0], sizeof(rec)), 0);
	for (int i = 0; i < 2; i++)
		ok[i] = calib_store_decode(rec[i], &s[i]) == 0;
	if (ok[0] && ok[1])
		*c = s[calib_store_newer(calib_store_generation(rec[1]),
					 calib_store_generation(rec[0]))];
	else if (ok[0] || ok[1])
		*c = s[ok[1]];
	return (uint8_t)(ok[0] || ok[1]);
}

static struct board_calibration random_calibration(uint32_t *rng)
{
	struct board_calibration c = {(int32_t)draw(rng, 6001) - 3000,
				      (int32_t)draw(rng, 6001) - 3000,
				      (uint16_t)(27500 + draw(rng, 1001))};

	return c;
}

static void test_reset_during_the_write(void **state)
{
	uint32_t rng = 28;
	int inside = 0, torn_bytes = 0, news = 0;

	(void)state;
	for (int k = 0; k < RESET_CASES; k++) {
		uint8_t brown_out = k % 2, keep_ram = (k / 2) % 2, moving = (uint8_t)draw(&rng, 2);
		uint8_t kept = draw(&rng, 4) != 0, newest_slot = (uint8_t)draw(&rng, 2);
		uint8_t gen = (uint8_t)draw(&rng, 256), ee[2 * CALIB_STORE_SIZE];
		uint8_t was[2 * CALIB_STORE_SIZE], now[2 * CALIB_STORE_SIZE];
		uint8_t info[PROTO_RESET_INFO_REPLY_LEN], dbg[PROTO_DEBUG_REPLY_LEN];
		uint8_t pos[PROTO_POSITION_REPLY_LEN], rej[3], s, on;
		struct board_calibration old = random_calibration(&rng);
		struct board_calibration newc = random_calibration(&rng), c, e;
		struct board_calibration older = random_calibration(&rng);
		struct avrsim *h = avrsim_open(elf_path, 400000);
		int last_at = -1, steps_after = -1, extra = (int)draw(&rng, 64);
		uint64_t spent = 0, into = 0; /* [cycles] since the write's first byte */
		unsigned coarse = k % 5 == 4;

		assert_non_null(h);
		/* The EEPROM as earlier calibrations left it: the newest in one slot, the other
		 * blank or one generation older; or blank (none kept yet). */
		memset(ee, 0xFF, sizeof(ee));
		if (kept) {
			calib_store_encode(&old, gen, &ee[newest_slot * CALIB_STORE_SIZE]);
			if (draw(&rng, 2))
				calib_store_encode(&older, (uint8_t)(gen - 1u),
						   &ee[(newest_slot ^ 1u) * CALIB_STORE_SIZE]);
		}
		assert_int_equal(avrsim_eeprom_write(h, 0, ee, sizeof(ee)), 0);
		h = avrsim_power_cycle(h);
		assert_non_null(h);
		run_ticks(h, 20);
		assert_int_equal(avr_calibrated(h, &c), kept);
		assert_true(!kept || same_cal(&c, &old));
		if (moving) { /* a GOTO runs (no physics: the robot stays, the order goes on) */
			static const uint8_t f[] = {PROTO_GOTO, 0x01, 0x2c, 0xff, 0x38, 0};

			assert_int_equal(avrsim_i2c_write(h, f, sizeof(f), 1), 0);
			run_ticks(h, 10 + draw(&rng, 100));
			assert_true(check_busy(h) & STATUS_BUSY_TRAJET);
		}
		send_calibration(h, &newc);

		/* The moment: anywhere in the 20 ticks that follow (mostly before or after the
		 * write), or `extra` steps of 1 to 64 cycles after the write's first byte. */
		avrsim_eeprom_read(h, 0, was, sizeof(was));
		if (coarse) {
			run_ticks(h, draw(&rng, 20));
			assert_int_equal(avrsim_run_cycles(h, draw(&rng, 16000)), 0);
		} else {
			while (steps_after < extra) {
				uint64_t d = 1u + draw(&rng, 64);

				assert_int_equal(avrsim_run_cycles(h, d), 0);
				spent += d;
				assert_true(spent < 40u * 16000u); /* the write came */
				avrsim_eeprom_read(h, 0, now, sizeof(now));
				for (int i = 0; i < (int)sizeof(now); i++)
					if (now[i] != was[i])
						last_at = i;
				if (memcmp(now, was, sizeof(now)) != 0 || steps_after >= 0) {
					steps_after++;
					into += steps_after ? d : 0;
				}
				memcpy(was, now, sizeof(was));
			}
			inside++;
		}
		if (brown_out && last_at >= 0 && draw(&rng, 2)) { /* the byte being written, torn */
			uint8_t v = (uint8_t)draw(&rng, 256);

			torn_bytes++;
			assert_int_equal(avrsim_eeprom_write(h, (uint16_t)last_at, &v, 1), 0);
		}
		assert_int_equal(avrsim_reset(h,
					      brown_out ? AVRSIM_BORF : AVRSIM_WDRF | AVRSIM_EXTRF,
					      keep_ram, rng),
				 0);
		run_ticks(h, 20);

		/* The master's next poll: reported, abandoned (this build cannot tell whether an
		 * order ran), the pose refused. */
		s = check_busy(h);
		assert_true(s & STATUS_PB_MOTEUR);
		assert_false(s & STATUS_BUSY_TRAJET);
		query(h, PROTO_RESET_INFO, info, sizeof(info));
		assert_int_equal(info[0], brown_out ? RESET_CAUSE_BROWN_OUT : RESET_CAUSE_WATCHDOG);
		assert_int_equal(info[1], 1);
		assert_int_equal(info[2], 1); /* pose_lost */
		query(h, PROTO_DEBUG, dbg, sizeof(dbg));
		assert_int_equal(dbg[21], END_REASON_RESET);
		query(h, PROTO_POSITION, pos, sizeof(pos));
		assert_int_equal(pos[5], 255);
		{
			static const uint8_t f[] = {PROTO_GOTO, 0, 0, 0, 0, 0};

			assert_int_equal(avrsim_i2c_write(h, f, sizeof(f), 1), 0);
			run_ticks(h, 10);
			query(h, PROTO_LAST_REJECT, rej, sizeof(rej));
			assert_int_equal(rej[0], REJECT_REFUSED_NO_POSE);
		}

		/* The calibration: the newest whole record, the old one or the new one, never a
		 * mix, never none once one was kept. */
		on = avr_calibrated(h, &c);
		assert_int_equal(on, eeprom_newest(h, &e));
		assert_true(!on || same_cal(&c, &e));
		assert_true(on || !kept);
		assert_true(!on || same_cal(&c, &old) || same_cal(&c, &newc));
		assert_int_equal(version_caps(h) & CAP_CALIBRATED, on ? CAP_CALIBRATED : 0);
		news += on && same_cal(&c, &newc) && !same_cal(&c, &old);
		print_message("case %d: %s, RAM %s, %s, %s; ", k,
			      brown_out ? "brown-out" : "watchdog", keep_ram ? "kept" : "scrambled",
			      kept ? "a calibration kept" : "none kept",
			      moving ? "in a GOTO" : "at rest");
		if (coarse)
			print_message("at a random moment: ");
		else
			print_message("%u cycles into the write: ", (unsigned)into);
		print_message("%s\n", !on                   ? "none"
				      : same_cal(&c, &newc) ? "the new one"
							    : "the old one");
		/* The board does not finish a torn record: it runs with what it loaded, and the
		 * EEPROM stays as the reset left it. The master sends it again: kept. */
		avrsim_eeprom_read(h, 0, was, sizeof(was));
		run_ticks(h, 40);
		avrsim_eeprom_read(h, 0, now, sizeof(now));
		assert_memory_equal(now, was, sizeof(now));
		send_calibration(h, &newc);
		run_ticks(h, 40);
		assert_int_equal(avr_calibrated(h, &c), 1);
		assert_true(same_cal(&c, &newc));
		assert_int_equal(eeprom_newest(h, &e), 1);
		assert_true(same_cal(&e, &newc));
		h = avrsim_power_cycle(h);
		assert_non_null(h);
		run_ticks(h, 20);
		assert_int_equal(avr_calibrated(h, &c), 1);
		assert_true(same_cal(&c, &newc));
		avrsim_close(h);
	}
	print_message("%d resets inside the write, %d bytes torn, %d left the new one\n", inside,
		      torn_bytes, news);
	assert_true(inside > 0 && torn_bytes > 0 && news > 0);
}

int main(int argc, char **argv)
{
	const struct CMUnitTest tests[] = {
		cmocka_unit_test(test_calibration_survives_power_cycle),
		cmocka_unit_test(test_corrupt_record_uncalibrated),
		cmocka_unit_test(test_power_cut_during_the_write),
		cmocka_unit_test(test_reset_during_the_write),
	};

	if (argc != 2) {
		fprintf(stderr, "usage: %s asserv_avr.elf\n", argv[0]);
		return 2;
	}
	elf_path = argv[1];
	return cmocka_run_group_tests(tests, NULL, NULL);
}
