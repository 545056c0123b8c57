/* What the board's files share (board.h is the public side): board_config.c (defaults and
 * checks), servo.c (board_tick()), planner.c (board_slow()), board.c (init, messages, replies).
 * Each function takes the part of struct board it owns and writes; the others come const. */
#ifndef ASSERV_BOARD_PARTS_H
#define ASSERV_BOARD_PARTS_H

#include "board.h"

#define UM_PER_MM 1000
#define STATUS_END_BITS (STATUS_CHOC_PANIER | STATUS_CHOC_BORD | STATUS_PB_MOTEUR)

/* 0 when board_init() takes cfg (its rates and their relations), or -1. */
int board_config_check(const struct board_config *cfg);

/* Drive track / encoder track [2^-16], for comparing drive-wheel and free-wheel travel. */
int32_t board_free_ratio_q16(const struct board_config *cfg, uint32_t track_um);

/* max(1, encoder track / drive track) [2^-16], rounded up: a free wheel travels that much more
 * than its drive wheel in a turn in place. */
uint32_t board_turn_q16(const struct board_config *cfg, uint32_t track_um);

/* The servo at power-on: counting from in, holding the planner's set points, nothing handed
 * over, no period begun. Returns 0, or -1 when a module refuses its configuration. */
int servo_init(struct servo *s, const struct board_config *cfg, const struct board_inputs *in,
	       const struct orders *orders);

/* A new period: its sums and switches from zero. */
void snapshot_clear(struct board_snapshot *p);

/* The planner at power-on, on the servo's first measure. Returns 0, or -1 when a module
 * refuses its configuration. */
int planner_init(struct planner *pl, const struct board_config *cfg, const struct board_inputs *in,
		 int32_t dist_um);

/* The measure at the end of period p, whose sums and switches are in p (m->pose: the
 * planner's own). */
void planner_measure(const struct planner *pl, const struct board_config *cfg,
		     const struct board_snapshot *p, struct orders_measure *m);

/* The running order's bits of the status. */
void planner_update_status(struct planner *pl);

/* A new estimate, at once (SET_NEW_POS, a recalibration). */
void planner_set_pose(struct planner *pl, const struct odometry_pose *pose);

/* New gains for the servo's PIDs, handed over with draft (their integrals kept). */
void planner_set_gains(struct planner *pl, struct board_handover *draft,
		       const struct control_gains *g);

/* A message from the master, in the planner's step 3 (board.c). */
void board_apply(struct planner *pl, struct mailbox *mb, const struct board_config *cfg,
		 const struct proto_msg *msg);

/* Start an order now (board.c): the end bits cleared, the orders' state machine on it. */
void board_start_order(struct planner *pl, const struct proto_msg *msg);

/* Match play (motion.c), at the planner's steps: */
void motion_init(struct motion *mo, const struct board_config *cfg, const struct orders *o,
		 uint16_t slow_hz);
/* step 3: an order (GOTO, GOTO_REVERSE, GOTO_PANIER, STOP, PAUSE, RESUME): numbered, queued
 * with APPEND, or run at once; one refused for PB_GRAVE ends FAULT; SET_SPEED_SCALE and
 * SET_CORNER. */
void motion_order(struct planner *pl, const struct proto_msg *msg);
void motion_refused(struct planner *pl, const struct proto_msg *msg);
void motion_setting(struct planner *pl, const struct proto_msg *msg);
/* step 5, before the orders: a pass-through corner's extension, and its switch to the next
 * order at the corner; after them: an order that ended runs the next one, or drops the queue. */
void motion_before(struct planner *pl, const struct board_config *cfg);
void motion_after(struct planner *pl);
/* step 7: MOTION's reply, and CHECK_BUSY's end bits of a queued order's predecessor. */
void motion_publish(const struct planner *pl, struct proto_snapshot *s);

/* SET_ODOMETRIE's calibration, checked, its wheels derived for the servo (board.c). */
int board_calibrate(struct planner *pl, struct board_wheels *w, const struct board_config *cfg,
		    const struct board_calibration *cal);

/* The reply snapshot of the planner's last period p, drafted in proto (proto_draft()): the
 * caller flips it public. */
void board_publish(const struct planner *pl, const struct board_snapshot *p, struct proto *proto);

#endif
