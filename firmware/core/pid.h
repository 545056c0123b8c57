/* PID on a following error (set point minus measure), used by both polar loops (distance and
 * rotation expressed as wheel arc): error in um in, duty out.
 *
 * Gains are in the protocol's units (protocol/messages.toml SET_FILTRE_RAW):
 *   p [2^-12 full duty per mm of error]
 *   i [2^-12 full duty per mm*s of integrated error]
 *   d [2^-16 full duty per mm/s of error rate]
 * so that duty_q15 = 32768 * (p 2^-12 e_mm + i 2^-12 integral_mm_s + d 2^-16 de_dt_mm_s).
 * The derivative is the error's change from a first-order low-pass of the error, of time
 * constant 2^d_shift ticks (d_shift 0: the change between two ticks), which is the low-pass of
 * the tick-to-tick change: one encoder count is read as a speed spread over 2^d_shift ticks, not
 * a kick in one. The low-pass lags the error by at most d_lag_max_um: beyond, the raw change goes
 * through. docs/control.md "PID" gives the fixed-point formats, the low-pass and the
 * anti-windup.
 */
#ifndef ASSERV_PID_H
#define ASSERV_PID_H

#include <stdint.h>

#include "feature_set.h" /* CONFIG_QUIET_SERVO: the derivative's low-pass */
#include "fixmath.h"

#include "arch_pid.h" /* struct arch_pid_fast: the domain of the architecture's kernel */

#define PID_TICK_HZ_MIN 100
#define PID_TICK_HZ_MAX 2000
/* Errors beyond this are clipped [um] (4.19 m: more than the field's diagonal). */
#define PID_ERR_MAX_UM 4194304
/* The derivative's low-pass: a time constant of at most 2^PID_D_SHIFT_MAX ticks. */
#define PID_D_SHIFT_MAX 6

struct pid_config {
	uint16_t p;            /* [2^-12 full duty per mm] 0..65535 */
	uint16_t i;            /* [2^-12 full duty per mm*s] 0..65535 */
	uint16_t d;            /* [2^-16 full duty per mm/s] 0..65535 */
	int16_t out_limit_q15; /* [2^-15 full duty] 1..32767: |output| <= this */
	uint16_t tick_hz;      /* [Hz] PID_TICK_HZ_MIN..PID_TICK_HZ_MAX */
#if CONFIG_QUIET_SERVO
	/* The derivative's low-pass: time constant 2^d_shift ticks, 0..PID_D_SHIFT_MAX (0: the
	 * raw difference of two ticks' errors). A build without CONFIG_QUIET_SERVO has neither
	 * field: its derivative is the raw difference. */
	uint8_t d_shift;
	/* [um] the low-pass lags the error by at most this (d_shift > 0): a change of the error's
	 * rate beyond quantization (a shock, a rebound) is read at once, not over 2^d_shift ticks.
	 * 1..PID_ERR_MAX_UM. */
	int32_t d_lag_max_um;
#endif
};

/* Gains converted once: P and D to [2^-12 duty_q15] per um and per 2^d_shift um/tick, I to
 * [2^-24 duty_q15] per um*tick (docs/control.md "PID"). */
