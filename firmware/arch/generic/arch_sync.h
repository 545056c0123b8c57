/* Ordering between the servo's interrupt and the planner's context (board.h): arch_barrier()
 * keeps the compiler from moving memory accesses across it. Both contexts run on one core, so a
 * compiler barrier is enough: the planner's hand-over is complete in memory before the flag
 * that passes it, and the snapshot is read after the flag that says it is there. */
#ifndef ASSERV_ARCH_SYNC_H
#define ASSERV_ARCH_SYNC_H

#ifdef __GNUC__
#define arch_barrier() __asm__ __volatile__("" ::: "memory")
#else
#define arch_barrier() ((void)0)
#endif

#endif
