/* The shared protocol vectors (protocol/vectors.toml, through vectors_gen.h) against the AVR
 * binary in simavr, over its TWI at 100 kHz: the same checks as firmware/tests/test_protocol.c
 * makes on the protocol layer, with the queue, the selection and the snapshot read from (or, for
 * the snapshot a sequence assumes, written into) the AVR's RAM. Each vector starts from a fresh
 * reset, after the first control tick, with the control timer's interrupt masked so that no tick
 * takes the queue; a vector's "tick" unmasks it until the queue has been taken and the replies
 * published (a tick; with two rates, a run of the slow steps and the next hand-over). */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <string.h>

#include <cmocka.h>

#include "avrsim.h"
#include "protocol.h"
#include "vectors_gen.h"

#define N_OF(a) (sizeof(a) / sizeof((a)[0]))

/* The capabilities the AVR's build leaves out (docs/avr.md). */
#define AVR_LEFT_OUT                                                                               \
	(CAP_FIX | CAP_PAUSE | CAP_SPEED_SCALE | CAP_QUEUE | CAP_CORNERS | CAP_QUIET_SERVO)
static const char *elf_path;

static struct avrsim *boot(void)
{
	struct avrsim *h = avrsim_open(elf_path, 100000);

	assert_non_null(h);
	assert_int_equal(avrsim_run_to_tick_end(h), 0);
	avrsim_tick_enable(h, 0);
	assert_int_equal(avrsim_run_until_idle(h), 0); /* periods already due run first */
	return h;
}

static uint8_t board_u8(const struct avrsim *h, uint16_t off)
{
	uint8_t v;

	avrsim_peek(h, (uint16_t)(avrsim_board(h) + off), &v, 1);
	return v;
}

static int32_t board_i32(const struct avrsim *h, uint16_t off)
{
	uint8_t b[4];

	avrsim_peek(h, (uint16_t)(avrsim_board(h) + off), b, 4);
	return (int32_t)((uint32_t)b[0] | (uint32_t)b[1] << 8 | (uint32_t)b[2] << 16 |
			 (uint32_t)b[3] << 24);
}

static void write_frame(struct avrsim *h, const uint8_t *bytes, uint8_t n, int stop)
{
	assert_int_equal(avrsim_i2c_write(h, bytes, n, stop), 0);
}

static void read_frame(struct avrsim *h, uint8_t *out, uint8_t n)
{
	assert_int_equal(avrsim_i2c_read(h, out, n), 0);
}

/* Both snapshot buffers: a read finds the vector's snapshot whichever is published. */
static void poke_snapshot(struct avrsim *h, const struct vec_snapshot *v)
{
	const struct avr_layout *l = avrsim_layout(h);
	uint8_t s[64];

	assert_true(l->snap_size <= sizeof(s));
	memset(s, 0, sizeof(s));
	s[l->snap_x_mm] = (uint8_t)v->x_mm;
	s[l->snap_x_mm + 1] = (uint8_t)((uint16_t)v->x_mm >> 8);
	s[l->snap_y_mm] = (uint8_t)v->y_mm;
	s[l->snap_y_mm + 1] = (uint8_t)((uint16_t)v->y_mm >> 8);
	s[l->snap_angle_2deg] = (uint8_t)v->angle_2deg;
	s[l->snap_radius_mm] = v->radius_mm;
	s[l->snap_status] = v->status;
	s[l->snap_sensors] = v->sensors;
	for (int i = 0; i < 2; i++)
		avrsim_poke(h, (uint16_t)(avrsim_board(h) + l->proto_snap + i * l->snap_size), s,
			    l->snap_size);
}

/* A frame of an extension the AVR's build leaves out (firmware/ports/avr/CMakeLists.txt,
 * docs/avr.md): position fixes (CONFIG_FIX 0) and match play (CONFIG_MOTION_* 0), whose
 * messages and options it rejects UNSUPPORTED. */
