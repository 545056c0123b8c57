/* The native reference run of the AVR binary: the same core built for the host, on the same
 * physics, fed what the AVR port measures (its encoder counts, switches and line sensors at the
 * tick) and driving the physics with the duty the AVR's PWM produces (avr_units.h,
 * avrsim_duty_q15()). The physics runs the control period after the tick, as the host port does
 * (firmware/ports/host) and as the exact lockstep of avrsim.h makes the AVR see it, in the same
 * substeps. */
#ifndef ASSERV_HARNESS_REF_H
#define ASSERV_HARNESS_REF_H

#include <stdint.h>

#include "board.h"
#include "sim.h"

struct ref {
	struct sim sim;
	struct board board;
	uint64_t tick_ns;
	uint64_t ticks;
};

/* Starts the physics and the board on its first reading. Returns 0, or -1. */
int ref_init(struct ref *r, const struct board_config *bc, const struct sim_config *sc,
	     const struct sim_field *f);

/* One control period: the board's tick on the sensors of this instant, then the physics over the
 * period with the quantised duties. */
void ref_tick(struct ref *r);

/* The I2C master between two ticks, as the protocol layer sees it (host_i2c_* of the host port):
 * a write (stop = 0: a read follows by repeated start), a read of n bytes ending with STOP. */
void ref_i2c_write(struct ref *r, const uint8_t *data, uint8_t n, int stop);
void ref_i2c_read(struct ref *r, uint8_t *out, uint8_t n);

#endif
