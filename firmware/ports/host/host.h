/* The host port: the HAL implemented on the simulator (sim/), in deterministic lockstep. One
 * struct host is one simulated board on one simulated robot; many can exist in a process. */
#ifndef ASSERV_HOST_H
#define ASSERV_HOST_H

#include <stdint.h>

#include "board.h"
#include "host_sample_gen.h"
#include "nvm_bytes.h"
#include "sim.h"

/* The simulated board's storage [bytes]: RAM, erased to 0xFF, written at once. */
#define HOST_NVM_SIZE 64u

/* The byte storage under hal_nvm.h (nvm_bytes.h's lower layer), one per simulated board: the
 * EEPROM it models. */
struct nvm_bytes_dev {
	uint8_t mem[HOST_NVM_SIZE];
};

struct host {
	struct sim sim;
	struct board board;
	uint64_t tick_ns; /* control period */
	uint64_t ticks;   /* control periods run */
	uint64_t now_ns;  /* host_advance_ns()'s clock: control tick k runs at k * tick_ns */
	struct nvm_bytes_dev storage; /* the board's storage: kept by host_power_cycle() */
	struct hal_nvm nvm;           /* the calibration's records in it (hal_nvm.h) */
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

/* The storage as a board finds it at power-on: n bytes of data (n <= HOST_NVM_SIZE; data may be
 * NULL with n 0), the rest erased (0xFF). Takes effect at the next host_power_cycle(): host_init()
 * starts with an erased storage. Returns 0, or -1 if n is too large (nothing changes). */
int host_nvm_set(struct host *h, const uint8_t *data, uint16_t n);

/* A power cycle between two ticks: the board starts again as at power-on (board_init() with the
 * configuration it was started with, on the sensors of now, then the calibration its storage
 * holds, hal_nvm_load()), the motors off, the I2C transaction in progress lost. The robot stays
 * where it is, the clock and the storage go on. Returns host_init()'s board result: 0 or -1. */
int host_power_cycle(struct host *h);

/* A reset between two ticks, of a cause (RESET_CAUSE_*): the motors off for down_ms (the robot
 * coasts, the physics runs, the board does not), then the board starts again with that cause
 * (board_restart()) from the RAM it kept (keep_ram 1) or from RAM scrambled by the reset
 * (keep_ram 0: a brown-out deep enough to lose it), then the calibration its storage holds.
 * RESET_CAUSE_POWER_ON is host_power_cycle(). Returns 0 or -1. */
int host_reset(struct host *h, uint8_t cause, int keep_ram, uint16_t down_ms);

/* One control period: the board's tick on the current sensors, then the physics over the
 * period with the new duties. */
void host_tick(struct host *h);

/* I2C master side, between two ticks: a write of n bytes (stop = 0: the next read follows by a
 * repeated start), and a read of n bytes ending with a STOP. */
void host_i2c_write(struct host *h, const uint8_t *data, uint8_t n, int stop);
void host_i2c_read(struct host *h, uint8_t *out, uint8_t n);

/* struct host_sample: one row of the trace host_advance_ns() records at each control tick, after
 * the board's tick (all doubles, so that Python reads a buffer of them as a structured array).
 * Truth is the simulator's, estimates the board's. Its columns are trace.toml's, generated into
 * host_sample_gen.h and python/asserv/_columns.py by gen_trace.py. */

/* Runs the simulated board for duration_ns: control ticks at multiples of tick_ns (the first at
 * now_ns = 0), the physics in between, so that an I2C byte can arrive at any instant between two
 * ticks (host_i2c_* act at now_ns). Records one host_sample per tick into buf while fewer than
 * cap are recorded (buf may be NULL with cap 0) and stops early when buf is full, so that the
 * caller can empty it and call again. Returns the nanoseconds advanced; *n_out receives the
 * samples written. */
uint64_t host_advance_ns(struct host *h, uint64_t duration_ns, struct host_sample *buf,
			 uint32_t cap, uint32_t *n_out);

#endif
