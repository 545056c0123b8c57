/* The board's protocol layer against the shared vectors (protocol/vectors.toml) and the rules of
 * docs/protocol.md that the vectors cannot express. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <string.h>

#include <cmocka.h>

#include "protocol.h"
#include "vectors_gen.h"

#define N_OF(a) (sizeof(a) / sizeof((a)[0]))

static void write_frame(struct proto *p, const uint8_t *bytes, uint8_t n, int stop)
{
	proto_master_write(p, bytes, n, stop);
}

static void read_frame(struct proto *p, uint8_t *out, uint8_t n)
{
	proto_master_read(p, out, n);
}

static struct proto_snapshot snapshot_of(const struct vec_snapshot *v)
{
	struct proto_snapshot s;

	memset(&s, 0, sizeof(s));
	s.x_mm = v->x_mm;
	s.y_mm = v->y_mm;
	s.angle_2deg = v->angle_2deg;
	s.radius_mm = v->radius_mm;
	s.status = v->status;
	s.sensors = v->sensors;
	return s;
}

static void test_crc_vectors(void **state)
{
	(void)state;
	for (size_t i = 0; i < N_OF(vec_crcs); i++)
		assert_int_equal(proto_crc8(0, vec_crcs[i].bytes, vec_crcs[i].len),
				 vec_crcs[i].crc);
}

static void test_write_vectors(void **state)
{
	(void)state;
	for (size_t i = 0; i < N_OF(vec_writes); i++) {
		const struct vec_write *v = &vec_writes[i];
		struct proto p;
		struct proto_msg m;
		uint8_t status[1];
		uint8_t reject[3];

		proto_init(&p);
		write_frame(&p, v->bytes, v->len, 1);
		print_message("%s\n", v->name);
		if (v->accept_designation < 0) {
			assert_int_equal(proto_poll(&p, &m), 0);
			read_frame(&p, status, 1);
			assert_int_equal(status[0], STATUS_COMMANDE_REJETEE);
			write_frame(&p, (const uint8_t[]){PROTO_LAST_REJECT}, 1, 1);
			read_frame(&p, reject, 3);
			assert_int_equal(reject[0], v->reject);
			assert_int_equal(reject[1], v->bytes[0]);
			assert_int_equal(reject[2], 1);
			continue;
		}
		if (proto_lookup((uint8_t)v->accept_designation)->kind == PROTO_KIND_ETAT) {
			/* Accepted ETAT writes select a reply and queue nothing. */
			assert_int_equal(proto_poll(&p, &m), 0);
			assert_int_equal(p.selected, v->accept_designation);
			continue;
		}
		assert_int_equal(proto_poll(&p, &m), 1);
		assert_int_equal(m.designation, v->accept_designation);
		assert_int_equal(m.n_args, v->n_args);
		for (uint8_t a = 0; a < v->n_args; a++)
			assert_int_equal(m.arg[a], v->args[a]);
		assert_int_equal(proto_poll(&p, &m), 0);
		read_frame(&p, status, 1);
		assert_int_equal(status[0] & STATUS_COMMANDE_REJETEE, 0);
	}
}

static void test_sequence_vectors(void **state)
{
	(void)state;
	for (size_t i = 0; i < N_OF(vec_sequences); i++) {
		const struct vec_sequence *sq = &vec_sequences[i];
		struct proto_snapshot snap = snapshot_of(&sq->snapshot);
		struct proto p;

		print_message("%s\n", sq->name);
		proto_init(&p);
		proto_publish(&p, &snap);
		for (uint8_t k = 0; k < sq->n_steps; k++) {
			const struct vec_step *st = &sq->steps[k];
			uint8_t got[PROTO_MAX_REPLY + 4];
			struct proto_msg m;

			if (st->op == 't') {
				while (proto_poll(&p, &m))
					;
				proto_publish(&p, &snap);
				continue;
			}
			if (st->op == 'w' || st->op == 'W')
				write_frame(&p, st->bytes, st->len,
					    !(st->op == 'W' && st->restart));
			if (st->op == 'r' || st->op == 'W') {
				read_frame(&p, got, st->read_len);
				assert_memory_equal(got, st->expect, st->read_len);
			}
		}
	}
}

/* A rejected frame changes nothing: whatever the master sends, the queue only ever receives
 * frames that pass every check, and a rejection leaves the queue and the selection as a valid
 * frame would not. */
static void test_rejected_frame_changes_nothing(void **state)
{
	struct proto p;
	struct proto_msg m;
	const uint8_t good[] = {6, 100, 100};
	const uint8_t bad[] = {6, 100, 0};

	(void)state;
	proto_init(&p);
	write_frame(&p, good, sizeof(good), 1);
	write_frame(&p, bad, sizeof(bad), 1);
	assert_int_equal(proto_poll(&p, &m), 1);
	assert_int_equal(m.arg[ARG_SET_VITESSE_TRAJ_ACCEL_CM_S2], 100);
	assert_int_equal(proto_poll(&p, &m), 0);
}

