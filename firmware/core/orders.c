/* Orders: the state machine of GOTO, GOTO_REVERSE, GOTO_PANIER and STOP (see orders.h). */
#include "orders.h"

#include <string.h>

#include "fixmath.h"
#include "protocol_defs.h"

#define CM_TO_UM 10000

/* A heading change [turn * 2^32] as an arc on the angle axis [um]. */
static int32_t orders_arc_um(const struct orders *o, int32_t dheading_turn32)
{
	return fx_mul_shr32(dheading_turn32, (uint32_t)o->pi_track_um);
}

static struct profile_limits limits_of(uint8_t speed_cm_s, uint8_t accel_cm_s2, uint32_t jerk)
{
	struct profile_limits l;

	l.v_max_um_s = (int32_t)speed_cm_s * CM_TO_UM;
	l.a_max_um_s2 = (int32_t)accel_cm_s2 * CM_TO_UM;
	l.j_max_um_s3 = (int32_t)jerk;
	return l;
}

/* floor(a / k) for a >= 0 and k in [2^-8] (k >= 1), at most 2^23 - 1: in 32 bits (an AVR's 64-bit
 * division is thousands of cycles; this runs at each setting and each state an order enters). */
static int32_t div_q8(int32_t a, uint16_t k_q8)
{
	uint32_t q = (uint32_t)a / k_q8, r = (uint32_t)a % k_q8;

	if (q >= ((uint32_t)1 << 15))
		return ((int32_t)1 << 23) - 1;
	return (int32_t)((q << 8) + (r << 8) / k_q8);
}

/* The accelerations within the grip, whatever the master set (docs/control.md "Grip"): of 7/8
 * of the grip (1/8 left for the loop's corrections), the distance axis gets at most 3/4, and
 * the angle axis what the distance axis leaves, so that a turn that still brakes while the line
 * starts, or a re-aim while accelerating, never asks the wheels for more than the grip gives.
 * Kept in o->grip_a_um_s2 at each SET_VITESSE_*: the states apply them without a division. */
static void grip_split(const struct orders *o, int32_t lin_max, int32_t rot_max, int32_t out[2])
{
	int32_t grip = o->cfg.grip_um_s2 - (o->cfg.grip_um_s2 >> 3); /* 1/8 for the loop */
	int32_t lin = grip - (grip >> 2), rot;

	if (lin_max < lin)
		lin = lin_max;
	rot = div_q8(grip - lin, o->cfg.rot_grip_q8);
	if (rot < PROFILE_A_MIN_UM_S2)
		rot = PROFILE_A_MIN_UM_S2;
	if (rot_max < rot)
		rot = rot_max;
	out[0] = lin;
	out[1] = rot;
}

static void grip_share(struct orders *o)
{
	grip_split(o, o->traj.a_max_um_s2, o->rot.a_max_um_s2, o->grip_a_um_s2);
}

/* The stop after a shock's settings at rate_hz (orders_shock()); its state is zero (memset). */
static void init_give_way(struct orders *o, int32_t count_um_s)
{
	uint16_t rate_hz = o->rate_hz;

	o->rest_ticks = (uint8_t)(rate_hz >= 250 ? rate_hz / 125 : 1); /* 8 ms */
	o->brake_dv_um_s = o->cfg.grip_um_s2 / (int32_t)rate_hz;       /* >= 50 */
	/* Two counts a tick: one reads anything from 0 to 2 counts' speed. At most 0.4 m/s, so
	 * that brake_away() stays in 32 bits. */
	o->rebound_um_s = o->cfg.arrive_speed_um_s + 2 * o->brake_dv_um_s;
	if (o->rebound_um_s < 2 * count_um_s)
		o->rebound_um_s = 2 * count_um_s;
	if (o->rebound_um_s > 400000)
		o->rebound_um_s = 400000;
	/* Thrown again once at rest (give_way_axis()): two counts, a hold at rest rocks by a count
	 * either way; only where a tick's speed cannot tell a robot about to stop from one moving
	 * away (2 counts a tick above arrive_speed and two ticks of braking: a slow spin reads as a
	 * count or none). At slower rates the speed read tells it: 0, never. */
	if (2 * count_um_s > o->cfg.arrive_speed_um_s + 2 * o->brake_dv_um_s) {
		o->throw_um = 2 * (count_um_s / (int32_t)rate_hz + 1);
		/* The speed the rebound and the hold read, over rest_ticks (give_way_axis()). */
		while (((unsigned)o->rest_ticks >> (o->speed_shift + 1u)) != 0)
			o->speed_shift++;
	}
}

int orders_init(struct orders *o, const struct orders_config *cfg, uint16_t rate_hz,
		int32_t count_um_s, int32_t dist_um, int32_t angle_um)
{
	struct profile_config pc;

	if (cfg->drive_track_um < 10000u || cfg->drive_track_um > 1000000u ||
	    cfg->aim_delay_steps > 1 || cfg->n_baskets > ORDERS_MAX_BASKETS ||
	    cfg->settle_ms == 0 || cfg->grip_um_s2 < 100000 || cfg->grip_um_s2 > 50000000 ||
	    cfg->rot_grip_q8 == 0)
		return -1;
	/* Every field from a known value, whatever the memory held (a power cycle re-inits a
	 * board in place): no recalibration, border push or frozen target carried over. */
	memset(o, 0, sizeof(*o));
	o->cfg = *cfg;
	o->rate_hz = rate_hz;
	/* pi as 355/113 (8e-8 relative). */
	o->pi_track_um = fx_div_round((int32_t)cfg->drive_track_um * 355, 113);
	/* The specification's initial state: 10 cm/s, 40 cm/s^2. */
	o->traj = limits_of(10, 40, cfg->jerk_um_s3);
	o->rot = o->traj;
	pc.tick_hz = rate_hz;
	pc.limits = o->traj;
	if (profile_init(&o->dist, &pc, dist_um) || profile_init(&o->angle, &pc, angle_um))
		return -1;
	grip_share(o);
	/* PAUSE brakes at the grip's shares, whatever the master's accelerations. */
	grip_split(o, PROFILE_A_MAX_UM_S2, PROFILE_A_MAX_UM_S2, &o->grip_a_um_s2[2]);
	{
		struct profile_limits d = o->traj, r = o->rot;

		d.a_max_um_s2 = o->grip_a_um_s2[0];
		r.a_max_um_s2 = o->grip_a_um_s2[1];
		profile_set_limits(&o->dist, &d);
		profile_set_limits(&o->angle, &r);
	}
	o->designation = 0xFFu;
	o->scale_percent = 100;
	o->settle_ticks = fx_ticks_of_ms(cfg->settle_ms, rate_hz);
	o->settle_timeout_ticks = fx_ticks_of_ms(cfg->settle_timeout_ms, rate_hz);
	o->square_ticks = fx_ticks_of_ms(cfg->square_ms, rate_hz);
	o->aim_period = (uint8_t)(rate_hz >= 500 ? rate_hz / 250 : 1);
	o->aim_wait = 0;
	o->bearing_valid = 0;
	o->trig_valid = 0;
	o->state = ORDER_STATE_IDLE;
	o->end_reason = END_REASON_NONE;
	init_give_way(o, count_um_s);
	o->sp_dist.pos_um = dist_um;
	o->sp_dist.vel_um_s = 0;
	o->sp_dist.acc_um_s2 = 0;
	o->sp_angle.pos_um = angle_um;
	o->sp_angle.vel_um_s = 0;
	o->sp_angle.acc_um_s2 = 0;
	return 0;
}

