/* The board: odometry, orders, motion profiles, control and stop conditions. A port samples its
 * inputs, calls board_tick() once per control period and applies the outputs, and runs
 * board_slow() when board_slow_due(); its I2C interrupt talks to &board.proto (protocol.h).
 *
 * Two steps (docs/architecture.md, "Two steps"): board_tick() is the servo (odometry, set
 * points, the two PIDs, the duties), every tick; board_slow() is the planner (messages, stop
 * conditions, orders and profiles, pose, error radius, recalibrations, reply snapshot), every
 * 2^slow_shift ticks, on a snapshot the servo took at the period's end; the servo takes its
 * results planner_ticks ticks after that snapshot. One rate (slow_shift 0) is the same code with
 * a period of one tick. With planner_ticks 0 board_tick() runs board_slow() itself between the
 * snapshot and the hand-over; otherwise a port runs it in a lower-priority context (the AVR's
 * main loop, preempted by the servo's interrupt), and the results do not depend on when it
 * runs, as long as it is done within planner_ticks. */
#ifndef ASSERV_BOARD_H
#define ASSERV_BOARD_H

#include <stdint.h>

#include "control.h"
#include "faults.h"
#include "motion.h"
#include "fix.h"
#include "keep.h"
#include "odometry.h"
#include "orders.h"
#include "protocol.h"
#include "recal.h"
#include "uncertainty.h"

/* What the port samples before each tick (hal/ gives the meaning of each). */
struct board_inputs {
	uint16_t free_count[2];  /* free encoder wheels, [counts], wrapping */
	uint16_t motor_count[2]; /* drive motor encoders, [counts], wrapping */
	int16_t current_ma[2];
	uint8_t shocks; /* bit n = CAPTEUR_n pressed */
	uint8_t basket; /* 1 = basket contact closed */
	uint8_t lines;  /* bit n = line sensor n sees a line */
};

/* What the port applies after each tick. */
struct board_outputs {
	int16_t duty_q15[2];
};

/* The bounds of the odometry's calibration residuals, as uncertainty_model states them. */
struct board_residuals {
	uint32_t ratio_error_ppm; /* right/left wheel factor ratio [1e-6] */
	uint32_t track_error_um;  /* encoder track, including the common scale's effect [um] */
	uint32_t scale_error_ppm; /* common wheel factor [1e-6] */
};

/* An odometry calibration (SET_ODOMETRIE's arguments, docs/calibration.md): what a port stores
 * to install it again at the next power-on. */
struct board_calibration {
	int32_t ratio_ppm; /* -30000..30000 */
	int32_t scale_ppm; /* -30000..30000 */
	uint16_t track_10um;
};

struct board_config {
	uint16_t tick_hz; /* control rate, 100..2000: the servo's; the planner's is >> slow_shift */
	uint8_t slow_shift; /* the planner every 2^slow_shift ticks, 0..3, at 100 Hz or more */
	/* The servo takes the planner's results this many ticks after the snapshot they work
	 * on, 0..2^slow_shift: the time a port gives them. 0: board_tick() runs the planner itself,
	 * between the snapshot and the hand-over (one context: the host, the STM32, the AVR at one
	 * rate); the AVR at 125 Hz runs it in its main loop, preempted by the servo: 3. */
	uint8_t planner_ticks;
	struct odometry_config
		odometry; /* the build's nominal wheels (SET_ODOMETRIE scales them) */
	struct uncertainty_config uncertainty;
	/* The residual bounds of the odometry's model: of a calibrated robot, and of one whose
	 * odometry is not calibrated (the build's nominal wheel factors and track against the real
	 * wheels). The error radius uses uncalibrated's until a calibration is installed. */
	struct board_residuals calibrated;
	struct board_residuals uncalibrated;
	struct control_config control;
	struct faults_config faults;
	struct orders_config orders;
	struct recal_config recal;
	struct odometry_pose start; /* the specification: x 0, at the end of the field, angle 0 */
	/* How well the robot is placed at the start (bounds at the uncertainty's probability):
	 * the error radius starts from them. 0 and 0: the start pose is the reference. */
	uint32_t start_radius_um;
	uint32_t start_heading_bound_turn32;
	/* What the odometry may not see, by which the error radius widens: a slide sideways in a
	 * collision, decelerated by the wheels' friction; a free wheel that does not count. */
	struct board_unseen {
		uint32_t slide_decel_mm_s2; /* 0: no widening at a collision */
		uint32_t reach_um; /* the outline's farthest point from the encoder axis midpoint */
		/* a free wheel silent while its motor travels this much net travels unseen */
		uint32_t silent_min_um;
	} unseen;
};

