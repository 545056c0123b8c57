/* The specification's annex session (docs/protocol.md section 11) played by an I2C master at
 * 400 kHz against the AVR binary in simavr on the robot physics (exact lockstep, avrsim.h), and
 * the same master bytes at the same ticks against the native build of the core on the same
 * physics (ref.h): every control tick, the odometry state in the AVR's RAM (x, y in um * 2^16,
 * the heading, the counts it integrated) and the duties it output equal the native ones bit for
 * bit, and so does every byte the master reads (test_annex_replies for POSITION's error radius,
 * kept apart because the odometry does not depend on it); the session ends where the annex
 * says. With two rates (robot.c's slow_shift, which both runs have) the native run does the
 * slow steps right after the tick; the master waits for the AVR's to be done before it acts,
 * so that both see the same queue and snapshot (if they are not done by the next tick, the
 * master waits that tick out on both sides). */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <string.h>
#include <math.h>

#include <cmocka.h>

#include "robot.h"
#include "avrsim.h"
#include "ref.h"

#define SEED 6u
#define MAX_SECONDS 40u

static const char *elf_path;

/* The physics of the robot robot.c describes: the simulator's default robot with 48-count
 * motor encoders, one robot off the shelf (seeded errors), put down 300 mm in front of the pose
 * the board starts from (board_default_config(): against the border, where it could not turn
 * on the spot); the master declares that first (SET_NEW_POS). */
#define START_OFFSET_MM 300

static void physics(const struct board_config *bc, struct sim_config *sc, struct sim_field *f)
{
	sim_config_defaults(sc);
	sc->motor.encoder_cpr = 48;
	sc->start.x_mm = bc->start.x_um / 1000.0;
	sc->start.y_mm = bc->start.y_um / 1000.0 + START_OFFSET_MM;
	sc->start.heading_rad = 0.0;
	sim_config_randomize(sc, SEED);
	sim_field_defaults(f);
}

/* The master: where the robot really is (SET_NEW_POS: estimate - truth = -300 mm in y), then the
 * annex's writes, its `while (BUSY_TRAJET)` as a CHECK_BUSY read every 10 ms, and a POSITION read
 * (write, repeated start, read) after each GOTO. */
enum { ACT_WRITE, ACT_WAIT_IDLE, ACT_POSITION, ACT_END };

struct action {
	uint8_t kind;
	uint8_t len;
	uint8_t bytes[8];
};

static const struct action annex[] = {
	{ACT_WRITE, 7, {0x0a, 0x00, 0x00, 0xfe, 0xd4, 0x00, 0x00}}, /* SET_NEW_POS 0, -300, 0 */
	{ACT_WRITE, 2, {0x06, 0x64}},                               /* SET_VITESSE_TRAJ 100 */
	{ACT_WRITE, 2, {0x07, 0x32}},                               /* SET_VITESSE_ROT 50 */
	{ACT_WRITE, 6, {0x00, 0x00, 0xc8, 0x00, 0x64, 0x00}},       /* GOTO 200, 100 */
	{ACT_WAIT_IDLE, 0, {0}},
	{ACT_POSITION, 0, {0}},
	{ACT_WRITE, 6, {0x00, 0x00, 0x64, 0x00, 0x32, 0x00}}, /* GOTO 100, 50 */
	{ACT_WAIT_IDLE, 0, {0}},
	{ACT_POSITION, 0, {0}},
	{ACT_WRITE, 2, {0x02, 0x16}}, /* GOTO_PANIER 22 */
	{ACT_WAIT_IDLE, 0, {0}},
	{ACT_POSITION, 0, {0}},
	{ACT_END, 0, {0}},
};

struct master {
	uint32_t next;       /* action */
	uint32_t poll_ticks; /* 10 ms */
	uint32_t wait;       /* ticks until the next poll */
	uint8_t status;      /* last CHECK_BUSY */
	int16_t pos[3][3];   /* POSITION after each wait: x, y, angle */
	uint8_t n_pos;
	uint32_t transactions;
};

