/* Ordering between the servo's interrupt and the planner's main loop: the generic compiler
 * barrier (one core, no cache). */
#include "../generic/arch_sync.h"
