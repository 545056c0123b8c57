/* The board's side of the I2C protocol (see protocol.h and docs/protocol.md). */
#include "protocol.h"

#include <stddef.h>
#include <string.h>

#include "feature_set.h"

#define ADDR_W ((uint8_t)(PROTO_ADDRESS << 1))
#define ADDR_R ((uint8_t)((PROTO_ADDRESS << 1) | 1u))

/* head and tail are free-running byte counters: their difference is the fill level. */
typedef char proto_queue_depth_divides_256[(256 % PROTO_QUEUE_DEPTH == 0) ? 1 : -1];

/* An order replaces the current one, so until the core publishes it, the status shows the new
 * order running and none of the end bits the order will clear. */
#define STATUS_CLEARED_BY_ORDER (STATUS_PB_MOTEUR | STATUS_CHOC_BORD | STATUS_CHOC_PANIER)

/* The CRC-8 of the 16 values of a nibble in the top half (polynomial 0x07): a byte is two
 * lookups, where the bit-by-bit loop took about 100 cycles on an AVR, in the I2C interrupt. */
static const uint8_t crc8_nibble[16] = {
	0x00, 0x07, 0x0e, 0x09, 0x1c, 0x1b, 0x12, 0x15,
	0x38, 0x3f, 0x36, 0x31, 0x24, 0x23, 0x2a, 0x2d,
};

static uint8_t crc8_byte(uint8_t crc, uint8_t b)
{
	crc ^= b;
	crc = (uint8_t)(crc << 4) ^ crc8_nibble[crc >> 4];
	return (uint8_t)(crc << 4) ^ crc8_nibble[crc >> 4];
}

uint8_t proto_crc8(uint8_t crc, const uint8_t *data, uint8_t n)
{
	for (uint8_t i = 0; i < n; i++)
		crc = crc8_byte(crc, data[i]);
	return crc;
}

/* An order that replaces or ends the running one: until the core publishes it, the status shows
 * it (pending_status). PAUSE and RESUME keep the running order and its status. */
static int replaces(const struct proto_msg_desc *d)
{
	return d->kind == PROTO_KIND_ORDRE && d->designation != PROTO_PAUSE &&
	       d->designation != PROTO_RESUME;
}

static uint8_t crc_of_byte(uint8_t b)
{
	return crc8_byte(0, b);
}

void proto_init(struct proto *p)
{
	memset(p, 0, sizeof(*p));
	p->selected = PROTO_NONE;
}

static const struct proto_snapshot *published(const struct proto *p)
{
	return &p->snap[p->snap_index & 1u];
}

uint8_t proto_status(const struct proto *p)
{
	uint8_t s = published(p)->status & (uint8_t)~STATUS_COMMANDE_REJETEE;
	if (p->orders_in != p->orders_published) {
		s &= (uint8_t)~STATUS_CLEARED_BY_ORDER;
		s |= p->pending_status;
	}
	if (p->rejected)
		s |= STATUS_COMMANDE_REJETEE;
	return s;
}

static uint8_t put_u16(uint8_t *out, uint16_t v)
{
	out[0] = (uint8_t)(v >> 8);
	out[1] = (uint8_t)v;
	return 2;
}

