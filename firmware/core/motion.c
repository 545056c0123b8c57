/* Match play (motion.h): sequence numbers, the motion queue, PAUSE and RESUME, the speed scale,
 * the pass-through corners and the MOTION reply, on the planner's orders. */
#include "motion.h"

#include <stddef.h>

#include "board_parts.h"
#include "fixmath.h"
#include "protocol_defs.h"

/* 1 / a deceleration [ms per mm/s, 2^-8], rounded up, saturating: a division, made where the
 * deceleration is set (at init, at a curve's or a pivot's start), not at each braking. */
static uint16_t ms_per_mm_s_q8_of(int32_t a_um_s2)
{
	uint32_t a = (uint32_t)a_um_s2 / 1000u;
	uint32_t r = ((1000u << 8) + a - 1u) / (a > 0 ? a : 1u);

	return (uint16_t)(r > 0xFFFFu ? 0xFFFFu : r);
}

void motion_init(struct motion *mo, const struct board_config *cfg, const struct orders *o,
		 uint16_t slow_hz)
{
	*mo = (struct motion){0};
	mo->ms_per_tick_q8 = (uint16_t)((1000u << 8) / slow_hz);
	for (uint8_t k = 0; k < 2; k++) /* 1 / PAUSE's deceleration of each axis */
		mo->ms_per_mm_s_q8[k] = ms_per_mm_s_q8_of(o->grip_a_um_s2[2 + k]);
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

#if CONFIG_MOTION_CORNERS
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

/* A curve's radius at most [um] (a corner of less than a degree: the line goes on). */
#define CORNER_R_MAX_UM 10000000
/* Slower than this, a curve is not worth it [um/s]: the corner as before the curves. */
#define CORNER_V_MIN_UM_S 50000
#define Q30 ((int64_t)1 << 30)

/* A speed limit at the speed scale, as apply_limits() (orders.c) gives it outside a curve. */
static int32_t scaled(const struct orders *o, int32_t v_um_s)
{
	v_um_s = v_um_s * o->scale_percent / 100;
	return v_um_s < 1 ? 1 : v_um_s;
}

/* The limits a corner's curve keeps, from the orders' present ones: [0] the line's speed,
 * [1] the heading's wheel speed, [2] the centripetal acceleration (a quarter of the grip), [3]
 * the heading's wheel acceleration on the clothoids (half of 7/8 of the grip at most), [4]
 * half the drive track, [5] k times it (the yaw's share of a wheel's grip). */
static void corner_limits(const struct orders *o, int64_t lim[6])
{
	int64_t g7 = o->cfg.grip_um_s2 - (o->cfg.grip_um_s2 >> 3);
	int64_t rot = g7 * 160 / o->cfg.rot_grip_q8; /* 5/8 of g7 over k */

	lim[0] = scaled(o, o->traj.v_max_um_s);
	lim[1] = scaled(o, o->rot.v_max_um_s);
	lim[2] = o->cfg.grip_um_s2 / 3;
	lim[3] = o->rot.a_max_um_s2 < rot ? o->rot.a_max_um_s2 : rot;
	lim[4] = o->cfg.drive_track_um / 2u;
	lim[5] = lim[4] * o->cfg.rot_grip_q8 / 256;
}

/* The fastest curve of radius sh->r_um through a turn theta whose half has the cosine and sine
 * cos_q30, sin_q30: v^2 within the centripetal acceleration, v r / h within the heading's wheel
 * speed; the clothoids (the curvature's rise at the heading's acceleration: h v^2 / (r a)
 * long) within the turn's arc and within the tolerance's share (their shift p = L^2 / 24 r).
 * The curve starts reach_um before the point; it passes (r + p) / cos - r from the point (its
 * middle, on the bisector), which p_max keeps within the tolerance (fit_try()). */
static void corner_shape(struct motion_shape *sh, const int64_t lim[6], uint32_t theta,
			 int32_t cos_q30, int32_t sin_q30, int64_t p_max)
{
	int64_t r = sh->r_um, v = lim[0], l_max, vv, p;
	int64_t arc = (int64_t)((uint64_t)theta * (uint64_t)r * 710u / 113u >> 32);

	if ((int64_t)fx_isqrt64((uint64_t)(lim[2] * r)) < v)
		v = fx_isqrt64((uint64_t)(lim[2] * r));
	if (lim[1] * r / lim[4] < v)
		v = lim[1] * r / lim[4];
	vv = v * v;
	l_max = fx_isqrt64((uint64_t)(24 * r * (p_max > 0 ? p_max : 0)));
	if (l_max > arc)
		l_max = arc;
	sh->clothoid_um = lim[4] * vv / (r * lim[3]);
	if (sh->clothoid_um > l_max) { /* a slower curve: the clothoid's length goes as v^2 */
		vv = l_max * lim[3] / lim[4] * r;
		v = fx_isqrt64((uint64_t)vv);
		sh->clothoid_um = l_max;
	}
	p = sh->clothoid_um * sh->clothoid_um / (24 * r);
	sh->v_um_s = v;
	sh->arc_um = arc - sh->clothoid_um;
	sh->reach_um = (r + p) * sin_q30 / (cos_q30 > 0 ? cos_q30 : 1) + sh->clothoid_um / 2;
}

/* The curve through a turn theta [turn32] between a line whose point is len1_um ahead and one
 * len2_um long, passing within the tolerance of the point (and so of the lines): the largest
 * radius whose arc alone passes within five eighths of the tolerance, ((r / cos) - r), the
 * clothoids' shift p within what that leaves of seven eighths (the curve passes (r + p) / cos
 * - r from the point), and the curve within half of either line (its radius smaller until it
 * is), at most v_cap_um_s and r_max_um. In up to six tries, one a call: fit_start() (FIT_OK at
 * once for a turn under a third of a degree, the line going on; else FIT_MORE), then fit_try()
 * while it returns FIT_MORE. */
enum fit_result { FIT_OK, FIT_NONE, FIT_MORE };

static enum fit_result fit_start(struct motion_fit *ft, struct motion_shape *sh,
				 const struct orders *o, int32_t tol_um, uint32_t theta,
				 int64_t len1_um, int64_t len2_um, int64_t free_um,
				 int64_t v_cap_um_s, int64_t r_max_um)
{
	int64_t dev = tol_um * 5 / 8;

	corner_limits(o, ft->lim);
	if (ft->lim[0] > v_cap_um_s)
		ft->lim[0] = v_cap_um_s;
	if (theta < ((uint32_t)1 << 22)) { /* a third of a degree: the line goes on */
		*sh = (struct motion_shape){.r_um = CORNER_R_MAX_UM, .v_um_s = ft->lim[0]};
		return FIT_OK;
	}
	ft->half_um = (len1_um < len2_um ? len1_um : len2_um) / 2;
	ft->free_um = free_um;
	ft->tol_um = tol_um;
	ft->theta = theta;
	ft->tries = 0;
	fx_sincos(theta / 2u, &ft->sin_q30, &ft->cos_q30);
	sh->r_um =
		Q30 - ft->cos_q30 > 0 ? dev * ft->cos_q30 / (Q30 - ft->cos_q30) : CORNER_R_MAX_UM;
	if (sh->r_um > r_max_um)
		sh->r_um = r_max_um;
	return FIT_MORE;
}

static enum fit_result fit_try(struct motion_fit *ft, struct motion_shape *sh)
{
	int64_t c = ft->cos_q30, half = ft->half_um, free_um = ft->free_um, tail, aim;

	if (sh->r_um < 1000)
		return FIT_NONE;
	/* An arc about a free wheel would leave it still while its motor turns: the lost encoder
	 * of faults.c. An arc an eighth of their half track inside instead (within a sixteenth,
	 * the robot turning faster than planned as the arc began did). */
	if (sh->r_um > free_um - free_um / 8 && sh->r_um < free_um + free_um / 8)
		sh->r_um = free_um - free_um / 8;
	corner_shape(sh, ft->lim, ft->theta, ft->cos_q30, ft->sin_q30,
		     (int64_t)ft->tol_um * 7 / 8 * c / Q30 - sh->r_um * (Q30 - c) / Q30);
	if (sh->reach_um <= half)
		return sh->v_um_s >= CORNER_V_MIN_UM_S ? FIT_OK : FIT_NONE;
	if (ft->tries == 5)
		return FIT_NONE;
	/* The radius that would reach half, were the clothoids as long: they grow as the radius
	 * shrinks at the line's speed (h v^2 / (r a')), so each try aims a sixteenth of half
	 * shorter than the last, and a gentle turn fits within the tries. */
	tail = sh->clothoid_um / 2;
	aim = half - half * ft->tries / 16;
	sh->r_um = aim > tail ? sh->r_um * (aim - tail) / (sh->reach_um - tail) - 1 : sh->r_um / 2;
	ft->tries++;
	return FIT_MORE;
}

/* A pivot (docs/control.md "Corners", 6): the line brakes to rest at the point while the heading
 * starts turning e_um before it, and the next line starts while the heading brakes its last
 * phi_um (on the angle axis). Each overlap strays from its line by at most a_h e^2 / (6 a h) and
 * a phi^2 / (6 a_h h) (the line braking or starting at a, the heading's rate from or to rest at
 * a_h, h half the drive track), kept within half the tolerance. Planned once for a corner and
 * the one it looks ahead at, from the shape kept in struct motion (the overlaps' time:
 * sqrt(2 e / a) + sqrt(2 phi / a_h)). */
static void pivot_shape_of(struct motion_pivot_shape *pv, const struct orders *o, int32_t tol_um)
{
	int64_t a = o->grip_a_um_s2[0], ah = o->grip_a_um_s2[1];
	int64_t k = 3 * (int64_t)tol_um * (int64_t)(o->cfg.drive_track_um / 2u); /* 6 dev h */
	int64_t turn = o->pi_track_um / 12; /* 30 degrees on the angle axis */

	/* Each overlap turns the heading by 30 degrees at most: the heading turns by a_h e / a
	 * in the first (on the angle axis), and phi in the last. */
	pv->e_um = fx_isqrt64((uint64_t)(k * a / ah));
	if (pv->e_um > turn * a / ah)
		pv->e_um = turn * a / ah;
	pv->phi_um = fx_isqrt64((uint64_t)(k * ah / a));
	if (pv->phi_um > turn)
		pv->phi_um = turn;
	pv->overlap_us = fx_isqrt64((uint64_t)(2 * pv->e_um * 1000000000000 / a)) +
			 fx_isqrt64((uint64_t)(2 * pv->phi_um * 1000000000000 / ah));
	/* phi on the angle axis as a heading [turn * 2^32] */
	pv->phi_turn32 = (uint32_t)((pv->phi_um << 32) / o->pi_track_um);
}

/* The pivot's shape made again when the accelerations (SET_VITESSE_*) or the tolerance
 * (SET_CORNER) changed: 1, and no corner is planned in this period (its 64-bit square roots and
 * divisions and a corner's planning would add up: bench/stm32.py --corners). */
static int pivot_refresh(struct motion *mo, const struct orders *o)
{
	int32_t key[3] = {o->grip_a_um_s2[0], o->grip_a_um_s2[1], mo->corner_um};

	if (key[0] == mo->pivot_key[0] && key[1] == mo->pivot_key[1] && key[2] == mo->pivot_key[2])
		return 0;
	for (uint8_t i = 0; i < 3; i++)
		mo->pivot_key[i] = key[i];
	pivot_shape_of(&mo->pivot_shape, o, mo->corner_um);
	return 1;
}

/* A rest-to-rest move of d_um at v_um_s and a_um_s2 at most [us]. */
static int64_t move_us(int64_t d_um, int64_t v_um_s, int64_t a_um_s2)
{
	if (d_um * a_um_s2 >= v_um_s * v_um_s)
		return d_um * 1000000 / v_um_s + v_um_s * 1000000 / a_um_s2;
	return 2 * (int64_t)fx_isqrt64((uint64_t)(d_um * 1000000000000 / a_um_s2));
}

/* 1 when a pivot pv through a turn theta between lines len1_um and len2_um long loses less time
 * than the curve sh (sh->v_um_s 0: none), each against the polyline at the line's speed v (the
 * speed limit, or the peak the shorter line allows) [us]: the pivot v / a and what of the turn
 * in place its overlaps leave (the first shorter within half the line: e no more than that);
 * the curve its ramps from and to v, (v - v_c)^2 / (a v), and its length at v_c against the
 * polyline's it replaces at v. */
static int corner_pivots(const struct orders *o, const struct motion_shape *sh, uint32_t theta,
			 int64_t len1_um, int64_t len2_um, const struct motion_pivot_shape *pv)
{
	int64_t a = o->grip_a_um_s2[0], v = scaled(o, o->traj.v_max_um_s);
	int64_t len = len1_um < len2_um ? len1_um : len2_um, vc = sh->v_um_s, turn, t;
	int64_t curve_us, pivot_us;

	if (v * v > a * len)
		v = fx_isqrt64((uint64_t)(a * len));
	if (vc < CORNER_V_MIN_UM_S || v <= vc)
		return vc < CORNER_V_MIN_UM_S;
	turn = (int64_t)((uint64_t)theta * (uint32_t)o->pi_track_um >> 32);
	t = move_us(turn, scaled(o, o->rot.v_max_um_s), o->grip_a_um_s2[1]) -
	    (pv->e_um > len1_um / 2 ? pv->overlap_us * len1_um / 2 / pv->e_um : pv->overlap_us);
	pivot_us = v * 1000000 / a + (t > 0 ? t : 0);
	curve_us = (v - vc) * (v - vc) / a * 1000000 / v +
		   (2 * sh->clothoid_um + sh->arc_um) * 1000000 / vc -
		   2 * sh->reach_um * 1000000 / v;
	return pivot_us < curve_us;
}
#endif

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
	if (!CONFIG_MOTION_ANY)
		return;
	order_ended(pl);
	if (CONFIG_MOTION_PAUSE) /* MOTION's braking figures: none to report without it */
		update_braking(&pl->motion, &pl->orders);
}