static void test_abort_rejects_the_write(void **state)
{
	struct proto p;
	struct proto_msg m;
	uint8_t got[3];

	(void)state;
	proto_init(&p);
	write_frame(&p, (const uint8_t[]){0, 0, 200, 0, 100, 0}, 6, 0);
	proto_on_abort(&p);
	proto_on_stop(&p);
	assert_int_equal(proto_poll(&p, &m), 0);
	write_frame(&p, (const uint8_t[]){PROTO_LAST_REJECT}, 1, 1);
	read_frame(&p, got, 3);
	assert_int_equal(got[0], REJECT_ABORTED);
	assert_int_equal(got[1], PROTO_GOTO);
}

/* The reply is taken from the snapshot published when the designation arrived: a tick that
 * publishes between the selection and the read does not tear it. */
static void test_position_reply_is_one_snapshot(void **state)
{
	struct proto p;
	struct proto_snapshot a, b;
	uint8_t got[6];

	(void)state;
	memset(&a, 0, sizeof(a));
	a.x_mm = 0x0102;
	a.y_mm = 0x0304;
	a.angle_2deg = 5;
	a.radius_mm = 6;
	b = a;
	b.x_mm = 0x7F7F;
	b.y_mm = 0x7E7E;
	b.angle_2deg = 77;
	b.radius_mm = 78;
	proto_init(&p);
	proto_publish(&p, &a);
	write_frame(&p, (const uint8_t[]){PROTO_POSITION}, 1, 1);
	proto_publish(&p, &b);
	proto_on_read_start(&p);
	got[0] = proto_read_byte(&p);
	proto_publish(&p, &a);
	for (int i = 1; i < 6; i++)
		got[i] = proto_read_byte(&p);
	proto_on_stop(&p);
	assert_memory_equal(got, ((const uint8_t[]){1, 2, 3, 4, 5, 6}), 6);
}

static void test_debug_frame_layout(void **state)
{
	struct proto p;
	struct proto_snapshot s;
	uint8_t got[PROTO_DEBUG_REPLY_LEN + 1];
	const uint8_t want[PROTO_DEBUG_REPLY_LEN] = {0x12, 0x34, 0xB9, 0xB0, 0x03, 0xE8, 0xFF, 0x9C,
						     0x00, 0x0A, 0xFF, 0xF6, 0x7F, 0xFF, 0x80, 0x01,
						     0x01, 0xF4, 0x00, 0x00, 2,    1};

	(void)state;
	memset(&s, 0, sizeof(s));
	s.debug.tick = 0x1234;
	s.debug.heading_cdeg = -18000;
	s.debug.speed_mm_s = 1000;
	s.debug.turn_rate_cdeg_s = -100;
	s.debug.dist_err_um = 10;
	s.debug.angle_err_um = -10;
	s.debug.duty_left_q15 = 32767;
	s.debug.duty_right_q15 = -32767;
	s.debug.current_left_ma = 500;
	s.debug.current_right_ma = 0;
	s.debug.order_state = ORDER_STATE_TRANSLATE;
	s.debug.end_reason = END_REASON_DONE;
	proto_init(&p);
	proto_publish(&p, &s);
	write_frame(&p, (const uint8_t[]){PROTO_DEBUG}, 1, 1);
	read_frame(&p, got, sizeof(got));
	assert_memory_equal(got, want, sizeof(want));
	assert_int_equal(got[PROTO_DEBUG_REPLY_LEN],
			 proto_crc8(proto_crc8(0, &(uint8_t){(PROTO_ADDRESS << 1) | 1}, 1), want,
				    sizeof(want)));
}

/* Every reply the table declares is packed at the length the table gives. */
static void test_reply_lengths_match_table(void **state)
{
	struct proto p;
	struct proto_snapshot s;
	uint8_t out[PROTO_MAX_REPLY];

	(void)state;
	memset(&s, 0, sizeof(s));
	proto_init(&p);
	for (size_t i = 0; i < PROTO_N_MSGS; i++)
		assert_int_equal(proto_pack_reply(&p, proto_msgs[i].designation, &s, out),
				 proto_msgs[i].reply_len);
}

/* Read, repeated start, read: the second read is a read of its own (the status byte and its
 * PEC), and nothing is written past the reply buffer. */
