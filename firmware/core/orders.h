/* Orders: GOTO, GOTO_REVERSE, GOTO_PANIER and STOP as a state machine that drives two motion
 * profiles, one per polar axis. Both axes are in [um]: the distance axis is the travel of the
 * encoder-wheel midpoint, the angle axis is the heading as an arc at the drive wheels
 * (heading [rad] * drive track / 2), so one set of PID gains means the same on both. */
#ifndef ASSERV_ORDERS_H
#define ASSERV_ORDERS_H

#include <stdint.h>

#include "feature_set.h"
#include "odometry.h"
#include "profile.h"

#define ORDERS_MAX_BASKETS 4

/* GOTO's option bits (the specification's "recalage ligne" and "recalage contact"). */
#define ORDERS_OPT_LINE 0x01u
#define ORDERS_OPT_BORDER 0x02u

/* A basket seen from above: a circle the front contact switch touches. */
struct orders_basket {
	int32_t x_um;
	int32_t y_um;
	int32_t radius_um;
};

struct orders_config {
	uint32_t drive_track_um;        /* between the drive wheels' contact points */
	uint32_t heading_window_turn32; /* GOTO translates once the heading error is below this */
	int32_t freeze_radius_um;       /* within this distance of the target, no re-aiming */
	int32_t arrive_window_um;       /* settled when both following errors are below this */
	int32_t arrive_speed_um_s;      /* ... and both measured speeds below this */
	uint16_t settle_ms;             /* ... for this long (consecutive updates) */
	uint16_t settle_timeout_ms;     /* an order ends DONE after this long in SETTLE anyway */
	int32_t push_speed_um_s;   /* GOTO_PANIER's approach speed (capped by the traj limit) */
	int32_t push_max_um;       /* GOTO_PANIER gives up (PB_MOTEUR, NO_BASKET) after this */
	int32_t basket_contact_um; /* from the encoder axis midpoint to the basket switch */
	uint8_t n_baskets;
	struct orders_basket baskets[ORDERS_MAX_BASKETS];
	/* Planner steps between the one that takes a GOTO and its first aim, 0 or 1: 0 turns or
	 * translates at once; 1 spreads the order's first work over two steps, which the AVR's
	 * 125 Hz planner needs to keep its CPU budget (firmware/ports/avr/robot.c). */
	uint8_t aim_delay_steps;
	uint32_t jerk_um_s3; /* 0: trapezoids; else S-curves with this jerk on both axes */
	/* The acceleration the drive wheels' grip allows [um/s^2] (mu g times the weight's share
	 * on the drive wheels), 100000..50000000: the braking after a shock. */
	int32_t grip_um_s2;
	/* The friction circle, along the wheels: a wheel pushes the body with m a / 2 for the
	 * distance axis and 2 I a' / track^2 for the angle axis (a' its arc acceleration), so the
	 * grip holds while a + k a' <= grip_um_s2, k = 4 I / (m track^2) [2^-8], 1..65535. */
	uint16_t rot_grip_q8;

	/* Basket recalibration: the basket switch closes only when the basket's centre is within
	 * this of the robot's heading line (set by the switch's width; 0: no lateral constraint).
	 */
	int32_t basket_lateral_um;
	uint32_t basket_bound_um; /* residual along the approach after a basket contact */

	/* Border recalibration (GOTO option bit 1). The field's borders: x = +/- half length,
	 * y = +/- half width [um]; no border recalibration when borders is 0. */
	uint8_t borders;
	int32_t half_length_um;
	int32_t half_width_um;
	int32_t front_um;                     /* from the encoder axis midpoint to the front edge */
	uint8_t front_shock_mask;             /* the shock sensors on the front edge */
	int32_t border_speed_um_s;            /* approach speed (capped by the traj limit) */
	int32_t border_extra_um;              /* gives up this far past the expected contact */
	int32_t border_block_um;              /* a following error this large is a contact too */
	int32_t border_depth_um;              /* the push: setpoint this far past the contact */
	uint16_t square_ms;                   /* the push lasts this long, heading loop relaxed */
	int32_t backoff_um;                   /* then backs off this far */
	uint32_t border_bound_um;             /* residual of the coordinate across the border */
	uint32_t border_heading_bound_turn32; /* residual of the heading once squared up */
};

/* A recalibration the state machine asks the board to apply (orders_take_recal()). */
struct orders_recal {
	uint8_t pending;
	uint8_t axis;              /* 0: x known, 1: y known */
	struct odometry_pose pose; /* the estimate with the coordinate and the heading set */
};

