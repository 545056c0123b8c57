/* The AVR firmware binary run in simavr, in lockstep with the robot physics (sim/): the
 * harness plays the I2C master at a real bus speed (it models the ATmega's TWI slave itself,
 * because simavr 1.6's is broken), feeds the quadrature edges of the four encoders at the cycles
 * the physics gives, drives the switches, line sensors and current-sense inputs, and reads the
 * PWM duty back from the timer registers. Deterministic: the same binary and inputs give the
 * same cycles and bits. docs/avr.md describes the lockstep modes. */
#ifndef ASSERV_HARNESS_AVRSIM_H
#define ASSERV_HARNESS_AVRSIM_H

#include <stdint.h>
#include <stdio.h>

#include "avr_layout.h"
#include "sim.h"

#define AVRSIM_F_CPU 16000000u

enum avrsim_lockstep {
	/* No physics: the inputs stay as avrsim_open() set them (at rest, nothing pressed). */
	AVRSIM_NO_PHYSICS = 0,
	/* The physics follows the cycles: 100 us substeps of 1600 cycles from the first control
	 * period on, edges interpolated inside each substep, the duty read at each substep's
	 * start. What the board sees on a robot, latencies included. */
	AVRSIM_REALTIME,
	/* The physics stands still from the control timer's compare match until the tick has
	 * written its duties (the TICK pin falls); the period's 1 ms of physics then runs, with
	 * that duty, in the cycles left before the next compare match (less a guard). The tick
	 * therefore samples the sensors of the instant of its compare match and its duty acts
	 * from that instant: the timing of the native host port, so that both runs can be
	 * compared bit for bit. With two rates only the servo stands still: the slow steps
	 * run in real cycles, in the window, and the servo preempts them if they run past the
	 * next compare match (avrsim_run_to_slow_done() lets a master wait for them, as the
	 * native run's master finds them done). */
	AVRSIM_EXACT,
};

struct avrsim_count {
	uint64_t n;      /* occurrences */
	uint64_t cycles; /* sum */
	uint64_t max;
};

struct avrsim_stats {
	uint64_t cycles;                /* simulated since the last reset of the stats */
	uint64_t idle;                  /* of which asleep */
	struct avrsim_count tick;       /* TICK pin high, rise to fall (interrupts included) */
	struct avrsim_count servo;      /* the same without the interrupts that ran inside it */
	struct avrsim_count servo_slow; /* two rates: servo, at the slow ticks only (the hand-over
					 * and the snapshot: one tick in 2^slow_shift) */
	struct avrsim_count servo_handover; /* two rates: servo, at the ticks that take the slow
					     * steps' results (planner_ticks after a slow tick) */
	struct avrsim_count servo_other; /* servo, at the other ticks (all of them with one rate) */
	struct avrsim_count slow;        /* two rates: each run of the slow steps (SLOW pin high),
					  * without the servo and the interrupts that preempted it */
	struct avrsim_count period;      /* cycles awake per control period (compare to compare),
					  * with the interrupts' 4-cycle responses */
	struct avrsim_count isr_sum; /* cycles of interrupts (the servo's own excluded) per control
				      * period, responses included */
	struct avrsim_count fast;    /* the servo's and the interrupts' cycles per control period */
	struct avrsim_count window;  /* cycles awake in 2^slow_shift consecutive control periods
				      * (a slow period, at any phase; one period with one rate) */
	struct avrsim_count isr[64]; /* per vector, each with its 4-cycle response; max: the
				      * longest, without what nested in it. The servo is not its
				      * vector's (it is servo above) */
	struct avrsim_count twi[32]; /* the TWI interrupt per status (index status >> 3) */
	struct avrsim_count stretch[32]; /* SCL held low past the master's low half-period,
					  * per status that held it [cycles] */
	uint64_t twi_bytes;              /* address and data bytes on the bus */
	uint64_t edges;                  /* encoder edges delivered */
	struct avrsim_count edge_wait;   /* from an encoder edge to the first instruction of the
					  * interrupt that reads it [cycles] */
	uint64_t stop_pending_at_start;  /* a START waited for the last STOP's interrupt */
	uint64_t compares_held;          /* exact mode: compare matches whose interrupt waited
					  * for the master (avrsim_master_hold()) */
	uint16_t sp_min;                 /* lowest stack pointer seen */
};

struct avrsim;

