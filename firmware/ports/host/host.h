/* The host port: the HAL implemented on the simulator (sim/), in deterministic lockstep. One
 * struct host is one simulated board on one simulated robot; many can exist in a process. */
#ifndef ASSERV_HOST_H
#define ASSERV_HOST_H

#include <stdint.h>

#include "board.h"
#include "sim.h"

struct host {
	struct sim sim;
	struct board board;
	uint64_t tick_ns; /* control period */
	uint64_t ticks;   /* control periods run */
};

/* The board configuration that matches a simulated robot: encoder wheels, tracks, motor
 * encoders, baskets and start pose taken from the simulator's configuration and field
 * (calibrated board: nominal values, not the robot's hidden errors). */
void host_board_config(const struct sim_config *sc, const struct sim_field *f,
		       struct board_config *bc);

/* Start the robot at the board's start pose (plus the simulator's start error) and the board
 * on the first sensor reading. Returns 0, -1 for a bad board configuration, or the
 * simulator's error. Interrupt-safe: no (there are none on the host). */
int host_init(struct host *h, const struct board_config *bc, const struct sim_config *sc,
	      const struct sim_field *f);

/* One control period: the board's tick on the current sensors, then the physics over the
 * period with the new duties. */
void host_tick(struct host *h);

/* I2C master side, between two ticks: a write of n bytes (stop = 0: the next read follows by a
 * repeated start), and a read of n bytes ending with a STOP. */
void host_i2c_write(struct host *h, const uint8_t *data, uint8_t n, int stop);
void host_i2c_read(struct host *h, uint8_t *out, uint8_t n);

#endif
