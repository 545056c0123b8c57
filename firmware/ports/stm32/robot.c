/* The robot this binary drives: robot/stm32.toml, the reference robot of board_default_config()
 * (the simulator's default robot) with its 2048-count motor encoders, which the timers decode in
 * hardware (stm32_robot_gen.h, generated from it by robot/gen_robot.py), at 1 kHz with
 * everything at the servo rate (slow_shift 0). A team describes its robot in robot/stm32.toml
 * and edits this file for the rest. */
#include "stm32_port.h"

#include "stm32_robot_gen.h"

void stm32_robot_config(struct board_config *cfg)
{
	board_default_config(cfg);
	/* the wheels, encoders, motors and outline of robot/stm32.toml */
	stm32_robot_gen(cfg);
	/* The basket contact in the middle of the 250 mm outline's front edge. */
	cfg->orders.basket_contact_um = 125000;
	cfg->tick_hz = 1000;
	cfg->slow_shift = 0;
}