/* Loads the ELF (an ATmega1284P at 16 MHz), resets it, drives every input pin to rest (encoders
 * at count 0, switches open, no line, 0 A) and the bus idle. i2c_hz: SCL frequency of the
 * master, 100000 or 400000. Returns NULL with a message on stderr. */
struct avrsim *avrsim_open(const char *elf_path, uint32_t i2c_hz);
void avrsim_close(struct avrsim *h);

/* The EEPROM (AVRSIM_EEPROM_SIZE bytes, 0xFF after avrsim_open(), as a new chip), read or
 * written as a programmer would, between two runs: n bytes from offset. Return 0, or -1 when the
 * range leaves the EEPROM (nothing done). The firmware's own writes go through simavr's EEPROM
 * model (its EEPE clears at once: a write is never seen in progress). */
#define AVRSIM_EEPROM_SIZE 4096u
int avrsim_eeprom_read(const struct avrsim *h, uint16_t offset, uint8_t *buf, uint16_t n);
int avrsim_eeprom_write(struct avrsim *h, uint16_t offset, const uint8_t *buf, uint16_t n);

/* A power cycle: the same binary starts again from reset in a new simulated chip (RAM,
 * registers, cycle count and statistics lost, the inputs at rest, the bus idle, no physics)
 * that keeps the EEPROM's contents. h is closed. Returns the new harness, or NULL with a
 * message on stderr. */
struct avrsim *avrsim_power_cycle(struct avrsim *h);

/* A reset now, between two instructions, that leaves MCUSR's flags mcusr (AVRSIM_*RF: the
 * datasheet's 10.2) as the chip's reset logic would: the registers and I/O to their reset values
 * (the PWM off at once), the program from address 0, while the physics, the encoder wires and
 * the inputs go on in real time (the firmware's start-up takes its cycles). The RAM keeps its
 * contents (keep_ram 1), or is filled with bytes drawn from seed (the supply fell below what
 * holds it). The bus must be idle. Returns 0, or -1 with a message on stderr. */
#define AVRSIM_PORF 0x01u
#define AVRSIM_EXTRF 0x02u
#define AVRSIM_BORF 0x04u
#define AVRSIM_WDRF 0x08u
#define AVRSIM_JTRF 0x10u
int avrsim_reset(struct avrsim *h, uint8_t mcusr, int keep_ram, uint32_t seed);

/* Attaches the physics before the first control period (the robot at rest: the board's counts
 * at reset are the simulator's). sc, f are copied. Returns 0 or -1. */
int avrsim_physics(struct avrsim *h, const struct sim_config *sc, const struct sim_field *f,
		   enum avrsim_lockstep mode);

/* Runs until the TICK pin falls (a control period's work is done; its duties are set). */
int avrsim_run_to_tick_end(struct avrsim *h);
/* Two rates: runs until the slow steps the servo handed over are done (the board's slow_due
 * back to 0 and the SLOW pin low), or until the next tick ends if that comes first. Returns 0
 * (done; at once with one rate or nothing due), 1 (a tick ended first: deal with it, call
 * again), -1 on error. */
int avrsim_run_to_slow_done(struct avrsim *h);
/* Runs until the slow steps have run once (the SLOW pin falls) and the servo has taken their
 * results, at the next hand-over (the tick that makes them due again): the queue is taken and
 * the replies published then. With one rate, one tick (it runs them). */
int avrsim_run_slow_steps(struct avrsim *h);
/* Runs until the firmware sleeps between two ticks (TICK pin low). */
int avrsim_run_until_idle(struct avrsim *h);
/* Runs n cycles (at least). */
int avrsim_run_cycles(struct avrsim *h, uint64_t n);

/* I2C master transactions, blocking: the AVR (and the physics) run while the bus does.
 * avrsim_i2c_write: S (or Sr if the bus is held) 0x04 [data...], then P if stop, otherwise the
 * bus stays held for a read by repeated start. n may be 0 (address only). avrsim_i2c_read:
 * S or Sr, 0x05, n bytes (the last NACKed), P. Return 0, or -1 on a NACK or a timeout. */
int avrsim_i2c_write(struct avrsim *h, const uint8_t *data, uint8_t n, int stop);
int avrsim_i2c_read(struct avrsim *h, uint8_t *out, uint8_t n);

/* The 7-bit address the master's next transactions go to (PROTO_ADDRESS after open). */
void avrsim_i2c_address(struct avrsim *h, uint8_t address);

/* Masks or unmasks the control timer's interrupt (as a debugger would): with it masked, no
 * tick runs and the protocol's queue and snapshot stay as they are. */
