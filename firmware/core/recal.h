/* Line recalibration ("recalage ligne", GOTO option bit 0): line sensors under the robot that
 * cross a known painted line correct the coordinate across that line, and the heading when two
 * sensors cross the same line. The rules that make a crossing usable (docs/recalibration.md):
 *   - the robot drives straight (GOTO's TRANSLATE with the option set) from the sensor's entry
 *     onto the line to its exit: the crossing's centre is the midpoint of the two;
 *   - the heading is within max_angle of the line's normal (30 degrees by default);
 *   - the width crossed, measured along the normal, is the line's width within width_tol_um
 *     (a line end, a corner or a stain is not a crossing);
 *   - exactly one known line lies within the error radius (plus margin_um) of the crossing:
 *     none, or two, and the crossing is ignored, never applied.
 * Lines are axis-aligned segments (x0 == x1 or y0 == y1); others in the table are never used. */
#ifndef ASSERV_RECAL_H
#define ASSERV_RECAL_H

#include <stdint.h>

#include "odometry.h"
#include "uncertainty.h"

#define RECAL_MAX_SENSORS 4
#define RECAL_MAX_LINES 8

/* A painted line: the segment (x0, y0)-(x1, y1) [um], width_um wide (FIELD_LINES' order). */
struct recal_line {
	int32_t x0_um;
	int32_t y0_um;
	int32_t x1_um;
	int32_t y1_um;
	int32_t width_um;
};

/* A line sensor in the robot frame [um]: x ahead of the encoder axis midpoint, y to the left. */
struct recal_point {
	int32_t x_um;
	int32_t y_um;
};

struct recal_config {
	uint8_t n_sensors; /* 0..RECAL_MAX_SENSORS; bit n of the line input is sensor n */
	struct recal_point sensors[RECAL_MAX_SENSORS];
	uint8_t n_lines; /* 0..RECAL_MAX_LINES */
	struct recal_line lines[RECAL_MAX_LINES];
	uint32_t max_angle_turn32; /* heading within this of the line's normal, < 1/4 turn */
	int32_t width_tol_um;      /* |width crossed - line width| at most this */
	int32_t margin_um;         /* candidate lines: within the error radius plus this */
	int32_t pair_window_um;    /* two sensors' crossings within this travel make a pair */
	uint32_t bound_um;         /* residual across the line, before the tick's quantisation */
	uint32_t pair_bound_um;    /* residual of the difference of two sensors' crossings [um] */
	/* A pair gives the heading only when the heading moved at most this from the first
	 * sensor's entry to the second's exit: the robot drove straight (< 1/4 turn). */
	uint32_t straight_turn32;
};

/* What a crossing gives: the corrected pose, and which parts of it are new. */
struct recal_fix {
	uint8_t what;                  /* RECAL_FIX_* bits; 0: nothing to apply */
	struct odometry_pose pose;     /* the estimate with the corrections applied */
	uint32_t normal_turn32;        /* the line's normal: the direction now known */
	uint32_t bound_um;             /* ... within this, across the line */
	uint32_t heading_bound_turn32; /* the heading's bound when RECAL_FIX_HEADING */
	uint8_t line;                  /* index of the line in the table */
};

#define RECAL_FIX_POSITION 1u
#define RECAL_FIX_HEADING 2u

/* The line sensors as the tick sees them, to time their edges (recal_sense()). */
struct recal_sense {
	uint8_t on;           /* bit n: sensor n saw a line at the last tick */
	int32_t prev_dist_um; /* the distance axis one tick ago */
};

/* The edges of a period of one or more ticks, each timed at its tick: what recal_take() judges
 * the crossings from. An edge seen at a tick happened during the tick's period: its best
 * estimate is the middle of that step. */
struct recal_edges {
	uint8_t on;   /* bit n: sensor n on a line at the period's end */
	uint8_t rose; /* bit n: sensor n entered a line during the period (the last entry kept) */
	uint8_t fell; /* bit n: ... left one (the last exit kept) */
	int32_t rise_um[RECAL_MAX_SENSORS];      /* distance axis at the entry [um] */
	int32_t fall_um[RECAL_MAX_SENSORS];      /* ... at the exit [um] */
	int32_t fall_step_um[RECAL_MAX_SENSORS]; /* the exit tick's step: its timing error */
};

struct recal {
	struct recal_config cfg;
	int32_t sin_max_q30; /* sin(max_angle) [2^-30] */
	uint8_t armed;       /* bit n: its entry was seen while enabled (a crossing in progress) */
	int32_t entry_um[RECAL_MAX_SENSORS];              /* distance axis at the entry [um] */
	uint32_t entry_heading_turn32[RECAL_MAX_SENSORS]; /* the estimate's heading then */
	/* The last crossing applied, to pair it with another sensor's crossing of the same line. */
	uint8_t last_valid;
	uint8_t last_sensor;
	uint8_t last_line;
	int32_t last_mid_um;                /* distance axis at its centre */
	uint32_t last_entry_heading_turn32; /* the heading at its entry */
	uint16_t crossings; /* crossings applied since init, wrapping (telemetry, tests) */
	uint16_t ignored;   /* crossings seen but refused by the rules, wrapping */
};

/* Returns 0, or -1 when the configuration is out of range. interrupt-safe: no. */
int recal_init(struct recal *r, const struct recal_config *cfg);

/* Start timing edges: no sensor on a line, the distance axis at dist_um. */
void recal_sense_init(struct recal_sense *s, struct recal_edges *e, int32_t dist_um);

/* One tick: the sensors now (lines, bit n = sensor n on a line, unused bits 0) and the distance
 * axis; their changes are added to e (cleared by recal_take()). Cheap: the servo's tick runs it.
 * interrupt-safe: no (tick only). */
void recal_sense(struct recal_sense *s, struct recal_edges *e, uint8_t lines, int32_t dist_um);

/* The edges of e (then cleared), at the period's end: enabled (the running order allows line
 * recalibration and drives straight), the estimate and the distance axis now, and the
 * uncertainty, whose error radius and heading bound are read only when a sensor left a line.
 * Fills fix (fix->what == 0 when nothing is to be applied); the caller applies fix->pose and
 * resets the uncertainty. interrupt-safe: no. */
void recal_take(struct recal *r, struct recal_edges *e, int enabled,
		const struct odometry_pose *pose, int32_t dist_um, const struct uncertainty *u,
		struct recal_fix *fix);

#endif
