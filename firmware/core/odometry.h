/* Odometry from two free encoder wheels, in two halves: the counter (the servo's, every tick)
 * turns the free-running 16-bit counters into an exact heading and distance; the position (the
 * planner's) is moved along arcs of their steps, exactly integrated. The heading cannot drift.
 *
 * Frame: x along heading 0, y to its left, heading counter-clockwise (the right wheel going
 * forward alone turns the robot left). Counters increase when their wheel rolls forward.
 * Model and fixed-point formats: docs/odometry.md.
 */
#ifndef ASSERV_ODOMETRY_H
#define ASSERV_ODOMETRY_H

#include <stdint.h>

#include "fixmath.h"

/* Ranges accepted by odometry_counter_init and odometry_derive_config. */
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

/* What the last odometry_count() measured (all zero after init). */
struct odometry_step {
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

/* The servo's half (board.h, struct servo): every tick, the counters -> the heading and the
 * distance, exact. */
struct odometry_counter {
	struct odometry_config cfg; /* in effect: the build's, or SET_ODOMETRIE's */
	struct odometry_wheel left;
	struct odometry_wheel right;

	uint16_t left_count;
	uint16_t right_count;
	/* Heading [turn * 2^64], lower and upper 32 bits: the start heading plus the exact sum of
	 * the counts times the per-count changes above, modulo one turn (2^64). The steps come
	 * from it; the robot's estimated heading is the planner's (it takes SET_NEW_POS and the
	 * recalibrations), moved by the same steps. */
	uint32_t heading_q64[2];
	uint32_t heading_turn32; /* heading_q64 rounded to [turn * 2^32] */
	/* Signed travel of the midpoint since init [um * 2^17]: whole um (an int32_t kept in a
	 * uint32_t, so that it wraps without overflow beyond +-2147 m) and the fraction,
	 * 0..2^17 - 1. Exact. */
	uint32_t distance_um;
	uint32_t distance_frac;
	struct odometry_step step; /* the last count's */
};

/* The planner's half (board.h, struct planner): the position, moved along arcs made of the
 * counter's steps. */
struct odometry_position {
	/* [um * 2^16]: whole um (an int32_t kept in a uint32_t) and the fraction. */
	uint32_t x_um;
	uint32_t y_um;
	uint16_t x_frac;
	uint16_t y_frac;
	/* The last mean heading the position was advanced along, and its sine and cosine
	 * [2^-30]. */
	uint32_t trig_turn32;
	int32_t trig_sin_q30;
	int32_t trig_cos_q30;
};

/* Start from the current counter values (so that the first count does not jump), at
 * heading_turn32. Returns 0, or -EDOM if cfg is out of range (c is then unusable).
 * Interrupt-safe: no. */
int odometry_counter_init(struct odometry_counter *c, const struct odometry_config *cfg,
			  uint16_t left_count, uint16_t right_count, uint32_t heading_turn32);

/* Start at (x_um, y_um). Interrupt-safe: no. */
void odometry_position_init(struct odometry_position *p, int32_t x_um, int32_t y_um);

/* 0 when odometry_derive_config() would take cfg, or -EDOM. Interrupt-safe: yes. */
int odometry_check_config(const struct odometry_config *cfg);

/* New wheel factors and track in two steps, prepared in one context and installed in another
 * (board.h: the planner derives, the servo installs at a period's end). First the wheels'
 * tables of cfg, the costly part (two long divisions: about 75 000 cycles on an AVR); returns 0,
 * or -EDOM (wheels untouched). Interrupt-safe: yes. */
int odometry_derive_config(const struct odometry_config *cfg, struct odometry_wheel wheels[2]);

/* ... then cfg and its tables in place of the current ones: a copy of 780 bytes. The heading
 * (to 2^-64 turn) and the distance are kept; the next count uses the new factors.
 * Interrupt-safe: no (between two counts). */
void odometry_install_config(struct odometry_counter *c, const struct odometry_config *cfg,
			     const struct odometry_wheel wheels[2]);

/* One tick: read both counters (free-running, wrapping at 65536; at most 32767 counts of travel
 * per tick in either direction) -> the heading, the step and the distance. Returns 0, or
 * -ERANGE if a wheel moved more than ODOMETRY_STEP_Q16_MAX in the tick: its travel is then
 * clamped to that value and the caller should treat it as an encoder fault.
 * Interrupt-safe: no (call from the tick only). */
int odometry_count(struct odometry_counter *c, uint16_t left_count, uint16_t right_count);

/* The travel of a wheel [um * 2^16] over a signed count change, with its factor k (a wheel's
 * odometry_wheel.k): exact, a magnitude above ODOMETRY_STEP_Q16_MAX clamped to it. Over
 * several ticks, the sum of theirs (the travel is linear in the counts) but in the clamped
 * case. Interrupt-safe: yes. */
int32_t odometry_travel_q16(const uint16_t k[2], int16_t counts);

/* The position moved along one arc: a tick's, or a period's made of its summed wheel travels
 * and heading changes and the heading at its end (one arc of constant curvature from the
 * period's start to its end). The board runs odometry_count() every tick and this once a
 * period; with a period of one tick the two are the tick's exact odometry.
 * Interrupt-safe: each no against itself. */
void odometry_arc_of(struct odometry_arc *a, int32_t left_q16, int32_t right_q16,
		     int32_t dtheta_turn32, uint32_t heading_turn32);
void odometry_advance(struct odometry_position *p, const struct odometry_arc *a);

/* Replace the position (start, recalibration, SET_NEW_POS). Interrupt-safe: no. */
void odometry_set_position(struct odometry_position *p, int32_t x_um, int32_t y_um);

/* A length kept as whole um (an int32_t in a uint32_t) and a fraction, half = half a um in the
 * fraction's unit, rounded to nearest with ties away from zero (saturated). */
static inline int32_t odometry_round_um(uint32_t whole_um, uint32_t frac, uint32_t half)
{
	int32_t w = fx_int32_of(whole_um);

	if (w >= 0 ? frac >= half : frac > half)
		return w == INT32_MAX ? w : w + 1;
	return w;
}

/* The position, rounded to the micrometre (saturated to int32). Interrupt-safe: no. */
static inline int32_t odometry_get_x_um(const struct odometry_position *p)
{
	return odometry_round_um(p->x_um, p->x_frac, 0x8000u);
}

static inline int32_t odometry_get_y_um(const struct odometry_position *p)
{
	return odometry_round_um(p->y_um, p->y_frac, 0x8000u);
}

/* The counted heading [turn * 2^32]. Interrupt-safe: no. */
static inline uint32_t odometry_get_heading_turn32(const struct odometry_counter *c)
{
	return c->heading_turn32;
}

/* Signed travel of the midpoint since init [um], rounded from an exact sum, saturated to int32
 * (2147 m), for a distance loop. Interrupt-safe: no. */
static inline int32_t odometry_get_distance_um(const struct odometry_counter *c)
{
	return odometry_round_um(c->distance_um, c->distance_frac, 0x10000u);
}

#endif