void avrsim_tick_enable(struct avrsim *h, int on);

/* Exact mode (nothing in the others): with on, the master is about to act between two ticks,
 * as the native run's master does; a compare match that comes before it is done (off) waits:
 * its interrupt is held until then, and the control timer and the physics stand still from the
 * compare match as for any tick, so the tick samples the same inputs and its duty acts from
 * the same instant. The firmware sees a compare match at the end of the hold. Meant for a
 * master that waited for the slow steps (avrsim_run_to_slow_done()), which would otherwise go
 * on during the hold. Returns 1 without holding if a compare match has already come and its
 * tick not ended (run it first: avrsim_run_to_tick_end()), else 0. */
int avrsim_master_hold(struct avrsim *h, int on);

/* Without physics: the four encoders (as below) turn at constant rates [counts/s, signed] from
 * now on, their edges evenly spaced. Returns 0, or -1 with physics attached. */
int avrsim_encoders_turn(struct avrsim *h, const double counts_per_s[4]);

/* Without physics: the shock switches, the basket contact, the line sensors and the motor
 * currents of s (shock_mask, basket, line_mask, current_mA) on the pins and ADC inputs from
 * now on. Returns 0, or -1 with physics attached. */
int avrsim_sensors_set(struct avrsim *h, const struct sim_sensors *s);

/* Encoder e (0 free left, 1 free right, 2 motor left, 3 motor right): the count its pins show
 * now, from the edges delivered so far (the physics' count at the edge). */
int64_t avrsim_encoder_edges(const struct avrsim *h, int e);

/* The data address of a variable of the binary, by name. Returns 0, or -1 if there is none. */
int avrsim_symbol(const struct avrsim *h, const char *name, uint16_t *addr);

/* 1 when no interrupt runs and none is pending. */
int avrsim_interrupts_idle(const struct avrsim *h);

/* The board in the AVR's RAM: its data address and the layout record (avr_layout.h). */
uint16_t avrsim_board(const struct avrsim *h);
const struct avr_layout *avrsim_layout(const struct avrsim *h);
void avrsim_peek(const struct avrsim *h, uint16_t addr, void *buf, uint16_t n);
void avrsim_poke(struct avrsim *h, uint16_t addr, const void *buf, uint16_t n);

/* The physics the AVR drives (NULL without it), the current cycle, the cycle of the next
 * compare match of the control timer, and the control periods seen. */
const struct sim *avrsim_sim(const struct avrsim *h);
uint64_t avrsim_cycle(const struct avrsim *h);
uint64_t avrsim_next_compare(const struct avrsim *h);
uint64_t avrsim_ticks(const struct avrsim *h);

/* The binary's cfg.slow_shift (the slow steps every 2^n ticks; 0: one rate), read at its first
 * tick (0 before). 1 while the slow steps are due or running (always 0 with one rate). */
uint8_t avrsim_slow_shift(const struct avrsim *h);
int avrsim_slow_pending(const struct avrsim *h);

/* Statistics since the last avrsim_stats_reset(). */
const struct avrsim_stats *avrsim_stats(const struct avrsim *h);
void avrsim_stats_reset(struct avrsim *h);

/* Per-function profile (slower): cycles attributed to the function whose code runs (self) and
 * to every function on the call stack (inclusive), interrupts apart from what they preempt.
 * Two parts: the tick (TICK pin high; with two rates the servo) and the slow steps (SLOW pin
 * high, the servo that preempts them excluded). With tick_only, nothing else; otherwise the
 * rest goes with the tick. Starts from zero. The report lists a part's top functions by
 * inclusive cycles, divided by per: over every run profiled, or (worst) in the longest run
 * alone. */
enum avrsim_part { AVRSIM_PART_TICK, AVRSIM_PART_SLOW };
void avrsim_profile(struct avrsim *h, int on, int tick_only);
void avrsim_profile_report(const struct avrsim *h, FILE *out, enum avrsim_part part, int top,
			   uint64_t per, int worst);

/* Flash and RAM of the binary (bytes): .text + .data, .data + .bss + .noinit. */
void avrsim_sizes(const struct avrsim *h, uint32_t *flash, uint32_t *ram);

/* The duty the physics receives for compare counts and a direction pin (high = backward),
 * [2^-15]: what the board's hal_motor_set() produces, as the motor sees it. */
int16_t avrsim_duty_q15(uint16_t counts, int backward);

#endif
