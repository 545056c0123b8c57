/* The robot the AVR binary drives (robot.c). Plain C: the simavr harness includes it too. */
#ifndef ASSERV_AVR_ROBOT_H
#define ASSERV_AVR_ROBOT_H

#include "board.h"

/* Build options (docs/avr.md), given by CMake; these defaults for a build without it. The
 * slow steps run every 2^CONFIG_AVR_SLOW_SHIFT ticks; the port's execution model follows it
 * (tick.c). */
#ifndef CONFIG_AVR_TICK_HZ
#define CONFIG_AVR_TICK_HZ 1000
#endif
#ifndef CONFIG_AVR_SLOW_SHIFT
#define CONFIG_AVR_SLOW_SHIFT 0
#endif

/* The board configuration compiled into the binary: board_default_config() adapted to this
 * board (motor encoders, control rate CONFIG_AVR_TICK_HZ, slow steps every
 * 2^CONFIG_AVR_SLOW_SHIFT ticks). */
void avr_robot_config(struct board_config *cfg);

#endif
