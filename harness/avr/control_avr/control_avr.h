/* The mailbox between test_avr_control (the host, through simavr) and control_avr.elf (the AVR),
 * and the operations on the PID and the polar control that both run: cta_run (control_ops.c) is
 * compiled for each, so the host's results come from the portable C and the AVR's from its
 * kernels (firmware/arch/avr). The handshake is fixmath_avr.h's (FXA_READY in GPIOR0, the mailbox's
 * address in GPIOR1:GPIOR2); the host writes the arguments, then the operation, and runs the AVR
 * until the operation byte is 0 again. Integers are little-endian, as the AVR stores them. */
#ifndef ASSERV_HARNESS_CONTROL_AVR_H
#define ASSERV_HARNESS_CONTROL_AVR_H

#include <stdint.h>

#include "control.h"
#include "odometry.h"
#include "pid.h"

#define CTA_N_ARGS 17
#define CTA_N_RES 32

#define CTA_OFF_OP 0                                /* uint8_t: the operation, 0 when done */
#define CTA_OFF_ARGS 4                              /* int32_t[CTA_N_ARGS] */
#define CTA_OFF_RES (CTA_OFF_ARGS + 4 * CTA_N_ARGS) /* int32_t[CTA_N_RES] */
#define CTA_SIZE (CTA_OFF_RES + 4 * CTA_N_RES)

/* The low-pass of the PIDs' derivative (CONFIG_QUIET_SERVO) is the portable C on both: the
 * AVR's firmware leaves it out, this binary has it, so that its bit identity on a 16-bit int is
 * tested all the same. res[0] is the function's return value (0 for void); the rest, the state
 * after it: the pid's
 * for CTA_PID_*, the control's for CTA_CTL_*, the position's and the kept sine and cosine for
 * CTA_ODO_ADVANCE (cta_run lists them). */
enum cta_op {
	CTA_NOP = 1,     /* nothing: the mailbox's own cycles */
	CTA_PID_INIT,    /* pid_init(p, i, d, out_limit_q15, tick_hz, d_shift, d_lag_max_um) */
	CTA_PID_SET,     /* pid_set_config(the same) */
	CTA_PID_RESET,   /* pid_reset() */
	CTA_PID_UPDATE,  /* pid_update(err_um) */
	CTA_PID_RAW_D,   /* pid_set_raw_d(raw) */
	CTA_CTL_INIT,    /* control_init(tick_hz, duty_max_q15, ff speed, accel, angle accel,
			  * the presets' p i d x 3, gain slew, d_filter_ms, d_lag_max_um) */
	CTA_CTL_GAINS,   /* control_set_gains(p, i, d) */
	CTA_CTL_PRESET,  /* control_set_gains(preset n), -1 for no such preset */
	CTA_CTL_RESET,   /* control_reset() */
	CTA_CTL_OFF,     /* control_off() */
	CTA_CTL_UPDATE,  /* control_update(sp_dist pos vel acc, sp_angle pos vel acc, dist_um,
			  * angle_um) */
	CTA_CTL_RAW_D,   /* control_raw_d(axes) */
	CTA_ODO_ADVANCE, /* odometry_arc_of(left_q16, right_q16, dtheta, heading) then
			  * odometry_advance() from x_um, y_um, x_frac, y_frac and the kept
			  * trig_turn32, trig_sin_q30, trig_cos_q30 */
	CTA_OPS
};

struct cta_state {
	struct pid pid;
	struct control ctl;
	struct odometry_position odo;
};

void cta_run(struct cta_state *s, uint8_t op, const int32_t *arg, int32_t *res);

#endif