uint8_t proto_pack_reply(const struct proto *p, uint8_t designation, const struct proto_snapshot *s,
			 uint8_t *out)
{
	const struct proto_debug *d = &s->debug;
	uint8_t n = 0;

	switch (designation) {
	case PROTO_CHECK_BUSY:
		out[n++] = proto_status(p);
		break;
	case PROTO_POSITION:
		n += put_u16(&out[n], (uint16_t)s->x_mm);
		n += put_u16(&out[n], (uint16_t)s->y_mm);
		out[n++] = (uint8_t)s->angle_2deg;
		out[n++] = s->radius_mm;
		break;
	case PROTO_INFO_CHOC:
		out[n++] = s->sensors;
		break;
	case PROTO_VERSION:
		out[n++] = PROTO_VERSION_MAJOR;
		out[n++] = PROTO_VERSION_MINOR;
		n += put_u16(
			&out[n],
			(uint16_t)(CAP_BUILD | (s->calibrated ? CAP_CALIBRATED : 0u) |
				   (s->reset.tracked ? CAP_RESET_INFO : 0u) |
				   (s->reset.tracked && CONFIG_KEEP_POSE ? CAP_KEEP_POSE : 0u)));
		break;
	case PROTO_LAST_REJECT:
		out[n++] = p->last_reject;
		out[n++] = p->last_reject_designation;
		out[n++] = p->reject_count;
		break;
	case PROTO_DEBUG:
		n += put_u16(&out[n], d->tick);
		n += put_u16(&out[n], (uint16_t)d->heading_cdeg);
		n += put_u16(&out[n], (uint16_t)d->speed_mm_s);
		n += put_u16(&out[n], (uint16_t)d->turn_rate_cdeg_s);
		n += put_u16(&out[n], (uint16_t)d->dist_err_um);
		n += put_u16(&out[n], (uint16_t)d->angle_err_um);
		n += put_u16(&out[n], (uint16_t)d->duty_left_q15);
		n += put_u16(&out[n], (uint16_t)d->duty_right_q15);
		n += put_u16(&out[n], (uint16_t)d->current_left_ma);
		n += put_u16(&out[n], (uint16_t)d->current_right_ma);
		out[n++] = d->order_state;
		out[n++] = d->end_reason;
		break;
	case PROTO_MOTION:
		out[n++] = s->motion.running_seq;
		out[n++] = s->motion.pending;
		out[n++] = s->motion.flags;
		out[n++] = s->motion.last_seq;
		out[n++] = s->motion.last_end;
		n += put_u16(&out[n], s->motion.braking_mm);
		n += put_u16(&out[n], s->motion.braking_ms);
		out[n++] = s->motion.scale_percent;
		break;
	case PROTO_RESET_INFO:
		out[n++] = s->reset.cause;
		out[n++] = s->reset.count;
		out[n++] = s->reset.pose_lost;
		out[n++] = s->reset.widened_mm;
		break;
	case PROTO_FIX_INFO:
		n += put_u16(&out[n], s->fix.fused);
		n += put_u16(&out[n], s->fix.outliers);
		n += put_u16(&out[n], s->fix.too_old);
		out[n++] = s->fix.last;
		out[n++] = s->fix.last_d2;
		break;
	default:
		break;
	}
	return n;
}

static void reject(struct proto *p, uint8_t reason)
{
	p->rejected = 1;
	p->last_reject = reason;
	p->last_reject_designation = p->rx_len ? p->rx[0] : 0xFFu; /* 0xFF: no byte came */
	if (p->reject_count < 255u)
		p->reject_count++;
}

/* Decode and range-check the params of rx[] into m. Returns 0 or a REJECT_ code. */
static uint8_t decode_params(const struct proto *p, const struct proto_msg_desc *d,
			     uint8_t n_params, struct proto_msg *m)
{
	uint8_t pos = 1;

	m->designation = d->designation;
	m->n_args = n_params;
	for (uint8_t i = 0; i < PROTO_MAX_PARAMS; i++)
		m->arg[i] = 0;
	for (uint8_t i = 0; i < n_params; i++) {
		const struct proto_param_desc *pd = &proto_params[d->first_param + i];
		int32_t v;

		switch (pd->type) {
		case PROTO_U8:
			v = p->rx[pos];
			pos += 1;
			break;
		case PROTO_S8:
			v = (int8_t)p->rx[pos];
			pos += 1;
			break;
		case PROTO_U16:
			v = (int32_t)(((uint16_t)p->rx[pos] << 8) | p->rx[pos + 1]);
			pos += 2;
			break;
		default: /* PROTO_S16 */
			v = (int16_t)(uint16_t)(((uint16_t)p->rx[pos] << 8) | p->rx[pos + 1]);
			pos += 2;
			break;
		}
		if (pd->mask) {
			if ((uint8_t)v & (uint8_t)~pd->mask)
				return REJECT_RESERVED_BIT;
		} else if (v < pd->min || v > pd->max) {
			return REJECT_OUT_OF_RANGE;
		}
		m->arg[i] = v;
	}
	return REJECT_NONE;
}

/* The options byte of a motion order, 0 when it has none. */
static uint8_t options_of(const struct proto_msg *m)
{
	switch (m->designation) {
	case PROTO_GOTO:
		return (uint8_t)m->arg[ARG_GOTO_OPTIONS];
	case PROTO_GOTO_REVERSE:
		return (uint8_t)m->arg[ARG_GOTO_REVERSE_OPTIONS];
	case PROTO_GOTO_PANIER:
		return (uint8_t)m->arg[ARG_GOTO_PANIER_OPTIONS];
	default:
		return 0;
	}
}

/* The checks of issue 31's extensions (docs/protocol.md, "Match play"), after the table's:
 * what this build leaves out, options that cannot combine, an APPEND the motion queue has no
 * room for. Returns 0 or a REJECT_ code. */