/* The setpoint of one axis for this tick, for the controller. */
struct orders_axis {
	int32_t pos_um;
	int32_t vel_um_s;
	int32_t acc_um_s2;
};

/* A pass-through corner's curve (docs/control.md "Corners"), planned by motion.c: the distance
 * axis at most v_um_s, accelerating at most a_um_s2, and the heading slaved to the distance
 * travelled along a clothoid (clothoid_um), an arc (arc_um) and a clothoid back, turn_um in all
 * on the angle axis (signed; the heading of the next line, set when the curve starts). */
struct orders_curve {
	int32_t v_um_s;
	int32_t a_um_s2;
	int32_t clothoid_um;
	int32_t arc_um;
	int32_t turn_um;
	int32_t rest_um; /* the line after the curve, to its point */
};

/* What the state machine needs to know of the robot this tick. */
struct orders_measure {
	struct odometry_pose pose; /* estimate */
	int32_t dist_um;           /* distance axis */
	int32_t angle_um;          /* angle axis */
	int32_t dist_speed_um_s;   /* measured, for the settle test */
	int32_t angle_speed_um_s;
	uint8_t basket_contact;
	uint8_t basket_shock; /* a basket-side shock sensor is pressed */
	uint8_t shocks;       /* the shock sensors, bit n = CAPTEUR_n */
};

struct orders {
	struct orders_config cfg;
	int32_t pi_track_um; /* pi * drive track: one turn of heading on the angle axis */
	struct profile dist;
	struct profile angle;
	struct profile_limits traj; /* SET_VITESSE_TRAJ */
	struct profile_limits rot;  /* SET_VITESSE_ROT */
	/* Their accelerations within the grip (orders.c); [2], [3]: PAUSE's, the grip's shares
	 * whatever the master set. */
	int32_t grip_a_um_s2[4];
	uint8_t designation; /* the running or last order, PROTO_NONE before the first */
	uint8_t state;       /* ORDER_STATE_* */
	uint8_t end_reason;  /* END_REASON_* of the last order that ended */
	uint8_t options;     /* GOTO options */
	int32_t target_x_um;
	int32_t target_y_um;
	uint32_t target_heading_turn32;
	int32_t push_start_um;
	/* cfg's durations in updates (at rate_hz) */
	uint16_t settle_ticks;
	uint16_t settle_timeout_ticks;
	uint16_t square_ticks;
	uint16_t settle_count;
	uint16_t settle_time;
	uint8_t frozen; /* GOTO within the freeze radius: targets no longer follow the estimate */
	/* A running GOTO re-aims every aim_period ticks (rate_hz / 250, at least 1): its targets
	 * are points of the axes that move little from one tick to the next. */
	uint8_t aim_period;
	uint8_t aim_wait; /* ticks until the next re-aim */
	/* The last bearing of the target and the estimated position it was computed from. */
	uint8_t bearing_valid;
	int32_t bearing_x_um;
	int32_t bearing_y_um;
	uint32_t bearing_turn32;
	/* The last estimated heading projected on, and its sine and cosine [2^-30]. */
	uint8_t trig_valid;
	uint32_t trig_turn32;
	int32_t trig_sin_q30;
	int32_t trig_cos_q30;
	struct orders_axis sp_dist;
	struct orders_axis sp_angle;
	/* Border recalibration in progress: the border faced (0 +X, 1 +Y, 2 -X, 3 -Y) and the
	 * ticks of the push. */
	uint8_t border;
	uint8_t border_side;
	uint16_t square_count;
	struct orders_recal recal;
	/* After a shock, until the next order: the side of the obstacle on each axis (distance,
	 * angle: 1 ahead, -1 behind, 0 none), where the hold never pulls the robot back to
	 * (orders_shock()); gave_way is set when a hold point moved away from it. */
	uint8_t give_way; /* bit 0: on; bit 1 + axis: that axis has stopped; bit 3 + axis: and
			   * then come to rest after any rebound; bit 5 + axis: thrown again */
	int8_t shock_side[2];
	uint8_t gave_way;
	uint8_t braking;         /* bit axis: brake at grip_um_s2 this tick (the feed-forward);
				  * bit 2 + axis: brake that axis's motion away, at away_um_s */
	int32_t away_um_s[2];    /* each axis's speed away from the obstacle, braked this tick */
	int32_t rebound_um_s;    /* faster away than this, a rebound is braked at the grip */
	uint8_t rest_ticks;      /* an axis has stopped after this many ticks of no progress */
	uint8_t still[2];        /* ticks since each axis last went further towards the obstacle */
	int32_t brake_dv_um_s;   /* the speed a tick of braking at grip_um_s2 takes away */
	uint16_t brake_ticks[2]; /* what braking at grip_um_s2 from the shock's speed takes */
	int32_t reach_um[2];     /* how far each axis went towards the obstacle */
	int32_t rest_um[2];      /* at rest after its rebound: where it was up to rest_ticks ago */
	int32_t throw_um;        /* moved away from there by more, it is thrown again (0 never) */
	int32_t speed_q[2];      /* each axis's speed [um/s], low-passed over 2^speed_shift ticks,
				  * in Q speed_shift (give_way_axis()) */
	uint8_t speed_shift;     /* log2 rest_ticks: 0 where a tick reads the speed (AVR rates) */
	uint16_t rate_hz;        /* orders_update() calls per second */
	/* Match play (motion.c): a paused order keeps its state and its targets, its profiles
	 * braked to rest; the speed scale [%] of both axes' speed limits; a pass-through corner's
	 * extension of GOTO's distance target past its point [um]. */
	uint8_t paused;
	uint8_t scale_percent;
	int32_t paused_target_um[2];
	int32_t through_um;
	/* A GOTO that started on a pass-through corner's curve (orders_curve_start()): in ROTATE,
	 * the angle set point a function of the distance set point from (curve_d0, curve_a0) on,
	 * until the curve's length; then TRANSLATE. */
	uint8_t curve;
	struct orders_curve cv;
	int32_t curve_d0;
	int32_t curve_a0;
#if CONFIG_MOTION_CORNERS
	/* A GOTO that started on a pass-through corner's pivot (orders_pivot_start()): its line
	 * starts once the heading is within this of the bearing and the heading's rate brakes. */
	uint32_t pivot_turn32;
#endif
#if CONFIG_FIX
	/* The last orders_update() re-aimed a GOTO: a heavy period, which a position fix's fusion
	 * does not share (planner.c, step 6). */
	uint8_t aimed;
#endif
};

