/* The robot the AVR binary drives (robot.c). Plain C: the simavr harness includes it too. */
#ifndef ASSERV_AVR_ROBOT_H
#define ASSERV_AVR_ROBOT_H

#include "board.h"

/* The board configuration compiled into the binary: board_default_config() adapted to this
 * board (motor encoders, control rate CONFIG_AVR_TICK_HZ). */
void avr_robot_config(struct board_config *cfg);

#endif