static void apply_limits(struct orders *o)
{
	struct profile_limits d = o->traj, r = o->rot;

	int32_t push = o->border ? o->cfg.border_speed_um_s : o->cfg.push_speed_um_s;

	if (o->state == ORDER_STATE_PUSH && d.v_max_um_s > push)
		d.v_max_um_s = push;
	if (o->scale_percent < 100) { /* SET_SPEED_SCALE: at most 2.55 m/s x 100 in 32 bits */
		d.v_max_um_s = d.v_max_um_s * o->scale_percent / 100;
		r.v_max_um_s = r.v_max_um_s * o->scale_percent / 100;
		d.v_max_um_s = d.v_max_um_s < 1 ? 1 : d.v_max_um_s;
		r.v_max_um_s = r.v_max_um_s < 1 ? 1 : r.v_max_um_s;
	}
	/* PAUSE at the grip's shares; in a pivot, at the pivot's own (within the grip too): the
	 * line braking as it did to the point, the heading as fast as it turned */
	d.a_max_um_s2 = o->grip_a_um_s2[o->paused && !orders_pivoting(o) ? 2 : 0];
	r.a_max_um_s2 = o->grip_a_um_s2[o->paused && !orders_pivoting(o) ? 3 : 1];
	if (CONFIG_MOTION_CORNERS && o->curve) { /* paused too: braking along the curve */
		if (d.v_max_um_s > o->cv.v_um_s)
			d.v_max_um_s = o->cv.v_um_s;
		d.a_max_um_s2 = o->cv.a_um_s2;
	}
	profile_set_limits(&o->dist, &d);
	profile_set_limits(&o->angle, &r);
}

static void set_limits(struct orders *o, struct profile_limits *l, uint8_t speed_cm_s,
		       uint8_t accel_cm_s2)
{
	struct profile_limits n = limits_of(speed_cm_s, accel_cm_s2, o->cfg.jerk_um_s3);

	if (speed_cm_s)
		l->v_max_um_s = n.v_max_um_s;
	if (accel_cm_s2)
		l->a_max_um_s2 = n.a_max_um_s2;
	grip_share(o);
	apply_limits(o);
}

void orders_set_traj_limits(struct orders *o, uint8_t speed_cm_s, uint8_t accel_cm_s2)
{
	set_limits(o, &o->traj, speed_cm_s, accel_cm_s2);
}

void orders_set_rot_limits(struct orders *o, uint8_t speed_cm_s, uint8_t accel_cm_s2)
{
	set_limits(o, &o->rot, speed_cm_s, accel_cm_s2);
}

static void enter(struct orders *o, uint8_t state)
{
	o->state = state;
	o->settle_count = 0;
	o->settle_time = 0;
	apply_limits(o);
}

/* The curve left before its end (a new order, an abort): the angle profile takes over the
 * heading's motion where the curve has it. */
static void curve_leave(struct orders *o)
{
	if (!CONFIG_MOTION_CORNERS || !o->curve)
		return;
	o->curve = 0;
	profile_follow(&o->angle, o->sp_angle.pos_um, o->sp_angle.vel_um_s);
}

static void begin(struct orders *o, uint8_t designation)
{
	curve_leave(o);
	o->designation = designation;
	o->frozen = 0;
	o->bearing_valid = 0; /* a new target */
	o->aim_wait = o->aim_period;
	o->border = 0;
	o->recal.pending = 0;
	o->give_way = 0;
	o->braking = 0;
	o->paused = 0;
	o->through_um = 0;
#if CONFIG_MOTION_CORNERS
	o->pivot_turn32 = 0;
#endif
}

static void end(struct orders *o, uint8_t reason)
{
	curve_leave(o);
	o->border = 0;
	o->state = ORDER_STATE_IDLE;
	o->end_reason = reason;
	apply_limits(o);
}

/* Aim the angle axis at an absolute heading, from the current estimate. */
static void aim(struct orders *o, const struct orders_measure *m, uint32_t heading_turn32)
{
	int32_t d = fx_angle_diff(heading_turn32, m->pose.heading_turn32);

	profile_set_target(&o->angle, m->angle_um + orders_arc_um(o, d));
}

/* The bearing of the target from the estimate. fx_atan2 divides bit by bit (about a thousand
 * cycles on an AVR), so its result is kept with the position it was computed from: turning on
 * the spot moves the estimated position little or not at all (the two wheel travels cancel), a
 * second call in the same tick finds it too, and the same inputs give the same output. */
static uint32_t bearing(struct orders *o, const struct odometry_pose *p)
{
	if (!o->bearing_valid || p->x_um != o->bearing_x_um || p->y_um != o->bearing_y_um) {
		o->bearing_turn32 = fx_atan2(o->target_y_um - p->y_um, o->target_x_um - p->x_um);
		o->bearing_x_um = p->x_um;
		o->bearing_y_um = p->y_um;
		o->bearing_valid = 1;
	}
	return o->bearing_turn32;
}