/* 1 when the last orders_update() re-aimed a GOTO (0 where the fixes are compiled out). */
static inline uint8_t orders_aimed(const struct orders *o)
{
#if CONFIG_FIX
	return o->aimed;
#else
	(void)o;
	return 0;
#endif
}

/* Power-on: no order, holding (dist_um, angle_um); limits 10 cm/s, 40 cm/s^2 on both axes;
 * updated rate_hz times a second; count_um_s: the speed one free-wheel count over an update
 * reads (the odometry's, rounded up). Returns 0 or -1 when the configuration is out of range.
 * Interrupt-safe: no. */
int orders_init(struct orders *o, const struct orders_config *cfg, uint16_t rate_hz,
		int32_t count_um_s, int32_t dist_um, int32_t angle_um);

/* SET_VITESSE_TRAJ / SET_VITESSE_ROT: new limits [cm/s], [cm/s^2] (0 leaves one unchanged);
 * a running profile replans from where it is. Interrupt-safe: no. */
void orders_set_traj_limits(struct orders *o, uint8_t speed_cm_s, uint8_t accel_cm_s2);
void orders_set_rot_limits(struct orders *o, uint8_t speed_cm_s, uint8_t accel_cm_s2);

/* Start an order; a running one is replaced smoothly (the profiles continue from their current
 * velocity). Interrupt-safe: no. */
void orders_goto(struct orders *o, const struct orders_measure *m, int32_t x_um, int32_t y_um,
		 uint8_t options);
void orders_goto_reverse(struct orders *o, const struct orders_measure *m, int32_t distance_um);
void orders_goto_panier(struct orders *o, const struct orders_measure *m, uint32_t heading_turn32);
void orders_stop(struct orders *o);

/* End the running order at once (shock, motor fault): both setpoints jump to the measured
 * position with zero velocity, so the controller stops driving in the same tick. */
void orders_abort(struct orders *o, const struct orders_measure *m, uint8_t end_reason);

