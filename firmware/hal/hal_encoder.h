/* Porting contract: quadrature encoders. */
#ifndef ASSERV_HAL_ENCODER_H
#define ASSERV_HAL_ENCODER_H

#include <stdint.h>

enum hal_side { HAL_LEFT = 0, HAL_RIGHT = 1 };

/* Free-running count of a free (non-driven) encoder wheel, x4 decoding, wrapping at 2^16;
 * forward motion of the robot counts up on both sides. The core differentiates it once per tick,
 * so it must not move by 32768 counts or more in one control period.
 * May be called from an interrupt: yes (the control interrupt). Must be read atomically. */
uint16_t hal_encoder_free(enum hal_side side);

/* Free-running count of the encoder on a drive motor's shaft (same conventions), or a constant
 * on a board without motor encoders (the board then cannot detect slip).
 * May be called from an interrupt: yes. */
uint16_t hal_encoder_motor(enum hal_side side);

#endif