/* The target within the freeze radius of the estimate: floor(|(dx, dy)|) <= R exactly, as
 * dx^2 + dy^2 < (R + 1)^2 (no square root), and a component beyond R decides without a
 * multiplication, which is the case for all but the last few centimetres of a GOTO. Up to
 * R = 46 mm the squares add up in 32 bits. */
static int within_freeze(const struct orders *o, const struct odometry_pose *p)
{
	int32_t dx = o->target_x_um - p->x_um;
	int32_t dy = o->target_y_um - p->y_um;
	int32_t r = o->cfg.freeze_radius_um;
	int64_t r1 = (int64_t)r + 1;

	if (r < 0 || dx > r || dx < -r || dy > r || dy < -r)
		return 0;
	if (r < 46340) {
		uint32_t ux = (uint32_t)(dx >= 0 ? dx : -dx), uy = (uint32_t)(dy >= 0 ? dy : -dy);

		return fx_mul_u16((uint16_t)ux, (uint16_t)ux) +
			       fx_mul_u16((uint16_t)uy, (uint16_t)uy) <
		       (uint32_t)(r + 1) * (uint32_t)(r + 1);
	}
	return (int64_t)dx * dx + (int64_t)dy * dy < r1 * r1;
}

/* The projection of the target on the heading [um], for GOTO's distance axis. The sine and
 * cosine of the heading are kept with it: going straight, the estimated heading often does not
 * change from one tick to the next. */
static int32_t projection(struct orders *o, const struct odometry_pose *p)
{
	int32_t dx = o->target_x_um - p->x_um;
	int32_t dy = o->target_y_um - p->y_um;

	if (!o->trig_valid || p->heading_turn32 != o->trig_turn32) {
		fx_sincos(p->heading_turn32, &o->trig_sin_q30, &o->trig_cos_q30);
		o->trig_turn32 = p->heading_turn32;
		o->trig_valid = 1;
	}
	/* Each product rounded: within 1 um of the exact sum. */
	return fx_mul_q30(dx, o->trig_cos_q30) + fx_mul_q30(dy, o->trig_sin_q30);
}

/* Too close to aim: no spinning on the spot, a straight correction along the current heading
 * (backwards if the target is just behind), the angle braking where it is. */
static void straight_correction(struct orders *o, const struct orders_measure *m)
{
	o->frozen = 1;
	enter(o, ORDER_STATE_TRANSLATE);
	profile_set_target(&o->dist, m->dist_um + projection(o, &m->pose));
	profile_stop(&o->angle);
}

void orders_goto(struct orders *o, const struct orders_measure *m, int32_t x_um, int32_t y_um,
		 uint8_t options)
{
	begin(o, PROTO_GOTO);
	o->options = options;
	o->target_x_um = x_um;
	o->target_y_um = y_um;
	if (within_freeze(o, &m->pose)) {
		straight_correction(o, m);
		return;
	}
	enter(o, ORDER_STATE_ROTATE);
	profile_stop(&o->dist);
	/* The first aim (a bearing, the angle's target) at this very step, or aim_delay_steps
	 * later: a robot that already faces the target translates then. */
	o->aim_wait = (uint8_t)(1u + o->cfg.aim_delay_steps);
}

void orders_goto_reverse(struct orders *o, const struct orders_measure *m, int32_t distance_um)
{
	begin(o, PROTO_GOTO_REVERSE);
	enter(o, ORDER_STATE_TRANSLATE);
	profile_set_target(&o->dist, m->dist_um - distance_um);
	profile_stop(&o->angle);
}

void orders_goto_panier(struct orders *o, const struct orders_measure *m, uint32_t heading_turn32)
{
	begin(o, PROTO_GOTO_PANIER);
	o->target_heading_turn32 = heading_turn32;
	enter(o, ORDER_STATE_ROTATE);
	profile_stop(&o->dist);
	aim(o, m, heading_turn32);
}

void orders_stop(struct orders *o)
{
	begin(o, PROTO_STOP);
	enter(o, ORDER_STATE_STOPPING);
	profile_stop(&o->dist);
	profile_stop(&o->angle);
}

static void hold_measured(struct orders *o, const struct orders_measure *m)
{
	o->curve = 0;
	profile_reset(&o->dist, m->dist_um);
	profile_reset(&o->angle, m->angle_um);
	o->sp_dist.pos_um = m->dist_um;
	o->sp_dist.vel_um_s = 0;
	o->sp_dist.acc_um_s2 = 0;
	o->sp_angle.pos_um = m->angle_um;
	o->sp_angle.vel_um_s = 0;
	o->sp_angle.acc_um_s2 = 0;
}

void orders_abort(struct orders *o, const struct orders_measure *m, uint8_t end_reason)
{
	hold_measured(o, m);
	end(o, end_reason);
}

/* The side an axis moved towards: its measured speed, else its set point's velocity, if either
 * is above the arrival speed. */
static int8_t side_of(int32_t speed_um_s, int32_t set_um_s, int32_t slow_um_s)
{
	if (fx_abs32(speed_um_s) < slow_um_s)
		speed_um_s = set_um_s;
	if (fx_abs32(speed_um_s) < slow_um_s)
		return 0;
	return speed_um_s > 0 ? 1 : -1;
}

/* The whole ticks braking at the grip's deceleration takes from the set point's speed, else the
 * measured one (at low speed a tick's measure is a whole encoder count or none). */
static uint16_t brake_ticks(const struct orders *o, int32_t set_um_s, int32_t speed_um_s)
{
	int32_t dv = o->brake_dv_um_s;
	int32_t v = fx_abs32(set_um_s) >= o->cfg.arrive_speed_um_s ? fx_abs32(set_um_s)
								   : fx_abs32(speed_um_s);
	int32_t n = v / dv;

	return (uint16_t)(n > 0xFFFF ? 0xFFFF : n);
}