/* End the running order on a shock: as orders_abort(), then, until the next order, a stop that
 * stops (docs/control.md "After a shock"). The obstacle is on the side each axis moved towards
 * (m's speeds, else the set points' velocities). Each such axis brakes with the grip's
 * deceleration as a feed-forward for as long as that takes from the set point's speed, while it
 * still goes towards the obstacle (within the last 4 ms); once it has gone no
 * further for 8 ms (rest_ticks), its hold point moves to where it stopped. If it bounced off,
 * until it has not moved away for rest_ticks, it is braked along its motion away, at the grip
 * above rebound_um_s and in proportion to the speed read below, its hold point going with it.
 * Thrown away again at rest (by more than throw_um within twice rest_ticks: a second corner's
 * contact), it is braked so again, in proportion below arrive_speed and two ticks of braking
 * only. From then on, a robot on the far side of its hold point by more than throw_um (two
 * counts, 0 at the AVR's rates) and about to stop moving away (slower than arrive_speed and two
 * ticks of braking) is held where it is: the hold pulls it back towards the obstacle by
 * throw_um at most (a creep's counts). At 1 kHz these speeds are low-passed over rest_ticks
 * (speed_q). gave_way tells the board that a hold point moved (the integrals go).
 * Interrupt-safe: no. */
void orders_shock(struct orders *o, const struct orders_measure *m, uint8_t end_reason);

/* One tick: advance the state machine and the profiles; fills sp_dist and sp_angle.
 * Returns END_REASON_NONE, or the reason when the order ended during this tick (for
 * END_REASON_BASKET the caller recalibrates from orders_basket_pose()). */
uint8_t orders_update(struct orders *o, const struct orders_measure *m);

/* After a basket contact: the pose the basket's geometry gives (docs/recalibration.md): the
 * coordinate along the heading from the circle and the contact offset, the lateral offset of the
 * basket's centre clamped to +/- basket_lateral_um, the heading kept (a point contact on a circle
 * does not measure it). Returns 0, or -1 with no basket configured. */
int orders_basket_pose(const struct orders *o, const struct odometry_pose *estimate,
		       struct odometry_pose *out);

/* PAUSE: both profiles brake to rest at their limits (within the grip) and hold; the order keeps
 * its state and its targets, and does not advance. Nothing when idle or stopping, or paused.
 * Interrupt-safe: no. */
void orders_pause(struct orders *o);

/* RESUME: the paused order goes on to the same targets from where the robot stands (a GOTO
 * re-aims at its next update). Nothing when not paused. Interrupt-safe: no. */
void orders_resume(struct orders *o);

/* A GOTO that has just started (ROTATE) from the moving robot at a pass-through corner turns on
 * curve c instead of in place: the distance axis keeps going at c's speed while the heading
 * turns to heading_turn32 along the curve (docs/control.md "Corners"), then TRANSLATE. Nothing
 * for another order or state. Interrupt-safe: no. */
void orders_curve_start(struct orders *o, const struct orders_measure *m,
			const struct orders_curve *c, uint32_t heading_turn32);

/* A GOTO that has just started (ROTATE) from the moving robot at a pass-through corner's pivot
 * (docs/control.md "Corners", 6): the distance axis goes on to stop_um (the last point) while
 * the heading turns, and the line starts once the heading is within turn32 of its bearing, its
 * rate braking, the distance axis at rest. Nothing for another order or state. Interrupt-safe:
 * no. */
void orders_pivot_start(struct orders *o, int32_t stop_um, uint32_t turn32);

/* 1 from a pivot's start (orders_pivot_start()) until its turn is over (its line's heading
 * at rest) or another order begins; 0 without the corners. */
static inline int orders_pivoting(const struct orders *o)
{
#if CONFIG_MOTION_CORNERS
	return o->pivot_turn32 != 0;
#else
	(void)o;
	return 0;
#endif
}

/* SET_SPEED_SCALE: both axes' speed limits times percent / 100 (at least 1 um/s), at once,
 * also for the running order (it slows down at its acceleration limit). Interrupt-safe: no. */
void orders_set_speed_scale(struct orders *o, uint8_t percent);

/* 1 while an order runs (BUSY_TRAJET). */
int orders_busy(const struct orders *o);

/* 1 while a border recalibration pushes (FILTRE_SOUPLE's gains apply). */
int orders_soft(const struct orders *o);

/* After a shock, until each axis that went towards the obstacle has come to rest after any
 * rebound (orders_shock()): 3 (bit 0 distance, bit 1 angle), the PIDs of both axes read the raw
 * derivative, not its low-pass (docs/control.md "PID"), whose lag behind a hard braking, or a
 * spin the contact gave, would drive the robot on once it has stopped; else 0. */
uint8_t orders_raw_d(const struct orders *o);

/* The shock sensors an order expects to close (the front ones against the border). */
uint8_t orders_expected_shocks(const struct orders *o);

/* The recalibration asked for this tick, if any (then cleared). Returns 1 and fills r, or 0. */
int orders_take_recal(struct orders *o, struct orders_recal *r);

#endif
