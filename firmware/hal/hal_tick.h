/* Porting contract: the control period. */
#ifndef ASSERV_HAL_TICK_H
#define ASSERV_HAL_TICK_H

#include <stdint.h>

/* Start calling the port's control routine every 1/rate_hz seconds (a timer interrupt, or the
 * simulator's lockstep). The routine samples the HAL inputs, calls board_tick() and applies the
 * outputs; it must not be re-entered. The I2C interrupt may preempt it or run between two ticks.
 * May be called from an interrupt: no (once, at start-up). */
void hal_tick_start(uint16_t rate_hz);

#endif
