/* The planner: board_slow(), once a period (board.h). It owns struct planner, works on the
 * servo's snapshot in the mailbox's up half, and drafts the servo's next set points in its down
 * half. */
#include <stddef.h>

#include "arch_sync.h"
#include "board_parts.h"
#include "fixmath.h"
#include "protocol_defs.h"

int planner_init(struct planner *pl, const struct board_config *cfg, const struct board_inputs *in,
		 int32_t dist_um)
{
	const uint16_t slow_hz = (uint16_t)(cfg->tick_hz >> cfg->slow_shift);
	/* the odometry's model: uncalibrated until a calibration */
	const struct uncertainty_model um = {
		cfg->odometry.track_um, cfg->uncalibrated.ratio_error_ppm,
		cfg->uncalibrated.track_error_um, cfg->uncalibrated.scale_error_ppm};
	/* half the larger free wheel's count [um, rounded up], a planner step's worth */
	uint32_t q = cfg->odometry.left_um_per_count_q16;

	if (cfg->odometry.right_um_per_count_q16 > q)
		q = cfg->odometry.right_um_per_count_q16;
	/* The modules run at the planner's rate: their durations, in ms, in their updates. */
	if (uncertainty_init(&pl->uncertainty, &cfg->uncertainty, slow_hz, &um) ||
	    faults_init(&pl->faults, &cfg->faults, slow_hz, in->motor_count) ||
	    orders_init(&pl->orders, &cfg->orders, slow_hz, (int32_t)(((q >> 17) + 1u) * slow_hz),
			dist_um, 0) ||
	    recal_init(&pl->recal, &cfg->recal))
		return -1;
	odometry_position_init(&pl->position, cfg->start.x_um, cfg->start.y_um);
	uncertainty_reset(&pl->uncertainty, cfg->start_radius_um, cfg->start_heading_bound_turn32);
	pl->m.pose = cfg->start;
	pl->soft = 0;
	pl->gains = cfg->control.presets[FILTRE_STD];
	pl->slow_hz = slow_hz;
	pl->free_ratio_q16 = board_free_ratio_q16(cfg, cfg->odometry.track_um);
	pl->shocks = 0;
	pl->free_base[0] = in->free_count[0];
	pl->free_base[1] = in->free_count[1];
	pl->status = 0;
	pl->timeout_ticks = 0;
	pl->silent_ticks = 0;
	pl->fed = 0;
	pl->timed_out = 0;
	pl->calibrated = 0;
	pl->calibration = (struct board_calibration){0, 0, 0};
	pl->motor_base[0] = in->motor_count[0];
	pl->motor_base[1] = in->motor_count[1];
	for (uint8_t i = 0; i < 2; i++) {
		pl->silent_counts[i] = 0;
		pl->silent_widened[i] = 0;
	}
	/* lost_min_um in motor counts, rounded down */
	pl->silent_min_counts = cfg->faults.motor_um_per_count_q16 == 0
					? UINT32_MAX
					: (uint32_t)(((uint64_t)(cfg->faults.lost_min_um > 0
									 ? cfg->faults.lost_min_um
									 : 0)
						      << 16) /
						     cfg->faults.motor_um_per_count_q16);
	pl->silent_turn_q16 = board_turn_q16(cfg, cfg->odometry.track_um);
	motion_init(&pl->motion, cfg, &pl->orders, slow_hz);
	fix_init(&pl->fix, slow_hz);
	pl->reset = (struct board_reset){0, RESET_CAUSE_POWER_ON, 0, 0, 0};
	return 0;
}

/* a - b saturated, in 32 bits (a following error far out of range is still far out). */
static int32_t sub_sat(int32_t a, int32_t b)
{
	if (b < 0 && a > INT32_MAX + b)
		return INT32_MAX;
	if (b > 0 && a < INT32_MIN + b)
		return INT32_MIN;
	return a - b;
}