/* What the servo hands the planner at the end of a period (the mailbox's up half): the measure
 * of that tick and the sums of the period since the last one. */
struct board_snapshot {
	struct board_inputs in; /* of that tick, but shocks and basket: pressed at any tick of it */
	int32_t dist_um;        /* the distance axis at the period's end */
	int32_t angle_um;       /* the angle axis at the period's end */
	/* The sums of the ticks' steps over the period, modulo 2^32 (a period's are far below: 8
	 * ticks of at most 32.8 mm; they would wrap after 2 km in one period, the planner
	 * stuck). The free wheels' travels are the planner's, from in.free_count (a period's
	 * count change is read as a signed 16-bit one: 8 ticks at 2.5 m/s are 256 counts). */
	int32_t ds_um;         /* distance axis change over the period */
	int32_t arc_um;        /* angle axis change over the period */
	int32_t dtheta_turn32; /* heading change over the period */
	int32_t sp_dist_um;    /* the servo's set points at that tick */
	int32_t sp_angle_um;
	int32_t dist_err_um; /* the control's, for DEBUG */
	int32_t angle_err_um;
	int16_t duty_q15[2];
	struct recal_edges edges; /* the line sensors' edges of the period */
	uint16_t tick;
	uint8_t encoder_fault; /* a wheel jumped at a tick of the period */
	/* SET_ODOMETRIE's wheels installed at the period's last tick, after its travel: the
	 * period's counts are worth the factors before, kept here (odometry_wheel.k). */
	uint8_t wheels_replaced;
	uint16_t wheel_k[2][2];
	uint8_t msg_head; /* the messages queued until then; later ones wait a period */
};

/* What the planner hands the servo (the mailbox's down half), taken planner_ticks after the
 * snapshot it worked on: the set points of both axes for the end of the next period, the step
 * per tick that takes the servo there from the last ones, and what else changes at once. */
struct board_handover {
	struct orders_axis dist;
	struct orders_axis angle;
	struct orders_axis dist_step;
	struct orders_axis angle_step;
	struct control_gains gains; /* with set_gains */
	uint8_t set_gains;
	uint8_t reset;      /* forget the PIDs' integrals */
	uint8_t jump;       /* the set points at once, not over the period (a stop: hold here) */
	uint8_t motors_off; /* PB_GRAVE or PB_MOTEUR: no control until the next order */
#if CONFIG_QUIET_SERVO
	uint8_t raw_d; /* bit axis: its PID's raw derivative (orders_raw_d()) */
#endif
	uint8_t publish; /* a reply snapshot is drafted (proto_draft()) */
};

/* SET_ODOMETRIE's wheels, derived by the planner (the costly part), installed by the servo at
 * the end of a period after its travel. Not double-buffered: 780 bytes, and the planner writes
 * them only while pending is 0. */
struct board_wheels {
	struct odometry_config cfg;
	struct odometry_wheel wheels[2];
	uint8_t pending;
};

