/* The fixed-point kernels of fixmath.h for an ARMv7-M core (Cortex-M3, M4: the STM32 port): the
 * plain C reference of firmware/arch/generic/arch_fx.h, but for the kernels listed here, which
 * use the core's CLZ and hardware divide. Each gives the reference's bits (test_arch_armv7m on
 * the host; harness/stm32's sessions compare the binary's whole state with the host build's).
 *
 * Why: the error radius's fusion of a position fix (uncertainty_fuse_begin(), _step()) takes
 * square roots of 32 bits, a corner's planning (motion.c) ten of 64 bits in one planner period;
 * the references' take several times the instructions on a Cortex-M4 (bench/stm32.py --fixes
 * and --corners print those periods' load). */
#ifndef ASSERV_ARCH_ARMV7M_FX_H
#define ASSERV_ARCH_ARMV7M_FX_H

#if !defined(__GNUC__) || !defined(__ARM_ARCH) || __ARM_ARCH < 7
#error "firmware/arch/armv7m: GCC for ARMv7-M (CLZ, UDIV); other targets use firmware/arch/generic"
#endif

#include "arch_isqrt.h"

#define ARCH_FX_ISQRT32_REM fx_isqrt32_rem_newton
#define ARCH_FX_ISQRT64 fx_isqrt64_newton

#include "../generic/arch_fx.h"

#endif