static uint8_t check_motion(const struct proto *p, const struct proto_msg *m)
{
	uint8_t opt = options_of(m);
	uint8_t d = m->designation;

	if ((!CONFIG_MOTION_PAUSE &&
	     (d == PROTO_PAUSE || d == PROTO_RESUME || d == PROTO_MOTION)) ||
	    (!CONFIG_MOTION_SPEED_SCALE && d == PROTO_SET_SPEED_SCALE) ||
	    (!CONFIG_MOTION_QUEUE && (opt & PROTO_OPT_APPEND)) ||
	    (!CONFIG_MOTION_CORNERS && (d == PROTO_SET_CORNER || (opt & PROTO_OPT_PASS_THROUGH))))
		return REJECT_UNSUPPORTED;
	if ((opt & PROTO_OPT_PASS_THROUGH) && (opt & PROTO_OPT_RECAL))
		return REJECT_BAD_OPTIONS;
	if ((opt & PROTO_OPT_APPEND) &&
	    (uint8_t)(p->appends_in - published(p)->motion.appends_done) >=
		    PROTO_MOTION_QUEUE_DEPTH)
		return REJECT_MOTION_QUEUE_FULL;
	return REJECT_NONE;
}

static void select_reply(struct proto *p, uint8_t designation)
{
	p->selected = designation;
	p->tx_len = proto_pack_reply(p, designation, published(p), p->tx);
	p->tx_pos = 0;
}

/* A write frame is over: judge it whole, then apply it whole or not at all. */
/* A well-formed write that the board's state refuses, or REJECT_NONE: an order under PB_GRAVE,
 * BOOTLOADER while an order drives, a motion order while the pose is lost, a full queue. */
static uint8_t admit(const struct proto *p, const struct proto_msg_desc *d)
{
	if (d->kind == PROTO_KIND_ORDRE && (published(p)->status & STATUS_PB_GRAVE))
		return REJECT_REFUSED_PB_GRAVE;
	/* Leaving for the bootloader stops the control: not while an order drives. */
	if (d->designation == PROTO_BOOTLOADER &&
	    ((published(p)->status & STATUS_BUSY_TRAJET) || p->orders_in != p->orders_published))
		return REJECT_REFUSED_BUSY;
	if (d->kind == PROTO_KIND_ORDRE && d->designation != PROTO_STOP &&
	    published(p)->reset.pose_lost && !p->pose_declared)
		return REJECT_REFUSED_NO_POSE;
	if ((uint8_t)(p->head - p->tail) >= PROTO_QUEUE_DEPTH)
		return REJECT_QUEUE_FULL;
	return REJECT_NONE;
}

static void end_write(struct proto *p)
{
	const struct proto_msg_desc *d;
	struct proto_msg m;
	uint8_t n = p->rx_len;
	uint8_t n_params;
	uint8_t reason;

	p->in_write = 0;
	if (n == 0 && !p->rx_overflow)
		return; /* address-only write (SMBus quick command, i2cdetect): not a frame */
	p->selected = PROTO_NONE;
	if (p->rx_overflow) {
		reject(p, REJECT_BAD_LENGTH);
		return;
	}
	d = proto_lookup(p->rx[0]);
	if (d == NULL) {
		reject(p, REJECT_UNKNOWN_DESIGNATION);
		return;
	}
	if (n == d->write_len) {
		n_params = d->n_params;
	} else if (n == d->short_len) {
		n_params = d->min_params;
	} else if (n == d->write_len + 1u) {
		n_params = d->n_params;
		if (proto_crc8(crc_of_byte(ADDR_W), p->rx, (uint8_t)(n - 1u)) != p->rx[n - 1u]) {
			reject(p, REJECT_BAD_PEC);
			return;
		}
	} else {
		reject(p, REJECT_BAD_LENGTH);
		return;
	}
	reason = decode_params(p, d, n_params, &m);
	if (reason == REJECT_NONE)
		reason = check_motion(p, &m);
	if (reason == REJECT_NONE && !feature_set_has(d->designation))
		reason = REJECT_UNSUPPORTED;
	if (reason != REJECT_NONE) {
		reject(p, reason);
		return;
	}
	if (d->kind == PROTO_KIND_ETAT) {
		/* A read selection is not an order: it leaves COMMANDE_REJETEE for the master to
		 * read. */
		select_reply(p, d->designation);
		return;
	}
	reason = admit(p, d);
	if (reason != REJECT_NONE) {
		reject(p, reason);
		return;
	}
	if (d->designation == PROTO_SET_NEW_POS)
		p->pose_declared = 1;
	p->queue[p->head % PROTO_QUEUE_DEPTH] = m;
	p->head++;
	p->rejected = 0;
	if (replaces(d)) {
		p->pending_status = STATUS_BUSY_TRAJET;
		if (d->designation == PROTO_GOTO_PANIER)
			p->pending_status |= STATUS_BUSY_GOTO_PANIER;
		p->orders_in++;
		if (options_of(&m) & PROTO_OPT_APPEND)
			p->appends_in++;
	}
}

