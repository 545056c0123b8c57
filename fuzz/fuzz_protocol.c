/* libFuzzer target: the protocol layer (firmware/core/protocol.c) alone, fed I2C events in any
 * order (fuzz_events.h). Besides the sanitizers, it checks after every event, against a model of
 * docs/protocol.md kept here:
 *   - a rejected frame changes nothing but the rejection fields: the queue, the counts of orders
 *     and the snapshots are as before, and it is counted and flagged (COMMANDE_REJETEE,
 *     LAST_REJECT);
 *   - a write is judged the same however it ends (STOP, START, repeated start);
 *   - every message the control tick takes passes the message table's checks;
 *   - a read returns the reply selected by the last accepted ETAT designation (else CHECK_BUSY),
 *     from the snapshot published when it was selected, then its PEC over every byte of the
 *     transaction since the START of the selecting write (repeated start) or of the read, then
 *     0xFF;
 *   - the status byte: bit 7 clear, COMMANDE_REJETEE as the model says, BUSY_TRAJET while an
 *     accepted order is not yet published.
 * TICK (kind 6) is the first half of a control tick: the core takes every queued message. ENV
 * (kind 7) is the second half: the core publishes a snapshot whose status bits are the next
 * byte's low 6 bits. An ENV with no TICK since the last one takes the messages first, so the
 * core's order (poll, then publish) holds, and bus events may fall between the two halves as an
 * interrupt preempting the tick does. */
#include <stddef.h>
#include <stdint.h>
#include <string.h>

#include "fuzz_events.h"
#include "protocol.h"

#define ADDR_W ((uint8_t)(PROTO_ADDRESS << 1))
#define ADDR_R ((uint8_t)(ADDR_W | 1u))
#define CORE_STATUS_BITS 0x3Fu /* the status bits the core publishes */

struct model {
	uint8_t in_write, in_read;
	uint8_t seg_crc;  /* CRC of the current write: address + data bytes */
	uint8_t restart;  /* a repeated start ended that write: the next read's PEC covers it */
	uint8_t selected; /* per the rules of docs/protocol.md, PROTO_NONE when none */
	uint8_t rejected; /* COMMANDE_REJETEE */
	uint8_t orders_accepted, orders_polled_at_publish, orders_polled;
	uint8_t polled_since_publish;
	uint16_t ticks;
	struct proto_snapshot published; /* the last snapshot published */
	struct proto_snapshot at_select; /* the one published when the selection was made */
	uint8_t expect[PROTO_MAX_REPLY + 1];
	uint8_t expect_len, read_pos;
};

static struct proto p;
static struct model m;

static int msg_equal(const struct proto_msg *a, const struct proto_msg *b)
{
	if (a->designation != b->designation || a->n_args != b->n_args)
		return 0;
	for (uint8_t i = 0; i < PROTO_MAX_PARAMS; i++)
		if (a->arg[i] != b->arg[i])
			return 0;
	return 1;
}

/* What the control tick and the master see of the layer, as opposed to the bookkeeping of the
 * transaction in progress: equal before and after a rejected frame. */
static void check_unchanged(const struct proto *before, const struct proto *after)
{
	FUZZ_CHECK(after->head == before->head && after->tail == before->tail);
	for (uint8_t i = before->tail; i != before->head; i++)
		FUZZ_CHECK(msg_equal(&after->queue[i % PROTO_QUEUE_DEPTH],
				     &before->queue[i % PROTO_QUEUE_DEPTH]));
	FUZZ_CHECK(after->orders_in == before->orders_in);
	FUZZ_CHECK(after->orders_taken == before->orders_taken);
	FUZZ_CHECK(after->orders_published == before->orders_published);
	FUZZ_CHECK(after->pending_status == before->pending_status);
	FUZZ_CHECK(after->snap_index == before->snap_index);
	FUZZ_CHECK(fuzz_snap_equal(&after->snap[0], &before->snap[0]));
	FUZZ_CHECK(fuzz_snap_equal(&after->snap[1], &before->snap[1]));
}

/* A message taken by the core obeys the table: an ORDRE or a SET, a full or short form, every
 * param within its range or its mask. */