struct pid {
	struct pid_config cfg;
	int32_t kp_q12;
	int32_t kd_q12;
	uint32_t ki_q24; /* below 2^27: i 65535 at 100 Hz is 87 958 863 */
	/* P and D are each clipped to 8 times the full duty (2^30 [2^-12 duty_q15]): beyond these
	 * errors. */
	int32_t p_err_max_um;
	int32_t d_err_max_um;
	struct arch_pid_fast fast; /* the architecture's, set from kp and kd (arch_pid.h) */
	int32_t i_max_q8;          /* out_limit_q15 << 8: the integral's bound, as its upper part */
	struct fx48 i_acc_q24; /* [2^-24 duty_q15] integral contribution, |.| <= out_limit * 2^24 */
	/* The error the derivative is taken from: with d_shift 0 the previous tick's, else the
	 * low-pass's, floor(d_lp / 2^d_shift). */
	int32_t prev_err_um;
	/* 0 after a reset, else the architecture's mark of prev_err_um (arch_pid.h:
	 * pid_arch_fast_mark). The tick after a reset reads no change of the error: with d_shift 0
	 * the derivative is 0; else the low-pass first moves with the error's jump (a set point's
	 * jump is not a speed), and the derivative goes on from what it had read. */
	uint8_t has_prev;
	int16_t out_q15; /* last output */
#if CONFIG_QUIET_SERVO
	/* With d_shift > 0 only: the low-pass of the error [2^-d_shift um], and the last error
	 * [um] (clipped), from which a reset's jump is measured. pid_forget zeroes both. */
	int32_t d_lp;
	int32_t d_last_um;
	/* With d_shift > 0: the derivative is the raw change of two ticks' errors while set
	 * (pid_set_raw_d()), the low-pass following the error at rest. */
	uint8_t raw_d;
#endif
};

/* Set the gains, limit and tick rate, and reset. Returns 0, or -1 if cfg is out of range.
 * Interrupt-safe: no. */
int pid_init(struct pid *c, const struct pid_config *cfg);

/* Change the settings while running (e.g. SET_FILTRE_RAW). The integral is kept as a duty, so a
 * new i gain does not make the output jump; it is clipped to the new limit. Returns 0, or -1
 * (nothing changed) if cfg is out of range. Interrupt-safe: no (same context as pid_update). */
int pid_set_config(struct pid *c, const struct pid_config *cfg);

/* Forget the integral and the previous error (e.g. when the loop is disabled or the set point
 * is reset); the derivative's low-pass keeps what it read (has_prev above). Interrupt-safe: no
 * (same context as pid_update). */
void pid_reset(struct pid *c);

/* pid_reset, and forget the low-pass too (the motors are off: the PID no longer runs, what it
 * read goes stale). Interrupt-safe: no (same context as pid_update). */
void pid_forget(struct pid *c);

/* raw 1: the derivative is the raw change of two ticks' errors (as with d_shift 0, the same
 * gain), not the low-pass's, until set back to 0; the low-pass then starts from the last error,
 * at rest (a robot braked to rest after a shock, orders_raw_d()). Interrupt-safe: no (same
 * context as pid_update). */
static inline void pid_set_raw_d(struct pid *c, uint8_t raw)
{
#if CONFIG_QUIET_SERVO
	c->raw_d = raw;
#else
	(void)c;
	(void)raw;
#endif
}

/* 1 when the derivative goes through the low-pass (d_shift > 0, in a build that has it). */
static inline uint8_t pid_d_filtered(const struct pid *c)
{
#if CONFIG_QUIET_SERVO
	return c->cfg.d_shift != 0;
#else
	(void)c;
	return 0;
#endif
}

/* One tick with the following error err_um [um] (any int32; clipped to +/-PID_ERR_MAX_UM).
 * Returns the duty [2^-15 full duty], within +/-out_limit_q15. Anti-windup: the integral's
 * contribution is clipped to the output limit, and the integral does not grow while the output
 * is saturated in the direction of the error. No division. Interrupt-safe: yes. */
static inline int16_t pid_update(struct pid *c, int32_t err_um);

/* pid_update in portable C, on any error: the reference of the architecture's kernel. */
int16_t pid_update_c(struct pid *c, int32_t err_um);

#define PID_ARCH_KERNEL
#include "arch_pid.h" /* pid_arch_update_small(), which reads struct pid */

/* The architecture's small-error kernel when it takes the tick, else the portable C. */
static inline int16_t pid_update(struct pid *c, int32_t err_um)
{
	int16_t out_q15;

	if (!pid_d_filtered(c) && pid_arch_update_small(c, &err_um, &out_q15))
		return out_q15;
	return pid_update_c(c, err_um);
}

#endif