struct run {
	struct avrsim *h;
	struct ref *ref;
	struct master m;
	uint32_t tick;
};

static void write_both(struct run *r, const uint8_t *b, uint8_t n, int stop)
{
	assert_int_equal(avrsim_i2c_write(r->h, b, n, stop), 0);
	ref_i2c_write(r->ref, b, n, stop);
	r->m.transactions++;
}

static void hex(char *out, const uint8_t *b, uint8_t n)
{
	for (uint8_t i = 0; i < n; i++)
		sprintf(out + 3 * i, " %02x", b[i]);
}

/* The first reply that differed only in POSITION's error radius (test_annex_replies). */
static char radius_mismatch[256];

static void read_both(struct run *r, uint8_t *out, uint8_t n, int position)
{
	uint8_t want[16];
	char a[64], b[64];

	assert_int_equal(avrsim_i2c_read(r->h, out, n), 0);
	r->m.transactions++;
	ref_i2c_read(r->ref, want, n);
	if (memcmp(out, want, n) == 0)
		return;
	hex(a, out, n);
	hex(b, want, n);
	if (position && memcmp(out, want, 5) == 0) {
		if (!radius_mismatch[0])
			snprintf(radius_mismatch, sizeof(radius_mismatch),
				 "tick %u: POSITION from the AVR%s, from the native core%s",
				 r->tick, a, b);
		return;
	}
	fail_msg("tick %u: the AVR replied%s, the native core%s", r->tick, a, b);
}

/* The master's work between this tick and the next. Returns 0 when the session is over. */
static int master_step(struct run *r)
{
	struct master *m = &r->m;
	uint8_t rep[6];

	for (;;) {
		const struct action *a = &annex[m->next];

		switch (a->kind) {
		case ACT_WRITE:
			write_both(r, a->bytes, a->len, 1);
			m->next++;
			m->wait = 0;
			return 1; /* one write per tick, as a master's loop would */
		case ACT_WAIT_IDLE:
			if (m->wait > 0) {
				m->wait--;
				return 1;
			}
			read_both(r, rep, 1, 0);
			m->status = rep[0];
			m->wait = m->poll_ticks - 1u;
			if (m->status & STATUS_BUSY_TRAJET)
				return 1;
			m->next++;
			break;
		case ACT_POSITION:
			write_both(r, (const uint8_t[]){PROTO_POSITION}, 1, 0);
			read_both(r, rep, 6, 1);
			m->pos[m->n_pos][0] = (int16_t)(uint16_t)(rep[0] << 8 | rep[1]);
			m->pos[m->n_pos][1] = (int16_t)(uint16_t)(rep[2] << 8 | rep[3]);
			m->pos[m->n_pos][2] = (int8_t)rep[4];
			m->n_pos++;
			m->next++;
			return 1;
		default:
			return 0;
		}
	}
}

static int64_t le(const uint8_t *b, int n)
{
	uint64_t v = 0;

	for (int i = n - 1; i >= 0; i--)
		v = v << 8 | b[i];
	return (int64_t)v;
}

/* The AVR's servo state against the native one, at a tick's end: the counts, heading and
 * duties. */
