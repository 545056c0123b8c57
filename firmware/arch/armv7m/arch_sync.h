/* Ordering between the servo's interrupt and the planner on ARMv7-M: one core, so the
 * reference's compiler barrier. */
#include "../generic/arch_sync.h"
