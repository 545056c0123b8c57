/* The servo: board_tick(), every tick (board.h). It owns struct servo, sums the period it
 * hands the planner in the mailbox's up half, and takes the planner's results from its down
 * half. */
#include <stddef.h>

#include "board_parts.h"
#include "fixmath.h"

int servo_init(struct servo *s, const struct board_config *cfg, const struct board_inputs *in,
	       const struct orders *orders)
{
	if (odometry_counter_init(&s->counter, &cfg->odometry, in->free_count[0], in->free_count[1],
				  cfg->start.heading_turn32) ||
	    control_init(&s->control, &cfg->control, cfg->tick_hz))
		return -1;
	s->angle_hi = 0;
	s->angle_lo = 0;
	s->angle_um = 0;
	s->arc_um = 0;
	s->pi_track_um = orders->pi_track_um;
	s->sp_dist = orders->sp_dist;
	s->sp_angle = orders->sp_angle;
	s->tick = 0;
	s->slow_overruns = 0;
	s->slow_mask = (uint8_t)((1u << cfg->slow_shift) - 1u);
	s->line_mask = (uint8_t)((1u << cfg->recal.n_sensors) - 1u);
	s->motors_off = 0;
	s->phase = 1;
	s->since_snapshot = 0;
	s->awaiting = 0;
	s->last_out.duty_q15[0] = 0;
	s->last_out.duty_q15[1] = 0;
	return 0;
}

void snapshot_clear(struct board_snapshot *p)
{
	p->ds_um = 0;
	p->arc_um = 0;
	p->dtheta_turn32 = 0;
	p->in.shocks = 0;
	p->in.basket = 0;
	p->encoder_fault = 0;
	p->wheels_replaced = 0;
	p->edges.rose = 0;
	p->edges.fell = 0;
}

/* The angle axis [um of drive-wheel arc]: the exact sum of the heading steps times pi * drive
 * track, kept in [um * 2^32] (the product of a step and pi * track is exact; summing it is the
 * unwrapped heading times pi * track, bit for bit). Also the step's own arc, rounded, for the
 * measured turn rate. */
static void angle_axis_step(struct servo *s, int32_t dtheta_turn32)
{
	uint32_t m = dtheta_turn32 >= 0 ? (uint32_t)dtheta_turn32
					: (uint32_t)0 - (uint32_t)dtheta_turn32;
	uint32_t lo, hi = fx_mul_u32_wide(m, (uint32_t)s->pi_track_um, &lo);
	uint32_t old_lo = s->angle_lo;
	int32_t w;

	/* The step's arc rounded half away from zero. */
	s->arc_um = (int32_t)(hi + (lo >> 31));
	if (dtheta_turn32 < 0) {
		s->arc_um = -s->arc_um;
		s->angle_lo = old_lo - lo;
		s->angle_hi -= hi + (old_lo < lo);
	} else {
		s->angle_lo = old_lo + lo;
		s->angle_hi += hi + (s->angle_lo < old_lo);
	}
	/* Rounded half away from zero, like the rest of the core. */
	w = fx_int32_of(s->angle_hi);
	if (w >= 0 ? s->angle_lo >= 0x80000000u : s->angle_lo > 0x80000000u)
		w = w == INT32_MAX ? w : w + 1;
	s->angle_um = w;
}

/* One axis's set point a tick further towards the handed-over one (reached at the period's
 * last tick). Its acceleration is the handed-over one from the hand-over on (take_handover()). */
static void sp_advance(struct orders_axis *sp, const struct orders_axis *step,
		       const struct orders_axis *end, int last)
{
	if (last) { /* the acceleration stays the handed-over one */
		sp->pos_um = end->pos_um;
		sp->vel_um_s = end->vel_um_s;
		return;
	}
	sp->pos_um += step->pos_um;
	sp->vel_um_s += step->vel_um_s;
}

/* New wheel factors (SET_ODOMETRIE), at the end of the period p, after its travel: its counts
 * are worth the old factors, which it keeps. */
static void take_wheels(struct servo *s, struct board_wheels *w, struct board_snapshot *p)
{
	p->wheels_replaced = 1;
	p->wheel_k[0][0] = s->counter.left.k[0];
	p->wheel_k[0][1] = s->counter.left.k[1];
	p->wheel_k[1][0] = s->counter.right.k[0];
	p->wheel_k[1][1] = s->counter.right.k[1];
	odometry_install_config(&s->counter, &w->cfg, w->wheels);
	w->pending = 0;
}

/* The planner's results, taken by the servo: set points, gains, the reply's flip. The draft
 * becomes the servo's, its one-shot requests cleared, so that it comes back to the planner
 * clean as its next draft. */
static void take_handover(struct servo *s, struct mailbox *mb, struct proto *proto,
			  uint8_t slow_shift)
{
	struct board_handover *h;

	mb->down_index ^= 1u;
	h = &mb->down[mb->down_index];
	if (h->set_gains) {
		control_set_gains(&s->control, &h->gains);
		h->set_gains = 0;
	}
	if (h->reset) {
		control_reset(&s->control);
		h->reset = 0;
	}
	s->motors_off = h->motors_off;
#if CONFIG_QUIET_SERVO
	control_raw_d(&s->control, h->raw_d);
#endif
	if (h->publish) {
		proto_flip(proto);
		h->publish = 0;
	}
	/* The set points go from where they are to the new ones over the next period; the
	 * acceleration is the new one at once (the control's feed-forward then computes its term
	 * once a period). */
	s->phase = 0;
	s->sp_dist.acc_um_s2 = h->dist.acc_um_s2;
	s->sp_angle.acc_um_s2 = h->angle.acc_um_s2;
	if (h->jump) {
		s->sp_dist = h->dist;
		s->sp_angle = h->angle;
		s->phase = (uint8_t)(1u << slow_shift);
		h->jump = 0;
	}
}

