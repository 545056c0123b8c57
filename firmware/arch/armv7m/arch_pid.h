/* The PID's small-error kernel on ARMv7-M: the reference's (no kernel; pid.c's C is the fastest
 * form on a 32-bit core with a single-cycle multiply). pid.h includes it twice, as the
 * reference. */
#include "../generic/arch_pid.h"
