/* SET_TIMEOUT fed by accepted writes only (issue 28, item 5) on the AVR binary in simavr: the
 * sessions of asserv.sim.silence (python/tests/test_timeout_sim.py on the simulator,
 * harness/stm32/test_timeout.py on the STM32's binary), drawn at random. SET_TIMEOUT, a slow GOTO
 * that outlasts the session, then the order thread's accepted writes (HEARTBEAT or a setting
 * sent again) after gaps under the timeout, and at the end a hang (a gap over it) or not; in
 * every gap the polling thread reads CHECK_BUSY and DEBUG at its own period, and writes the
 * board rejects come between. At every poll, t ms after the last accepted write, the order runs
 * while t is under the timeout and has been stopped once t passes it by LATE_MS: STOPPING, then
 * at rest PB_MOTEUR with DEBUG end_reason TIMEOUT, never the 0x00 of a finished order. The
 * slow steps run at 125 Hz here: a write is taken at the next 8 ms period and the timeout is
 * rounded up to periods, so the margins are wider than the host's. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <string.h>

#include <cmocka.h>

#include "avrsim.h"
#include "protocol.h"
#include "robot.h"

#define CASES 24
#define CYCLES_PER_MS (AVRSIM_F_CPU / 1000u)
/* A poll this close under the timeout may see it (a write's bus time). */
#define EARLY_MS 2u
/* From the timeout to the poll that sees it: the write taken at the next slow period, the
 * timeout rounded up to periods, the hand-over and the snapshot: four periods. */
#define LATE_MS 32u
/* Gaps of the order thread under the timeout by this much: taken a period late, still under. */
#define UNDER_MS 16u
#define TARGET_X_MM 1200

static const char *elf_path;

struct run {
	struct avrsim *h;
	uint32_t rng;
	uint32_t timeout_ms;
	uint64_t last;  /* the cycle the last accepted write ended */
	unsigned polls; /* checked, over the whole test */
	unsigned late;  /* of which past the timeout */
};

static uint32_t draw(struct run *r, uint32_t n)
{
	r->rng = r->rng * 1664525u + 1013904223u; /* Numerical Recipes' LCG */
	return (r->rng >> 8) % n;
}

static void run_ticks(struct avrsim *h, unsigned n)
{
	for (unsigned t = 0; t < n; t++)
		assert_int_equal(avrsim_run_to_tick_end(h), 0);
}

static void sleep_until(struct avrsim *h, uint64_t cycle)
{
	uint64_t now = avrsim_cycle(h);

	if (cycle > now)
		assert_int_equal(avrsim_run_cycles(h, cycle - now), 0);
}

static uint32_t since_ms(const struct run *r)
{
	return (uint32_t)((avrsim_cycle(r->h) - r->last) / CYCLES_PER_MS);
}

static void query(struct avrsim *h, uint8_t designation, uint8_t *out, uint8_t n)
{
	assert_int_equal(avrsim_i2c_write(h, &designation, 1, 0), 0);
	assert_int_equal(avrsim_i2c_read(h, out, n), 0);
}

static void send(struct avrsim *h, const uint8_t *b, uint8_t n)
{
	assert_int_equal(avrsim_i2c_write(h, b, n, 1), 0);
}

/* An accepted write of the order thread: the silence counts from its end. */
static void write_accepted(struct run *r, const uint8_t *b, uint8_t n)
{
	send(r->h, b, n);
	r->last = avrsim_cycle(r->h);
}

static void go_to(struct run *r, int x_mm, int y_mm)
{
	uint8_t f[6] = {PROTO_GOTO,    (uint8_t)((unsigned)x_mm >> 8),
			(uint8_t)x_mm, (uint8_t)((unsigned)y_mm >> 8),
			(uint8_t)y_mm, 0};

	write_accepted(r, f, sizeof(f));
}

static uint8_t status_now(struct avrsim *h)
{
	uint8_t s;

	query(h, PROTO_CHECK_BUSY, &s, 1);
	return (uint8_t)(s & ~STATUS_COMMANDE_REJETEE);
}

/* The polling thread's read: CHECK_BUSY, then DEBUG, each against the time since the last
 * accepted write. */
static void poll(struct run *r)
{
	uint8_t d[PROTO_DEBUG_REPLY_LEN], state, end;
	uint32_t t = since_ms(r), td;
	uint8_t s = status_now(r->h);

	td = since_ms(r);
	query(r->h, PROTO_DEBUG, d, sizeof(d));
	state = d[20];
	end = d[21];
	r->polls++;
	if (t + EARLY_MS < r->timeout_ms) /* running */
		assert_int_equal(s, STATUS_BUSY_TRAJET);
	if (td + EARLY_MS <
	    r->timeout_ms) /* DEBUG's plain snapshot: IDLE until the GOTO is taken */
		assert_true(state != ORDER_STATE_STOPPING && end != END_REASON_TIMEOUT);
	if (t >= r->timeout_ms + LATE_MS) { /* stopped: braking, or abandoned */
		r->late++;
		assert_true(s == STATUS_PB_MOTEUR || (s & STATUS_BUSY_TRAJET));
	}
	if (td >= r->timeout_ms + LATE_MS)
		assert_true(state == ORDER_STATE_STOPPING ||
			    (state == ORDER_STATE_IDLE && end == END_REASON_TIMEOUT));
}

