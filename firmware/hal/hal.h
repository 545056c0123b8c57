/* The porting contract: what a port (ports/host, ports/avr, ports/stm32; ports/template to start
 * a new one) provides so that the core runs.
 *
 * The core itself never calls these: a port's control interrupt samples the inputs into a
 * struct board_inputs, calls board_tick() (core/board.h), and applies struct board_outputs.
 * Keeping the core a pure function of its inputs lets one process run many simulated boards and
 * lets the tests feed it any sequence. Sides are HAL_LEFT and HAL_RIGHT. The storage (hal_nvm.h)
 * is at the level of the calibration's record, called by the port's main loop only.
 */
#ifndef ASSERV_HAL_H
#define ASSERV_HAL_H

#include "hal_encoder.h"
#include "hal_i2c.h"
#include "hal_motor.h"
#include "hal_nvm.h"
#include "hal_sensors.h"
#include "hal_tick.h"

#endif
