/* One-dimensional motion profile generator, evaluated once per control tick: the set point of
 * one polar axis (distance along a line, or rotation expressed as wheel arc), in um.
 *
 * Two modes, chosen by the jerk limit:
 *   - j_max = 0: time-optimal trapezoid (velocity and acceleration limits);
 *   - j_max > 0: S-curve, the same trapezoid smoothed by a moving average of n_filt = a/j ticks
 *     (Biagiotti & Melchiorri, "FIR filters for online trajectory planning", 2012), with one
 *     extra rule on the trapezoid so that the jerk of the result never exceeds j_max.
 * A new target, new limits, a stop or a reset may come at any tick, also while moving: the set
 * point continues from its current position and velocity (and acceleration). docs/control.md
 * gives the algorithm, the formats and the durations.
 *
 * Internal formats: position [um * 2^16] (int64), velocity [um/tick * 2^16], acceleration
 * [um/tick^2 * 2^16]. The motion ends exactly on the target (an integer um) with zero velocity.
 */
#ifndef ASSERV_PROFILE_H
#define ASSERV_PROFILE_H

#include <stdint.h>

#include "fixmath.h"

/* Longest smoothing window of the S-curve [tick]; 4 bytes of RAM per tick and per profile.
 * When a/j is longer than this, the acceleration is lowered to j * CONFIG_PROFILE_JERK_TICKS_MAX
 * / tick_hz so that the jerk limit still holds. */
#ifndef CONFIG_PROFILE_JERK_TICKS_MAX
#define CONFIG_PROFILE_JERK_TICKS_MAX 256
#endif

#define PROFILE_TICK_HZ_MIN 100
#define PROFILE_TICK_HZ_MAX 2000
#define PROFILE_V_MAX_UM_S 3000000   /* 3 m/s */
#define PROFILE_A_MIN_UM_S2 1000     /* 1 mm/s^2 */
#define PROFILE_A_MAX_UM_S2 10000000 /* 10 m/s^2 */
#define PROFILE_J_MIN_UM_S3 1000     /* 1 mm/s^3, when not 0 */

/* Limits of one axis. They change at run time (SET_VITESSE_TRAJ, SET_VITESSE_ROT). */
struct profile_limits {
	int32_t v_max_um_s;  /* [um/s] 1..PROFILE_V_MAX_UM_S */
	int32_t a_max_um_s2; /* [um/s^2] PROFILE_A_MIN_UM_S2..PROFILE_A_MAX_UM_S2 */
	int32_t j_max_um_s3; /* [um/s^3] 0 (trapezoid) or PROFILE_J_MIN_UM_S3..INT32_MAX */
};

/* Settings fixed at init. */
struct profile_config {
	uint16_t tick_hz;             /* [Hz] PROFILE_TICK_HZ_MIN..PROFILE_TICK_HZ_MAX */
	struct profile_limits limits; /* initial limits */
};

/* The set point of one tick. */
struct profile_out {
	int32_t pos_um;    /* [um] */
	int32_t vel_um_s;  /* [um/s], for feed-forward */
	int32_t acc_um_s2; /* [um/s^2], for feed-forward: velocity change over the last tick
			    * (on the first done tick, the last step of the braking) */
	uint8_t done;      /* 1: on the target exactly, velocity 0; stays so until a new order */
};

/* Limits converted to ticks; recomputed when the limits change, never per tick. */
struct profile_params {
	uint16_t tick_hz;
	struct profile_limits lim; /* as given */
	int32_t v_max_q16;         /* [um/tick * 2^16] */
	int32_t a_full_q16;        /* [um/tick^2 * 2^16] a_max */
	int32_t a_q16;             /* [um/tick^2 * 2^16] in effect: a_max, or lower (S-curve) */
	uint8_t a_bits;            /* fx_bit_length32(a_q16), for the divisions by a */
	int32_t j_um_s3;           /* [um/s^3] jerk limit in effect for this motion */
	uint16_t n_filt;           /* [tick] smoothing window, 1 for a trapezoid */
	uint16_t hold_len;         /* [tick] n_filt for an S-curve, 0 for a trapezoid */
	struct fx48 r_far_q16;     /* [um * 2^16] beyond this, braking never limits */
	struct fx48 a_hold_q16;    /* a (hold_len + 1) [um/tick * 2^16] */
	uint32_t hz2;              /* tick_hz^2 */
	int32_t vel_full_um_s;     /* the output velocity at v_max_q16, and the output */
	int32_t acc_full_um_s2;    /* acceleration of a step of a_q16 (the common cases) */
};

