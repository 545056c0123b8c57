/* The shock switches, the basket contact and the line sensors (hal_sensors.h) on GPIOC, read
 * once per tick: that sampling is their debouncing (a bounce shorter than a period is seen at
 * most once), as on the AVR. Pins: pinmap.h. */
#include "hal.h"
#include "pinmap.h"
#include "stm32_gpio.h"
#include "stm32_port.h"
#include "stm32f4_regs.h"

void stm32_sensors_init(void)
{
	RCC_AHB1ENR |= RCC_AHB1ENR_GPIOCEN;
	/* Switches to ground with pull-ups; line sensors drive their pins. */
	for (uint32_t pin = 0; pin <= PIN_BASKET; pin++)
		stm32_gpio_pull_up(PIN_SENSOR_PORT, pin);
}

uint8_t hal_shock_read(void)
{
	return (uint8_t)~GPIO_IDR(PIN_SENSOR_PORT);
}

uint8_t hal_basket_contact(void)
{
	return (uint8_t)(((GPIO_IDR(PIN_SENSOR_PORT) >> PIN_BASKET) & 1u) ^ 1u);
}

uint8_t hal_line_read(void)
{
	return (uint8_t)((GPIO_IDR(PIN_SENSOR_PORT) >> PIN_LINE0) & 0xFu);
}