static int compiled_out(const struct vec_write *v)
{
	const int d = v->accept_designation;

	if (d == PROTO_SET_FIX || d == PROTO_FIX_INFO || d == PROTO_PAUSE || d == PROTO_RESUME ||
	    d == PROTO_SET_SPEED_SCALE || d == PROTO_MOTION || d == PROTO_SET_CORNER)
		return 1;
	if (d == PROTO_GOTO && v->len >= 6)
		return (v->bytes[5] & (PROTO_OPT_APPEND | PROTO_OPT_PASS_THROUGH)) != 0;
	if ((d == PROTO_GOTO_REVERSE || d == PROTO_GOTO_PANIER) && v->len >= 3 &&
	    v->len >= proto_lookup((uint8_t)d)->write_len)
		return (v->bytes[2] & PROTO_OPT_APPEND) != 0;
	return 0;
}

static void test_write_vectors(void **state)
{
	(void)state;
	for (size_t i = 0; i < N_OF(vec_writes); i++) {
		const struct vec_write *v = &vec_writes[i];
		struct avrsim *h = boot();
		const struct avr_layout *l = avrsim_layout(h);
		uint8_t status[1], reject[3], head, tail;

		print_message("%s\n", v->name);
		write_frame(h, v->bytes, v->len, 1);
		head = board_u8(h, l->proto_head);
		tail = board_u8(h, l->proto_tail);
		if (compiled_out(v)) {
			/* compiled out of the AVR (position fixes, match play: docs/avr.md):
			 * rejected, nothing queued */
			assert_int_equal(head, tail);
			write_frame(h, (const uint8_t[]){PROTO_LAST_REJECT}, 1, 1);
			read_frame(h, reject, 3);
			assert_int_equal(reject[0], REJECT_UNSUPPORTED);
		} else if (v->accept_designation < 0) {
			assert_int_equal(head, tail);
			read_frame(h, status, 1);
			assert_int_equal(status[0], STATUS_COMMANDE_REJETEE);
			write_frame(h, (const uint8_t[]){PROTO_LAST_REJECT}, 1, 1);
			read_frame(h, reject, 3);
			/* the AVR leaves PASS_THROUGH out: it refuses the frame for that first */
			assert_int_equal(reject[0], v->reject == REJECT_BAD_OPTIONS
							    ? REJECT_UNSUPPORTED
							    : v->reject);
			assert_int_equal(reject[1], v->bytes[0]);
			assert_int_equal(reject[2], 1);
		} else if (proto_lookup((uint8_t)v->accept_designation)->kind == PROTO_KIND_ETAT) {
			/* Accepted ETAT writes select a reply and queue nothing. */
			assert_int_equal(head, tail);
			assert_int_equal(board_u8(h, l->proto_selected), v->accept_designation);
		} else {
			uint16_t m = (uint16_t)(l->proto_queue +
						(tail % PROTO_QUEUE_DEPTH) * l->msg_size);

			assert_int_equal((uint8_t)(head - tail), 1);
			assert_int_equal(board_u8(h, (uint16_t)(m + l->msg_designation)),
					 v->accept_designation);
			assert_int_equal(board_u8(h, (uint16_t)(m + l->msg_n_args)), v->n_args);
			for (uint8_t a = 0; a < v->n_args; a++)
				assert_int_equal(board_i32(h, (uint16_t)(m + l->msg_arg + 4 * a)),
						 v->args[a]);
			read_frame(h, status, 1);
			assert_int_equal(status[0] & STATUS_COMMANDE_REJETEE, 0);
		}
		avrsim_close(h);
	}
}

