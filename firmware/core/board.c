/* The board: power-on, the master's messages and the replies (board.h). The servo's tick is
 * servo.c, the planner's steps planner.c, the defaults board_config.c. */
#include "board.h"

#include <errno.h>
#include <stddef.h>
#include <string.h>

#include "board_parts.h"
#include "fixmath.h"
#include "protocol_defs.h"

#define POSITION_MAX_MM 32000 /* the range of POSITION's x and y (messages.toml) */

/* The mailbox at power-on: set points where the orders start, nothing handed over, and the
 * reply snapshot of power-on, from a period of no time at all (up[1], the planner's). */
static void mailbox_init(struct board *b, const struct board_inputs *in)
{
	struct mailbox *mb = &b->mailbox;
	struct board_snapshot *p = &mb->up[1];

	mb->down[0] = (struct board_handover){0};
	mb->down[0].dist = b->planner.orders.sp_dist;
	mb->down[0].angle = b->planner.orders.sp_angle;
	mb->down[1] = mb->down[0];
	mb->wheels.pending = 0;
	mb->up_index = 0;
	mb->down_index = 0;
	mb->slow_due = 0;
	snapshot_clear(&mb->up[0]);
	p->in = *in;
	snapshot_clear(p);
	p->in.shocks = in->shocks;
	p->in.basket = in->basket;
	p->dist_um = odometry_get_distance_um(&b->servo.counter);
	p->angle_um = b->servo.angle_um;
	p->tick = 0;
	p->dist_err_um = 0;
	p->angle_err_um = 0;
	p->duty_q15[0] = 0;
	p->duty_q15[1] = 0;
}

int board_init(struct board *b, const struct board_config *cfg, const struct board_inputs *in)
{
	struct board_snapshot *p;

	if (board_config_check(cfg))
		return -1;
	/* As a chip's start-up clears its RAM: a board initialised again in place (a power
	 * cycle of the host port) starts from the same state as a fresh one. */
	memset(b, 0, offsetof(struct board, keep));
	b->cfg = *cfg;
	proto_init(&b->proto);
	if (planner_init(&b->planner, cfg, in, 0) ||
	    servo_init(&b->servo, cfg, in, &b->planner.orders))
		return -1;
	mailbox_init(b, in);
	recal_sense_init(&b->servo.lines, &b->mailbox.up[0].edges,
			 odometry_get_distance_um(&b->servo.counter));
	p = &b->mailbox.up[1];
	planner_measure(&b->planner, cfg, p, &b->planner.m);
	planner_update_status(&b->planner);
	board_publish(&b->planner, p, &b->proto);
	proto_flip(&b->proto);
	snapshot_clear(p); /* the servo's next period */
	return 0;
}

void board_keep_save(const struct planner *pl, struct board_keep *k)
{
	k->x_um = pl->m.pose.x_um;
	k->y_um = pl->m.pose.y_um;
	k->heading_turn32 = pl->m.pose.heading_turn32;
	k->radius_um = pl->uncertainty.saturated ? UINT32_MAX : pl->uncertainty.radius_um;
	uncertainty_keep(&pl->uncertainty, &k->u);
	k->speed_um_s = fx_mag32(pl->m.dist_speed_um_s);
	k->turn_um_s = fx_mag32(pl->m.angle_speed_um_s);
	k->spare0 = 0;
	k->resets = pl->reset.count;
	k->pose_lost = pl->reset.pose_lost;
	k->spare = 0;
	keep_seal(k);
}

/* A kept record after a reset: the pose and radius it held, widened by the travel it may have
 * missed (down_ms, and the planner period since it was written, at its speed). */
static void resume(struct planner *pl, const struct board_config *cfg, const struct board_keep *k,
		   uint16_t down_ms)
{
	const struct odometry_pose pose = {k->x_um, k->y_um, k->heading_turn32};
	uint64_t ms = (uint64_t)down_ms + (1000u + pl->slow_hz - 1u) / pl->slow_hz;
	/* the farthest point moves reach / (drive track / 2) times as fast as the angle axis */
	uint64_t v = k->speed_um_s + ((uint64_t)k->turn_um_s * cfg->unseen.reach_um * 2u +
				      cfg->orders.drive_track_um - 1u) /
					     cfg->orders.drive_track_um;
	uint64_t pos = (v * ms + 999u) / 1000u;
	/* each wheel's arc on the angle axis, as one encoder wheel's travel (uncertainty_widen())
	 */
	uint64_t wheel =
		((((uint64_t)k->turn_um_s * ms + 999u) / 1000u * 2u * pl->silent_turn_q16) +
		 0xffffu) >>
		16;

	planner_set_pose(pl, &pose);
	uncertainty_resume(&pl->uncertainty, k->radius_um, &k->u,
			   pos > UINT32_MAX ? UINT32_MAX : (uint32_t)pos,
			   wheel > UINT32_MAX ? UINT32_MAX : (uint32_t)wheel);
	pl->reset.widened_mm = (uint8_t)(pos >= 255000u ? 255u : (pos + 999u) / 1000u);
}