/* The servo: what board_tick() owns and writes, every tick. */
struct servo {
	struct odometry_counter counter;
	struct control control; /* with the gains in effect */
	/* The angle axis: the exact sum of the heading steps [turn * 2^32] times pi * drive track
	 * [um], i.e. [um * 2^32], as hi 2^32 + lo (hi an int32_t modulo 2^32). */
	uint32_t angle_hi;
	uint32_t angle_lo;
	int32_t angle_um;           /* the angle axis, rounded */
	int32_t arc_um;             /* this tick's heading step on the angle axis, rounded */
	int32_t pi_track_um;        /* pi * drive track, as the planner's orders have it */
	struct orders_axis sp_dist; /* the set points of this tick */
	struct orders_axis sp_angle;
	struct recal_sense lines; /* the line sensors' state for timing their edges */
	uint16_t tick;
	uint16_t slow_overruns; /* hand-overs that waited for board_slow() past planner_ticks */
	uint8_t slow_mask;      /* 2^slow_shift - 1 */
	uint8_t line_mask;      /* the line sensors in use */
	uint8_t motors_off;     /* handed over: the duties stay 0 */
	uint8_t phase;          /* ticks into the set points' period, 1..2^slow_shift */
	uint8_t since_snapshot; /* ticks since the last snapshot (saturated) */
	uint8_t awaiting;       /* a snapshot is out: its hand-over is not taken yet */
	struct board_outputs last_out;
};

/* The planner: what board_slow() owns and writes, once a period. */
struct planner {
	struct odometry_position position;
	struct orders_measure m; /* the snapshot's measure, as the planner corrected it: m.pose is
				  * the estimate */
	struct uncertainty uncertainty;
	struct orders orders;
	struct faults faults;
	struct recal recal;
	uint8_t soft;                     /* FILTRE_SOUPLE's gains put in by a border push */
	struct control_gains gains;       /* in effect, or handed over to be */
	struct control_gains saved_gains; /* ... and the gains a border push replaced */
	uint16_t slow_hz;                 /* tick_hz >> slow_shift */
	int32_t free_ratio_q16;           /* drive track / encoder track [2^-16] */
	uint8_t shocks;                   /* the snapshot's shock sensors */
	uint16_t free_base[2];            /* the free wheels' counts at the last period's end */
	uint8_t status;                   /* STATUS_* owned by the core */
	uint32_t timeout_ticks;           /* SET_TIMEOUT [slow ticks], 0: off (power-on) */
	uint32_t silent_ticks;            /* [slow ticks] since the master's last accepted write */
	uint8_t fed;                      /* an accepted write this period (step_silence()) */
	uint8_t timed_out;                /* the last order was stopped by the timeout */
	uint8_t calibrated;               /* a calibration is installed: calibration holds it */
	uint8_t boot_request;             /* BOOTLOADER accepted: the port enters its bootloader */
	struct board_calibration calibration;
	uint16_t motor_base[2]; /* the motors' counts at the last period's end */
	/* Since each free wheel last counted: its motor's net travel, and how much of it has
	 * widened the error radius [motor counts] (silent_wheels()). */
	int32_t silent_counts[2];
	uint32_t silent_widened[2];
	uint32_t silent_min_counts; /* faults.lost_min_um in motor counts */
	uint32_t silent_turn_q16;   /* max(1, encoder track / drive track) [2^-16] */
	struct motion motion;       /* match play: the queue, the pause, the scale (motion.c) */
	struct fix fix;             /* the pose history and the fixes (SET_FIX) */
	struct board_reset {
		uint8_t tracked;    /* the port reports its resets (board_restart()) */
		uint8_t cause;      /* RESET_CAUSE_* of the last start */
		uint8_t count;      /* resets since power-on, saturating */
		uint8_t pose_lost;  /* motion orders refused until SET_NEW_POS */
		uint8_t widened_mm; /* the radius's widening for the time the board was down */
	} reset;
};

/* Between the two: each half a double buffer of one type. up[up_index] is the period the servo
 * sums, up[up_index ^ 1] the last one, the planner's input; down[down_index] the servo's set
 * points, down[down_index ^ 1] the planner's draft of the next ones. slow_due passes the turn:
 * set by the servo with a snapshot, cleared by the planner when its draft is complete. */
struct mailbox {
	struct board_snapshot up[2];
	struct board_handover down[2];
	struct board_wheels wheels;
	uint8_t up_index;
	uint8_t down_index;
	volatile uint8_t slow_due;
};

struct board {
	struct board_config cfg; /* read-only after board_init() */
	struct proto proto;      /* shared with the I2C interrupt */
	struct servo servo;
	struct mailbox mailbox; /* beside the servo, which reads it every tick */
	struct planner planner;
	/* What survives a reset (keep.h): last, and left as it is by board_init(), so that a port
	 * that keeps struct board in RAM its start-up does not clear finds it at board_restart().
	 * Written at every planner period once board_restart() has run. */
	struct board_keep keep;
};

