/* The PID and the polar control run on the AVR (pid.c and control.c as the firmware compiles them,
 * their assembly included) on operations the host sends through simavr: test_avr_control
 * compares each result with the host's portable C. Compiled like the firmware (-O2 -flto). */
#include <avr/io.h>
#include <stddef.h>
#include <stdint.h>

#include "control_avr.h"
#include "fixmath_avr/fixmath_avr.h"

/* The mailbox, laid out as control_avr.h says (the AVR has no padding). Only the operation is
 * volatile: the host writes it last and waits for it to be 0 again; the compiler barriers keep
 * the arguments' reads and the results' writes between the two. */
static struct {
	volatile uint8_t op;
	uint8_t unused[CTA_OFF_ARGS - 1];
	int32_t arg[CTA_N_ARGS];
	int32_t res[CTA_N_RES];
} box;
static struct cta_state state;

typedef char layout_check[offsetof(__typeof__(box), res) == CTA_OFF_RES ? 1 : -1];

int main(void)
{
	GPIOR1 = (uint8_t)(uintptr_t)&box;
	GPIOR2 = (uint8_t)((uintptr_t)&box >> 8);
	GPIOR0 = FXA_READY;
	for (;;) {
		uint8_t op = box.op;

		if (op == 0)
			continue;
		__asm__ volatile("" ::: "memory");
		cta_run(&state, op, box.arg, box.res);
		__asm__ volatile("" ::: "memory");
		box.op = 0;
	}
}