static void end_read(struct proto *p)
{
	if (p->in_read)
		p->transactions++; /* counted here rather than while SCL is held at its start */
	p->in_read = 0;
	p->selected = PROTO_NONE;
	p->tx_len = 0;
	p->tx_pos = 0;
	p->restart_crc = 0;
}

void proto_on_write_start(struct proto *p)
{
	if (p->in_write)
		end_write(p);
	else if (p->in_read)
		end_read(p);
	p->restart_crc = 0;
	p->write_crc = crc_of_byte(ADDR_W);
	p->rx_len = 0;
	p->rx_overflow = 0;
	p->in_write = 1;
	p->transactions++;
}

void proto_on_byte(struct proto *p, uint8_t byte)
{
	if (!p->in_write)
		return; /* a byte outside a write: the port reported no start, nothing to judge */
	p->write_crc = crc8_byte(p->write_crc, byte); /* every byte, for a PEC after Sr */
	if (p->rx_len < PROTO_MAX_WRITE)
		p->rx[p->rx_len++] = byte;
	else
		p->rx_overflow = 1;
}

void proto_on_restart(struct proto *p)
{
	if (p->in_write) {
		p->restart_crc = 1; /* a read that follows continues the PEC */
		end_write(p);
	} else if (p->in_read) {
		end_read(p); /* read, repeated start, read: the first read is over */
	}
}

void proto_on_read_start(struct proto *p)
{
	uint8_t crc;

	if (p->in_read)
		end_read(p); /* read, repeated start, read: the first read is over */
	if (p->in_write) {
		p->restart_crc = 1; /* the port reported no repeated start */
		end_write(p);
	}
	if (p->selected == PROTO_NONE)
		select_reply(p, PROTO_CHECK_BUSY);
	else if (p->selected == PROTO_CHECK_BUSY || p->selected == PROTO_LAST_REJECT)
		select_reply(p, p->selected); /* status bits may have moved since the selection */
	/* SMBus PEC covers the whole transaction since its START: the selecting write too when the
	 * read follows it by a repeated start. It is summed as the bytes go out (proto_read_byte),
	 * so that the clock held before the first byte only covers the packing. */
	crc = p->restart_crc ? p->write_crc : 0;
	p->read_crc = crc8_byte(crc, ADDR_R);
	p->tx_len++; /* the PEC's place */
	p->tx_pos = 0;
	p->in_read = 1;
}

uint8_t proto_read_byte(struct proto *p)
{
	uint8_t b;

	if (p->tx_pos + 1u < p->tx_len) {
		b = p->tx[p->tx_pos++];
		p->read_crc = crc8_byte(p->read_crc, b);
		return b;
	}
	/* Only in a read: outside one (a port out of step) the reply has no PEC slot yet, and
	 * the PEC would overwrite its last byte. The branch above only moves what the read's
	 * start resets. */
	if (p->tx_pos < p->tx_len && p->in_read) {
		/* The PEC, over every byte before it. */
		p->tx[p->tx_pos++] = p->read_crc;
		return p->read_crc;
	}
	return 0xFFu; /* the bus's idle level: what a master reads from a released SDA */
}

void proto_on_stop(struct proto *p)
{
	if (p->in_write)
		end_write(p);
	else if (p->in_read)
		end_read(p);
	p->restart_crc = 0;
}

void proto_on_abort(struct proto *p)
{
	if (p->in_write) {
		p->in_write = 0;
		p->selected = PROTO_NONE;
		reject(p, REJECT_ABORTED);
	}
	end_read(p);
}

int proto_poll(struct proto *p, struct proto_msg *out)
{
	uint8_t t = p->tail;

	if (t == p->head)
		return 0;
	*out = p->queue[t % PROTO_QUEUE_DEPTH];
	p->tail = (uint8_t)(t + 1u);
	if (replaces(proto_lookup(out->designation)))
		p->orders_taken++;
	return 1;
}

struct proto_snapshot *proto_draft(struct proto *p)
{
	return &p->snap[(p->snap_index + 1u) & 1u];
}

void proto_flip(struct proto *p)
{
	p->snap_index = (uint8_t)((p->snap_index + 1u) & 1u);
	p->orders_published = p->orders_taken;
}

void proto_publish(struct proto *p, const struct proto_snapshot *s)
{
	*proto_draft(p) = *s;
	proto_flip(p);
}

void proto_master_write(struct proto *p, const uint8_t *data, uint8_t n, int stop)
{
	proto_on_write_start(p);
	for (uint8_t i = 0; i < n; i++)
		proto_on_byte(p, data[i]);
	if (stop)
		proto_on_stop(p);
}

void proto_master_read(struct proto *p, uint8_t *out, uint8_t n)
{
	proto_on_read_start(p);
	for (uint8_t i = 0; i < n; i++)
		out[i] = proto_read_byte(p);
	proto_on_stop(p);
}