/* The braking step count n last found for one hold h (0, and hold_len), with g_h(n a) (the
 * distance of braking from n a after h ticks of cruise) and n a, so that moving n by one is
 * two additions: the generator's common case (docs/control.md). */
struct profile_hint {
	uint32_t n;
	struct fx48 g_q16; /* [um * 2^16] */
	int32_t an_q16;    /* [um/tick * 2^16] */
	uint8_t valid;
};

struct profile {
	struct profile_params prm;
	struct fx48 target_q16; /* [um * 2^16], a whole number of um */
	/* The trapezoid (before smoothing). */
	struct fx48 pos_in_q16; /* [um * 2^16] */
	int32_t vel_in_q16;     /* [um/tick * 2^16] */
	uint16_t hold; /* [tick] S-curve: no acceleration of sign -hold_sign for this long */
	int8_t hold_sign;
	uint8_t stopping;
	uint16_t quiet; /* [tick] consecutive ticks with vel_in 0, saturated at n_filt */
	/* S-curve only, the moving average: last n_filt trapezoid velocities, their sum, and the
	 * sum of the last n_filt trapezoid positions (the set point times n_filt, exact). */
	uint16_t idx;
	int64_t vel_sum_q16; /* [um/tick * 2^16] */
	int64_t pos_sum_q16; /* [um * 2^16] */
	int32_t hist_q16[CONFIG_PROFILE_JERK_TICKS_MAX];
	struct profile_out out;
	struct profile_hint hint[2]; /* for h = 0 and h = hold_len */
	uint8_t far_ready; /* r_far is that of the current limits (set by choose_window()) */
};

/* Start at rest at pos_um [um] with cfg's limits. Returns 0, or -1 if a setting is out of range
 * (p is then unusable). Interrupt-safe: no (call before the tick runs). */
int profile_init(struct profile *p, const struct profile_config *cfg, int32_t pos_um);

/* New limits, taken into account from the next tick, also while moving: a velocity above the new
 * v_max decelerates at a_max. In S-curve mode the smoothing window is chosen when a motion starts
 * from rest: while moving, a new j_max waits for the next rest, and lowered a_max / v_max are
 * reached by the output within n_filt ticks (the jerk limit in effect always holds).
 * Returns 0, or -1 (limits unchanged) if out of range. Interrupt-safe: no (same context as
 * profile_update). */
int profile_set_limits(struct profile *p, const struct profile_limits *lim);

/* Go to target_um [um], from the current state; replaces any previous target or stop. A target
 * behind the current motion brakes and reverses. Interrupt-safe: no (same context as
 * profile_update). */
void profile_set_target(struct profile *p, int32_t target_um);

/* Decelerate to rest at a_max from the current state (the braking distance, rounded up to a
 * whole um). Returns the position where the trapezoid comes to rest [um] (the set point too).
 * Interrupt-safe: no (same context as profile_update). */
int32_t profile_stop(struct profile *p);

/* Hold here: position pos_um [um], velocity and acceleration 0, target pos_um (e.g. after a
 * recalibration moved the frame). Interrupt-safe: no (same context as profile_update). */
void profile_reset(struct profile *p, int32_t pos_um);

/* Trapezoid only (j_max 0): take over a motion made elsewhere, at pos_um [um] and vel_um_s
 * [um/s] now, braking to rest from there at a_max (as profile_stop()) until a new target.
 * Interrupt-safe: no (same context as profile_update). */
void profile_follow(struct profile *p, int32_t pos_um, int32_t vel_um_s);

/* One control tick: advance the set point and return it (also kept in p->out). Bounded time: far
 * from the target additions only; when braking limits the motion, a 32 / 16-bit division, and
 * a square root only when the target or the limits jumped; in S-curve mode three 64-bit
 * divisions more for the outputs. Interrupt-safe: yes (it may be the tick interrupt), provided
 * the other functions are not called concurrently. */
const struct profile_out *profile_update(struct profile *p);

/* The target [um] (profile_set_target(), or where a stop or a reset holds). Interrupt-safe:
 * yes. */
static inline int32_t profile_get_target_um(const struct profile *p)
{
	return p->target_q16.hi;
}

/* 1 when the set point is on the target, at rest. Interrupt-safe: yes. */
int profile_is_done(const struct profile *p);

#endif
