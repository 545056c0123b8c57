/* Template port: the robot this binary drives, the board configuration the core runs with (as
 * ports/avr/robot.c and ports/stm32/robot.c). A real port describes its robot in
 * robot/<name>.toml, generates <name>_robot_gen.h from it (robot/gen_robot.py) and applies it
 * here; the rest (the rates, the sensors' positions) it sets here by hand. */
#include "template_port.h"

/* The reference robot's defaults. cfg->tick_hz is the control rate hal_tick_start() gets;
 * cfg->slow_shift and cfg->planner_ticks must be those the port's execution model runs (tick.c):
 * 0 and 0 when the control interrupt runs the planner too. */
void template_robot_config(struct board_config *cfg)
{
	board_default_config(cfg);
}
