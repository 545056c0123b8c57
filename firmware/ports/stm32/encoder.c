/* The four quadrature encoders (hal_encoder.h) on timers in encoder mode: no interrupt per edge.
 * Pins: pinmap.h. */
#include "hal.h"
#include "pinmap.h"
#include "stm32_gpio.h"
#include "stm32_port.h"
#include "stm32f4_regs.h"

/* Encoder mode 3 (RM0390 17.3.16): the counter counts up and down on both edges of both inputs,
 * x4, with no prescaler; a digital filter of 8 samples at the timer's clock (IC1F = IC2F = 3)
 * rejects glitches under 0.1 us. 16 bits, as hal_encoder.h wants. */
static void encoder_timer_init(uint32_t tim)
{
	TIM_CR1(tim) = 0;
	TIM_PSC(tim) = 0;
	TIM_ARR(tim) = 0xFFFFu;
	TIM_CCMR1(tim) = TIM_CCMR1_CC1S_TI1 | TIM_CCMR1_CC2S_TI2 | 3u << TIM_CCMR1_IC1F_POS |
			 3u << TIM_CCMR1_IC2F_POS;
	TIM_CCER(tim) = 0; /* both inputs not inverted: A leading B counts up */
	TIM_SMCR(tim) = TIM_SMCR_SMS_ENCODER3;
	TIM_CNT(tim) = 0;
	TIM_CR1(tim) = TIM_CR1_CEN;
}

void stm32_encoder_init(void)
{
	RCC_AHB1ENR |= RCC_AHB1ENR_GPIOAEN | RCC_AHB1ENR_GPIOBEN;
	RCC_APB1ENR |=
		RCC_APB1ENR_TIM2EN | RCC_APB1ENR_TIM3EN | RCC_APB1ENR_TIM4EN | RCC_APB1ENR_TIM5EN;
	/* RM0390 Table 11, alternate functions. */
	stm32_gpio_af(GPIOA_BASE, 6u, 2u);
	stm32_gpio_af(GPIOA_BASE, 7u, 2u);
	stm32_gpio_af(GPIOB_BASE, 6u, 2u);
	stm32_gpio_af(GPIOB_BASE, 7u, 2u);
	stm32_gpio_af(GPIOA_BASE, 0u, 2u);
	stm32_gpio_af(GPIOA_BASE, 1u, 2u);
	stm32_gpio_af(GPIOA_BASE, 15u, 1u);
	stm32_gpio_af(GPIOB_BASE, 3u, 1u);
	encoder_timer_init(ENC_FREE_LEFT_TIM);
	encoder_timer_init(ENC_FREE_RIGHT_TIM);
	encoder_timer_init(ENC_MOTOR_LEFT_TIM);
	encoder_timer_init(ENC_MOTOR_RIGHT_TIM);
}

uint16_t hal_encoder_free(enum hal_side side)
{
	return (uint16_t)TIM_CNT(side == HAL_LEFT ? ENC_FREE_LEFT_TIM : ENC_FREE_RIGHT_TIM);
}

uint16_t hal_encoder_motor(enum hal_side side)
{
	return (uint16_t)TIM_CNT(side == HAL_LEFT ? ENC_MOTOR_LEFT_TIM : ENC_MOTOR_RIGHT_TIM);
}
