/* The board: odometry, orders, motion profiles, control and stop conditions, run by one tick
 * function. A port samples its inputs, calls board_tick() once per control period and applies
 * the outputs; its I2C interrupt talks to &board.proto (protocol.h). */
#ifndef ASSERV_BOARD_H
#define ASSERV_BOARD_H

#include <stdint.h>

#include "control.h"
#include "faults.h"
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

struct board_config {
	uint16_t tick_hz; /* control rate, 100..2000 */
	struct odometry_config odometry;
	struct uncertainty_config uncertainty;
	struct control_config control;
	struct faults_config faults;
	struct orders_config orders;
	struct recal_config recal;
	struct odometry_pose start; /* the specification: x 0, at the end of the field, angle 0 */
	/* How well the robot is placed at the start (bounds at the uncertainty's probability):
	 * the error radius starts from them. 0 and 0: the start pose is the reference. */
	uint32_t start_radius_um;
	uint32_t start_heading_bound_turn32;
};

struct board {
	struct board_config cfg;
	struct proto proto; /* shared with the I2C interrupt */
	struct odometry odometry;
	struct uncertainty uncertainty;
	struct orders orders;
	struct control control;
	struct faults faults;
	struct recal recal;
	uint8_t soft;                     /* FILTRE_SOUPLE's gains put in by a border push */
	struct control_gains saved_gains; /* ... and the gains it replaced */
	/* The angle axis: the exact sum of the odometry's heading steps [turn * 2^32] times
	 * pi * drive track [um], i.e. [um * 2^32], as hi 2^32 + lo (hi an int32_t modulo 2^32). */
	uint32_t angle_hi;
	uint32_t angle_lo;
	int32_t angle_um;       /* the angle axis, rounded */
	int32_t arc_um;         /* this tick's heading step on the angle axis, rounded */
	int32_t free_ratio_q16; /* drive track / encoder track [2^-16] */
	uint16_t tick;
	uint8_t shocks;            /* this tick's shock sensors */
	uint8_t status;            /* STATUS_* owned by the core */
	uint32_t timeout_ticks;    /* SET_TIMEOUT [ticks], 0: off (power-on) */
	uint32_t silent_ticks;     /* [ticks] since a transaction last addressed the board */
	uint8_t transactions_seen; /* proto.transactions at the last tick */
	uint8_t timed_out;         /* the last order was stopped by the timeout */
	struct board_outputs last_out;
};

/* Defaults for the reference robot (docs/control.md): 25 mm free wheels at 2000 counts/rev,
 * 280 mm encoder track, 160 mm drive track, motors that reach 1.6 m/s at full duty, 1 kHz. */
void board_default_config(struct board_config *cfg);

/* Power-on: the pose at cfg->start, the specification's initial limits (10 cm/s, 40 cm/s^2),
 * FILTRE_STD, no order; in gives the encoder counts to start from (no jump at the first tick).
 * Returns 0, or -1 when the configuration is out of range. Interrupt-safe: no. */
int board_init(struct board *b, const struct board_config *cfg, const struct board_inputs *in);

/* One control period, in order: encoders -> odometry -> error radius -> line recalibration ->
 * messages -> the master's silence -> stop conditions -> orders -> profiles -> border/basket
 * recalibration -> control -> outputs -> reply snapshot.
 * Interrupt-safe: it is the control interrupt; it must not be re-entered. */
void board_tick(struct board *b, const struct board_inputs *in, struct board_outputs *out);

#endif