void orders_shock(struct orders *o, const struct orders_measure *m, uint8_t end_reason)
{
	int32_t slow = o->cfg.arrive_speed_um_s;

	o->shock_side[0] = side_of(m->dist_speed_um_s, o->sp_dist.vel_um_s, slow);
	o->shock_side[1] = side_of(m->angle_speed_um_s, o->sp_angle.vel_um_s, slow);
	o->brake_ticks[0] = brake_ticks(o, o->sp_dist.vel_um_s, m->dist_speed_um_s);
	o->brake_ticks[1] = brake_ticks(o, o->sp_angle.vel_um_s, m->angle_speed_um_s);
	orders_abort(o, m, end_reason);
	o->give_way = 1;
	o->reach_um[0] = m->dist_um;
	o->reach_um[1] = m->angle_um;
	o->still[0] = 0;
	o->still[1] = 0;
	o->away_um_s[0] = 0;
	o->away_um_s[1] = 0;
	o->speed_q[0] = m->dist_speed_um_s * (1 << o->speed_shift);
	o->speed_q[1] = m->angle_speed_um_s * (1 << o->speed_shift);
}

/* An axis's speed [um/s] low-passed over 2^speed_shift ticks (a first order: q += v - q / 2^k),
 * from one tick's measure speed_um_s: where a tick reads a whole encoder count or none, a slow
 * motion reads as its average, not as a count's speed on one tick in several. With speed_shift 0
 * it is the tick's measure. */
static int32_t smooth_speed(struct orders *o, uint8_t axis, int32_t speed_um_s)
{
	o->speed_q[axis] += speed_um_s - fx_floor_shr(o->speed_q[axis], o->speed_shift);
	return fx_floor_shr(o->speed_q[axis], o->speed_shift);
}

/* a - b, the axes' wrapping difference (the positions compared are close). */
static int32_t wrap_sub(int32_t a, int32_t b)
{
	return (int32_t)((uint32_t)a - (uint32_t)b);
}

/* An axis that bounced off the obstacle, moving away from it at away_um_s (m's, > 0 away), its
 * hold point beyond_um towards the obstacle from it, before it first comes to rest: braked along
 * its motion away (brake_away()), its hold point going with it. A hold point on the obstacle's
 * side goes with it too; one on the far side stays, so that the hold resists a robot turned
 * back towards the obstacle. Returns 0 once it has not moved away for rest_ticks. */
static int rebound(struct orders *o, uint8_t axis, struct profile *p, int32_t pos_um,
		   int32_t away_um_s, int32_t beyond_um)
{
	if (beyond_um > 0 || away_um_s > o->cfg.arrive_speed_um_s) {
		profile_reset(p, pos_um);
		o->gave_way = 1;
	}
	if (away_um_s > o->cfg.arrive_speed_um_s) {
		o->away_um_s[axis] = away_um_s;
		o->braking |= (uint8_t)(4u << axis);
		o->still[axis] = 0;
		return 1;
	}
	return ++o->still[axis] < o->rest_ticks;
}

/* An axis at rest after its rebound, at pos_um: 1 when it has moved away from the obstacle (side)
 * by more than throw_um (two counts) from where it was up to twice rest_ticks ago: thrown
 * again. One tick's speed cannot tell it: a spin slower than a count a tick reads as a count or
 * none, as the rocking of a hold at rest. */
static int thrown(struct orders *o, uint8_t axis, int32_t pos_um, int8_t side)
{
	int32_t away = wrap_sub(o->rest_um[axis], pos_um);

	if (!o->throw_um)
		return 0;
	if (side < 0)
		away = wrap_sub(0, away);
	if (away > o->throw_um) {
		o->rest_um[axis] = pos_um;
		return 1;
	}
	if (++o->still[axis] >= 2 * o->rest_ticks) {
		o->still[axis] = 0;
		o->rest_um[axis] = pos_um;
	}
	return 0;
}

static void give_way_rest(struct orders *o, uint8_t axis, struct profile *p, int32_t pos_um,
			  int32_t away, int32_t beyond);

/* One axis of the stop after a shock (orders_shock()), at pos_um going towards the obstacle at
 * speed_um_s (m's). */
static void give_way_axis(struct orders *o, uint8_t axis, struct profile *p, int32_t pos_um,
			  int32_t speed_um_s)
{
	int8_t side = o->shock_side[axis];
	uint8_t stopped = (uint8_t)(2u << axis);
	int32_t slow = o->cfg.arrive_speed_um_s;
	int32_t further = wrap_sub(pos_um, o->reach_um[axis]);
	int32_t beyond = wrap_sub(p->out.pos_um, pos_um);
	int32_t smooth = smooth_speed(o, axis, speed_um_s), away;

	if (side == 0) {
		/* Not moving at the shock: the contact moved it (a corner turned by the obstacle).
		 * Holding that back would press the obstacle: wherever it slows down, hold it. */
		if (beyond != 0 && fx_abs32(speed_um_s) < slow) {
			profile_reset(p, pos_um);
			o->gave_way = 1;
		}
		return;
	}
	if (side < 0) { /* wrapping too (fuzzed positions may be far apart) */
		further = wrap_sub(0, further);
		beyond = wrap_sub(0, beyond);
		speed_um_s = -speed_um_s; /* a product of two 16-bit values (planner_measure()) */
		smooth = -smooth;
	}
	if (!(o->give_way & stopped)) {
		/* Braking for the braking time, while it still goes towards the obstacle (it went
		 * further within half rest_ticks, and not back this tick). */
		if (further > 0) {
			o->reach_um[axis] = pos_um;
			o->still[axis] = 0;
		} else if (speed_um_s <= -slow || ++o->still[axis] >= o->rest_ticks) {
			/* The first stop (against the obstacle, or bouncing off it): hold there. */
			o->give_way |= stopped;
			o->brake_ticks[axis] = 0;
			o->still[axis] = 0;
			profile_reset(p, pos_um);
			o->gave_way = 1;
			beyond = 0;
			/* The low-pass from this tick's measure: not the approach's speed. */
			smooth = speed_um_s;
			o->speed_q[axis] = side * speed_um_s * (1 << o->speed_shift);
		}
		if (o->brake_ticks[axis] > 0) {
			o->brake_ticks[axis]--;
			if (speed_um_s >= 0 &&
			    o->still[axis] < (uint8_t)((o->rest_ticks + 1u) >> 1))
				o->braking |= (uint8_t)(1u << axis);
		}
		if (!(o->give_way & stopped))
			return;
	}
	/* Moving away: a tick's measure from two counts a tick (it tells the speed, at once), the
	 * low-passed speed below (a count on one tick in several is not a count's speed). */
	away = -speed_um_s >= o->rebound_um_s ? -speed_um_s : -smooth;
	give_way_rest(o, axis, p, pos_um, away, beyond);
}