int board_restart(struct board *b, const struct board_config *cfg, const struct board_inputs *in,
		  uint8_t cause, uint16_t down_ms)
{
	const struct board_keep k = b->keep; /* before anything writes it */
	struct planner *pl = &b->planner;
	int valid = keep_valid(&k);

	if (board_init(b, cfg, in))
		return -1;
	pl->reset.tracked = 1;
	pl->reset.cause = cause;
	if (cause != RESET_CAUSE_POWER_ON) {
		pl->reset.count = valid ? (uint8_t)(k.resets < 255u ? k.resets + 1u : 255u) : 1u;
		if (CONFIG_KEEP_POSE && valid && !k.pose_lost) {
			resume(pl, cfg, &k, down_ms);
		} else { /* nothing kept: the estimate is the power-on one, the truth unknown */
			uncertainty_reset(&pl->uncertainty, UINT32_MAX, (uint32_t)1 << 31);
			pl->reset.pose_lost = 1;
		}
		/* Said at the master's next poll, idle or not, until its next order: an order may
		 * have been abandoned, and every setting (speeds, gains, SET_TIMEOUT, scales) is
		 * back at its power-on value, for the master to send again. */
		pl->status |= STATUS_PB_MOTEUR;
		pl->orders.end_reason = END_REASON_RESET;
	}
	board_keep_save(pl, &b->keep);
	board_publish(pl, &b->mailbox.up[1], &b->proto);
	proto_flip(&b->proto);
	return 0;
}

/* A new order clears what the last one ended with. */
static void start_order(struct planner *pl)
{
	pl->status &= (uint8_t)~STATUS_END_BITS;
	pl->timed_out = 0;
	faults_order_started(&pl->faults, pl->shocks);
}

/* A coordinate corrected by SET_NEW_POS [um], kept within what POSITION reports: repeated
 * corrections cannot push the estimate out of the protocol's range (nor overflow it). */
static int32_t corrected_um(int32_t estimate_um, int32_t err_mm)
{
	int64_t v = (int64_t)estimate_um - (int64_t)err_mm * UM_PER_MM;
	const int64_t max_um = (int64_t)POSITION_MAX_MM * UM_PER_MM;

	return (int32_t)(v > max_um ? max_um : v < -max_um ? -max_um : v);
}

static void set_new_pos(struct planner *pl, const struct proto_msg *msg)
{
	struct odometry_pose p = pl->m.pose;

	/* The master sends the estimate's error (estimate - truth): subtract it. */
	p.x_um = corrected_um(p.x_um, msg->arg[ARG_SET_NEW_POS_ERR_X_MM]);
	p.y_um = corrected_um(p.y_um, msg->arg[ARG_SET_NEW_POS_ERR_Y_MM]);
	p.heading_turn32 -= fx_deg_to_turn32(msg->arg[ARG_SET_NEW_POS_ERR_ANGLE_DEG]);
	/* Only the estimate moves, not the axes: the robot stays put, and a running GOTO re-aims
	 * from the corrected estimate at its next update (a frozen one keeps its targets). */
	planner_set_pose(pl, &p);
	pl->reset.pose_lost = 0; /* the master set it: motion orders again (board_restart()) */
}

