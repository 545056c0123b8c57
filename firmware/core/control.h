/* Polar control: per axis, feed-forward from the profile's velocity and acceleration plus a PID
 * on the following error, then the mix of the two axes into the two motor duties. */
#ifndef ASSERV_CONTROL_H
#define ASSERV_CONTROL_H

#include <stdint.h>

#include "orders.h"
#include "pid.h"

#define CONTROL_N_PRESETS 3

/* SET_FILTRE_RAW's gains (units in pid.h). */
struct control_gains {
	uint16_t p;
	uint16_t i;
	uint16_t d;
};

struct control_config {
	int16_t duty_max_q15;                /* output limit of each motor */
	int32_t ff_speed_q15_per_m_s;        /* duty that holds a wheel speed of 1 m/s */
	int32_t ff_accel_q15_per_m_s2;       /* extra duty per m/s^2 along the distance axis */
	int32_t ff_angle_accel_q15_per_m_s2; /* ... and per m/s^2 of wheel arc when turning */
	/* A change of gains is bumpless: the step it makes in each axis's PID output is taken
	 * in no faster than this [duty_q15 per s], 1..2^24, distance and angle (docs/control.md
	 * "A change of gains"). */
	int32_t gain_slew_q15_per_s[2];
#if CONFIG_QUIET_SERVO
	/* [ms] the time constant of the PIDs' derivative's low-pass, rounded to a power of two
	 * ticks (pid_config.d_shift; docs/control.md "PID"); 0: the raw difference of two ticks */
	uint8_t d_filter_ms;
	/* [um] ... which lags the following error by at most this, 1..4194304 (pid_config) */
	int32_t d_lag_max_um;
#endif
	struct control_gains
		presets[CONTROL_N_PRESETS]; /* FILTRE_STD, FILTRE_SOUPLE, FILTRE_RAIDE */
};

/* An axis's feed-forward term of the acceleration, with the acceleration it is of. */
struct control_ff_memo {
	int32_t acc_um_s2;
	int32_t term_q15;
};

struct control {
	/* The fields of every tick first (the AVR reaches them by short offsets), the settings
	 * last. */
	int32_t k_speed_q20; /* [duty_q15 per um/s * 2^20] */
	int32_t k_accel_q20; /* [duty_q15 per um/s^2 * 2^20] */
	int32_t k_angle_accel_q20;
	uint8_t ff_narrow; /* all three below 2^16 */
	struct control_ff_memo
		ff_acc[2]; /* distance, angle: computed when the acceleration changes */
	struct pid dist;
	struct pid angle;
	int32_t dist_err_um; /* last following errors */
	int32_t angle_err_um;
	int16_t duty_q15[2];        /* last output, HAL_LEFT, HAL_RIGHT */
	uint8_t bumping;            /* a step pending or left on either axis (below) */
	uint16_t tick_hz;           /* the servo's rate [Hz] */
	struct control_gains gains; /* in effect */
	/* A change of gains: each axis's PID output before it (bit axis pending: the step is
	 * measured on the next tick), and what is left of the step [duty_q15], added to the
	 * PID's output and brought to 0 by slew_q15[] a tick. */
	int16_t bump_from_q15[2]; /* distance, angle */
	int32_t bump_q15[2];
	int32_t slew_q15[2];
	uint8_t bump_pending;
	struct control_config cfg;
};

/* At tick_hz ticks a second. Returns 0, or -1 when the configuration is out of range. Starts
 * with FILTRE_STD. Interrupt-safe: no. */
int control_init(struct control *c, const struct control_config *cfg, uint16_t tick_hz);

/* SET_FILTRE_RAW: gains on both axes; the integrals are kept, and the step the new P and D make
 * in the output is taken in at cfg->gain_slew_q15_per_s. Interrupt-safe: no. */
void control_set_gains(struct control *c, const struct control_gains *g);

/* Forget the integrals, derivatives and a change of gains' step (after a hard stop).
 * Interrupt-safe: no. */
void control_reset(struct control *c);

/* One tick: setpoints and measures of both axes [um] -> duties [q15] in duty_q15[].
 * Interrupt-safe: no. */
void control_update(struct control *c, const struct orders_axis *sp_dist,
		    const struct orders_axis *sp_angle, int32_t dist_um, int32_t angle_um);

/* bit 0 distance, bit 1 angle: that axis's PID reads the raw derivative (pid_set_raw_d()), while
 * it brakes to rest after a shock (orders_raw_d()). Interrupt-safe: no. */
static inline void control_raw_d(struct control *c, uint8_t axes)
{
	pid_set_raw_d(&c->dist, (uint8_t)(axes & 1u));
	pid_set_raw_d(&c->angle, (uint8_t)((axes >> 1) & 1u));
}

/* Motors off (PB_GRAVE). Interrupt-safe: no. */
void control_off(struct control *c);

#endif
