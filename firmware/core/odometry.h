/* Odometry from two free encoder wheels: the pose (x, y, heading) integrated once per tick from
 * the free-running 16-bit counters, with exact arc integration and a heading that cannot drift.
 *
 * Frame: x along heading 0, y to its left, heading counter-clockwise (the right wheel going
 * forward alone turns the robot left). Counters increase when their wheel rolls forward.
 * Model and fixed-point formats: docs/odometry.md.
 */
#ifndef ASSERV_ODOMETRY_H
#define ASSERV_ODOMETRY_H

#include <stdint.h>

#include "fixmath.h"

/* Ranges accepted by odometry_init and odometry_set_config. */
#define ODOMETRY_UM_PER_COUNT_Q16_MAX ((uint32_t)1 << 24) /* 256 um per count */
#define ODOMETRY_TRACK_UM_MIN ((uint32_t)1 << 14)         /* 16.4 mm */
#define ODOMETRY_TRACK_UM_MAX ((uint32_t)1 << 21)         /* 2.097 m */
/* Largest travel of one wheel in one tick [um * 2^16] (32.8 mm); more is reported as an error. */
#define ODOMETRY_STEP_Q16_MAX INT32_MAX

struct odometry_config {
	uint32_t left_um_per_count_q16;  /* [um per count * 2^16], 1..2^24 */
	uint32_t right_um_per_count_q16; /* [um per count * 2^16], 1..2^24 */
	uint32_t track_um;               /* distance between the encoder wheels [um], 2^14..2^21 */
};

struct odometry_pose {
	int32_t x_um;
	int32_t y_um;
	uint32_t heading_turn32; /* [turn * 2^32] */
};

/* What the last odometry_count (or odometry_update) measured. The wheels' travels are
 * odometry_update()'s only: a caller of odometry_count() that needs them over several ticks
 * takes them from the counts (odometry_travel_q16()). */
struct odometry_step {
	int32_t left_q16;      /* travel of the left wheel [um * 2^16], exact (odometry_update) */
	int32_t right_q16;     /* travel of the right wheel [um * 2^16], exact (odometry_update) */
	int32_t ds_um;         /* travel of the midpoint, (left + right) / 2, rounded [um] */
	int32_t dtheta_turn32; /* heading change [turn * 2^32], counter-clockwise positive */
};

/* A stretch of travel for odometry_advance(): the midpoint's, twice, as sign and magnitude, the
 * heading change along it and the heading at its end. */
struct odometry_arc {
	uint32_t twice_ds_q16; /* |left + right| [um * 2^16] */
	uint8_t neg;           /* the midpoint went backwards */
	int32_t dtheta_turn32; /* [turn * 2^32], counter-clockwise positive */
	uint32_t heading_turn32;
};

/* Counts per tick up to this many (exclusive) are looked up rather than multiplied: 32 covers
 * 2.5 mm per tick with the reference robot's 78.5 um per count (2.5 m/s at 1 kHz). */
#define ODOMETRY_TABLE_COUNTS 32

/* What n counts of one wheel give: its travel [um * 2^16] and the heading change [turn * 2^64],
 * lower and upper 32 bits; exact products, as magnitudes. */
struct odometry_move {
	uint32_t travel_q16;
	uint32_t turn_q64[2];
};

/* Per wheel, derived from its factor and the track: the moves of n counts, n = 0..
 * ODOMETRY_TABLE_COUNTS-1, and the factor in 16-bit halves for the larger counts (their change
 * per count is move[1].turn_q64). 388 bytes. */
struct odometry_wheel {
	struct odometry_move move[ODOMETRY_TABLE_COUNTS];
	uint16_t k[2]; /* factor: low and high 16 bits */
};

struct odometry {
	struct odometry_config cfg;
	struct odometry_wheel left;
	struct odometry_wheel right;

	uint16_t left_count;
	uint16_t right_count;
	/* Heading [turn * 2^64], lower and upper 32 bits: the heading set last plus the exact sum
	 * of the counts times the per-count changes above, modulo one turn (2^64). */
	uint32_t heading_q64[2];
	uint32_t heading_turn32; /* heading_q64 rounded to [turn * 2^32] */
	/* Position [um * 2^16]: whole um (an int32_t kept in a uint32_t, so that it wraps without
	 * overflow beyond +-2147 m) and the fraction. */
	uint32_t x_um;
	uint32_t y_um;
	uint16_t x_frac;
	uint16_t y_frac;
	/* Signed travel of the midpoint since init [um * 2^17]: whole um (as x_um) and the
	 * fraction, 0..2^17 - 1. Exact. */
	uint32_t distance_um;
	uint32_t distance_frac;
	struct odometry_step step;
	/* The last mean heading the pose was advanced along, and its sine and cosine [2^-30]. */
	uint32_t trig_turn32;
	int32_t trig_sin_q30;
	int32_t trig_cos_q30;
};

/* Start from the current counter values (so the first update does not jump), at pose (0, 0, 0).
 * Returns 0, or -EDOM if cfg is out of range (o is then unusable).
 * interrupt-safe: no. */