void planner_measure(const struct planner *pl, const struct board_config *cfg,
		     const struct board_snapshot *p, struct orders_measure *m)
{
	m->dist_um = p->dist_um;
	m->angle_um = p->angle_um;
	/* A period's steps are below 32.8 mm up to 3 m/s: 16 x 16-bit products. */
	m->dist_speed_um_s = fx_mul_s16(fx_sat16(p->ds_um), (int16_t)pl->slow_hz);
	m->angle_speed_um_s = fx_mul_s16(fx_sat16(p->arc_um), (int16_t)pl->slow_hz);
	m->basket_contact = p->in.basket;
	m->basket_shock = (p->in.shocks & cfg->faults.shock_basket_mask) != 0;
	m->shocks = p->in.shocks;
}

void planner_update_status(struct planner *pl)
{
	uint8_t s = pl->status & (uint8_t)(STATUS_END_BITS | STATUS_PB_GRAVE);

	if (orders_busy(&pl->orders)) {
		s |= STATUS_BUSY_TRAJET;
		if (pl->orders.designation == PROTO_GOTO_PANIER)
			s |= STATUS_BUSY_GOTO_PANIER;
	} else if (pl->timed_out) {
		s |= STATUS_PB_MOTEUR; /* abandoned for the master's silence, not finished */
	}
	pl->status = s;
}

/* The estimate's position moves; the servo counts heading changes only (its angle axis), so
 * the robot stays put and a running GOTO re-aims from the new estimate. */
void planner_set_pose(struct planner *pl, const struct odometry_pose *pose)
{
	odometry_set_position(&pl->position, pose->x_um, pose->y_um);
	pl->m.pose = *pose;
	fix_forget(&pl->fix, pose, &pl->uncertainty); /* older fixes would undo it */
}

void planner_set_gains(struct planner *pl, struct board_handover *draft,
		       const struct control_gains *g)
{
	pl->gains = *g;
	draft->gains = *g;
	draft->set_gains = 1;
}

/* The larger magnitude. */
static int32_t max_mag(int32_t a, int32_t b)
{
	return (int32_t)(fx_mag32(a) > fx_mag32(b) ? fx_mag32(a) : fx_mag32(b));
}

/* A collision or a blocked robot (a shock, a motor problem): the robot may be shoved sideways,
 * which the free wheels do not measure, by up to what sliding from its speed takes,
 * v^2 / (2 slide_decel), v the speed of its farthest point (measured or commanded, the larger:
 * a blocked robot's set point still runs). The error radius widens by that. */
static void contact_slide(struct planner *pl, const struct board_config *c)
{
	const struct orders_measure *m = &pl->m;
	uint64_t v = (uint64_t)max_mag(m->dist_speed_um_s, pl->orders.sp_dist.vel_um_s);
	uint64_t w = (uint64_t)max_mag(m->angle_speed_um_s, pl->orders.sp_angle.vel_um_s);
	uint64_t slide;

	if (c->unseen.slide_decel_mm_s2 == 0)
		return;
	/* the angle axis moves at the drive wheels' speed: a point reach_um from the axis moves
	 * reach / (drive track / 2) times as fast */
	v += (w * c->unseen.reach_um * 2 + c->orders.drive_track_um - 1) / c->orders.drive_track_um;
	if (v > 10000000u)
		v = 10000000u; /* 10 m/s */
	/* [um]: v^2 [um^2/s^2] / (2 a [mm/s^2] 1000) */
	slide = (v * v + 2000u * c->unseen.slide_decel_mm_s2 - 1) /
		(2000u * c->unseen.slide_decel_mm_s2);
	uncertainty_widen(&pl->uncertainty, (uint32_t)(slide > 0xffffffffu ? 0xffffffffu : slide),
			  0);
}

