/* Match play (motion.h): sequence numbers, the motion queue, PAUSE and RESUME, the speed scale,
 * the pass-through corners and the MOTION reply, on the planner's orders. */
#include "motion.h"

#include <stddef.h>

#include "board_parts.h"
#include "fixmath.h"
#include "protocol_defs.h"

void motion_init(struct motion *mo, const struct board_config *cfg, const struct orders *o,
		 uint16_t slow_hz)
{
	*mo = (struct motion){0};
	mo->ms_per_tick_q8 = (uint16_t)((1000u << 8) / slow_hz);
	for (uint8_t k = 0; k < 2; k++) { /* 1 / PAUSE's deceleration [ms per mm/s, 2^-8] */
		uint32_t a = (uint32_t)o->grip_a_um_s2[2 + k] / 1000u;   /* at init: a division */
		uint32_t r = ((1000u << 8) + a - 1u) / (a > 0 ? a : 1u); /* rounded up */

		mo->ms_per_mm_s_q8[k] = (uint16_t)(r > 0xFFFFu ? 0xFFFFu : r);
	}
	mo->scale_percent = 100;
	mo->corner_um = MOTION_CORNER_DEFAULT_MM * UM_PER_MM;
	/* A message waits for the period's end, the planner works on it (planner_ticks), the
	 * servo takes the new set points over the next period. */
	mo->latency_ticks = (uint8_t)(cfg->planner_ticks > 0 ? 3 : 2);
}

static uint8_t options_of(const struct proto_msg *msg)
{
	switch (msg->designation) {
	case PROTO_GOTO:
		return (uint8_t)msg->arg[ARG_GOTO_OPTIONS];
	case PROTO_GOTO_REVERSE:
		return (uint8_t)msg->arg[ARG_GOTO_REVERSE_OPTIONS];
	case PROTO_GOTO_PANIER:
		return (uint8_t)msg->arg[ARG_GOTO_PANIER_OPTIONS];
	default:
		return 0;
	}
}

/* Run an order now, as its sequence number's; from the queue, the end bits of the order that
 * ended before it stay readable until it ends. */
static void run(struct planner *pl, const struct proto_msg *msg, uint8_t seq, uint8_t queued)
{
	struct motion *mo = &pl->motion;
	uint8_t stale = pl->status & STATUS_END_BITS;

	if (options_of(msg) & PROTO_OPT_APPEND)
		mo->appends_done++;
	board_start_order(pl, msg);
	mo->running = 1;
	mo->running_seq = seq;
	mo->from_queue = queued;
	mo->stale_bits = queued ? stale : 0;
	mo->through = (options_of(msg) & PROTO_OPT_PASS_THROUGH) != 0;
}

/* Every waiting order dropped (a replacement, STOP, a fault): none of them ran. */
static void drop_queue(struct motion *mo)
{
	for (; mo->count > 0;
	     mo->count--, mo->head = (uint8_t)((mo->head + 1u) % PROTO_MOTION_QUEUE_DEPTH))
		if (options_of(&mo->queue[mo->head].msg) & PROTO_OPT_APPEND)
			mo->appends_done++;
}

/* The next waiting order, if any and not paused. */
static void run_next(struct planner *pl)
{
	struct motion *mo = &pl->motion;
	const struct motion_entry *e = &mo->queue[mo->head];

	if (mo->count == 0 || mo->paused)
		return;
	mo->head = (uint8_t)((mo->head + 1u) % PROTO_MOTION_QUEUE_DEPTH);
	mo->count--;
	run(pl, &e->msg, e->seq, 1);
}

static void enqueue(struct motion *mo, const struct proto_msg *msg, uint8_t seq)
{
	struct motion_entry *e;

	if (mo->count >= PROTO_MOTION_QUEUE_DEPTH) { /* the protocol layer refuses it first */
		mo->appends_done++;
		return;
	}
	e = &mo->queue[(mo->head + mo->count) % PROTO_MOTION_QUEUE_DEPTH];
	e->msg = *msg;
	e->seq = seq;
	mo->count++;
}

void motion_order(struct planner *pl, const struct proto_msg *msg)
{
	struct motion *mo = &pl->motion;
	uint8_t d = msg->designation;

	if (d == PROTO_PAUSE) {
		mo->paused = 1;
		orders_pause(&pl->orders);
		return;
	}
	if (d == PROTO_RESUME) {
		mo->paused = 0; /* a waiting order starts after the orders (motion_after()) */
		orders_resume(&pl->orders);
		return;
	}
	if (d == PROTO_STOP) { /* abandons everything; the running order ends STOPPED */
		drop_queue(mo);
		mo->paused = 0;
		board_start_order(pl, msg);
		return;
	}
	mo->seq++;
	if ((options_of(msg) & PROTO_OPT_APPEND) && (mo->running || mo->count || mo->paused)) {
		enqueue(mo, msg, mo->seq);
		return;
	}
	drop_queue(mo);
	mo->paused = 0;
	run(pl, msg, mo->seq, 0);
}