/* The period's end: what the planner works on, and a new period. The control's side is the
 * last tick's (the snapshot is taken before this one's control). */
static void take_snapshot(const struct servo *s, struct mailbox *mb, const struct proto *proto,
			  const struct board_inputs *in, int32_t dist_um)
{
	struct board_snapshot *p = &mb->up[mb->up_index];

	p->tick = s->tick;
	p->dist_err_um = s->control.dist_err_um;
	p->angle_err_um = s->control.angle_err_um;
	p->duty_q15[0] = s->control.duty_q15[0];
	p->duty_q15[1] = s->control.duty_q15[1];
	/* The tick's inputs but the switches, which are the period's. */
	p->in.free_count[0] = in->free_count[0];
	p->in.free_count[1] = in->free_count[1];
	p->in.motor_count[0] = in->motor_count[0];
	p->in.motor_count[1] = in->motor_count[1];
	p->in.current_ma[0] = in->current_ma[0];
	p->in.current_ma[1] = in->current_ma[1];
	p->in.lines = in->lines;
	p->dist_um = dist_um;
	p->angle_um = s->angle_um;
	p->sp_dist_um = s->sp_dist.pos_um;
	p->sp_angle_um = s->sp_angle.pos_um;
	p->msg_head = proto->head;
	/* The next period was cleared by the planner, done with it (board_slow()). */
	mb->up_index ^= 1u;
	mb->up[mb->up_index].edges.on = p->edges.on;
}

void board_tick(struct board *b, const struct board_inputs *in, struct board_outputs *out)
{
	struct servo *s = &b->servo;
	struct mailbox *mb = &b->mailbox;
	struct board_snapshot *p = &mb->up[mb->up_index];
	const struct odometry_step *step;
	uint8_t period_ends = (s->tick & s->slow_mask) == 0;
	int32_t dist_um;

	/* 1. Encoders -> odometry (a wheel that jumps more than a tick can travel is a fault). */
	if (odometry_count(&s->counter, in->free_count[0], in->free_count[1]) != 0)
		p->encoder_fault = 1;
	step = &s->counter.step;
	dist_um = odometry_get_distance_um(&s->counter); /* the tick's distance axis */
	/* The angle axis only moves with the heading. */
	if (step->dtheta_turn32 != 0)
		angle_axis_step(s, step->dtheta_turn32);
	else
		s->arc_um = 0;

	/* 2. The period's sums for the planner; the switches, kept if pressed at any tick; the
	 * line sensors' edges, timed at their tick. */
	p->ds_um = (int32_t)((uint32_t)p->ds_um + (uint32_t)step->ds_um);
	p->arc_um = (int32_t)((uint32_t)p->arc_um + (uint32_t)s->arc_um);
	p->dtheta_turn32 = (int32_t)((uint32_t)p->dtheta_turn32 + (uint32_t)step->dtheta_turn32);
	p->in.shocks |= in->shocks;
	p->in.basket |= in->basket;
	recal_sense(&s->lines, &p->edges, in->lines & s->line_mask, dist_um);

	/* 3. At the period's end: new wheel factors (after its travel), then the snapshot the
	 * planner works on next, unless the last one's results are not taken yet (the period goes
	 * on). With planner_ticks 0 it runs here, in this tick. */
	if (s->since_snapshot < UINT8_MAX)
		s->since_snapshot++;
	if (period_ends && !mb->slow_due && mb->wheels.pending)
		take_wheels(s, &mb->wheels, p);
	if (period_ends && !mb->slow_due && !s->awaiting) {
		take_snapshot(s, mb, &b->proto, in, dist_um);
		s->since_snapshot = 0;
		s->awaiting = 1;
		mb->slow_due = 1;
		if (b->cfg.planner_ticks == 0)
			board_slow(b);
	}

	/* 4. The planner's results, planner_ticks after the snapshot it worked on (later if it
	 * still runs: an overrun). */
	if (s->awaiting && s->since_snapshot >= b->cfg.planner_ticks) {
		if (!mb->slow_due) {
			take_handover(s, mb, &b->proto, b->cfg.slow_shift);
			s->awaiting = 0;
		} else if (s->since_snapshot == b->cfg.planner_ticks) {
			s->slow_overruns++;
		}
	}

	/* 5. The set points of this tick, a step towards the handed-over ones. */
	if (s->phase <= s->slow_mask) { /* phase < 2^shift */
		const struct board_handover *h = &mb->down[mb->down_index];
		uint8_t last = s->phase == s->slow_mask;

		s->phase++;
		sp_advance(&s->sp_dist, &h->dist_step, &h->dist, last);
		sp_advance(&s->sp_angle, &h->angle_step, &h->angle, last);
	}

	/* 6. Control: feed-forward + PID on both axes, mixed into the motor duties; none after a
	 * motor problem (planner.c, step 7). */
	if (s->motors_off)
		control_off(&s->control);
	else
		control_update(&s->control, &s->sp_dist, &s->sp_angle, dist_um, s->angle_um);

	/* 7. Outputs. */
	out->duty_q15[0] = s->control.duty_q15[0];
	out->duty_q15[1] = s->control.duty_q15[1];
	s->last_out = *out;
	s->tick++;
}
