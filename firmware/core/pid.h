/* PID on a following error (set point minus measure), used by both polar loops (distance and
 * rotation expressed as wheel arc): error in um in, duty out.
 *
 * Gains are in the protocol's units (protocol/messages.toml SET_FILTRE_RAW):
 *   p [2^-12 full duty per mm of error]
 *   i [2^-12 full duty per mm*s of integrated error]
 *   d [2^-16 full duty per mm/s of error rate]
 * so that duty_q15 = 32768 * (p 2^-12 e_mm + i 2^-12 integral_mm_s + d 2^-16 de_dt_mm_s).
 * The derivative is taken on the error difference between two ticks. docs/control.md "PID" gives
 * the fixed-point formats and the anti-windup.
 */
#ifndef ASSERV_PID_H
#define ASSERV_PID_H

#include <stdint.h>

#include "fixmath.h"

#include "arch_pid.h" /* struct arch_pid_fast: the domain of the architecture's kernel */

#define PID_TICK_HZ_MIN 100
#define PID_TICK_HZ_MAX 2000
/* Errors beyond this are clipped [um] (4.19 m: more than the field's diagonal). */
#define PID_ERR_MAX_UM 4194304

struct pid_config {
	uint16_t p;            /* [2^-12 full duty per mm] 0..65535 */
	uint16_t i;            /* [2^-12 full duty per mm*s] 0..65535 */
	uint16_t d;            /* [2^-16 full duty per mm/s] 0..65535 */
	int16_t out_limit_q15; /* [2^-15 full duty] 1..32767: |output| <= this */
	uint16_t tick_hz;      /* [Hz] PID_TICK_HZ_MIN..PID_TICK_HZ_MAX */
};

/* Gains converted once: P and D to [2^-12 duty_q15] per um and per um/tick, I to [2^-24 duty_q15]
 * per um*tick (docs/control.md "PID"). */
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
	int32_t prev_err_um;
	/* 0 after a reset (the first derivative is 0), else the architecture's mark of the previous
	 * error (arch_pid.h: pid_arch_fast_mark). */
	uint8_t has_prev;
	int16_t out_q15; /* last output */
};

/* Set the gains, limit and tick rate, and reset. Returns 0, or -1 if cfg is out of range.
 * Interrupt-safe: no. */
int pid_init(struct pid *c, const struct pid_config *cfg);

/* Change the settings while running (e.g. SET_FILTRE_RAW). The integral is kept as a duty, so a
 * new i gain does not make the output jump; it is clipped to the new limit. Returns 0, or -1
 * (nothing changed) if cfg is out of range. Interrupt-safe: no (same context as pid_update). */
int pid_set_config(struct pid *c, const struct pid_config *cfg);

/* Forget the integral and the previous error (e.g. when the loop is disabled or the set point
 * is reset). Interrupt-safe: no (same context as pid_update). */
void pid_reset(struct pid *c);

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

	if (pid_arch_update_small(c, &err_um, &out_q15))
		return out_q15;
	return pid_update_c(c, err_um);
}

#endif