int odometry_init(struct odometry *o, const struct odometry_config *cfg, uint16_t left_count,
		  uint16_t right_count);

/* Change the wheel factors and track, keeping the current pose; takes effect from the next
 * update. Returns 0, or -EDOM if cfg is out of range (the old config is kept).
 * interrupt-safe: no (call between two ticks). */
int odometry_set_config(struct odometry *o, const struct odometry_config *cfg);

/* 0 when odometry_set_config() would take cfg, or -EDOM. Interrupt-safe: yes. */
int odometry_check_config(const struct odometry_config *cfg);

/* odometry_set_config() in two steps, for a caller that prepares in one context and installs in
 * another (board.h): the wheels' tables of cfg, the costly part (two long divisions: about
 * 75 000 cycles on an AVR); returns 0, or -EDOM (wheels untouched). Interrupt-safe: yes. */
int odometry_derive_config(const struct odometry_config *cfg, struct odometry_wheel wheels[2]);

/* ... then cfg and its tables in place of the current ones, the pose kept: a copy of 780 bytes.
 * Interrupt-safe: no (between two updates). */
void odometry_install_config(struct odometry *o, const struct odometry_config *cfg,
			     const struct odometry_wheel wheels[2]);

/* One tick: read both counters (free-running, wrapping at 65536; at most 32767 counts of travel
 * per tick in either direction) and integrate the pose: odometry_count() then odometry_advance()
 * along the tick's arc. Returns 0, or -ERANGE if a wheel moved more than ODOMETRY_STEP_Q16_MAX in
 * the tick: its travel is then clamped to that value and the caller should treat it as an
 * encoder fault.
 * interrupt-safe: no (call from the tick only). */
int odometry_update(struct odometry *o, uint16_t left_count, uint16_t right_count);

/* odometry_update() in two halves, for a caller that runs the position at a lower rate
 * (board.h): first, every tick, the counters -> the heading, the step (but the wheels' travels)
 * and the distance, not the position (same return value) ... */
int odometry_count(struct odometry *o, uint16_t left_count, uint16_t right_count);

/* The travel of a wheel [um * 2^16] over a signed count change, with its factor k (a wheel's
 * odometry_wheel.k): exact, a magnitude above ODOMETRY_STEP_Q16_MAX clamped to it. Over a tick,
 * what odometry_update() gives; over several, the sum of theirs (the travel is linear in the
 * counts) but in the clamped case. Interrupt-safe: yes. */
int32_t odometry_travel_q16(const uint16_t k[2], int16_t counts);

/* ... then, once per tick or once per period, the position moved along one arc: a tick's, or a
 * period's made of its summed wheel travels and heading changes and the heading at its end (one
 * arc of constant curvature from the period's start to its end). Called every tick after
 * odometry_count(), with the tick's travels, the pair is odometry_update() bit for bit.
 * Interrupt-safe: both yes against each other (they share no field); each no against itself. */
void odometry_arc_of(struct odometry_arc *a, int32_t left_q16, int32_t right_q16,
		     int32_t dtheta_turn32, uint32_t heading_turn32);
void odometry_advance(struct odometry *o, const struct odometry_arc *a);

/* Replace the pose (start position, recalibration, SET_NEW_POS); the counters are untouched.
 * interrupt-safe: no (call between two ticks). */
void odometry_set_pose(struct odometry *o, const struct odometry_pose *pose);

/* The position alone (odometry_advance()'s half of the pose). */
void odometry_set_position(struct odometry *o, int32_t x_um, int32_t y_um);

/* A length kept as whole um (an int32_t in a uint32_t) and a fraction, half = half a um in the
 * fraction's unit, rounded to nearest with ties away from zero (saturated). For the accessors
 * below, which are inline: the tick reads them every period. */
static inline int32_t odometry_round_um(uint32_t whole_um, uint32_t frac, uint32_t half)
{
	int32_t w = fx_int32_of(whole_um);

	if (w >= 0 ? frac >= half : frac > half)
		return w == INT32_MAX ? w : w + 1;
	return w;
}

/* The pose, rounded to the micrometre (saturated to int32).
 * interrupt-safe: no (read in the tick context, or with the tick masked). */
static inline struct odometry_pose odometry_get_pose(const struct odometry *o)
{
	struct odometry_pose p;

	p.x_um = odometry_round_um(o->x_um, o->x_frac, 0x8000u);
	p.y_um = odometry_round_um(o->y_um, o->y_frac, 0x8000u);
	p.heading_turn32 = o->heading_turn32;
	return p;
}

/* The last tick's wheel travels, midpoint travel and heading change (all zero after init).
 * interrupt-safe: no. */
static inline struct odometry_step odometry_get_step(const struct odometry *o)
{
	return o->step;
}

/* Signed travel of the midpoint since init [um], rounded from an exact sum, saturated to int32
 * (2147 m), for a distance loop. Not changed by set_pose.
 * interrupt-safe: no. */
static inline int32_t odometry_get_distance_um(const struct odometry *o)
{
	return odometry_round_um(o->distance_um, o->distance_frac, 0x10000u);
}

#endif