void motion_refused(struct planner *pl, const struct proto_msg *msg)
{
	struct motion *mo = &pl->motion;

	if (msg->designation == PROTO_PAUSE || msg->designation == PROTO_RESUME ||
	    msg->designation == PROTO_STOP)
		return;
	if (options_of(msg) & PROTO_OPT_APPEND)
		mo->appends_done++;
	mo->seq++;
	mo->last_seq = mo->seq;
	mo->last_end = END_REASON_FAULT;
}

void motion_setting(struct planner *pl, const struct proto_msg *msg)
{
	if (msg->designation == PROTO_SET_SPEED_SCALE) {
		pl->motion.scale_percent = (uint8_t)msg->arg[ARG_SET_SPEED_SCALE_PERCENT];
		orders_set_speed_scale(&pl->orders, pl->motion.scale_percent);
	} else { /* PROTO_SET_CORNER */
		pl->motion.corner_um = msg->arg[ARG_SET_CORNER_TOLERANCE_MM] * UM_PER_MM;
	}
}

/* [mm/s] or [mm/s^2], at least 1. */
static int32_t mm_of_um(int32_t um)
{
	int32_t mm = (int32_t)fx_udiv1000(fx_mag32(um));

	return mm > 0 ? mm : 1;
}

/* How far past a corner's point the distance axis may go (docs/control.md, "Corners"): braking
 * from the corner speed v_c over e = v_c^2 / (2 a), e at most 7/8 of the tolerance; and
 * v_c omega_max within a quarter of the grip, omega_max the angle axis's speed limit over half
 * the drive track. [um] */
static int32_t corner_reach_um(const struct planner *pl, const struct board_config *cfg)
{
	const struct orders *o = &pl->orders;
	int32_t a = mm_of_um(o->dist.prm.lim.a_max_um_s2);
	int32_t w = mm_of_um(o->angle.prm.lim.v_max_um_s);
	int32_t half_track = mm_of_um((int32_t)(cfg->orders.drive_track_um / 2u));
	int32_t vc = mm_of_um(cfg->orders.grip_um_s2 / 4) * half_track / w; /* [mm/s] */
	int32_t e = pl->motion.corner_um - (pl->motion.corner_um >> 3);

	if (vc > 3000)
		vc = 3000;
	if (vc * vc / (2 * a) * UM_PER_MM < e)
		e = vc * vc / (2 * a) * UM_PER_MM;
	return e;
}

void motion_before(struct planner *pl, const struct board_config *cfg)
{
	struct motion *mo = &pl->motion;
	struct orders *o = &pl->orders;
	int32_t e;

	if (!mo->through)
		return;
	if (!mo->running || mo->count == 0 || mo->paused || o->designation != PROTO_GOTO ||
	    o->state != ORDER_STATE_TRANSLATE) {
		o->through_um = 0;
		return;
	}
	e = corner_reach_um(pl, cfg);
	o->through_um = e;
	if (profile_get_target_um(&o->dist) - o->sp_dist.pos_um > e)
		return;
	/* At the corner: this order is done, the next one turns while the line brakes. */
	mo->running = 0;
	mo->last_seq = mo->running_seq;
	mo->last_end = END_REASON_DONE;
	pl->status &= (uint8_t)~STATUS_END_BITS;
	run_next(pl);
}

/* The robot at rest: an order that ended on a contact (a basket) ended at speed, held where it
 * was measured; the next one waits until the hold has stopped it. */
static int at_rest(const struct planner *pl)
{
	int32_t slow = pl->orders.cfg.arrive_speed_um_s;

	return fx_abs32(pl->m.dist_speed_um_s) < slow && fx_abs32(pl->m.angle_speed_um_s) < slow;
}

static void update_braking(struct motion *mo, const struct orders *o);

/* An order that ended: MOTION's last ending, the next one or the queue dropped. */
static void order_ended(struct planner *pl)
{
	struct motion *mo = &pl->motion;
	uint8_t end;

	if (mo->running) {
		if (orders_busy(&pl->orders))
			return;
		end = pl->timed_out ? END_REASON_TIMEOUT : pl->orders.end_reason;
		mo->running = 0;
		mo->from_queue = 0;
		mo->stale_bits = 0;
		mo->last_seq = mo->running_seq;
		mo->last_end = end;
		if (end != END_REASON_DONE && end != END_REASON_BORDER && end != END_REASON_BASKET)
			drop_queue(mo);
	}
	if (mo->count && at_rest(pl))
		run_next(pl);
}

