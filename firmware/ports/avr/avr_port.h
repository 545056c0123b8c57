/* What the files of the ATmega1284P port share: the board instance, the set-up of each
 * peripheral, and the control period's flag. The HAL itself is firmware/hal/. */
#ifndef ASSERV_AVR_PORT_H
#define ASSERV_AVR_PORT_H

#include <stdint.h>

#include <avr/io.h>

#include "board.h"
#include "robot.h"

/* The one board, shared by the control tick (main loop) and the TWI interrupt (its proto). The
 * simavr harness finds it by this symbol name. */
extern struct board asserv_board;

/* Set-up, once, interrupts off: pins and pull-ups (sensors.c), encoder decoding (encoder.c),
 * PWM, direction pins and the current-sense ADC (motor.c). */
void avr_sensors_init(void);
void avr_encoder_init(void);
void avr_motor_init(void);

/* Sleeps until the tick timer's next compare match (or returns at once if one is due). Returns
 * the number of periods that elapsed since the last call: more than 1 is an overrun. Main loop
 * only. */
uint8_t avr_tick_wait(void);

#endif