/* An axis of the stop after a shock once stopped, or bouncing off (give_way_axis()), at pos_um
 * moving away from the obstacle at away_um_s, its hold point beyond_um on the obstacle's side.
 * Until it first comes to rest, a robot moving away is braked along its own motion, its hold
 * point going with it (rebound(), brake_away()). A hold left behind braked it instead: it drove
 * the wheels to full duty, spinning against the motion, and they carried the robot back towards
 * the obstacle once it stopped. From then on a robot on the far side of its hold point, slower
 * than arrive_speed and two ticks of braking, is held where it is, before the hold pulls it
 * back. */
static void give_way_rest(struct orders *o, uint8_t axis, struct profile *p, int32_t pos_um,
			  int32_t away, int32_t beyond)
{
	uint8_t rested = (uint8_t)(8u << axis);

	if (!(o->give_way & rested)) {
		if (rebound(o, axis, p, pos_um, away, beyond))
			return;
		o->give_way |= rested;
		o->rest_um[axis] = pos_um;
	} else if (thrown(o, axis, pos_um, o->shock_side[axis])) {
		/* Thrown away again once at rest (a second corner meeting the obstacle): braked as
		 * the first rebound, until it rests again, but harder below rebound_um_s (bit 5 +
		 * axis, brake_away()). */
		o->give_way &= (uint8_t)~rested;
		o->give_way |= (uint8_t)(0x20u << axis);
		o->still[axis] = 0;
		rebound(o, axis, p, pos_um, away, beyond);
		return;
	}
	/* At rest, a hold point on the obstacle's side: within throw_um of the robot (the rocking
	 * of a hold, a creep) it holds, pulling the robot back to where it rested; beyond, slower
	 * than arrive_speed and two ticks of braking (the low-passed speed: a creep reads as a
	 * count on some ticks), it moves to the robot. */
	if (beyond <= o->throw_um || away > o->cfg.arrive_speed_um_s + 2 * o->brake_dv_um_s)
		return;
	profile_reset(p, pos_um);
	o->gave_way = 1;
}

/* The set point has reached its target but for its last creep: within the arrive window of it,
 * slower than arrive_speed. The settle check overlaps the rest, which the profile finishes. */
static int nearly_done(const struct orders *o, const struct profile *p)
{
	const struct profile_out *out = &p->out;

	return out->done ||
	       (fx_abs32(profile_get_target_um(p) - out->pos_um) < o->cfg.arrive_window_um &&
		fx_abs32(out->vel_um_s) < o->cfg.arrive_speed_um_s);
}

/* The robot within the arrive window of both targets for settle_ms. */
static int settled(struct orders *o, const struct orders_measure *m)
{
	int32_t ed = profile_get_target_um(&o->dist) - m->dist_um;
	int32_t ea = profile_get_target_um(&o->angle) - m->angle_um;

	if (fx_abs32(ed) < o->cfg.arrive_window_um && fx_abs32(ea) < o->cfg.arrive_window_um) {
		if (o->settle_count < 0xFFFFu)
			o->settle_count++;
	} else {
		o->settle_count = 0;
	}
	if (o->settle_time < 0xFFFFu)
		o->settle_time++;
	return o->settle_count >= o->settle_ticks || o->settle_time >= o->settle_timeout_ticks;
}

static void step_goto(struct orders *o, const struct orders_measure *m)
{
	if (o->frozen)
		return;
	/* The targets are points of the axes; between two re-aims they stay where they are. */
	if (o->aim_wait > 1) {
		o->aim_wait--;
		return;
	}
	o->aim_wait = o->aim_period;
#if CONFIG_FIX
	o->aimed = 1;
#endif
	if (within_freeze(o, &m->pose)) {
		o->frozen = 1;
		return;
	}
	aim(o, m, bearing(o, &m->pose));
	if (o->state != ORDER_STATE_TRANSLATE)
		return;
	profile_set_target(&o->dist, m->dist_um + projection(o, &m->pose) + o->through_um);
#if CONFIG_MOTION_CORNERS
	if (o->pivot_turn32 != 0 && fx_abs32(o->sp_angle.vel_um_s) < o->cfg.arrive_speed_um_s)
		o->pivot_turn32 = 0; /* the pivot's turn is over: a plain line */
#endif
}

/* The curve's length [um]: a clothoid in, the arc, a clothoid out. */
static int32_t curve_length(const struct orders *o)
{
	return 2 * o->cv.clothoid_um + o->cv.arc_um;
}

void orders_curve_start(struct orders *o, const struct orders_measure *m,
			const struct orders_curve *c, uint32_t heading_turn32)
{
	if (!CONFIG_MOTION_CORNERS || o->designation != PROTO_GOTO ||
	    o->state != ORDER_STATE_ROTATE || o->frozen)
		return;
	o->curve = 1;
	o->cv = *c;
	o->curve_d0 = o->sp_dist.pos_um;
	o->curve_a0 = o->sp_angle.pos_um;
	/* The heading of the next line, as aim() would turn to it from the set point. */
	o->cv.turn_um = m->angle_um - o->curve_a0 +
			orders_arc_um(o, fx_angle_diff(heading_turn32, m->pose.heading_turn32));
	apply_limits(o);
	o->through_um = 0;
}

void orders_pivot_start(struct orders *o, int32_t stop_um, uint32_t turn32)
{
#if CONFIG_MOTION_CORNERS
	if (o->designation != PROTO_GOTO || o->state != ORDER_STATE_ROTATE || o->frozen)
		return;
	profile_set_target(&o->dist, stop_um);
	o->pivot_turn32 = turn32 > 0 ? turn32 : 1;
#else
	(void)o;
	(void)stop_um;
	(void)turn32;
#endif
}

