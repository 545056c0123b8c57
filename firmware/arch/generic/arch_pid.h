/* The PID's small-error kernel: pid_update() (pid.h) first offers each tick to
 * pid_arch_update_small(c, &err_um, &out_q15). An architecture whose general C is slow gives it
 * a faster form of the common case; it returns 1 with the state and *out_q15 exactly as pid.c's
 * portable C would leave them, or 0 having changed nothing. The portable C is the reference, and
 * on this architecture it is also the fastest form: there is no kernel, every tick declines.
 *
 * The kernel's domain is the architecture's too: struct arch_pid_fast, a member of struct pid
 * that pid.c sets through pid_arch_fast_init() when the gains change and never reads, and the
 * mark pid.c keeps of the previous error (pid_arch_fast_mark(): pid.c reads only whether it is
 * 0). This header gives the reference's (the one firmware/arch/avr uses): errors and their
 * differences within 16 bits, each term below 2^29 so that P + D needs no clip, and a previous
 * error within 16 bits. It computes them even where no kernel uses them, so that a test on any
 * machine knows which ticks a kernel takes (harness/avr's test_avr_control), and so that every
 * architecture's state has the same bits.
 *
 * pid.h includes this header twice: before struct pid for the domain, and after it, with
 * PID_ARCH_KERNEL defined, for the kernel, which reads struct pid's fields. */
#ifndef PID_ARCH_KERNEL
#ifndef ASSERV_ARCH_PID_FAST_H
#define ASSERV_ARCH_PID_FAST_H

#include <stdint.h>

/* The bound on P and D [2^-12 duty_q15] in the kernel's domain: their sum fits without a clip. */
#define ARCH_PID_FAST_TERM_MAX ((int32_t)1 << 29)

struct arch_pid_fast {
	/* The kernel takes an error up to p_err_um and a difference up to d_err_um [um] (each
	 * at most 32767). */
	int16_t p_err_um;
	int16_t d_err_um;
};

/* The largest error that the kernel multiplies by k [2^-12 duty_q15 per um, >= 0]: it fits
 * 16 bits, and k e < 2^29. */
static inline int16_t pid_arch_fast_bound(int32_t k)
{
	int32_t m = k == 0 ? INT16_MAX : (ARCH_PID_FAST_TERM_MAX - 1) / k;

	return (int16_t)(m < INT16_MAX ? m : INT16_MAX);
}

/* The domain for the gains kp_q12 and kd_q12 (struct pid). Plan time. */
static inline void pid_arch_fast_init(struct arch_pid_fast *f, int32_t kp_q12, int32_t kd_q12)
{
	f->p_err_um = pid_arch_fast_bound(kp_q12);
	f->d_err_um = pid_arch_fast_bound(kd_q12);
}

/* struct pid's has_prev after a tick of the portable C with the error e_um [um], which becomes
 * the previous one: 2 when it fits 16 bits (the kernel's next difference can be taken in 16
 * bits; the kernel leaves 2 too), else 1. Never 0, which means no previous error. */
static inline uint8_t pid_arch_fast_mark(int32_t e_um)
{
	return e_um >= INT16_MIN && e_um <= INT16_MAX ? 2 : 1;
}

#endif
#elif !defined(ASSERV_ARCH_PID_H)
#define ASSERV_ARCH_PID_H

static inline uint8_t pid_arch_update_small(struct pid *c, int32_t *err_um, int16_t *out_q15)
{
	(void)c;
	(void)err_um;
	(void)out_q15;
	return 0;
}

#endif
