/* Leaving the application for the bootloader (BOOTLOADER, docs/update.md): the motors off, the
 * request words at the end of RAM (boot_layout.h), then a system reset (PM0214 4.4.5), after
 * which the bootloader finds the request and serves the update instead of starting the
 * application again. */
#include "boot_layout.h"
#include "hal.h"
#include "stm32_port.h"
#include "stm32f4_regs.h"

#define SCB_AIRCR STM32_REG(0xE000ED0Cu) /* PM0214 4.4.5 */
#define SCB_AIRCR_SYSRESET (0x05FAu << 16 | 1u << 2)

void stm32_boot_enter(void)
{
	volatile uint32_t *request = (volatile uint32_t *)(uintptr_t)BOOT_REQUEST_ADDR;

	__asm__ volatile("cpsid i" ::: "memory");
	hal_motor_set(HAL_LEFT, 0);
	hal_motor_set(HAL_RIGHT, 0);
	request[0] = BOOT_REQUEST_MAGIC;
	request[1] = ~BOOT_REQUEST_MAGIC;
	__asm__ volatile("dsb" ::: "memory");
	SCB_AIRCR = SCB_AIRCR_SYSRESET;
	for (;;)
		;
}
