/* Match play (issue 31, docs/protocol.md "Match play"): the sequence numbers of the orders, the
 * motion queue (APPEND), PAUSE and RESUME, the speed scale, the pass-through corners, and what
 * MOTION reports. The planner owns a struct motion (board.h) and calls these at its steps: the
 * messages (3), before and after the orders (5), the reply snapshot (7). With none of the new
 * messages used, nothing here changes what the board does. */
#ifndef ASSERV_MOTION_H
#define ASSERV_MOTION_H

#include <stdint.h>

#include "feature_set.h"
#include "orders.h"
#include "protocol.h"

/* An order waiting in the queue: the message as it came, with its sequence number. */
struct motion_entry {
	struct proto_msg msg;
	uint8_t seq;
};

#if CONFIG_MOTION_CORNERS
/* What a curve of radius r_um is, at the corner's limits (docs/control.md "Corners"): its speed,
 * its clothoids' and its arc's lengths, and how far before the point it starts. */
struct motion_shape {
	int64_t r_um, v_um_s, clothoid_um, arc_um, reach_um;
};

/* A curve's fit in progress (motion.c, fit_start() and fit_try(), one try a call): the limits
 * it keeps, half the shorter line, the free wheels' arc's radius [um], the tolerance [um], the
 * half turn's sine and cosine [Q30], the turn [turn * 2^32], the tries done. */
struct motion_fit {
	int64_t lim[6];
	int64_t half_um, free_um;
	int32_t tol_um, sin_q30, cos_q30;
	uint32_t theta;
	uint8_t tries;
};
#endif

/* A pass-through corner's curve, planned for the running order and the next one (motion.c). */
struct motion_corner {
	uint8_t seq;             /* the running order's sequence number it is for */
	uint8_t next_seq;        /* ... and the next one's */
	uint8_t ok;              /* 1: a curve; 0: none fits (the corner as before the curves) */
	int32_t key[4];          /* the limits and the tolerance it was planned with */
	int32_t len1_um;         /* the line left to the point when first planned */
	int32_t reach_um;        /* the curve starts this far before the point */
	int32_t brake_um;        /* the line's braking to the curve's speed [um] */
	uint32_t heading_turn32; /* the next line's */
	struct orders_curve c;
#if CONFIG_MOTION_CORNERS /* the AVR's layout as without them: its budget is tight */
	/* The corner after it, looked ahead at (motion.c, plan_ahead()) */
	uint8_t ahead_seq;      /* the order after the next one */
	int32_t ahead_len1_um;  /* the line after this curve, as that corner is planned with */
	int32_t ahead_v_um_s;   /* the speed the line slows down to for it (0: a stop) */
	int32_t ahead_reach_um; /* ... this far before the next point */
	/* A pivot instead of a curve (ok 0; motion.c, pivot_plan()): the next order starts this
	 * far before the point, and its line once its heading is within pivot_turn32 */
	uint8_t pivot;
	int32_t pivot_um;
	uint32_t pivot_turn32;
	/* The plan in progress, a few steps a planner period (motion.c, plan_step()): its next
	 * step (PLAN_DONE: none), the fit being tried, the curve and the one looked ahead at, the
	 * turns [turn * 2^32] and the lines after each point [um], the free wheels' arc radius. */
	uint8_t step;
	struct motion_fit fit;
	struct motion_shape sh, ahead_sh;
	uint32_t theta, ahead_theta;
	int64_t len2_um, len3_um, free_um;
#endif
};

struct motion {
	struct motion_entry queue[PROTO_MOTION_QUEUE_DEPTH];
	uint8_t head;  /* the oldest waiting entry */
	uint8_t count; /* entries waiting, 0..PROTO_MOTION_QUEUE_DEPTH */
	uint8_t seq;   /* the last sequence number given (0 before the first order) */
	uint8_t running_seq;
	uint8_t running;    /* an order with a sequence number runs (running_seq) */
	uint8_t from_queue; /* ... and it came from the queue: stale_bits show the last ending */
	uint8_t stale_bits; /* the end bits of the order that ended before it (STATUS_*) */
	uint8_t last_seq;
	uint8_t last_end; /* END_REASON_* */
	uint8_t paused;
	uint8_t through;       /* the running order is a GOTO with PASS_THROUGH */
	uint8_t scale_percent; /* 0..100 */
	uint8_t appends_done;  /* APPEND orders started or dropped, wrapping (protocol.h) */
	uint8_t latency_ticks; /* [planner periods] from a message's last byte to its set points */
	int32_t corner_um;     /* SET_CORNER's tolerance [um] */
	struct motion_corner corner;
	uint32_t line_turn32;          /* the heading of the line after the running curve */
	uint16_t curve_ms_per_mm_s_q8; /* 1 / the curve's deceleration, as ms_per_mm_s_q8 */
	uint16_t ms_per_tick_q8;       /* a planner period [ms * 2^8] */
	/* 1 / PAUSE's deceleration of each axis [ms / (mm/s) * 2^8], exact down to 3.9 mm/s^2 */
	uint16_t ms_per_mm_s_q8[2];
	uint16_t braking_mm; /* MOTION's, and the set points' speeds and smoothing they are of */
	uint16_t braking_ms;
	int32_t braking_key[3];
	int32_t braking_vel[2];
#if CONFIG_MOTION_CORNERS
	uint16_t pivot_ms_per_mm_s_q8[2]; /* 1 / a pivot's accelerations, as ms_per_mm_s_q8 */
	/* A pivot's shape (motion.c, pivot_shape_of()) at the accelerations and the tolerance of
	 * pivot_key, made again in a period of its own when they change: e and phi [um], the time
	 * both overlaps take [us], phi as a heading [turn * 2^32]. */
	struct motion_pivot_shape {
		int64_t e_um, phi_um;
		int64_t overlap_us;
		uint32_t phi_turn32;
	} pivot_shape;
	int32_t pivot_key[3];
#endif
};

/* The default corner tolerance (SET_CORNER), [mm]. */
#define MOTION_CORNER_DEFAULT_MM 30

#endif