static void check_message(const struct proto_msg *msg)
{
	const struct proto_msg_desc *d = proto_lookup(msg->designation);

	FUZZ_CHECK(d != NULL && d->designation == msg->designation);
	FUZZ_CHECK(d->kind != PROTO_KIND_ETAT);
	FUZZ_CHECK(msg->n_args == d->n_params || msg->n_args == d->min_params);
	for (uint8_t i = 0; i < PROTO_MAX_PARAMS; i++) {
		int32_t v = msg->arg[i];

		if (i >= msg->n_args) {
			FUZZ_CHECK(v == 0);
			continue;
		}
		const struct proto_param_desc *pd = &proto_params[d->first_param + i];
		if (pd->mask)
			FUZZ_CHECK(v >= 0 && v <= 255 && (v & ~(int32_t)pd->mask) == 0);
		else
			FUZZ_CHECK(v >= pd->min && v <= pd->max);
	}
}

static void check_status(void)
{
	uint8_t s = proto_status(&p);

	FUZZ_CHECK((s & 0x80u) == 0);
	FUZZ_CHECK(((s & STATUS_COMMANDE_REJETEE) != 0) == m.rejected);
	if (m.orders_accepted != m.orders_polled_at_publish)
		FUZZ_CHECK(s & STATUS_BUSY_TRAJET);
	FUZZ_CHECK(p.in_write == m.in_write && p.in_read == m.in_read);
	FUZZ_CHECK((uint8_t)(p.head - p.tail) <= PROTO_QUEUE_DEPTH);
	FUZZ_CHECK(p.rx_len <= PROTO_MAX_WRITE);
	FUZZ_CHECK(p.tx_pos <= p.tx_len && p.tx_len <= sizeof(p.tx));
}

/* A write ends (STOP, START, repeated start or bus error): judge it on a copy first, then check
 * that the real event did the same, and that a rejection changed nothing. */
static void end_write(void (*event)(struct proto *))
{
	struct proto before = p, judged = p;
	int empty = before.rx_len == 0 && !before.rx_overflow;
	int aborted = event == proto_on_abort;
	int queued, selected, rejected;

	if (aborted)
		proto_on_abort(&judged);
	else
		proto_on_stop(&judged);
	queued = judged.head != before.head;
	selected = !aborted && !empty && judged.selected != PROTO_NONE;
	rejected = !queued && !selected && (aborted || !empty);
	FUZZ_CHECK(queued + selected + rejected <= 1);

	event(&p);

	if (!empty)
		m.selected = PROTO_NONE; /* any non-empty write drops the selection */
	if (rejected) {
		check_unchanged(&before, &p);
		FUZZ_CHECK(p.rejected == 1);
		FUZZ_CHECK(p.last_reject < 32u && ((REJECT_KNOWN_MASK >> p.last_reject) & 1u));
		FUZZ_CHECK(!aborted || p.last_reject == REJECT_ABORTED);
		FUZZ_CHECK(p.last_reject_designation == (before.rx_len ? before.rx[0] : 0xFFu));
		FUZZ_CHECK(p.reject_count ==
			   (before.reject_count < 255u ? before.reject_count + 1u : 255u));
		m.rejected = 1;
	} else if (queued) {
		struct proto_msg *got = &p.queue[before.head % PROTO_QUEUE_DEPTH];

		FUZZ_CHECK(p.head == (uint8_t)(before.head + 1u));
		FUZZ_CHECK(msg_equal(got, &judged.queue[before.head % PROTO_QUEUE_DEPTH]));
		FUZZ_CHECK(p.reject_count == before.reject_count && p.rejected == 0);
		m.rejected = 0;
		/* PAUSE and RESUME keep the running order: they show no new one as running */
		if (proto_lookup(got->designation)->kind == PROTO_KIND_ORDRE &&
		    got->designation != PROTO_PAUSE && got->designation != PROTO_RESUME)
			m.orders_accepted++;
	} else {
		FUZZ_CHECK(p.head == before.head && p.reject_count == before.reject_count);
		FUZZ_CHECK(p.rejected == before.rejected);
		if (selected) {
			FUZZ_CHECK(proto_lookup(judged.selected)->kind == PROTO_KIND_ETAT);
			m.selected = judged.selected;
			m.at_select = m.published;
		}
	}
	m.in_write = 0;
}

static void end_read(void)
{
	m.in_read = 0;
	m.selected = PROTO_NONE;
	m.restart = 0;
}