/* SET_FIX: the fix in the core's units, fused at the time it was measured (fix.c). */
static void set_fix(struct planner *pl, const struct proto_msg *msg)
{
	const int32_t *a = msg->arg;
	struct fix_meas z;

	z.x_um = a[ARG_SET_FIX_X_MM] * UM_PER_MM;
	z.y_um = a[ARG_SET_FIX_Y_MM] * UM_PER_MM;
	/* 0.01 degree: 2^32 / 36000 turn32 each, in 64 bits (a product: the angle may be negative,
	 * and a left shift of a negative value is undefined) */
	z.heading_turn32 =
		(uint32_t)((int64_t)a[ARG_SET_FIX_HEADING_CDEG] * ((int64_t)1 << 32) / 36000);
	z.sigma_um = (uint32_t)a[ARG_SET_FIX_SIGMA_MM] * UM_PER_MM;
	/* 0.1 degree: 2^32 / 3600 turn32 each, rounded up (the noise is never understated) */
	z.sigma_turn32 =
		(uint32_t)((((uint64_t)a[ARG_SET_FIX_SIGMA_HEADING_DDEG] << 32) + 3599u) / 3600u);
	z.age_ms = (uint16_t)a[ARG_SET_FIX_AGE_MS];
	(void)fix_apply(&pl->fix, &pl->position, &pl->m.pose, &pl->uncertainty, &z);
}

/* A nominal wheel factor times (1 + a / den) [um/count * 2^16], rounded. */
static int64_t scaled_factor(int64_t factor_q16, int32_t a, int32_t den)
{
	return fx_div_round64(factor_q16 * (den + a), den);
}

/* SET_ODOMETRIE: the calibrated wheel factors and encoder track, from the build's nominal
 * factors (cfg), so that the same message always gives the same configuration. The pose, the
 * error radius and the axes are kept; the servo measures with the new values from the end of
 * its period, and the error radius uses the calibrated residual bounds. A result outside the
 * odometry's ranges leaves the configuration as it was (-EDOM). */
int board_calibrate(struct planner *pl, struct board_wheels *w, const struct board_config *cfg,
		    const struct board_calibration *cal)
{
	const int32_t ppm = 1000000;
	struct odometry_config oc;
	struct uncertainty_model um;
	int64_t left, right;
	int err;

	if (cal->ratio_ppm < -30000 || cal->ratio_ppm > 30000 || cal->scale_ppm < -30000 ||
	    cal->scale_ppm > 30000)
		return -EDOM;
	left = scaled_factor(cfg->odometry.left_um_per_count_q16, cal->scale_ppm, ppm);
	right = scaled_factor(cfg->odometry.right_um_per_count_q16, cal->scale_ppm, ppm);
	/* right * (1 + r/2), left * (1 - r/2): a right/left ratio of 1 + r + r^2/2 + ... */
	left = scaled_factor(left, -cal->ratio_ppm, 2 * ppm);
	right = scaled_factor(right, cal->ratio_ppm, 2 * ppm);
	if (left < 1 || right < 1 || left > ODOMETRY_UM_PER_COUNT_Q16_MAX ||
	    right > ODOMETRY_UM_PER_COUNT_Q16_MAX)
		return -EDOM;
	oc.left_um_per_count_q16 = (uint32_t)left;
	oc.right_um_per_count_q16 = (uint32_t)right;
	oc.track_um = (uint32_t)cal->track_10um * 10u;
	um.track_um = oc.track_um;
	um.ratio_error_ppm = cfg->calibrated.ratio_error_ppm;
	um.track_error_um = cfg->calibrated.track_error_um;
	um.scale_error_ppm = cfg->calibrated.scale_error_ppm;
	err = odometry_check_config(&oc);
	if (err)
		return err;
	if (uncertainty_set_model(&pl->uncertainty, &um))
		return -EDOM;
	/* The odometry is the servo's: its tables are derived here, the servo copies them. */
	(void)odometry_derive_config(&oc, w->wheels); /* checked above */
	w->cfg = oc;
	w->pending = 1;
	pl->free_ratio_q16 = board_free_ratio_q16(cfg, oc.track_um);
	pl->silent_turn_q16 = board_turn_q16(cfg, oc.track_um);
	pl->calibrated = 1;
	pl->calibration = *cal;
	return 0;
}

int board_set_calibration(struct board *b, const struct board_calibration *cal)
{
	return board_calibrate(&b->planner, &b->mailbox.wheels, &b->cfg, cal);
}

static int set_odometrie(struct planner *pl, struct board_wheels *w, const struct board_config *cfg,
			 const struct proto_msg *msg)
{
	struct board_calibration cal;

	cal.ratio_ppm = msg->arg[ARG_SET_ODOMETRIE_RATIO_PPM];
	cal.scale_ppm = msg->arg[ARG_SET_ODOMETRIE_SCALE_PPM];
	cal.track_10um = (uint16_t)msg->arg[ARG_SET_ODOMETRIE_TRACK_10UM];
	return board_calibrate(pl, w, cfg, &cal);
}