static void test_sequence_vectors(void **state)
{
	(void)state;
	for (size_t i = 0; i < N_OF(vec_sequences); i++) {
		const struct vec_sequence *sq = &vec_sequences[i];
		struct avrsim *h = boot();

		print_message("%s\n", sq->name);
		poke_snapshot(h, &sq->snapshot);
		for (uint8_t k = 0; k < sq->n_steps; k++) {
			const struct vec_step *st = &sq->steps[k];
			uint8_t got[PROTO_MAX_REPLY + 4];

			if (st->op == 't') {
				avrsim_tick_enable(h, 1);
				assert_int_equal(avrsim_run_slow_steps(h), 0);
				avrsim_tick_enable(h, 0);
				assert_int_equal(avrsim_run_until_idle(h), 0);
				poke_snapshot(h, &sq->snapshot);
				continue;
			}
			if (st->op == 'w' || st->op == 'W')
				write_frame(h, st->bytes, st->len, !(st->op == 'W' && st->restart));
			if (st->op == 'r' || st->op == 'W') {
				uint8_t want[PROTO_MAX_REPLY + 4];

				memcpy(want, st->expect, st->read_len);
				if (st->op == 'W' &&
				    st->bytes[0] == PROTO_VERSION) { /* compiled out */
					want[2] &= (uint8_t) ~(AVR_LEFT_OUT >> 8);
					want[3] &= (uint8_t) ~(AVR_LEFT_OUT & 0xFFu);
				}
				read_frame(h, got, st->read_len);
				assert_memory_equal(got, want, st->read_len);
			}
		}
		avrsim_close(h);
	}
}

/* Another address is not acknowledged; the board's own still is afterwards. */
static void test_other_address_nacked(void **state)
{
	struct avrsim *h = boot();
	uint8_t s[1];

	(void)state;
	avrsim_i2c_address(h, PROTO_ADDRESS + 1);
	assert_int_equal(avrsim_i2c_read(h, s, 1), -1);
	assert_int_equal(avrsim_i2c_write(h, (const uint8_t[]){PROTO_STOP}, 1, 1), -1);
	avrsim_i2c_address(h, PROTO_ADDRESS);
	assert_int_equal(avrsim_i2c_read(h, s, 1), 0);
	assert_int_equal(s[0], 0);
	avrsim_close(h);
}

/* What the TWI interrupt costs per bus event, and how long it holds SCL, at 100 kHz (printed,
 * not asserted: bench_avr prints the same under load). */
static void test_twi_figures(void **state)
{
	static const struct {
		uint8_t status;
		const char *what;
	} ev[] = {{0x60, "own address + write"},    {0x80, "data byte received"},
		  {0xA0, "STOP or repeated start"}, {0xA8, "own address + read"},
		  {0xB8, "data byte sent, ACK"},    {0xC0, "data byte sent, NACK"}};
	struct avrsim *h = boot();
	const struct avrsim_stats *s = avrsim_stats(h);
	uint8_t r[8];

	(void)state;
	avrsim_stats_reset(h);
	write_frame(h, (const uint8_t[]){0, 0, 200, 0, 100, 0}, 6, 1);
	write_frame(h, (const uint8_t[]){PROTO_POSITION}, 1, 0);
	read_frame(h, r, 7);
	write_frame(h, (const uint8_t[]){PROTO_DEBUG}, 1, 1);
	read_frame(h, r, 8);
	for (size_t i = 0; i < N_OF(ev); i++) {
		const struct avrsim_count *c = &s->twi[ev[i].status >> 3];
		const struct avrsim_count *k = &s->stretch[ev[i].status >> 3];

		assert_true(c->n > 0);
		print_message("TWI 0x%02X %-24s %3llu cycles mean, %3llu max; SCL held %llu cycles "
			      "max past the master's low half-period\n",
			      ev[i].status, ev[i].what, (unsigned long long)(c->cycles / c->n),
			      (unsigned long long)c->max, (unsigned long long)k->max);
	}
	avrsim_close(h);
}

int main(int argc, char **argv)
{
	const struct CMUnitTest tests[] = {
		cmocka_unit_test(test_write_vectors),
		cmocka_unit_test(test_sequence_vectors),
		cmocka_unit_test(test_other_address_nacked),
		cmocka_unit_test(test_twi_figures),
	};

	if (argc != 2) {
		fprintf(stderr, "usage: %s asserv_avr.elf\n", argv[0]);
		return 2;
	}
	elf_path = argv[1];
	return cmocka_run_group_tests(tests, NULL, NULL);
}