/* Own address + read: the reply the model expects, and its PEC. */
static void start_read(void)
{
	uint8_t crc, sel, n;

	if (m.in_read)
		end_read();
	crc = (m.in_write || m.restart) ? m.seg_crc : 0; /* a repeated start: the write too */
	if (m.in_write)
		end_write(proto_on_read_start);
	else
		proto_on_read_start(&p);
	sel = m.selected == PROTO_NONE ? PROTO_CHECK_BUSY : m.selected;
	FUZZ_CHECK(p.selected == sel);
	if (sel == PROTO_CHECK_BUSY) {
		m.expect[0] = proto_status(&p);
		n = 1;
	} else if (sel == PROTO_LAST_REJECT) {
		m.expect[0] = p.last_reject;
		m.expect[1] = p.last_reject_designation;
		m.expect[2] = p.reject_count;
		n = 3;
	} else {
		n = proto_pack_reply(&p, sel, &m.at_select, m.expect);
	}
	FUZZ_CHECK(n == proto_lookup(sel)->reply_len);
	crc = proto_crc8(crc, &(const uint8_t){ADDR_R}, 1);
	m.expect[n] = proto_crc8(crc, m.expect, n);
	m.expect_len = (uint8_t)(n + 1u);
	m.read_pos = 0;
	m.in_read = 1;
}

static void tick_poll(void)
{
	struct proto_msg msg;

	while (proto_poll(&p, &msg)) {
		check_message(&msg);
		if (proto_lookup(msg.designation)->kind == PROTO_KIND_ORDRE &&
		    msg.designation != PROTO_PAUSE && msg.designation != PROTO_RESUME)
			m.orders_polled++;
	}
	m.polled_since_publish = 1;
}

static void tick_publish(uint8_t status)
{
	struct proto_snapshot s;

	if (!m.polled_since_publish)
		tick_poll();
	memset(&s, 0, sizeof(s));
	m.ticks++;
	/* Every byte of every reply changes from one tick to the next. */
	s.x_mm = (int16_t)(uint16_t)(m.ticks * 257u);
	s.y_mm = (int16_t)(uint16_t) ~(m.ticks * 257u);
	s.angle_2deg = (int8_t)(m.ticks % 181u - 90);
	s.radius_mm = (uint8_t)m.ticks;
	s.status = status & CORE_STATUS_BITS;
	s.sensors = status;
	s.debug.tick = m.ticks;
	s.debug.heading_cdeg = (int16_t)(uint16_t)(m.ticks * 31u);
	s.debug.order_state = (uint8_t)(m.ticks % 6u);
	proto_publish(&p, &s);
	m.published = s;
	m.orders_polled_at_publish = m.orders_polled;
	m.polled_since_publish = 0;
}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
	struct fuzz_input in = {data, size};
	uint8_t kind, n;
	int ok = 1;

	proto_init(&p);
	memset(&m, 0, sizeof(m));
	m.selected = PROTO_NONE;
	memset(&m.published, 0, sizeof(m.published));
	while (ok && fuzz_event(&in, &kind, &n)) {
		switch (kind) {
		case FUZZ_START_W:
			if (m.in_write)
				end_write(proto_on_write_start);
			else
				proto_on_write_start(&p);
			if (m.in_read)
				end_read();
			m.restart = 0;
			m.in_write = 1;
			m.seg_crc = proto_crc8(0, &(const uint8_t){ADDR_W}, 1);
			break;
		case FUZZ_DATA:
			for (uint8_t i = 0; i < n && ok; i++) {
				uint8_t b = fuzz_byte(&in, &ok);

				if (!ok)
					break;
				proto_on_byte(&p, b);
				if (m.in_write)
					m.seg_crc = proto_crc8(m.seg_crc, &b, 1);
			}
			break;
		case FUZZ_START_R:
			start_read();
			break;
		case FUZZ_READ:
			for (uint8_t i = 0; i < n; i++) {
				uint8_t b = proto_read_byte(&p);

				if (!m.in_read)
					continue; /* no read in progress: nothing the master can see
						   */
				FUZZ_CHECK(b == (m.read_pos < m.expect_len ? m.expect[m.read_pos]
									   : 0xFFu));
				if (m.read_pos < 255u)
					m.read_pos++;
			}
			break;
		case FUZZ_STOP:
			if (n % 2 == 0) { /* a repeated start */
				if (m.in_write) {
					end_write(proto_on_restart);
					m.restart = 1;
				} else {
					proto_on_restart(&p);
					if (m.in_read)
						end_read();
				}
				break;
			}
			if (m.in_write)
				end_write(proto_on_stop);
			else
				proto_on_stop(&p);
			if (m.in_read)
				end_read();
			m.restart = 0;
			break;
		case FUZZ_ABORT:
			if (m.in_write)
				end_write(proto_on_abort);
			else
				proto_on_abort(&p);
			end_read();
			break;
		case FUZZ_TICK:
			tick_poll();
			break;
		default: /* FUZZ_ENV */
			tick_publish(fuzz_byte(&in, &ok));
			break;
		}
		check_status();
	}
	return 0;
}
