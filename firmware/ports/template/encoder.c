/* Template port: the quadrature encoders (hal_encoder.h). Each wheel has a free-running 16-bit
 * count that the core differentiates itself: the port never resets it and never computes a
 * speed. The usual hardware: a timer in encoder mode (an STM32 TIMx with SMS = 011 counts x4 on
 * both edges of both channels, in hardware, with no interrupt), or pin-change interrupts that
 * step a counter in software (the AVR: firmware/ports/avr/encoder_isr.S). */
#include "hal.h"
#include "template_port.h"

/* The free (non-driven) wheels that measure the odometry. What the core expects:
 * - x4 decoding: every edge of A and B counts, so the count per revolution is 4 times the
 *   encoder's lines (the board configuration's um per count is that of one such count);
 * - forward motion of the robot counts up on both sides: the two wheels turn in opposite
 *   directions as seen from their shafts, so one side is usually inverted here (swap A and B,
 *   or the timer's polarity), never in the core;
 * - free-running, wrapping at 2^16: the core takes the difference with its last reading modulo
 *   2^16, so it must not move 32768 counts or more within one control period;
 * - read atomically: a count that an interrupt updates byte by byte on an 8-bit chip is read
 *   with that interrupt masked (a torn read is a jump of 256 counts, a 20 mm jump of the pose).
 * Called from the control interrupt, every tick (port_sample()). */
uint16_t hal_encoder_free(enum hal_side side)
{
	(void)side;
	return 0; /* the count of side's free wheel, e.g. (uint16_t)TIMx->CNT */
}

/* The encoders on the drive motors' shafts, same conventions (forward counts up). The core
 * compares them with the free wheels to detect a wheel that slips or an encoder that is lost,
 * so a port without motor encoders returns a constant and the board then detects neither.
 * Called from the control interrupt, only at the end of a planner period
 * (port_sample_period(), when board_period_ends()). */
uint16_t hal_encoder_motor(enum hal_side side)
{
	(void)side;
	return 0; /* a constant: no motor encoders on this board */
}