/* The robot, randomized by seed, 300 mm in front of where the board starts (as
 * test_avr_resets.c), declared by the master. */
static void start(struct run *r, uint32_t seed)
{
	struct board_config bc;
	struct sim_config sc;
	struct sim_field f;
	static const uint8_t declare[] = {PROTO_SET_NEW_POS, 0x00, 0x00, 0xfe, 0xd4, 0x00, 0x00};

	avr_robot_config(&bc);
	sim_config_defaults(&sc);
	sc.motor.encoder_cpr = 48;
	sc.start.x_mm = bc.start.x_um / 1000.0;
	sc.start.y_mm = bc.start.y_um / 1000.0 + 300;
	sc.start.heading_rad = 0.0;
	sim_config_randomize(&sc, seed);
	sim_field_defaults(&f);
	r->h = avrsim_open(elf_path, 400000);
	assert_non_null(r->h);
	assert_int_equal(avrsim_physics(r->h, &sc, &f, AVRSIM_REALTIME), 0);
	run_ticks(r->h, 20);
	send(r->h, declare, sizeof(declare));
	run_ticks(r->h, 20);
}

/* One gap of ms after the last accepted write: the polls every poll_ms from phase, up to
 * rejected writes; a gap under the timeout stops polling before the write is due. */
static void gap(struct run *r, uint32_t ms, int hang)
{
	static const uint8_t cut_short[] = {PROTO_SET_TIMEOUT, 0x01}; /* BAD_LENGTH */
	uint32_t poll_ms = 5 + draw(r, 36), at = draw(r, poll_ms), rejected = draw(r, ms + 1);
	uint64_t end = r->last + (uint64_t)ms * CYCLES_PER_MS;

	for (; at < ms; at += poll_ms) {
		if (!hang &&
		    since_ms(r) + 4u >= ms) /* the polls ran late: the write keeps its time */
			break;
		if (rejected <= at) {
			sleep_until(r->h, r->last + (uint64_t)rejected * CYCLES_PER_MS);
			send(r->h, cut_short, sizeof(cut_short));
			rejected = UINT32_MAX;
		}
		sleep_until(r->h, r->last + (uint64_t)at * CYCLES_PER_MS);
		poll(r);
	}
	sleep_until(r->h, end);
}

static void test_only_accepted_writes_feed_the_timeout(void **state)
{
	struct run r = {.rng = 5};
	unsigned hangs = 0;

	(void)state;
	for (int k = 0; k < CASES; k++) {
		static const uint8_t heartbeat[] = {PROTO_HEARTBEAT};
		static const uint8_t traj[] = {PROTO_SET_VITESSE_TRAJ, 20, 100};
		uint8_t timeout[3] = {PROTO_SET_TIMEOUT};
		uint32_t writes = draw(&r, 5);
		int hang = k % 2 == 0;

		r.timeout_ms = 60 + draw(&r, 340);
		timeout[1] = (uint8_t)(r.timeout_ms >> 8);
		timeout[2] = (uint8_t)r.timeout_ms;
		start(&r, draw(&r, 10000));
		send(r.h, traj, sizeof(traj));
		send(r.h, timeout, sizeof(timeout));
		go_to(&r, TARGET_X_MM, -550);
		print_message("case %d: timeout %u ms, %u writes, %s\n", k, (unsigned)r.timeout_ms,
			      (unsigned)writes, hang ? "then a hang" : "no hang");
		for (uint32_t i = 0; i < writes; i++) {
			gap(&r, 1 + draw(&r, r.timeout_ms - UNDER_MS), 0);
			if (draw(&r, 2))
				write_accepted(&r, heartbeat, sizeof(heartbeat));
			else
				write_accepted(&r, traj, sizeof(traj));
		}
		if (hang) {
			uint8_t d[PROTO_DEBUG_REPLY_LEN];
			unsigned waited = 0;

			hangs++;
			gap(&r, r.timeout_ms + LATE_MS + 10 + draw(&r, 150), 1);
			poll(&r);
			while (status_now(r.h) & STATUS_BUSY_TRAJET) { /* braking */
				run_ticks(r.h, 10);
				assert_true((waited += 10) < 3000);
			}
			assert_int_equal(status_now(r.h), STATUS_PB_MOTEUR);
			query(r.h, PROTO_DEBUG, d, sizeof(d));
			assert_int_equal(d[21], END_REASON_TIMEOUT);
			go_to(&r, 0, -550); /* the next order runs, PB_MOTEUR cleared */
			assert_int_equal(status_now(r.h), STATUS_BUSY_TRAJET);
		} else {
			poll(&r);
		}
		avrsim_close(r.h);
	}
	print_message("%u polls checked, %u of them past the timeout\n", r.polls, r.late);
	assert_true(hangs > 0 && r.late >= hangs); /* the stop was seen after each hang */
}

int main(int argc, char **argv)
{
	const struct CMUnitTest tests[] = {
		cmocka_unit_test(test_only_accepted_writes_feed_the_timeout),
	};

	if (argc < 2) {
		fprintf(stderr, "usage: %s asserv_avr.elf\n", argv[0]);
		return 2;
	}
	elf_path = argv[1];
	return cmocka_run_group_tests(tests, NULL, NULL);
}