/* A pivot's line may start (orders_pivot_start()): the heading within pivot_turn32 of the
 * bearing (heading_err) and its rate braking, the line at rest at the last point. */
static int pivot_go(const struct orders *o, uint32_t heading_err)
{
#if CONFIG_MOTION_CORNERS
	return o->pivot_turn32 != 0 && heading_err <= o->pivot_turn32 &&
	       profile_is_done(&o->dist) &&
	       (int64_t)o->sp_angle.acc_um_s2 * o->sp_angle.vel_um_s < 0;
#else
	(void)o;
	(void)heading_err;
	return 0;
#endif
}

/* On a curve: the line aims at the point along the curve and the line after it (and past it at
 * the next corner); at its end, the heading is the next line's, and the line aims at its point
 * from the estimate. */
static void step_curve(struct orders *o, const struct orders_measure *m)
{
	if (o->sp_dist.pos_um - o->curve_d0 < curve_length(o)) {
		profile_set_target(&o->dist, fx_sat32((int64_t)o->curve_d0 + curve_length(o) +
						      o->cv.rest_um + o->through_um));
		return;
	}
	o->curve = 0;
	profile_reset(&o->angle, o->curve_a0 + o->cv.turn_um);
	o->sp_angle.pos_um = o->curve_a0 + o->cv.turn_um;
	enter(o, ORDER_STATE_TRANSLATE);
	o->aim_wait = 0; /* the distance target, now */
	step_goto(o, m);
}

/* The angle set point on the curve, from the distance set point s along it: the heading's
 * curvature (as wheel arc per um of line, turn / (clothoid + arc) at most) rises linearly over
 * the first clothoid, holds on the arc, and falls over the last. Its velocity is the curvature
 * times the line's, its acceleration the curvature times the line's plus the curvature's rate
 * times the line's speed squared. 64-bit: the AVR has no corners (CONFIG_MOTION_CORNERS). */
static void curve_angle(struct orders *o)
{
	const struct orders_curve *c = &o->cv;
	int64_t s = (int64_t)o->sp_dist.pos_um - o->curve_d0, len = curve_length(o);
	int64_t v = o->sp_dist.vel_um_s, a = o->sp_dist.acc_um_s2, turn = c->turn_um;
	int64_t w = (int64_t)c->clothoid_um + c->arc_um, den = 2 * (int64_t)c->clothoid_um * w;
	int64_t pos, k_num, k_den = w, sigma = 0; /* curvature k_num / k_den; sigma [.. / den] */

	s = s < 0 ? 0 : s > len ? len : s;
	if (w == 0 || c->clothoid_um == 0) {
		pos = turn;
		k_num = 0;
		k_den = 1;
	} else if (s <= c->clothoid_um) {
		pos = fx_div_round64(turn * s * s, den);
		k_num = turn * s;
		k_den = (int64_t)c->clothoid_um * w;
		sigma = 2 * turn;
	} else if (s <= w) {
		pos = fx_div_round64(turn * (2 * s - c->clothoid_um), 2 * w);
		k_num = turn;
	} else {
		pos = turn - fx_div_round64(turn * (len - s) * (len - s), den);
		k_num = turn * (len - s);
		k_den = (int64_t)c->clothoid_um * w;
		sigma = -2 * turn;
	}
	o->sp_angle.pos_um = o->curve_a0 + (int32_t)pos;
	o->sp_angle.vel_um_s = fx_sat32(fx_div_round64(k_num * v, k_den));
	o->sp_angle.acc_um_s2 = fx_sat32(fx_div_round64(k_num * a, k_den) +
					 (sigma ? fx_div_round64(sigma * v * v, den) : 0));
}

/* The heading that faces border side (0 +X, 1 +Y, 2 -X, 3 -Y): a quarter turn per side. */
static uint32_t border_heading(uint8_t side)
{
	return (uint32_t)side << 30;
}

/* The gap between the front edge and border side, from the estimate [um]. */
static int32_t border_gap(const struct orders *o, const struct odometry_pose *p, uint8_t side)
{
	static const int8_t sign[4] = {1, 1, -1, -1};
	int32_t half = (side & 1u) ? o->cfg.half_width_um : o->cfg.half_length_um;
	int32_t c = (side & 1u) ? p->y_um : p->x_um;

	return half - sign[side] * c - o->cfg.front_um;
}

/* GOTO reached its point: turn to face the nearest border (by the estimate). */
static void start_border(struct orders *o, const struct orders_measure *m)
{
	uint8_t side = 0;

	for (uint8_t k = 1; k < 4; k++)
		if (border_gap(o, &m->pose, k) < border_gap(o, &m->pose, side))
			side = k;
	o->border = 1;
	o->border_side = side;
	enter(o, ORDER_STATE_ROTATE);
	profile_stop(&o->dist);
	aim(o, m, border_heading(side));
}

/* Squared up against the border: the coordinate across it is the border less the front
 * offset, and the heading faces it exactly. */
static void border_recal(struct orders *o, const struct orders_measure *m)
{
	uint8_t side = o->border_side;
	int32_t at = ((side & 1u) ? o->cfg.half_width_um : o->cfg.half_length_um) - o->cfg.front_um;

	o->recal.pose = m->pose;
	o->recal.pose.heading_turn32 = border_heading(side);
	o->recal.axis = side & 1u;
	if (side & 1u)
		o->recal.pose.y_um = side == 1 ? at : -at;
	else
		o->recal.pose.x_um = side == 0 ? at : -at;
	o->recal.pending = 1;
}