/* Stop the running order at once; the status says why. */
static void react(struct planner *pl, struct board_handover *draft, const struct board_config *cfg,
		  uint8_t event)
{
	static const uint8_t bits[] = {
		[FAULTS_SHOCK_BORD] = STATUS_CHOC_BORD,
		[FAULTS_SHOCK_PANIER] = STATUS_CHOC_PANIER,
		[FAULTS_MOTOR] = STATUS_PB_MOTEUR,
		[FAULTS_GRAVE] = STATUS_PB_GRAVE,
	};
	static const uint8_t reasons[] = {
		[FAULTS_SHOCK_BORD] = END_REASON_SHOCK,
		[FAULTS_SHOCK_PANIER] = END_REASON_SHOCK,
		[FAULTS_MOTOR] = END_REASON_MOTOR,
		[FAULTS_GRAVE] = END_REASON_FAULT,
	};

	if (event == FAULTS_NONE || ((pl->status & STATUS_PB_GRAVE) && event == FAULTS_GRAVE))
		return;
	if (event == FAULTS_YIELD) {
		/* Idle and overloaded: hold where the robot now is, keeping the last end. */
		orders_abort(&pl->orders, &pl->m, pl->orders.end_reason);
		draft->reset = 1;
		draft->jump = 1;
		return;
	}
	contact_slide(pl, cfg);
	if (event == FAULTS_SHOCK_BORD || event == FAULTS_SHOCK_PANIER)
		orders_shock(&pl->orders, &pl->m, reasons[event]); /* a hold that gives way */
	else
		orders_abort(&pl->orders, &pl->m, reasons[event]);
	draft->reset = 1;
	draft->jump = 1;
	pl->status |= bits[event];
	pl->timed_out = 0; /* a stop for the timeout ends on the fault instead */
}

/* Line recalibration, while a GOTO with option bit 0 drives straight (recal.h). */
static void recal_lines(struct planner *pl, struct recal_edges *e)
{
	const struct orders *o = &pl->orders;
	int enabled = o->designation == PROTO_GOTO && (o->options & ORDERS_OPT_LINE) &&
		      !o->border && o->state == ORDER_STATE_TRANSLATE;
	struct recal_fix fix;

	recal_take(&pl->recal, e, enabled, &pl->m.pose, pl->m.dist_um, &pl->uncertainty, &fix);
	if (!fix.what)
		return;
	planner_set_pose(pl, &fix.pose);
	if (fix.what & RECAL_FIX_HEADING)
		uncertainty_reset_heading(&pl->uncertainty, fix.heading_bound_turn32);
	uncertainty_reset_along(&pl->uncertainty, fix.normal_turn32, fix.bound_um);
}

/* A basket contact: the coordinate along the approach from the basket's geometry, the lateral
 * one clamped to the switch's window (orders_basket_pose()). */
static void recal_basket(struct planner *pl, const struct orders_config *oc)
{
	struct odometry_pose p;

	if (orders_basket_pose(&pl->orders, &pl->m.pose, &p) != 0)
		return;
	planner_set_pose(pl, &p);
	uncertainty_reset_along(&pl->uncertainty, p.heading_turn32, oc->basket_bound_um);
	if (oc->basket_lateral_um > 0)
		uncertainty_cap_along(&pl->uncertainty, p.heading_turn32 + ((uint32_t)1 << 30),
				      (uint32_t)oc->basket_lateral_um);
}

/* Squared up against a border: one coordinate and the heading (orders.c, border_recal()). */
static void recal_border(struct planner *pl, const struct orders_config *oc)
{
	struct orders_recal r;

	if (!orders_take_recal(&pl->orders, &r))
		return;
	planner_set_pose(pl, &r.pose);
	uncertainty_reset_heading(&pl->uncertainty, oc->border_heading_bound_turn32);
	uncertainty_reset_axis(&pl->uncertainty, r.axis ? UNCERTAINTY_AXIS_Y : UNCERTAINTY_AXIS_X,
			       oc->border_bound_um);
}

/* A border push runs on FILTRE_SOUPLE's gains; the gains in effect before come back after. */
static void select_gains(struct planner *pl, struct board_handover *draft,
			 const struct board_config *cfg)
{
	uint8_t soft = (uint8_t)orders_soft(&pl->orders);

	if (soft == pl->soft)
		return;
	if (soft) {
		pl->saved_gains = pl->gains;
		planner_set_gains(pl, draft, &cfg->control.presets[FILTRE_SOUPLE]);
	} else {
		planner_set_gains(pl, draft, &pl->saved_gains);
	}
	draft->reset = 1;
	pl->soft = soft;
}

