/* What survives a reset other than a power-on (issue 28): the planner's pose, its error radius,
 * whether it was lost and the count of resets, kept once a planner period in RAM that the
 * port's start-up does not clear (a .noinit section), with a check word. At the next start the
 * port gives it back with the reset cause (board_restart(), board.h): kept, the pose resumes with
 * the radius widened by what the robot may have travelled while the board was down; scrambled,
 * the pose is lost and motion orders are refused until the master sets it. */
#ifndef ASSERV_KEEP_H
#define ASSERV_KEEP_H

#include <stdint.h>

#include "uncertainty.h"

struct board_keep {
	int32_t x_um, y_um;
	uint32_t heading_turn32;
	uint32_t radius_um;
	struct uncertainty_kept u; /* the heading's uncertainty */
	uint32_t speed_um_s;       /* the distance axis's speed, magnitude [um/s] */
	uint32_t turn_um_s;        /* the angle axis's [um/s of wheel arc] */
	uint8_t spare0;    /* 0 (was: an order ran; every reset but a power-on now says so) */
	uint8_t resets;    /* since power-on, saturating */
	uint8_t pose_lost; /* lost at an earlier reset and not set since */
	uint8_t spare;
	uint32_t check; /* keep_check_word() of the words above */
};

/* The check word of k's contents: a power-on's random RAM matches it once in 2^32. */
uint32_t keep_check_word(const struct board_keep *k);

/* 1 when k holds what keep_check_word() sealed. Interrupt-safe: yes (reads k only). */
int keep_valid(const struct board_keep *k);

/* Seal k after writing its fields. */
void keep_seal(struct board_keep *k);

#endif