/* Defaults for the reference robot (docs/control.md): 25 mm free wheels at 2000 counts/rev,
 * 280 mm encoder track, 160 mm drive track, motors that reach 1.6 m/s at full duty, 1 kHz. */
void board_default_config(struct board_config *cfg);

/* Power-on: the pose at cfg->start, the specification's initial limits (10 cm/s, 40 cm/s^2),
 * FILTRE_STD, no order; in gives the encoder counts to start from (no jump at the first tick).
 * Every field of b but b->keep is set, whatever b held: b is cleared first, as a chip's start-up
 * clears its RAM, so cfg must not point into b. Returns 0, or -1 when the configuration is out of
 * range. Interrupt-safe: no. */
int board_init(struct board *b, const struct board_config *cfg, const struct board_inputs *in);

/* A start that knows why (keep.h): board_init(), then after any reset but a power-on the pose
 * and the radius that keep held resume, the radius widened by what the robot may have
 * travelled in down_ms (the time the board was down, start-up included) at the speed it had;
 * the status reads PB_MOTEUR, DEBUG end_reason RESET, idle or not, until the next order (an
 * order may have been abandoned, and the settings are the power-on ones). When keep does not
 * hold a valid record, the pose is lost: the radius reads 255 and motion orders are refused
 * (REFUSED_NO_POSE) until SET_NEW_POS. A power-on (cause RESET_CAUSE_POWER_ON) is board_init()
 * exactly. From then on the planner writes b->keep at every period; the port keeps b in RAM its
 * start-up does not clear. Returns board_init()'s result. Interrupt-safe: no. */
int board_restart(struct board *b, const struct board_config *cfg, const struct board_inputs *in,
		  uint8_t cause, uint16_t down_ms);

/* Install an odometry calibration, as SET_ODOMETRIE does (a port calls it after board_init()
 * with the one it stored). The pose is kept; the error radius keeps what it has accumulated and
 * uses the calibrated residual bounds from then on. Returns 0, or -EDOM when the factors fall
 * outside the odometry's ranges (nothing changes). Interrupt-safe: no (from the planner's
 * context, or before the first tick). */
int board_set_calibration(struct board *b, const struct board_calibration *cal);

/* One control period, the servo: encoders -> odometry -> period sums -> (the period's end: the
 * snapshot, and the planner itself with planner_ticks 0) -> (planner_ticks after the snapshot:
 * the hand-over) -> set points -> control -> outputs. Interrupt-safe: it is the control
 * interrupt; it must not be re-entered. */
void board_tick(struct board *b, const struct board_inputs *in, struct board_outputs *out);

/* 1 when the next board_tick() ends a period (a slow tick: every tick with slow_shift 0). Only
 * then does it read the inputs of the period's end, in->motor_count and in->current_ma (the
 * snapshot's, for the stop conditions and the replies): a port may leave them unsampled at the
 * other ticks. Interrupt-safe: from the context that calls board_tick(). */
static inline int board_period_ends(const struct board *b)
{
	return (b->servo.tick & b->servo.slow_mask) == 0;
}

/* The estimate of the robot's pose (what POSITION reports, at full resolution): the planner's
 * own, as of the last period it ran. Interrupt-safe: from the planner's context. */
static inline struct odometry_pose board_get_pose(const struct board *b)
{
	return b->planner.m.pose;
}

/* 1 when board_slow() has a snapshot to work on. Interrupt-safe: yes. */
static inline int board_slow_due(const struct board *b)
{
	return b->mailbox.slow_due != 0;
}

/* The planner, on the last snapshot: pose -> error radius -> line recalibration -> messages ->
 * the master's silence -> stop conditions -> orders -> profiles -> border/basket recalibration
 * -> reply snapshot. A port calls it when board_slow_due(), and it must end within planner_ticks
 * ticks (otherwise the servo counts a slow_overrun and takes its results when it ends).
 * Interrupt-safe: it may be preempted by board_tick(), not re-entered. */
void board_slow(struct board *b);

#endif
