/* The PID's small-error kernel: pid_update() (pid.c) first offers each tick to
 * pid_arch_update_small(c, &err_um, &out_q15). An architecture whose general C is slow gives it
 * a faster form of the common case (errors and their differences within c->p_err_fast_um and
 * c->d_err_fast_um, the previous error within 16 bits: c->has_prev == 2); it returns 1 with the
 * state and *out_q15 exactly as pid.c's portable C would leave them, or 0 having changed
 * nothing. The portable C is the reference, and on this architecture it is also the fastest
 * form: there is no kernel, every tick declines. */
#ifndef ASSERV_ARCH_PID_H
#define ASSERV_ARCH_PID_H

#include <stdint.h>

#include "pid.h"

static inline uint8_t pid_arch_update_small(struct pid *c, int32_t *err_um, int16_t *out_q15)
{
	(void)c;
	(void)err_um;
	(void)out_q15;
	return 0;
}

#endif