/* SET_FILTRE(_RAW): during a border push the soft gains stay, and the master's come after it
 * (planner.c, select_gains()); stiffer gains against the border would turn the contact into
 * PB_MOTEUR. */
static void master_gains(struct planner *pl, struct board_handover *draft,
			 const struct control_gains *g)
{
	if (pl->soft)
		pl->saved_gains = *g;
	else
		planner_set_gains(pl, draft, g);
}

/* The orders: each starts from the planner's measure (motion.c numbers and queues them). */
void board_start_order(struct planner *pl, const struct proto_msg *msg)
{
	const int32_t *a = msg->arg;

	start_order(pl);
	switch (msg->designation) {
	case PROTO_GOTO:
		orders_goto(&pl->orders, &pl->m, a[ARG_GOTO_X_MM] * UM_PER_MM,
			    a[ARG_GOTO_Y_MM] * UM_PER_MM,
			    (uint8_t)a[ARG_GOTO_OPTIONS] & (ORDERS_OPT_LINE | ORDERS_OPT_BORDER));
		break;
	case PROTO_GOTO_REVERSE:
		orders_goto_reverse(&pl->orders, &pl->m,
				    a[ARG_GOTO_REVERSE_DISTANCE_MM] * UM_PER_MM);
		break;
	case PROTO_GOTO_PANIER:
		orders_goto_panier(&pl->orders, &pl->m,
				   fx_deg_to_turn32(a[ARG_GOTO_PANIER_ANGLE_2DEG] * 2));
		break;
	default: /* PROTO_STOP */
		orders_stop(&pl->orders);
		break;
	}
}

void board_apply(struct planner *pl, struct mailbox *mb, const struct board_config *cfg,
		 const struct proto_msg *msg)
{
	const int32_t *a = msg->arg;
	struct board_handover *draft = &mb->down[mb->down_index ^ 1u];
	struct control_gains g;

	pl->fed = 1; /* an accepted write: the master is alive (SET_TIMEOUT) */
	if ((pl->status & STATUS_PB_GRAVE) &&
	    proto_lookup(msg->designation)->kind == PROTO_KIND_ORDRE) {
		motion_refused(pl, msg); /* raced the PB_GRAVE publication: refused like the */
		return;                  /* protocol layer does */
	}
	if (pl->reset.pose_lost && proto_lookup(msg->designation)->kind == PROTO_KIND_ORDRE &&
	    msg->designation != PROTO_STOP) {
		motion_refused(pl, msg); /* the same for a lost pose (REFUSED_NO_POSE) */
		return;
	}
	switch (msg->designation) {
	case PROTO_GOTO:
	case PROTO_GOTO_REVERSE:
	case PROTO_GOTO_PANIER:
	case PROTO_STOP:
	case PROTO_PAUSE:
	case PROTO_RESUME:
		motion_order(pl, msg);
		break;
	case PROTO_SET_SPEED_SCALE:
	case PROTO_SET_CORNER:
		motion_setting(pl, msg);
		break;
	case PROTO_SET_VITESSE_TRAJ:
		orders_set_traj_limits(
			&pl->orders, (uint8_t)a[ARG_SET_VITESSE_TRAJ_SPEED_CM_S],
			msg->n_args > 1 ? (uint8_t)a[ARG_SET_VITESSE_TRAJ_ACCEL_CM_S2] : 0);
		break;
	case PROTO_SET_VITESSE_ROT:
		orders_set_rot_limits(&pl->orders, (uint8_t)a[ARG_SET_VITESSE_ROT_SPEED_CM_S],
				      msg->n_args > 1 ? (uint8_t)a[ARG_SET_VITESSE_ROT_ACCEL_CM_S2]
						      : 0);
		break;
	case PROTO_SET_FILTRE:
		if ((uint8_t)a[ARG_SET_FILTRE_PRESET] < CONTROL_N_PRESETS) /* by the table */
			master_gains(pl, draft,
				     &cfg->control.presets[(uint8_t)a[ARG_SET_FILTRE_PRESET]]);
		break;
	case PROTO_SET_FILTRE_RAW:
		g.p = (uint16_t)a[ARG_SET_FILTRE_RAW_P];
		g.i = (uint16_t)a[ARG_SET_FILTRE_RAW_I];
		g.d = (uint16_t)a[ARG_SET_FILTRE_RAW_D];
		master_gains(pl, draft, &g);
		break;
	case PROTO_SET_NEW_POS:
		set_new_pos(pl, msg);
		break;
	case PROTO_SET_TIMEOUT:
		/* Rounded up: the robot never stops before the time the master gave. */
		pl->timeout_ticks =
			((uint32_t)a[ARG_SET_TIMEOUT_TIMEOUT_MS] * pl->slow_hz + 999u) / 1000u;
		break;
	case PROTO_HEARTBEAT:
		break; /* nothing but the master alive */
	case PROTO_SET_FIX:
		set_fix(pl, msg);
		break;
	case PROTO_SET_ODOMETRIE:
		/* in range by the message table; see set_odometrie */
		(void)set_odometrie(pl, &mb->wheels, cfg, msg);
		break;
	case PROTO_BOOTLOADER:
		/* The port leaves for its bootloader after this tick (docs/update.md); an order
		 * started since the protocol layer's check keeps the board here. */
		if (!orders_busy(&pl->orders))
			pl->boot_request = 1;
		break;
	default:
		break; /* ETAT messages never reach the queue */
	}
}