static uint8_t update_border(struct orders *o, const struct orders_measure *m)
{
	int32_t err;

	switch (o->state) {
	case ORDER_STATE_ROTATE:
		if (!profile_is_done(&o->angle) ||
		    fx_angle_dist(border_heading(o->border_side), m->pose.heading_turn32) >
			    o->cfg.heading_window_turn32)
			break;
		enter(o, ORDER_STATE_PUSH);
		profile_set_target(&o->dist, m->dist_um + border_gap(o, &m->pose, o->border_side) +
						     o->cfg.border_extra_um);
		break;
	case ORDER_STATE_PUSH:
		err = o->sp_dist.pos_um - m->dist_um;
		if ((m->shocks & o->cfg.front_shock_mask) || err > o->cfg.border_block_um) {
			/* Contact: push a little further, heading loop relaxed, so that the
			 * front edge lies flat against the border. */
			enter(o, ORDER_STATE_SQUARE);
			o->square_count = 0;
			/* From where it stands, at the push speed (a step of the setpoint would
			 * kick the derivative term). */
			profile_reset(&o->dist, m->dist_um);
			profile_set_target(&o->dist, m->dist_um + o->cfg.border_depth_um);
			break;
		}
		if (profile_is_done(&o->dist)) {
			end(o, END_REASON_DONE); /* no border where expected: no CHOC_BORD */
			return END_REASON_DONE;
		}
		break;
	case ORDER_STATE_SQUARE:
		if (++o->square_count < o->square_ticks)
			break;
		border_recal(o, m);
		enter(o, ORDER_STATE_BACK_OFF);
		profile_reset(&o->dist, m->dist_um);
		profile_reset(&o->angle, m->angle_um);
		profile_set_target(&o->dist, m->dist_um - o->cfg.backoff_um);
		break;
	case ORDER_STATE_BACK_OFF:
		if (profile_is_done(&o->dist)) {
			end(o, END_REASON_BORDER);
			return END_REASON_BORDER;
		}
		break;
	default:
		break;
	}
	return END_REASON_NONE;
}

static uint8_t update_state(struct orders *o, const struct orders_measure *m)
{
	uint32_t heading_err;

	if (o->border)
		return update_border(o, m);
	switch (o->state) {
	case ORDER_STATE_ROTATE:
		if (o->designation == PROTO_GOTO) {
			step_goto(o, m);
			if (o->frozen) {
				/* Carried within the freeze radius while still turning (a GOTO
				 * that replaced a fast move): the bearing is meaningless this
				 * close, finish with a straight correction along the heading. */
				straight_correction(o, m);
				break;
			}
		}
		/* GOTO: the bearing of the last re-aim (none yet on the order's first tick). */
		if (o->designation == PROTO_GOTO && !o->bearing_valid)
			break;
		heading_err = fx_angle_dist(
			o->designation == PROTO_GOTO
				? (o->bearing_valid ? o->bearing_turn32 : bearing(o, &m->pose))
				: o->target_heading_turn32,
			m->pose.heading_turn32);
		if (heading_err > o->cfg.heading_window_turn32 && !pivot_go(o, heading_err))
			break;
		if (o->designation == PROTO_GOTO_PANIER) {
			enter(o, ORDER_STATE_PUSH);
			o->push_start_um = m->dist_um;
			profile_set_target(&o->dist, m->dist_um + o->cfg.push_max_um);
		} else {
			enter(o, ORDER_STATE_TRANSLATE);
			o->aim_wait = 0; /* the distance target, now */
			step_goto(o, m);
		}
		break;
	case ORDER_STATE_TRANSLATE:
		if (o->designation == PROTO_GOTO)
			step_goto(o, m);
		if (!nearly_done(o, &o->dist) || !nearly_done(o, &o->angle))
			break;
		/* SETTLE, and at this very step: the robot may be settled already. */
		enter(o, ORDER_STATE_SETTLE);
		/* fall through */
	case ORDER_STATE_SETTLE:
		if (settled(o, m)) {
			if (o->designation == PROTO_GOTO && (o->options & ORDERS_OPT_BORDER) &&
			    o->cfg.borders) {
				start_border(o, m);
				break;
			}
			end(o, END_REASON_DONE);
			return END_REASON_DONE;
		}
		break;
	case ORDER_STATE_PUSH:
		if (m->basket_contact || m->basket_shock) {
			hold_measured(o, m);
			end(o, END_REASON_BASKET);
			return END_REASON_BASKET;
		}
		if (profile_is_done(&o->dist)) {
			/* The whole push and nothing touched: the basket was not reached. */
			end(o, END_REASON_NO_BASKET);
			return END_REASON_NO_BASKET;
		}
		break;
	case ORDER_STATE_STOPPING:
		if (profile_is_done(&o->dist) && profile_is_done(&o->angle)) {
			end(o, END_REASON_STOPPED);
			return END_REASON_STOPPED;
		}
		break;
	default:
		break;
	}
	return END_REASON_NONE;
}

static void copy_out(struct orders_axis *a, const struct profile_out *p)
{
	a->pos_um = p->pos_um;
	a->vel_um_s = p->vel_um_s;
	a->acc_um_s2 = p->acc_um_s2;
}

/* The braking feed-forward of an axis, against its motion towards the obstacle. */
static int32_t brake_acc(const struct orders *o, uint8_t axis)
{
	return o->shock_side[axis] > 0 ? -o->cfg.grip_um_s2 : o->cfg.grip_um_s2;
}

/* An axis braked while it moves away from the obstacle (rebound()), at v_um_s in the direction
 * dir of the axis: its set point a period on at that speed, the feed-forward braking at the
 * grip, or in proportion below rebound_um_s. A tick's measure reads a creeping robot's speed
 * as 0 or a whole count's: braking it at the grip until it reads 0 would brake on after it has
 * stopped, back towards the obstacle; in proportion it brakes as much as it moves, on average.
 * An axis thrown again once at rest (bit 5 + axis of give_way) reads the low-passed speed
 * only: it is braked in proportion below arrive_speed and two ticks of braking (a time constant
 * of 3 ms on the reference robot, not rebound_um_s's 17 ms, which let a slow spin die out). */
static void brake_away(const struct orders *o, uint8_t axis, struct orders_axis *sp, int32_t v_um_s,
		       int8_t dir)
{
	int32_t acc = o->cfg.grip_um_s2;
	int32_t ref = o->rebound_um_s;

	if (o->give_way & (0x20u << axis)) /* thrown again (give_way_axis()) */
		ref = o->cfg.arrive_speed_um_s + 2 * o->brake_dv_um_s;
	if (v_um_s < ref)
		acc = (acc >> 8) * ((v_um_s << 8) / ref);
	sp->pos_um += dir * (v_um_s / (int32_t)o->rate_hz);
	sp->vel_um_s = dir * v_um_s;
	sp->acc_um_s2 = -dir * acc;
}