/* An order ended by itself this step. */
static void finish(struct planner *pl, struct board_handover *draft, const struct board_config *cfg,
		   uint8_t reason)
{
	if (reason == END_REASON_BORDER)
		pl->status |= STATUS_CHOC_BORD;
	if (reason == END_REASON_NO_BASKET) /* not a motor fault: not counted towards PB_GRAVE */
		pl->status |= STATUS_PB_MOTEUR;
	if (reason != END_REASON_BASKET)
		return;
	pl->status |= STATUS_CHOC_PANIER;
	draft->reset = 1;
	recal_basket(pl, &cfg->orders);
}

/* A free wheel that does not count while its motor turns (a wire cut, a wheel lifted, whether an
 * order runs or not) may be travelling unseen. Once its motor's net travel since the wheel last
 * counted passes unseen.silent_min_um, that travel, scaled to the encoder track for a turn,
 * widens the error radius as the wheel's unseen travel (uncertainty_widen()), and so does its
 * growth until the wheel counts again. Net: the holding loop's twitches cancel out. A drive
 * wheel slipping or spinning on its side of a blocked robot widens it too, which is only
 * conservative. */
static void silent_wheels(struct planner *pl, const struct board_config *c,
			  const int32_t travel_q16[2], const uint16_t motor_count[2])
{
	for (uint8_t s = 0; s < 2; s++) {
		int16_t counts = (int16_t)(uint16_t)(motor_count[s] - pl->motor_base[s]);
		uint32_t mag;

		pl->motor_base[s] = motor_count[s];
		if (travel_q16[s] != 0) {
			pl->silent_counts[s] = 0;
			pl->silent_widened[s] = 0;
			continue;
		}
		if (counts == 0)
			continue;
		pl->silent_counts[s] = fx_add_sat32(pl->silent_counts[s], counts);
		mag = fx_mag32(pl->silent_counts[s]);
		if (mag > pl->silent_min_counts && mag > pl->silent_widened[s]) {
			/* motor counts to um of free-wheel travel, scaled for a turn: a fault's
			 * path */
			uint64_t um = (((uint64_t)(mag - pl->silent_widened[s]) *
						c->faults.motor_um_per_count_q16 +
					0xffffu) >>
				       16) * pl->silent_turn_q16 +
				      0xffffu;

			um >>= 16;
			uncertainty_widen(&pl->uncertainty, 0,
					  um > UINT32_MAX ? UINT32_MAX : (uint32_t)um);
			pl->silent_widened[s] = mag;
		}
	}
}

/* Step 0: the pose, along the period's travel as one arc ending at the period's heading change
 * from the last pose. The travels from the counts, with the factors the period's ticks had
 * (travel_q16[]: the free wheels' over the period). */
static void step_pose(struct planner *pl, const struct board_config *cfg,
		      const struct board_snapshot *p, const struct odometry_counter *counter,
		      int32_t travel_q16[2])
{
	struct odometry_arc arc;
	uint32_t heading_turn32 = pl->m.pose.heading_turn32 + (uint32_t)p->dtheta_turn32;
	const uint16_t *kl = p->wheels_replaced ? p->wheel_k[0] : counter->left.k;
	const uint16_t *kr = p->wheels_replaced ? p->wheel_k[1] : counter->right.k;

	travel_q16[0] = odometry_travel_q16(kl, (int16_t)(p->in.free_count[0] - pl->free_base[0]));
	travel_q16[1] = odometry_travel_q16(kr, (int16_t)(p->in.free_count[1] - pl->free_base[1]));
	pl->free_base[0] = p->in.free_count[0];
	pl->free_base[1] = p->in.free_count[1];
	odometry_arc_of(&arc, travel_q16[0], travel_q16[1], p->dtheta_turn32, heading_turn32);
	odometry_advance(&pl->position, &arc);
	pl->m.pose.x_um = odometry_get_x_um(&pl->position);
	pl->m.pose.y_um = odometry_get_y_um(&pl->position);
	pl->m.pose.heading_turn32 = heading_turn32;
	planner_measure(pl, cfg, p, &pl->m);
}