static void compare_servo(const struct run *r)
{
	const struct avr_layout *l = avrsim_layout(r->h);
	const struct odometry_counter *o = &r->ref->board.servo.counter;
	uint16_t b = avrsim_board(r->h);
	uint8_t hd[4], lc[2], rc[2], d[4];

	avrsim_peek(r->h, (uint16_t)(b + l->odo_heading), hd, 4);
	avrsim_peek(r->h, (uint16_t)(b + l->odo_left_count), lc, 2);
	avrsim_peek(r->h, (uint16_t)(b + l->odo_right_count), rc, 2);
	if ((uint16_t)le(lc, 2) != o->left_count || (uint16_t)le(rc, 2) != o->right_count)
		fail_msg("tick %u: the AVR integrated counts %u, %u, the native core %u, %u",
			 r->tick, (unsigned)le(lc, 2), (unsigned)le(rc, 2), o->left_count,
			 o->right_count);
	if ((uint32_t)le(hd, 4) != o->heading_turn32)
		fail_msg("tick %u: AVR heading %lu [turn * 2^32], native %lu", r->tick,
			 (unsigned long)le(hd, 4), (unsigned long)o->heading_turn32);
	avrsim_peek(r->h, (uint16_t)(b + l->duty), d, 4);
	if ((int16_t)le(d, 2) != r->ref->board.servo.last_out.duty_q15[0] ||
	    (int16_t)le(d + 2, 2) != r->ref->board.servo.last_out.duty_q15[1])
		fail_msg("tick %u: the AVR's duties %d, %d, the native core's %d, %d", r->tick,
			 (int16_t)le(d, 2), (int16_t)le(d + 2, 2),
			 r->ref->board.servo.last_out.duty_q15[0],
			 r->ref->board.servo.last_out.duty_q15[1]);
}

/* The position, which the slow steps integrate (once a period with two rates): compared once
 * the AVR's are done, as the native ones are when ref_tick() returns. */
static void compare_position(const struct run *r)
{
	const struct avr_layout *l = avrsim_layout(r->h);
	const struct odometry_position *o = &r->ref->board.planner.position;
	uint16_t b = avrsim_board(r->h);
	uint8_t x[4], y[4], xf[2], yf[2];

	avrsim_peek(r->h, (uint16_t)(b + l->odo_x_um), x, 4);
	avrsim_peek(r->h, (uint16_t)(b + l->odo_y_um), y, 4);
	avrsim_peek(r->h, (uint16_t)(b + l->odo_x_frac), xf, 2);
	avrsim_peek(r->h, (uint16_t)(b + l->odo_y_frac), yf, 2);
	if ((uint32_t)le(x, 4) != o->x_um || (uint32_t)le(y, 4) != o->y_um ||
	    (uint16_t)le(xf, 2) != o->x_frac || (uint16_t)le(yf, 2) != o->y_frac)
		fail_msg("tick %u: AVR estimate x %lu + %u y %lu + %u [um, 2^-16 um], native x "
			 "%lu + %u y %lu + %u",
			 r->tick, (unsigned long)le(x, 4), (unsigned)le(xf, 2),
			 (unsigned long)le(y, 4), (unsigned)le(yf, 2), (unsigned long)o->x_um,
			 o->x_frac, (unsigned long)o->y_um, o->y_frac);
}

static void start(struct run *r, enum avrsim_lockstep mode, struct ref *ref)
{
	struct board_config bc;
	struct sim_config sc;
	struct sim_field f;

	memset(r, 0, sizeof(*r));
	avr_robot_config(&bc);
	physics(&bc, &sc, &f);
	r->h = avrsim_open(elf_path, 400000);
	assert_non_null(r->h);
	assert_int_equal(avrsim_physics(r->h, &sc, &f, mode), 0);
	r->ref = ref;
	assert_int_equal(ref_init(ref, &bc, &sc, &f), 0);
	r->m.poll_ticks = bc.tick_hz / 100u;
}

static void print_positions(const struct run *r)
{
	for (uint8_t i = 0; i < r->m.n_pos; i++)
		print_message("  POSITION %u: (%d, %d) mm, %d x 2 deg\n", i, r->m.pos[i][0],
			      r->m.pos[i][1], r->m.pos[i][2]);
}

