/* What the files of the ATmega1284P port share: the board instance, the set-up of each
 * peripheral, and the control period's execution model (tick.c). The HAL itself is
 * firmware/hal/. */
#ifndef ASSERV_AVR_PORT_H
#define ASSERV_AVR_PORT_H

#include <stdint.h>

#include <avr/io.h>

#include "board.h"
#include "robot.h"

/* The one board, shared by the control tick (main loop, or the timer's interrupt for the servo
 * and the main loop for the slow steps with two rates) and the TWI interrupt (its proto). The
 * simavr harness finds it by this symbol name. */
extern struct board asserv_board;

/* The cause of this start (RESET_CAUSE_*) of MCUSR as the reset left it (reset.c). */
uint8_t avr_reset_cause(uint8_t mcusr);

/* The watchdog (watchdog.c): turned off by the start-up's .init3 code (a watchdog reset leaves
 * it on), started by main() with a 60 ms window, fed by the main loop. */
void avr_watchdog_off(void);
void avr_watchdog_start(void);
void avr_watchdog_feed(void);

/* Set-up, once, interrupts off: pins and pull-ups (sensors.c), encoder decoding (encoder.c),
 * PWM, direction pins and the current-sense ADC (motor.c). */
void avr_sensors_init(void);
void avr_encoder_init(void);
void avr_motor_init(void);

/* The control tick's current sense, first in each tick: the last conversion's reading filtered
 * into its channel's sum, the other channel's conversion started (motor.c). */
void avr_motor_sense(void);

#if CONFIG_AVR_SLOW_SHIFT == 0
/* One rate. Sleeps until the tick timer's next compare match (or returns at once if one is
 * due). Returns the number of periods that elapsed since the last call: more than 1 is an
 * overrun. Main loop only. */
uint8_t avr_tick_wait(void);
#else
/* Two rates. The servo: TICK high, avr_motor_sense(), port_control_tick(), TICK low,
 * avr_servo_alive set. Called by the timer's interrupt (tick_isr.S) with interrupts enabled, never
 * re-entered. */
void avr_servo_tick(void);
/* Set by each servo tick, cleared by the main loop when it feeds the watchdog. */
extern volatile uint8_t avr_servo_alive;
/* Sleeps until the servo has handed the slow steps a snapshot (returns at once if it has).
 * Main loop only. */
void avr_slow_wait(void);
#endif

#endif