/* round(um / 1000) saturated to 16 bits (ties away from zero). */
static int16_t mm_of(int32_t um)
{
	uint16_t q;

	if (um >= 32767500)
		return INT16_MAX;
	if (um <= -32768500)
		return INT16_MIN;
	q = fx_udiv1000(fx_mag32(um) + UM_PER_MM / 2u);
	return um >= 0 ? (int16_t)q : (int16_t) - (int32_t)q;
}

/* The heading in POSITION's 2-degree steps, rounded once from the heading itself (ties away
 * from zero): round(h 180 / 2^32) for h in [-2^31, 2^31), -90..90. */
static int8_t angle_2deg_of(uint32_t heading_turn32)
{
	int32_t h = (int32_t)heading_turn32;
	uint32_t lo, hi = fx_mul_u32_wide(fx_mag32(h), 180u, &lo);
	uint8_t q = (uint8_t)(hi + (lo >= 0x80000000u));

	return h >= 0 ? (int8_t)q : (int8_t) - (int16_t)q;
}

void board_publish(const struct planner *pl, const struct board_snapshot *p, struct proto *proto)
{
	const struct orders_measure *m = &pl->m;
	struct proto_snapshot *s = proto_draft(proto);
	int32_t cdeg = fx_turn32_to_cdeg(m->pose.heading_turn32);

	s->x_mm = mm_of(m->pose.x_um);
	s->y_mm = mm_of(m->pose.y_um);
	s->angle_2deg = angle_2deg_of(m->pose.heading_turn32); /* -90..90 */
	s->radius_mm = uncertainty_get_radius_mm(&pl->uncertainty);
	s->status = pl->status;
	motion_publish(pl, s);
	s->sensors = p->in.shocks;
	s->calibrated = pl->calibrated;
	s->debug.tick = p->tick;
	s->debug.heading_cdeg = (int16_t)cdeg;
	s->debug.speed_mm_s = mm_of(m->dist_speed_um_s);
	s->debug.turn_rate_cdeg_s = fx_sat16(fx_mul_s16(
		(int16_t)fx_turn32_to_cdeg((uint32_t)p->dtheta_turn32), (int16_t)pl->slow_hz));
	s->debug.dist_err_um = fx_sat16(p->dist_err_um);
	s->debug.angle_err_um = fx_sat16(p->angle_err_um);
	s->debug.duty_left_q15 = p->duty_q15[0];
	s->debug.duty_right_q15 = p->duty_q15[1];
	s->debug.current_left_ma = p->in.current_ma[0];
	s->debug.current_right_ma = p->in.current_ma[1];
	s->debug.order_state = pl->orders.state;
	s->reset.tracked = pl->reset.tracked;
	s->reset.cause = pl->reset.cause;
	s->reset.count = pl->reset.count;
	s->reset.pose_lost = pl->reset.pose_lost;
	s->reset.widened_mm = pl->reset.widened_mm;
	if (CONFIG_FIX) { /* FIX_INFO: a build without fixes has none to count */
		s->fix.fused = pl->fix.info.fused;
		s->fix.outliers = pl->fix.info.outliers;
		s->fix.too_old = pl->fix.info.too_old;
		s->fix.last = pl->fix.info.last;
		s->fix.last_d2 = pl->fix.info.last_d2;
	}
	s->debug.end_reason = (pl->timed_out && !orders_busy(&pl->orders)) ? END_REASON_TIMEOUT
									   : pl->orders.end_reason;
}
