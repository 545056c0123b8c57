/* Position fixes (SET_FIX): a short history of the planner's poses, so that a fix measured
 * age_ms ago is compared with the estimate of that moment, fused with the error radius's
 * covariance (uncertainty_fuse_begin(), over five periods), and its correction carried to now.
 * docs/strategy.md shows a master feeding its lidar's fixes; docs/protocol.md the message.
 *
 * CONFIG_FIX 0 (the AVR's build: its CPU budget has no room) compiles it out: the protocol layer
 * rejects SET_FIX and FIX_INFO as UNSUPPORTED and VERSION's CAP_FIX reads 0. */
#ifndef ASSERV_FIX_H
#define ASSERV_FIX_H

#include <stdint.h>

#include "feature_set.h"
#include "odometry.h"
#include "uncertainty.h"

/* One pose kept every FIX_SPACING_MS (rounded up to planner periods): 64 cover 630 ms or more,
 * beyond SET_FIX's 500 ms of age. */
#define FIX_SPACING_MS 10
#define FIX_HISTORY_N (CONFIG_FIX ? 64 : 1)
/* The gate: a squared Mahalanobis distance over 16 is an outlier (1 in 3 000 good fixes with a
 * heading, 1 in 3 000 000 without, when the noises are as declared). */
#define FIX_GATE_Q8 (16u << 8)
/* After this many outliers in a row the estimate, not the fixes, is taken to be wrong: the next
 * fix is fused with the radius first widened to reach it. */
#define FIX_YIELD_AFTER 5
/* Fixes that may wait for the error radius at once (20 Hz with jitter: 2 in 20 ms). */
#define FIX_QUEUE (CONFIG_FIX ? 4 : 1)
/* History entries a planner period moves with a fused fix's correction: the estimate now moves
 * at once, the entries since the measured time over the next periods (a 500 ms old fix's 50
 * entries in 7 periods at 1 kHz), and the next fix waits for them. One period's carrying stays
 * within the CPU budget (bench/stm32.py --fixes). */
#define FIX_CARRY_PER_PERIOD 8

struct fix_entry {
	int32_t x_um, y_um;
	uint32_t heading_turn32;
	uint32_t radius_um; /* the error radius then, for the growth since */
};

/* A fused fix's correction, still to be carried to the history entries since its time. */
struct fix_carry {
	struct fix_entry then;    /* the estimate at the measured time, before the fix */
	int32_t dx_um, dy_um;     /* the correction there */
	int32_t dheading_turn32;  /* and the turn about it */
	int32_t sin_q30, cos_q30; /* of dheading_turn32 */
	uint32_t shrink_um;       /* what the fix took off the error radius */
	uint8_t next;             /* the next entry to move, counted from the newest */
	uint8_t left;             /* entries still to move (0: none) */
};

/* A fix as SET_FIX carries it, in the core's units. */
struct fix_meas {
	int32_t x_um, y_um;
	uint32_t heading_turn32;
	uint32_t sigma_um;
	uint32_t sigma_turn32; /* 0: no heading */
	uint16_t age_ms;
};

/* What FIX_INFO reports. */
struct fix_info {
	uint16_t fused;
	uint16_t outliers;
	uint16_t too_old; /* TOO_OLD and STALE */
	uint8_t last;     /* FIX_RESULT_* */
	uint8_t last_d2;  /* saturating */
};

struct fix {
	struct fix_entry h[FIX_HISTORY_N]; /* h[head] the newest */
	uint32_t now;                      /* planner periods since power-on */
	uint32_t newest;                   /* the period of h[head] */
	uint32_t forget;                   /* fixes measured before this period are STALE */
	uint16_t slow_hz;
	uint8_t head;
	uint8_t count;
	uint8_t spacing; /* [planner periods] between two entries */
	uint8_t countdown;
	uint8_t outliers_in_a_row;
	/* Fixes waiting for the error radius to be between two batches (uncertainty_fuse_ready()),
	 * in the order they came, with the period each was measured at: one is fused at a time. */
	struct fix_meas waiting[FIX_QUEUE];
	uint32_t waiting_t[FIX_QUEUE];
	uint8_t first;
	uint8_t pending;
#if CONFIG_FIX
	struct fix_carry carry; /* the last fused fix's, over the next periods */
	/* The fix being fused (uncertainty_fuse_step(), a step a period): it, its period, the
	 * estimate then, the history entries at or after then (one more at each entry kept), the
	 * radius before. */
	struct fix_meas fusing;
	uint32_t fusing_t;
	struct fix_entry fusing_then;
	uint32_t fusing_newer;
	uint32_t fusing_before_um;
	uint8_t in_flight;
#endif
	struct fix_info info;
};

/* Power-on: no history, no fix. slow_hz: the planner's rate. Interrupt-safe: no. */
void fix_init(struct fix *f, uint16_t slow_hz);

/* Once a planner period, after the orders (their set points from the estimate before a fix:
 * a fused fix re-aims them at the next period): keeps the estimate of this period in the
 * history, moves the history with the last fix's correction (FIX_CARRY_PER_PERIOD entries), and
 * when that is done, takes the next step of the fusion in flight (uncertainty_fuse_step()), or
 * starts that of a fix that waited for the radius's batch to end; not when busy (the period
 * already did heavy work: the step then waits for the next one).
 * Interrupt-safe: no (the planner's context). */
#if CONFIG_FIX
void fix_record(struct fix *f, struct odometry_position *pos, struct odometry_pose *pose,
		struct uncertainty *u, uint8_t busy);
#else
static inline void fix_record(struct fix *f, struct odometry_position *pos,
			      struct odometry_pose *pose, struct uncertainty *u, uint8_t busy)
{
	(void)f;
	(void)pos;
	(void)pose;
	(void)u;
	(void)busy;
}
#endif

/* The estimate was set by other means (SET_NEW_POS, a recalibration): fixes measured before
 * now would undo it, and are STALE, the one in flight too (its fusion abandoned in u).
 * Interrupt-safe: no. */
void fix_forget(struct fix *f, const struct odometry_pose *pose, struct uncertainty *u);

/* A fix: compared with the estimate of the moment it was measured, gated, fused, its correction
 * carried to now (pose and pos, the planner's, moved as one rigid motion with the history since
 * then), from the first period the error radius is between two batches (within
 * UNCERTAINTY_STAGES periods), over five periods; one fix at a time, in the order they came;
 * FIX_QUEUE may wait, the oldest is dropped as TOO_OLD beyond; a fusion the radius abandons
 * (it changed meanwhile) is tried again first. Returns FIX_RESULT_NONE: fix_record() fuses it
 * and counts the result in f->info.
 * Interrupt-safe: no. */
uint8_t fix_apply(struct fix *f, struct odometry_position *pos, struct odometry_pose *pose,
		  struct uncertainty *u, const struct fix_meas *z);

#endif