static void test_read_restart_read(void **state)
{
	struct proto p;
	struct proto_snapshot s;
	uint8_t got[2];
	const uint8_t addr_r = (PROTO_ADDRESS << 1) | 1;

	(void)state;
	memset(&s, 0, sizeof(s));
	s.status = STATUS_BUSY_TRAJET;
	proto_init(&p);
	proto_publish(&p, &s);
	write_frame(&p, (const uint8_t[]){PROTO_DEBUG}, 1, 1);
	for (int k = 0; k < 4; k++) {
		proto_on_read_start(&p);
		for (int i = 0; i < PROTO_DEBUG_REPLY_LEN + 1; i++)
			(void)proto_read_byte(&p);
	}
	proto_on_read_start(&p);
	got[0] = proto_read_byte(&p);
	got[1] = proto_read_byte(&p);
	proto_on_stop(&p);
	assert_int_equal(got[0], STATUS_BUSY_TRAJET);
	assert_int_equal(got[1], proto_crc8(proto_crc8(0, &addr_r, 1), got, 1));
	assert_int_equal(p.in_read, 0);
}

/* The PEC of a read after a repeated start covers the whole transaction: an address-only write,
 * or a write longer than any message, included. */
static void test_restart_pec_covers_the_write(void **state)
{
	struct proto p;
	uint8_t got[2];
	const uint8_t long_write[] = {9, 1, 2, 3, 4, 5, 6, 7, 8, 9};
	uint8_t tr[16];
	uint8_t n = 0;

	(void)state;
	proto_init(&p);
	write_frame(&p, NULL, 0, 0);
	proto_on_read_start(&p);
	got[0] = proto_read_byte(&p);
	got[1] = proto_read_byte(&p);
	proto_on_stop(&p);
	tr[0] = PROTO_ADDRESS << 1;
	tr[1] = (PROTO_ADDRESS << 1) | 1;
	tr[2] = got[0];
	assert_int_equal(got[1], proto_crc8(0, tr, 3));

	write_frame(&p, long_write, sizeof(long_write), 0);
	proto_on_read_start(&p);
	got[0] = proto_read_byte(&p);
	got[1] = proto_read_byte(&p);
	proto_on_stop(&p);
	tr[n++] = PROTO_ADDRESS << 1;
	for (size_t i = 0; i < sizeof(long_write); i++)
		tr[n++] = long_write[i];
	tr[n++] = (PROTO_ADDRESS << 1) | 1;
	tr[n++] = got[0];
	assert_int_equal(got[0], STATUS_COMMANDE_REJETEE);
	assert_int_equal(got[1], proto_crc8(0, tr, n));
}

/* A bus error before any data byte: the rejected designation reads 0xFF, not GOTO's 0. */
/* Bytes fetched outside a read (a port out of step) change nothing: the read that follows
 * returns the selected reply and its PEC. Found by fuzz/fuzz_protocol. */
static void test_read_byte_outside_a_read(void **state)
{
	struct proto p;
	struct proto_snapshot s;
	uint8_t got[2];

	(void)state;
	memset(&s, 0, sizeof(s));
	s.sensors = 0x81;
	proto_init(&p);
	proto_publish(&p, &s);
	write_frame(&p, (const uint8_t[]){PROTO_INFO_CHOC}, 1, 1);
	(void)proto_read_byte(&p);
	(void)proto_read_byte(&p);
	read_frame(&p, got, 2);
	assert_memory_equal(got, ((const uint8_t[]){0x81, 0xCF}), 2);
}

static void test_abort_before_any_byte(void **state)
{
	struct proto p;
	uint8_t got[3];

	(void)state;
	proto_init(&p);
	proto_on_write_start(&p);
	proto_on_abort(&p);
	write_frame(&p, (const uint8_t[]){PROTO_LAST_REJECT}, 1, 1);
	read_frame(&p, got, 3);
	assert_int_equal(got[0], REJECT_ABORTED);
	assert_int_equal(got[1], 0xFF);
}

int main(void)
{
	const struct CMUnitTest tests[] = {
		cmocka_unit_test(test_crc_vectors),
		cmocka_unit_test(test_write_vectors),
		cmocka_unit_test(test_sequence_vectors),
		cmocka_unit_test(test_rejected_frame_changes_nothing),
		cmocka_unit_test(test_abort_rejects_the_write),
		cmocka_unit_test(test_position_reply_is_one_snapshot),
		cmocka_unit_test(test_debug_frame_layout),
		cmocka_unit_test(test_reply_lengths_match_table),
		cmocka_unit_test(test_read_restart_read),
		cmocka_unit_test(test_restart_pec_covers_the_write),
		cmocka_unit_test(test_abort_before_any_byte),
		cmocka_unit_test(test_read_byte_outside_a_read),
	};
	return cmocka_run_group_tests(tests, NULL, NULL);
}