uint8_t orders_update(struct orders *o, const struct orders_measure *m)
{
	uint8_t reason = END_REASON_NONE;

#if CONFIG_FIX
	o->aimed = 0;
#endif
	if (o->state != ORDER_STATE_IDLE) {
		if (CONFIG_MOTION_CORNERS && o->curve && !o->paused)
			step_curve(o, m);
		else if (!o->paused)
			reason = update_state(o, m);
	} else if (o->give_way) {
		o->braking = 0;
		give_way_axis(o, 0, &o->dist, m->dist_um, m->dist_speed_um_s);
		give_way_axis(o, 1, &o->angle, m->angle_um, m->angle_speed_um_s);
	}
	if (reason == END_REASON_BASKET)
		return reason; /* setpoints already hold the contact position */
	if (o->state == ORDER_STATE_SQUARE)
		profile_reset(&o->angle,
			      m->angle_um); /* the heading loop relaxed: no angle error */
	copy_out(&o->sp_dist, profile_update(&o->dist));
	if (CONFIG_MOTION_CORNERS && o->curve)
		curve_angle(o);
	else
		copy_out(&o->sp_angle, profile_update(&o->angle));
	if (o->braking) { /* after a shock (give_way_axis()): against the motion */
		if (o->braking & 1u)
			o->sp_dist.acc_um_s2 = brake_acc(o, 0);
		if (o->braking & 2u)
			o->sp_angle.acc_um_s2 = brake_acc(o, 1);
		if (o->braking & 4u)
			brake_away(o, 0, &o->sp_dist, o->away_um_s[0], (int8_t)-o->shock_side[0]);
		if (o->braking & 8u)
			brake_away(o, 1, &o->sp_angle, o->away_um_s[1], (int8_t)-o->shock_side[1]);
	}
	return reason;
}

int orders_basket_pose(const struct orders *o, const struct odometry_pose *estimate,
		       struct odometry_pose *out)
{
	const struct orders_basket *best = 0;
	int64_t best_d2 = 0, ex, ey, along, lateral, lim;
	int32_t s, c, reach;

	/* The basket touched is the one nearest to the switch's estimated position. */
	fx_sincos(estimate->heading_turn32, &s, &c);
	for (uint8_t i = 0; i < o->cfg.n_baskets; i++) {
		const struct orders_basket *b = &o->cfg.baskets[i];
		int64_t dx = (int64_t)b->x_um - estimate->x_um -
			     fx_shr_round64((int64_t)o->cfg.basket_contact_um * c, 30);
		int64_t dy = (int64_t)b->y_um - estimate->y_um -
			     fx_shr_round64((int64_t)o->cfg.basket_contact_um * s, 30);
		int64_t d2 = dx * dx + dy * dy;

		if (!best || d2 < best_d2) {
			best = b;
			best_d2 = d2;
		}
	}
	if (!best)
		return -1;
	/* The front edge touches the circle where its normal is the heading: the basket's centre
	 * is radius + contact offset ahead of the axis midpoint, exactly. Across the heading the
	 * switch only closes within basket_lateral_um of the centre: the estimate's lateral offset
	 * is kept, clamped to that. */
	reach = best->radius_um + o->cfg.basket_contact_um;
	ex = (int64_t)best->x_um - estimate->x_um;
	ey = (int64_t)best->y_um - estimate->y_um;
	along = reach;
	lateral = fx_shr_round64(-ex * s + ey * c, 30);
	lim = o->cfg.basket_lateral_um;
	if (lim > 0 && lateral > lim)
		lateral = lim;
	if (lim > 0 && lateral < -lim)
		lateral = -lim;
	out->heading_turn32 = estimate->heading_turn32;
	out->x_um = best->x_um - (int32_t)fx_shr_round64(along * c - lateral * s, 30);
	out->y_um = best->y_um - (int32_t)fx_shr_round64(along * s + lateral * c, 30);
	return 0;
}

void orders_pause(struct orders *o)
{
	if (o->state == ORDER_STATE_IDLE || o->state == ORDER_STATE_STOPPING || o->paused)
		return;
	o->paused = 1;
	o->paused_target_um[0] = profile_get_target_um(&o->dist);
	o->paused_target_um[1] = profile_get_target_um(&o->angle);
	apply_limits(o); /* the grip's accelerations; on a curve, the curve's */
	profile_stop(&o->dist);
	profile_stop(&o->angle); /* on a curve, the heading follows the line to rest */
}

void orders_resume(struct orders *o)
{
	if (!o->paused)
		return;
	o->paused = 0;
	apply_limits(o);
	profile_set_target(&o->dist, o->paused_target_um[0]);
	profile_set_target(&o->angle, o->paused_target_um[1]);
	if (o->designation == PROTO_GOTO && !o->frozen)
		o->aim_wait = 1; /* re-aim from where it stands, at the next update */
	o->settle_count = 0;
	o->settle_time = 0;
}

void orders_set_speed_scale(struct orders *o, uint8_t percent)
{
	o->scale_percent = percent > 100 ? 100 : percent;
	apply_limits(o);
}

int orders_busy(const struct orders *o)
{
	return o->state != ORDER_STATE_IDLE;
}

int orders_soft(const struct orders *o)
{
	return o->border && (o->state == ORDER_STATE_PUSH || o->state == ORDER_STATE_SQUARE);
}

uint8_t orders_raw_d(const struct orders *o)
{
	if (!o->give_way)
		return 0;
	for (uint8_t i = 0; i < 2; i++)
		if (o->shock_side[i] != 0 && !(o->give_way & (8u << i)))
			return 3;
	return 0;
}

uint8_t orders_expected_shocks(const struct orders *o)
{
	if (o->border && (o->state == ORDER_STATE_PUSH || o->state == ORDER_STATE_SQUARE ||
			  o->state == ORDER_STATE_BACK_OFF))
		return o->cfg.front_shock_mask;
	return 0;
}

int orders_take_recal(struct orders *o, struct orders_recal *r)
{
	if (!o->recal.pending)
		return 0;
	*r = o->recal;
	o->recal.pending = 0;
	return 1;
}
