/* The robot this binary drives: the reference robot of board_default_config() (the simulator's
 * default robot, sim/sim.h) with its 2048-count motor encoders, which the timers decode in
 * hardware, at 1 kHz with everything at the servo rate (slow_shift 0). A team edits this file for
 * its robot. */
#include "stm32_port.h"

void stm32_robot_config(struct board_config *cfg)
{
	board_default_config(cfg);
	/* 2 pi 32.5 mm / (2048 * 20.25) = 4.9239 um per count of a motor encoder, * 2^16. */
	cfg->faults.motor_um_per_count_q16 = 322692;
	/* The basket contact in the middle of the 250 mm outline's front edge. */
	cfg->orders.basket_contact_um = 125000;
	cfg->tick_hz = 1000;
	cfg->slow_shift = 0;
	cfg->control.tick_hz = 1000;
	cfg->orders.tick_hz = 1000;
}