static void test_annex_bit_identical(void **state)
{
	static struct ref ref;
	struct run r;
	uint16_t tick_hz;
	struct sim_truth t;
	int ticked = 0, waited = 0;
	uint8_t ov[2];

	(void)state;
	start(&r, AVRSIM_EXACT, &ref);
	for (r.tick = 0;; r.tick++) {
		uint64_t ticks;
		int slow, more;

		if (!ticked)
			assert_int_equal(avrsim_run_to_tick_end(r.h), 0);
		ref_tick(&ref);
		if (r.tick == 0) {
			avrsim_peek(r.h,
				    (uint16_t)(avrsim_board(r.h) + avrsim_layout(r.h)->tick_hz),
				    &tick_hz, 2);
			assert_int_equal(tick_hz, ref.board.cfg.tick_hz);
			assert_int_equal(avrsim_slow_shift(r.h), ref.board.cfg.slow_shift);
		}
		compare_servo(&r);
		slow = avrsim_run_to_slow_done(r.h);
		assert_true(slow >= 0);
		compare_position(&r);
		ticked = slow == 1;
		if (ticked) {
			waited++;
			continue;
		}
		/* The master's bytes reach the board before the next tick, as on the native side: a
		 * compare match that comes while the master acts waits for it (the slow steps are
		 * done, the physics stands still from the compare match on). */
		if (avrsim_master_hold(r.h, 1)) {
			assert_int_equal(avrsim_run_to_tick_end(r.h), 0);
			ticked = 1;
			waited++;
			continue;
		}
		ticks = avrsim_ticks(r.h);
		more = master_step(&r);
		avrsim_master_hold(r.h, 0);
		if (avrsim_ticks(r.h) != ticks)
			fail_msg("tick %u: the AVR ticked while the master acted", r.tick);
		if (!more)
			break;
		assert_true(r.tick < MAX_SECONDS * tick_hz);
	}
	sim_get_truth(avrsim_sim(r.h), &t);
	print_message("%u ticks at %u Hz: odometry state and duties bit-identical, %u "
		      "transactions; truth "
		      "(%.1f, %.1f) mm %.1f deg, status 0x%02x\n",
		      r.tick + 1, tick_hz, r.m.transactions, t.odo_pose.x_mm, t.odo_pose.y_mm,
		      t.odo_pose.heading_rad * 57.29577951308232, r.m.status);
	if (avrsim_slow_shift(r.h))
		print_message("two rates, slow steps every %u ticks: %llu runs, the longest %llu "
			      "cycles; the master waited %d times for them past the next tick, "
			      "and held %llu compare matches while it acted\n",
			      1u << avrsim_slow_shift(r.h),
			      (unsigned long long)avrsim_stats(r.h)->slow.n,
			      (unsigned long long)avrsim_stats(r.h)->slow.max, waited,
			      (unsigned long long)avrsim_stats(r.h)->compares_held);
	print_positions(&r);
	avrsim_peek(r.h, (uint16_t)(avrsim_board(r.h) + avrsim_layout(r.h)->slow_overruns), ov, 2);
	assert_int_equal(ov[0] | ov[1] << 8, ref.board.servo.slow_overruns);
	assert_int_equal(r.m.pos[0][0], 200);
	assert_int_equal(r.m.pos[0][1], 100);
	assert_int_equal(r.m.pos[1][0], 100);
	assert_int_equal(r.m.pos[1][1], 50);
	/* The annex's GOTO_PANIER finds no basket within its push here: PB_MOTEUR, the basket not
	 * reached (docs/protocol.md 4.3). */
	assert_int_equal(r.m.status & (STATUS_BUSY_TRAJET | STATUS_PB_MOTEUR | STATUS_PB_GRAVE),
			 STATUS_PB_MOTEUR);
	avrsim_close(r.h);
}

/* The error radius of every POSITION read was the same too (it comes from the core's error
 * estimate, which the odometry does not use). Reads what test_annex_bit_identical recorded. */
static void test_annex_replies(void **state)
{
	(void)state;
	if (radius_mismatch[0])
		fail_msg("%s", radius_mismatch);
}

int main(int argc, char **argv)
{
	const struct CMUnitTest tests[] = {
		cmocka_unit_test(test_annex_bit_identical),
		cmocka_unit_test(test_annex_replies),
	};

	if (argc != 2) {
		fprintf(stderr, "usage: %s asserv_avr.elf\n", argv[0]);
		return 2;
	}
	elf_path = argv[1];
	return cmocka_run_group_tests(tests, NULL, NULL);
}