/* Step 3b: the master's silence (SET_TIMEOUT): only its accepted writes (orders, settings,
 * HEARTBEAT) show it alive, as board_apply() counts them in fed; a poll does not, since a
 * master's polling thread (or a viewer) can run on while its strategy has hung. When it has
 * been silent for the timeout, the running order stops at the current limits, as by STOP, and
 * ends abandoned (PB_MOTEUR, DEBUG TIMEOUT) rather than looking finished. */
static void step_silence(struct planner *pl)
{
	if (pl->fed) {
		pl->fed = 0;
		pl->silent_ticks = 0;
	} else if (pl->silent_ticks < UINT32_MAX) {
		pl->silent_ticks++;
	}
	if (pl->timeout_ticks && pl->silent_ticks >= pl->timeout_ticks &&
	    orders_busy(&pl->orders) && pl->orders.state != ORDER_STATE_STOPPING) {
		orders_stop(&pl->orders);
		pl->timed_out = 1;
	}
}

/* Step 4: stop conditions: shocks, motor problems, unrecoverable faults. */
static void step_stops(struct planner *pl, struct board_handover *draft,
		       const struct board_config *cfg, const struct board_snapshot *p,
		       const int32_t travel_q16[2])
{
	const struct orders *o = &pl->orders;
	struct faults_inputs fi;
	uint8_t event;

	/* Pushing a basket closes the front bumper with the basket switch: the expected contact.
	 * Against the border, the front switches are the expected contact. */
	fi.shocks = (o->state == ORDER_STATE_PUSH && p->in.basket) ? 0 : p->in.shocks;
	fi.shocks &= (uint8_t)~orders_expected_shocks(o);
	fi.current_ma[0] = p->in.current_ma[0];
	fi.current_ma[1] = p->in.current_ma[1];
	fi.motor_count[0] = p->in.motor_count[0];
	fi.motor_count[1] = p->in.motor_count[1];
	fi.free_step_q16[0] = travel_q16[0];
	fi.free_step_q16[1] = travel_q16[1];
	fi.free_ratio_q16 = pl->free_ratio_q16;
	fi.dist_err_um = sub_sat(p->sp_dist_um, pl->m.dist_um);
	fi.angle_err_um = sub_sat(p->sp_angle_um, pl->m.angle_um);
	fi.moving = (uint8_t)orders_busy(o);
	fi.pushing = o->state == ORDER_STATE_PUSH || o->state == ORDER_STATE_SQUARE;
	event = faults_check(&pl->faults, &fi);
	react(pl, draft, cfg, p->encoder_fault ? FAULTS_GRAVE : event);
}

/* (end - from) / 2^shift, rounded down: a tick's share of a period's change. */
static void sp_step(struct orders_axis *step, const struct orders_axis *from,
		    const struct orders_axis *end, uint8_t shift)
{
	step->pos_um = fx_floor_shr(end->pos_um - from->pos_um, shift);
	step->vel_um_s = fx_floor_shr(end->vel_um_s - from->vel_um_s, shift);
	step->acc_um_s2 = 0;
}

/* Step 7: after a motor problem the motors stay off until the next order: holding the position
 * would drive the same stalled, slipping or overloaded motor again. Nothing holds the robot
 * then, so the set points follow it and the next order starts from where it is. Then the set
 * points, from the last ones, where the servo is at the hand-over (it gets there at the
 * period's last tick, or at once by a jump). */
static void step_handover(struct planner *pl, struct mailbox *mb, uint8_t slow_shift)
{
	const struct board_handover *now = &mb->down[mb->down_index];
	struct board_handover *next = &mb->down[mb->down_index ^ 1u];

	next->motors_off = (pl->status & (STATUS_PB_GRAVE | STATUS_PB_MOTEUR)) != 0;
	if (next->motors_off) {
		orders_abort(&pl->orders, &pl->m, pl->orders.end_reason);
		next->jump = 1;
	}
#if CONFIG_QUIET_SERVO
	next->raw_d = orders_raw_d(&pl->orders);
#endif
	next->dist = pl->orders.sp_dist;
	next->angle = pl->orders.sp_angle;
	sp_step(&next->dist_step, &now->dist, &next->dist, slow_shift);
	sp_step(&next->angle_step, &now->angle, &next->angle, slow_shift);
}

