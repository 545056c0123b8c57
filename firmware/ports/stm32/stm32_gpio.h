/* Pin set-up helpers the STM32F4 port's files share (RM0390 7.4: GPIOx_MODER, AFRL/AFRH,
 * PUPDR), each pin's field changed alone. Start-up only, interrupts off. */
#ifndef ASSERV_STM32_GPIO_H
#define ASSERV_STM32_GPIO_H

#include <stdint.h>

#include "stm32f4_regs.h"

/* The pin's mode: GPIO_MODE_IN, _OUT, _AF or _ANALOG. */
static inline void stm32_gpio_mode(uint32_t port, uint32_t pin, uint32_t mode)
{
	GPIO_MODER(port) = (GPIO_MODER(port) & ~(3u << (2u * pin))) | mode << (2u * pin);
}

/* The pin to its alternate function af (RM0390 Table 11), then in AF mode. */
static inline void stm32_gpio_af(uint32_t port, uint32_t pin, uint32_t af)
{
	if (pin < 8u)
		GPIO_AFRL(port) = (GPIO_AFRL(port) & ~(0xFu << (4u * pin))) | af << (4u * pin);
	else
		GPIO_AFRH(port) =
			(GPIO_AFRH(port) & ~(0xFu << (4u * (pin - 8u)))) | af << (4u * (pin - 8u));
	stm32_gpio_mode(port, pin, GPIO_MODE_AF);
}

static inline void stm32_gpio_pull_up(uint32_t port, uint32_t pin)
{
	GPIO_PUPDR(port) = (GPIO_PUPDR(port) & ~(3u << (2u * pin))) | 1u << (2u * pin);
}

#endif