/* Braking from v_um_s at PAUSE's deceleration on profile p of n_filt ticks' smoothing, with
 * the message's latency: time [ms], and distance [mm] when dist_mm is not NULL; rounded up. No
 * division but by 1000, 16 x 16-bit products (the AVR's planner runs it every period): 1 / a is
 * the init's (motion_init()). */
static uint16_t braking(const struct motion *mo, const struct profile *p, int32_t v_um_s,
			uint16_t ms_per_mm_s_q8, uint16_t *dist_mm)
{
	uint32_t mag = fx_mag32(v_um_s);
	uint16_t v = (uint16_t)(fx_udiv1000(mag > 4095000u ? 4095000u : mag) + 1u); /* [mm/s] */
	uint32_t lag =
		(fx_mul_u16((uint16_t)(p->prm.n_filt + mo->latency_ticks), mo->ms_per_tick_q8) +
		 255u) >>
		8;                                                       /* [ms] */
	uint32_t t = ((fx_mul_u16(v, ms_per_mm_s_q8) + 255u) >> 8) + 1u; /* v / a */
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

	if (!CONFIG_MOTION_ANY)
		return;
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

/* 1 / PAUSE's deceleration of an axis as ms_per_mm_s_q8: on a curve (mode 1), the curve's for
 * the line; in a pivot (2), the pivot's; else the grip's shares. */
static uint16_t braking_ms_per_mm_s_q8(const struct motion *mo, int32_t mode, uint8_t axis)
{
#if CONFIG_MOTION_CORNERS
	if (mode == 2)
		return mo->pivot_ms_per_mm_s_q8[axis];
#endif
	return mode == 1 && axis == 0 ? mo->curve_ms_per_mm_s_q8 : mo->ms_per_mm_s_q8[axis];
}

/* MOTION's braking distance and time, at the set points' speeds: computed again only when they
 * or the smoothing changed (a cruise costs nothing). */
static void update_braking(struct motion *mo, const struct orders *o)
{
	/* Each speed rounded up to a step of 2^14 um/s (16.4 mm/s): the figures are those of the
	 * step's top, bounds still, computed again a few times in an acceleration rather than at
	 * each period (bench_avr). */
	int32_t kd, ka, kf;
	uint16_t ta;

	if (o->sp_dist.vel_um_s == mo->braking_vel[0] && o->sp_angle.vel_um_s == mo->braking_vel[1])
		return; /* a cruise, a turn at its speed, a hold: the speeds did not change */
	mo->braking_vel[0] = o->sp_dist.vel_um_s;
	mo->braking_vel[1] = o->sp_angle.vel_um_s;
	kd = (int32_t)((fx_mag32(o->sp_dist.vel_um_s) + 16383u) >> 14);
	ka = (int32_t)((fx_mag32(o->sp_angle.vel_um_s) + 16383u) >> 14);
	kf = o->dist.prm.n_filt + o->angle.prm.n_filt;
	if (CONFIG_MOTION_CORNERS && o->curve) { /* the heading brakes with the line */
		ka = 0;
		kf += (int32_t)1 << 20;
	}
	if (orders_pivoting(o)) /* at the pivot's accelerations */
		kf += (int32_t)2 << 20;
	if (kd == mo->braking_key[0] && ka == mo->braking_key[1] && kf == mo->braking_key[2])
		return;
	mo->braking_key[0] = kd;
	mo->braking_key[1] = ka;
	mo->braking_key[2] = kf;
	mo->braking_mm = 0;
	mo->braking_ms = 0;
	if (kd != 0)
		mo->braking_ms = braking(mo, &o->dist, kd << 14,
					 braking_ms_per_mm_s_q8(mo, kf >> 20, 0), &mo->braking_mm);
	if (ka != 0) {
		ta = braking(mo, &o->angle, ka << 14, braking_ms_per_mm_s_q8(mo, kf >> 20, 1),
			     NULL);
		if (ta > mo->braking_ms)
			mo->braking_ms = ta;
	}
}

#if CONFIG_MOTION_CORNERS
/* A GOTO that a curve may join: no recalibration bit. */
static int curve_joins(const struct proto_msg *msg)
{
	return msg->designation == PROTO_GOTO &&
	       !(msg->arg[ARG_GOTO_OPTIONS] & (ORDERS_OPT_LINE | ORDERS_OPT_BORDER));
}

/* The running order's corner with the next one waiting, k (motion.h), planned again when either
 * order, a limit or the tolerance changed: the next order a GOTO without recalibration, the
 * trapezoid (no jerk limit), the line able to brake to the curve's speed before the curve. The
 * curve's speed, its deceleration (the line's share of half of 7/8 of the grip, with the
 * heading's part of the wheel's: a (1 + k h / r)), its shape, and where it starts.
 *
 * In steps, a few a planner period (CORNER_STEPS_PER_MS): each curve's fit tries one radius a
 * step, the pivot's comparison and the look ahead's are steps of their own, so that no period
 * pays for a whole plan (bench/stm32.py --corners). Until the plan is done, the corner is not
 * taken: the line keeps its aim. */
enum plan_step {
	PLAN_DONE,
	PLAN_FIT,       /* the curve's fit */
	PLAN_PIVOT,     /* a pivot instead, where it loses less time */
	PLAN_AHEAD,     /* the corner after it, looked ahead at */
	PLAN_AHEAD_FIT, /* its curve's fit */
	PLAN_AHEAD_END, /* its pivot's comparison, the speed the line must slow down to for it */
	PLAN_CAP,       /* the curve no faster than the line after it can slow down from */
	PLAN_CAP_FIT,   /* ... a slower fit on the same radius at most */
	PLAN_END,       /* its deceleration, and whether the line can still brake to it */
};
#define CORNER_STEPS_PER_MS 2

/* A pivot pv rather than the curve sh (v_um_s 0: none fits) at a corner k whose next order is a
 * GOTO a curve may join, when it loses less time (corner_pivots(), on the line k was first
 * planned with, as the corner before looked ahead at it): into k, 1. */
static int pivot_plan(struct motion_corner *k, const struct orders *o,
		      const struct motion_pivot_shape *pv)
{
	if (!corner_pivots(o, &k->sh, k->theta, k->len1_um, k->len2_um, pv))
		return 0;
	k->pivot = 1;
	k->pivot_um = (int32_t)(pv->e_um < k->len1_um / 2 ? pv->e_um : k->len1_um / 2);
	k->pivot_turn32 = pv->phi_turn32;
	return 1;
}

/* The line to the corner's point now [um]: on a curve, the line after it; else from the
 * estimate to the point, along the bearing. */
static int32_t line_left_um(const struct planner *pl)
{
	const struct orders *o = &pl->orders;
	int64_t px = (int64_t)o->target_x_um - pl->m.pose.x_um;
	int64_t py = (int64_t)o->target_y_um - pl->m.pose.y_um;

	return o->curve ? o->cv.rest_um : (int32_t)fx_isqrt64((uint64_t)(px * px + py * py));
}

/* The plan's first step: the corner's geometry, the curve's fit started. */
static void plan_start(struct planner *pl, const struct board_config *cfg,
		       const struct motion_entry *next, struct motion_corner *k)
{
	const struct orders *o = &pl->orders;
	int64_t dx = (int64_t)next->msg.arg[ARG_GOTO_X_MM] * UM_PER_MM - o->target_x_um;
	int64_t dy = (int64_t)next->msg.arg[ARG_GOTO_Y_MM] * UM_PER_MM - o->target_y_um;
	int32_t len1 = line_left_um(pl);
	uint32_t line = o->curve ? pl->motion.line_turn32 : o->bearing_turn32;

	k->ok = 0;
	k->pivot = 0;
	k->step = PLAN_DONE;
	if (k->seq != pl->motion.running_seq || k->next_seq != next->seq) {
		/* The curve looked ahead at, as the last corner planned it */
		if (o->curve && k->next_seq == pl->motion.running_seq &&
		    k->ahead_seq == next->seq && k->ahead_len1_um < len1)
			len1 = k->ahead_len1_um;
		k->len1_um = len1;
	}
	k->seq = pl->motion.running_seq;
	k->next_seq = next->seq;
	if (!curve_joins(&next->msg) || o->cfg.jerk_um_s3 != 0 || o->frozen ||
	    (!o->curve && !o->bearing_valid))
		return;
	k->heading_turn32 = fx_atan2((int32_t)dy, (int32_t)dx);
	k->theta = fx_angle_dist(k->heading_turn32, line);
	k->len2_um = fx_isqrt64((uint64_t)(dx * dx + dy * dy));
	k->free_um = (int64_t)(cfg->orders.drive_track_um / 2u) * 65536 / pl->free_ratio_q16;
	k->step = fit_start(&k->fit, &k->sh, o, pl->motion.corner_um, k->theta, k->len1_um,
			    k->len2_um, k->free_um, INT32_MAX, CORNER_R_MAX_UM) == FIT_MORE
			  ? PLAN_FIT
			  : PLAN_PIVOT;
}

/* Looking one corner ahead (docs/control.md "Corners", 4): the curve at the next order's point,
 * planned as it will be when this corner's curve starts (the line after this curve, towards
 * that point along k->heading_turn32), when the next order passes through to a GOTO waiting
 * behind it. Its speed is taken at most what stops the line halfway along the line after it,
 * where no curve there can start earlier (a fit keeps a curve within half of either line): that
 * curve's own look ahead then never asks it slower. Into k->ahead_*: the speed [um/s] the line
 * must be able to slow down to, and how far before the point; 0 and 0, a stop at the point,
 * when there is no such curve. The fit's start: the next step. */
static enum plan_step plan_ahead(struct motion_corner *k, const struct planner *pl)
{
	const struct motion *mo = &pl->motion;
	const struct motion_entry *next = &mo->queue[mo->head];
	const struct motion_entry *after = &mo->queue[(mo->head + 1u) % PROTO_MOTION_QUEUE_DEPTH];
	int64_t rest_um = k->len2_um - k->sh.reach_um, dx, dy;

	k->ahead_len1_um = (int32_t)rest_um;
	k->ahead_seq = after->seq;
	k->ahead_v_um_s = 0;
	k->ahead_reach_um = 0;
	if (mo->count < 2 || !(options_of(&next->msg) & PROTO_OPT_PASS_THROUGH) ||
	    !curve_joins(&after->msg))
		return PLAN_CAP;
	dx = (int64_t)(after->msg.arg[ARG_GOTO_X_MM] - next->msg.arg[ARG_GOTO_X_MM]) * UM_PER_MM;
	dy = (int64_t)(after->msg.arg[ARG_GOTO_Y_MM] - next->msg.arg[ARG_GOTO_Y_MM]) * UM_PER_MM;
	k->len3_um = fx_isqrt64((uint64_t)(dx * dx + dy * dy));
	k->ahead_theta = fx_angle_dist(fx_atan2((int32_t)dy, (int32_t)dx), k->heading_turn32);
	return fit_start(&k->fit, &k->ahead_sh, &pl->orders, mo->corner_um, k->ahead_theta, rest_um,
			 k->len3_um, k->free_um, INT32_MAX, CORNER_R_MAX_UM) == FIT_MORE
		       ? PLAN_AHEAD_FIT
		       : PLAN_AHEAD_END;
}

/* The corner looked ahead at, its curve fitted: a pivot there (a stop at the point), or the
 * speed the line after this curve must be able to slow down to for it. */
static void plan_ahead_end(struct motion_corner *k, const struct planner *pl)
{
	const struct orders *o = &pl->orders;
	const struct motion_shape *sh = &k->ahead_sh;
	int64_t a = o->grip_a_um_s2[0], room = k->len3_um / 2 - sh->reach_um, v = sh->v_um_s;

	if (corner_pivots(o, sh, k->ahead_theta, k->ahead_len1_um, k->len3_um,
			  &pl->motion.pivot_shape))
		return;
	if (v * v > 2 * a * room)
		v = room > 0 ? (int64_t)fx_isqrt64((uint64_t)(2 * a * room)) : 0;
	k->ahead_v_um_s = (int32_t)v;
	k->ahead_reach_um = (int32_t)sh->reach_um;
}

/* No faster than the line after the curve can slow down for what follows it: slower, on the
 * same radius at most (the curve starts no earlier, its clothoids shorter), the fit's start. */
static enum plan_step plan_cap(struct motion_corner *k, const struct planner *pl)
{
	const struct orders *o = &pl->orders;
	int64_t a = o->grip_a_um_s2[0];
	int64_t cap = (int64_t)k->ahead_v_um_s * k->ahead_v_um_s +
		      2 * a * (k->len2_um - k->sh.reach_um - k->ahead_reach_um - UM_PER_MM);

	cap = cap > 0 ? (int64_t)fx_isqrt64((uint64_t)cap) : 0;
	if (cap >= k->sh.v_um_s)
		return PLAN_END;
	return fit_start(&k->fit, &k->sh, o, pl->motion.corner_um, k->theta, k->len1_um, k->len2_um,
			 k->free_um, cap, k->sh.r_um) == FIT_MORE
		       ? PLAN_CAP_FIT
		       : PLAN_END;
}

/* The curve planned: its deceleration and where it starts, unless the line, as it is now, can
 * no longer brake to its speed before it. */
static void plan_end(struct motion_corner *k, const struct planner *pl,
		     const struct board_config *cfg)
{
	const struct orders *o = &pl->orders;
	const struct motion_shape *sh = &k->sh;
	int64_t lim[6], g7, a, v = sh->v_um_s, u = o->sp_dist.vel_um_s;

	corner_limits(o, lim);
	g7 = cfg->orders.grip_um_s2 - (cfg->orders.grip_um_s2 >> 3);
	a = g7 / 4 * sh->r_um / (sh->r_um + lim[5]);
	k->c.a_um_s2 = (int32_t)(a < o->grip_a_um_s2[0] ? a : o->grip_a_um_s2[0]);
	if (k->c.a_um_s2 < PROFILE_A_MIN_UM_S2)
		k->c.a_um_s2 = PROFILE_A_MIN_UM_S2;
	a = o->grip_a_um_s2[0]; /* the line's, out of the curve */
	if (u * u - v * v > 2 * a * (line_left_um(pl) - sh->reach_um)) /* too late for it */
		return;
	k->c.v_um_s = (int32_t)v;
	k->c.clothoid_um = (int32_t)sh->clothoid_um;
	k->c.arc_um = (int32_t)sh->arc_um;
	k->reach_um = (int32_t)sh->reach_um;
	k->c.rest_um = (int32_t)(k->len2_um - sh->reach_um);
	k->brake_um = (int32_t)(v * v / (2 * a));
	k->ok = 1;
}

/* The step after a fit's try: the same while it goes on, ok when it fitted, none when not. */
static enum plan_step after_try(enum fit_result r, enum plan_step now, enum plan_step ok,
				enum plan_step none)
{
	return r == FIT_MORE ? now : r == FIT_OK ? ok : none;
}

/* One step of the plan in progress. */
static void plan_step(struct planner *pl, const struct board_config *cfg, struct motion_corner *k)
{
	const struct orders *o = &pl->orders;
	int64_t u = o->sp_dist.vel_um_s, a = o->grip_a_um_s2[0];
	enum fit_result r;

	switch (k->step) {
	case PLAN_FIT:
		r = fit_try(&k->fit, &k->sh);
		/* no curve: a pivot, or the corner of before the curves */
		if (r == FIT_NONE)
			k->sh.v_um_s = 0;
		k->step = after_try(r, PLAN_FIT, PLAN_PIVOT, PLAN_PIVOT);
		break;
	case PLAN_PIVOT: /* a pivot, where the line can still stop at the point */
		if (u * u <= 2 * a * line_left_um(pl) && pivot_plan(k, o, &pl->motion.pivot_shape))
			k->step = PLAN_DONE;
		else
			k->step = k->sh.v_um_s == 0 ? PLAN_DONE : PLAN_AHEAD;
		break;
	case PLAN_AHEAD:
		k->step = plan_ahead(k, pl);
		break;
	case PLAN_AHEAD_FIT:
		r = fit_try(&k->fit, &k->ahead_sh);
		k->step = after_try(r, PLAN_AHEAD_FIT, PLAN_AHEAD_END, PLAN_CAP);
		break;
	case PLAN_AHEAD_END:
		plan_ahead_end(k, pl);
		k->step = PLAN_CAP;
		break;
	case PLAN_CAP:
		k->step = plan_cap(k, pl);
		break;
	case PLAN_CAP_FIT:
		r = fit_try(&k->fit, &k->sh);
		k->step = after_try(r, PLAN_CAP_FIT, PLAN_END, PLAN_DONE);
		break;
	default:
		plan_end(k, pl, cfg);
		k->step = PLAN_DONE;
		break;
	}
}

enum corner_plan { CORNER_KEPT, CORNER_PLANNED, CORNER_PLANNING };

/* The corner planned for the running order and the next, kept while neither they, the limits
 * nor the tolerance change: CORNER_PLANNED when its plan ended just now, CORNER_PLANNING while
 * it goes on. */
static enum corner_plan corner_current(struct planner *pl, const struct board_config *cfg)
{
	struct motion *mo = &pl->motion;
	const struct orders *o = &pl->orders;
	const struct motion_entry *next = &mo->queue[mo->head];
	int32_t key[4] = {o->traj.v_max_um_s, o->grip_a_um_s2[0], o->rot.v_max_um_s,
			  mo->corner_um + ((int32_t)o->scale_percent << 24)};
	struct motion_corner *k = &mo->corner;
	uint32_t steps = CORNER_STEPS_PER_MS * ((mo->ms_per_tick_q8 + 255u) >> 8);

	if (k->seq != mo->running_seq || k->next_seq != next->seq || k->key[0] != key[0] ||
	    k->key[1] != key[1] || k->key[2] != key[2] || k->key[3] != key[3]) {
		for (uint8_t i = 0; i < 4; i++)
			k->key[i] = key[i];
		plan_start(pl, cfg, next, k);
		steps--;
	} else if (k->step == PLAN_DONE) {
		return CORNER_KEPT;
	}
	for (; steps > 0 && k->step != PLAN_DONE; steps--)
		plan_step(pl, cfg, k);
	return k->step == PLAN_DONE ? CORNER_PLANNED : CORNER_PLANNING;
}
#endif

void motion_before(struct planner *pl, const struct board_config *cfg)
{
#if CONFIG_MOTION_CORNERS
	struct motion *mo = &pl->motion;
	struct orders *o = &pl->orders;
	const struct motion_corner *k = &mo->corner;
	enum corner_plan plan;
	int32_t e, stop_um;

	if (!mo->through || pivot_refresh(mo, o))
		return;
	if (!mo->running || mo->count == 0 || mo->paused || o->designation != PROTO_GOTO ||
	    (o->state != ORDER_STATE_TRANSLATE && !o->curve)) {
		o->through_um = 0;
		return;
	}
	plan = corner_current(pl, cfg);
	if (plan == CORNER_PLANNING) /* not taken before its plan is done: the line keeps its aim */
		return;
	if (plan == CORNER_PLANNED || o->curve) {
		/* The line aims past the point by what braking to the curve's speed takes, less
		 * the curve's start, from this very update on (on a curve, from its target). */
		o->through_um = k->ok ? k->brake_um - k->reach_um
				      : (k->pivot ? 0 : corner_reach_um(pl, cfg));
		o->aim_wait = 1;
		return;
	}
	e = k->ok ? k->brake_um : (k->pivot ? k->pivot_um : corner_reach_um(pl, cfg));
	if (!k->ok)
		o->through_um = k->pivot ? 0 : e;
	stop_um = profile_get_target_um(&o->dist);
	if (stop_um - o->sp_dist.pos_um > e)
		return;
	/* At the corner: this order is done, the next one starts on the curve (or turns while
	 * the line brakes). */
	mo->running = 0;
	mo->last_seq = mo->running_seq;
	mo->last_end = END_REASON_DONE;
	pl->status &= (uint8_t)~STATUS_END_BITS;
	run_next(pl);
	if (k->ok && mo->running) {
		orders_curve_start(o, &pl->m, &k->c, k->heading_turn32);
		mo->line_turn32 = k->heading_turn32;
		mo->curve_ms_per_mm_s_q8 = ms_per_mm_s_q8_of(k->c.a_um_s2);
		mo->braking_vel[0] = INT32_MIN; /* MOTION's figures again, at the curve's */
	} else if (k->pivot && mo->running) {
		orders_pivot_start(o, stop_um, k->pivot_turn32);
		for (uint8_t i = 0; i < 2; i++) /* MOTION's figures at the pivot's accelerations */
			mo->pivot_ms_per_mm_s_q8[i] = ms_per_mm_s_q8_of(o->grip_a_um_s2[i]);
		mo->braking_vel[0] = INT32_MIN;
	}
#else
	(void)pl;
	(void)cfg;
#endif
}