/* The planner's steps but the reply snapshot, on the last period (up[up_index ^ 1]). */
static void planner_steps(struct board *b)
{
	struct planner *pl = &b->planner;
	struct mailbox *mb = &b->mailbox;
	const struct board_config *cfg = &b->cfg;
	struct board_snapshot *p = &mb->up[mb->up_index ^ 1u];
	struct board_handover *draft = &mb->down[mb->down_index ^ 1u];
	struct proto_msg msg;
	int32_t travel_q16[2]; /* the free wheels' travels over the period */
	uint8_t reason;

	/* 0. The pose. */
	step_pose(pl, cfg, p, &b->servo.counter, travel_q16);

	/* 1. Error radius, from the period's travel, and what the free wheels may not have seen. */
	uncertainty_update(&pl->uncertainty, travel_q16[0], travel_q16[1],
			   pl->m.pose.heading_turn32);
	silent_wheels(pl, cfg, travel_q16, p->in.motor_count);
	uncertainty_advance(&pl->uncertainty, b->servo.slow_mask); /* its stages as fast in time */

	/* 2. The switches; line crossings. */
	pl->shocks = p->in.shocks;
	recal_lines(pl, &p->edges);

	/* 3. Messages from the master, in the order they arrived, until the period's end; then the
	 * master's silence. */
	while (b->proto.tail != p->msg_head && proto_poll(&b->proto, &msg))
		board_apply(pl, mb, cfg, &msg);
	step_silence(pl);

	/* 4. Stop conditions. */
	step_stops(pl, draft, cfg, p, travel_q16);

	/* 5. Orders -> profiles -> set points of both axes; the contact recalibrations; the
	 * queue's next order after one that ended (motion.c). */
	motion_before(pl, cfg);
	reason = orders_update(&pl->orders, &pl->m);
	if (pl->orders.gave_way) { /* the hold after a shock moved away from the obstacle */
		pl->orders.gave_way = 0;
		draft->reset = 1;
	}
	recal_border(pl, &cfg->orders);
	finish(pl, draft, cfg, reason);
	select_gains(pl, draft, cfg);
	motion_after(pl);
	planner_update_status(pl);

	/* 6. The history of estimates, and a position fix that waited (fix.c): after the orders, so
	 * that a fix's correction and the orders' re-aim at it fall in two periods; and not in a
	 * period that re-aimed, when re-aims are spread (a GOTO at 1 kHz: every 4th period), so
	 * that the two heaviest steps never add up (bench/stm32.py --fixes). */
	fix_record(&pl->fix, &pl->position, &pl->m.pose, &pl->uncertainty,
		   (uint8_t)(orders_aimed(&pl->orders) && pl->orders.aim_period > 1));

	/* 7. The hand-over's draft: motors off after a motor problem, the set points. */
	step_handover(pl, mb, cfg->slow_shift);
}

void board_slow(struct board *b)
{
	struct mailbox *mb = &b->mailbox;

	arch_barrier(); /* the snapshot after slow_due said it is there */
	planner_steps(b);
	if (CONFIG_KEEP_POSE && b->planner.reset.tracked) /* 8. What a reset keeps (keep.h). */
		board_keep_save(&b->planner, &b->keep);
	/* 7. The reply snapshot, made public at the hand-over with the servo's new state. */
	board_publish(&b->planner, &mb->up[mb->up_index ^ 1u], &b->proto);
	mb->down[mb->down_index ^ 1u].publish = 1;
	snapshot_clear(&mb->up[mb->up_index ^ 1u]); /* the servo's next period */
	arch_barrier();                             /* the draft complete before slow_due says so */
	mb->slow_due = 0;
}
