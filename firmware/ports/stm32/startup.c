/* Start-up of the STM32F4 port: the vector table (RM0390 10.2, Table 38; PM0214 2.3.4), the reset
 * handler that lays out RAM and calls main(), and the main loop's sleep. */
#include <stdint.h>

#include "stm32_port.h"
#include "stm32f4_regs.h"

/* From the linker script (stm32f446re.ld). _estack is declared as a function so that the
 * table, an array of function pointers, holds it without an object-to-function cast. */
extern void _estack(void);
extern uint32_t _sidata[], _sdata[], _edata[], _sbss[], _ebss[];

int main(void);
void Reset_Handler(void);
void Default_Handler(void);
void SysTick_Handler(void);
void I2C1_EV_IRQHandler(void);
void I2C1_ER_IRQHandler(void);

#define N_IRQ 97u /* the F446's (RM0390 Table 38: up to FMPI2C1 error, 96) */

/* Ten unused vectors. */
#define D Default_Handler
#define D10 D, D, D, D, D, D, D, D, D, D

__attribute__((section(".isr_vector"), used)) void (*const stm32_vectors[16u + N_IRQ])(void) = {
	_estack, Reset_Handler, D, D, D, D, D, D, D, D, D, D, D, D, D, SysTick_Handler,
	/* IRQ 0..29 */
	D10, D10, D10,
	/* IRQ 30, then 31 and 32 (RM0390 Table 38) */
	D, I2C1_EV_IRQHandler, I2C1_ER_IRQHandler,
	/* IRQ 33..96 */
	D10, D10, D10, D10, D10, D10, D, D, D, D};

void Reset_Handler(void)
{
	uint32_t *src = _sidata;
	uint32_t *dst = _sdata;

	while (dst < _edata)
		*dst++ = *src++;
	for (dst = _sbss; dst < _ebss;)
		*dst++ = 0;
	SCB_VTOR = (uint32_t)(uintptr_t)stm32_vectors;
	main();
	for (;;)
		;
}

/* A fault or an interrupt the port does not use: stop here, until the watchdog resets the chip
 * (main.c), which stops the motors. */
void Default_Handler(void)
{
	for (;;)
		;
}

/* One sleep of the main loop: the wfi is the function's first instruction, and the emulator
 * harness knows the CPU asleep when it reaches this address; an interrupt ends the wfi, and the
 * function returns after it. */
__attribute__((naked)) void stm32_idle(void)
{
	__asm__ volatile("wfi\n\tbx lr\n");
}
