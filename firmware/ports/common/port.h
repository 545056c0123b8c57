/* What every port does once per control period: sample the HAL, run the board's tick, apply
 * the duties. Ports call port_control_tick() from their control interrupt or lockstep. */
#ifndef ASSERV_PORT_H
#define ASSERV_PORT_H

#include "board.h"

/* Sample the HAL into in: the inputs of every tick (the free wheels' counts, hal_*_read), then
 * those of a period's end (the motors' counts, hal_motor_current_ma), which board_tick() reads
 * only when board_period_ends(). Interrupt-safe: they run in the control interrupt. */
void port_sample(struct board_inputs *in);
void port_sample_period(struct board_inputs *in);

/* Sample, board_tick(), hal_motor_set(). Must not be re-entered. */
void port_control_tick(struct board *b);

/* The slow steps when they are due (board_slow()): a port with one context calls it after each
 * port_control_tick(); one with two runs it in the lower-priority one. */
void port_slow(struct board *b);

#endif