void motion_after(struct planner *pl)
{
	order_ended(pl);
	update_braking(&pl->motion, &pl->orders);
}

/* Braking from v_um_s at PAUSE's deceleration on profile p of n_filt ticks' smoothing, with
 * the message's latency: time [ms], and distance [mm] when dist_mm is not NULL; rounded up. No
 * division but by 1000, 16 x 16-bit products (the AVR's planner runs it every period): 1 / a is
 * the init's (motion_init()). */
static uint16_t braking(const struct motion *mo, const struct profile *p, int32_t v_um_s,
			uint8_t axis, uint16_t *dist_mm)
{
	uint32_t mag = fx_mag32(v_um_s);
	uint16_t v = (uint16_t)(fx_udiv1000(mag > 4095000u ? 4095000u : mag) + 1u); /* [mm/s] */
	uint32_t lag =
		(fx_mul_u16((uint16_t)(p->prm.n_filt + mo->latency_ticks), mo->ms_per_tick_q8) +
		 255u) >>
		8;                                                                 /* [ms] */
	uint32_t t = ((fx_mul_u16(v, mo->ms_per_mm_s_q8[axis]) + 255u) >> 8) + 1u; /* v / a */
	uint32_t d;

	if (lag > 0xFFFFu)
		lag = 0xFFFFu;
	if (t > 0xFFFFu)
		t = 0xFFFFu;
	if (dist_mm) { /* v t / 2 + v lag, [mm/s x ms] */
		d = (fx_mul_u16(v, (uint16_t)t) >> 1) + fx_mul_u16(v, (uint16_t)lag);
		d = d >= 33553000u ? 0xFFFFu : fx_udiv1000(d) + 2u;
		*dist_mm = (uint16_t)(d > 0xFFFFu ? 0xFFFFu : d);
	}
	t += lag + 1u;
	return (uint16_t)(t > 0xFFFFu ? 0xFFFFu : t);
}

void motion_publish(const struct planner *pl, struct proto_snapshot *s)
{
	const struct motion *mo = &pl->motion;
	const struct orders *o = &pl->orders;
	struct proto_motion *out = &s->motion;
	out->running_seq = mo->running ? mo->running_seq : mo->seq;
	out->pending = mo->count;
	out->flags = (uint8_t)((mo->paused ? PROTO_MOTION_PAUSED : 0u) |
			       (orders_busy(o) ? PROTO_MOTION_RUNNING : 0u));
	out->last_seq = mo->last_seq;
	out->last_end = mo->last_end;
	out->scale_percent = mo->scale_percent;
	out->appends_done = mo->appends_done;
	out->braking_mm = 0;
	out->braking_ms = 0;
	if (mo->running && mo->from_queue)
		s->status |= mo->stale_bits; /* CHECK_BUSY: the end bits of the last order ended */
	if (mo->count)
		s->status |= STATUS_BUSY_TRAJET; /* waiting (paused) is busy too */
	out->braking_mm = mo->braking_mm;
	out->braking_ms = mo->braking_ms;
}

/* MOTION's braking distance and time, at the set points' speeds: computed again only when they
 * or the smoothing changed (a cruise costs nothing). */
static void update_braking(struct motion *mo, const struct orders *o)
{
	/* Each speed rounded up to a step of 2^14 um/s (16.4 mm/s): the figures are those of the
	 * step's top, bounds still, computed again a few times in an acceleration rather than at
	 * each period (bench_avr). */
	int32_t kd = (int32_t)((fx_mag32(o->sp_dist.vel_um_s) + 16383u) >> 14);
	int32_t ka = (int32_t)((fx_mag32(o->sp_angle.vel_um_s) + 16383u) >> 14);
	int32_t kf = o->dist.prm.n_filt + o->angle.prm.n_filt;
	uint16_t ta;

	if (kd == mo->braking_key[0] && ka == mo->braking_key[1] && kf == mo->braking_key[2])
		return;
	mo->braking_key[0] = kd;
	mo->braking_key[1] = ka;
	mo->braking_key[2] = kf;
	mo->braking_mm = 0;
	mo->braking_ms = 0;
	if (kd != 0)
		mo->braking_ms = braking(mo, &o->dist, kd << 14, 0, &mo->braking_mm);
	if (ka != 0) {
		ta = braking(mo, &o->angle, ka << 14, 1, NULL);
		if (ta > mo->braking_ms)
			mo->braking_ms = ta;
	}
}
