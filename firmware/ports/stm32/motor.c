/* The motors (hal_motor.h): PWM on TIM1 and the H-bridges' direction pins, the current sense on
 * ADC1's injected channels. Pins: pinmap.h. */
#include "hal.h"
#include "pinmap.h"
#include "stm32_gpio.h"
#include "stm32_port.h"
#include "stm32f4_regs.h"

static uint32_t adc_code[2];

void stm32_motor_init(void)
{
	RCC_AHB1ENR |= RCC_AHB1ENR_GPIOAEN | RCC_AHB1ENR_GPIOBEN;
	RCC_APB2ENR |= RCC_APB2ENR_TIM1EN | RCC_APB2ENR_ADC1EN;

	/* Direction pins low (bridge off), then PWM mode 1 on TIM1 channels 1 and 2 (RM0390
	 * 16.3.10), the compare values preloaded (taken at each update, so that a write never cuts
	 * a pulse), the main output enabled (BDTR.MOE, 16.4.18). */
	GPIO_BSRR(PIN_DIR_PORT) = 1u << (PIN_LEFT_IN1 + 16u) | 1u << (PIN_LEFT_IN2 + 16u) |
				  1u << (PIN_RIGHT_IN1 + 16u) | 1u << (PIN_RIGHT_IN2 + 16u);
	stm32_gpio_mode(PIN_DIR_PORT, PIN_LEFT_IN1, GPIO_MODE_OUT);
	stm32_gpio_mode(PIN_DIR_PORT, PIN_LEFT_IN2, GPIO_MODE_OUT);
	stm32_gpio_mode(PIN_DIR_PORT, PIN_RIGHT_IN1, GPIO_MODE_OUT);
	stm32_gpio_mode(PIN_DIR_PORT, PIN_RIGHT_IN2, GPIO_MODE_OUT);
	TIM_PSC(TIM1_BASE) = 0;
	TIM_ARR(TIM1_BASE) = STM32_PWM_PERIOD - 1u;
	TIM_CCR1(TIM1_BASE) = 0;
	TIM_CCR2(TIM1_BASE) = 0;
	TIM_CCMR1(TIM1_BASE) =
		TIM_CCMR1_OC1M_PWM1 | TIM_CCMR1_OC1PE | TIM_CCMR1_OC2M_PWM1 | TIM_CCMR1_OC2PE;
	TIM_CCER(TIM1_BASE) = TIM_CCER_CC1E | TIM_CCER_CC2E;
	TIM1_BDTR = TIM_BDTR_MOE;
	TIM_EGR(TIM1_BASE) = TIM_EGR_UG;
	TIM_CR1(TIM1_BASE) = TIM_CR1_ARPE | TIM_CR1_CEN;
	stm32_gpio_af(GPIOA_BASE, 8u, 1u);
	stm32_gpio_af(GPIOA_BASE, 9u, 1u);

	/* Current sense: ADC1 at PCLK2 / 4 = 22.5 MHz (36 MHz at most: RM0390 13.2 via the data
	 * sheet), the two channels as an injected sequence of two (JL = 1: RM0390 13.13.12 converts
	 * JSQ3 then JSQ4 into JDR1 and JDR2), 56 cycles of sampling each, scan mode. */
	stm32_gpio_mode(GPIOA_BASE, 4u, GPIO_MODE_ANALOG);
	stm32_gpio_mode(GPIOB_BASE, 0u, GPIO_MODE_ANALOG);
	ADC_CCR = 1u << ADC_CCR_ADCPRE_POS;
	ADC1_SMPR2 = 3u << (3u * ADC_CH_I_LEFT) | 3u << (3u * ADC_CH_I_RIGHT);
	ADC1_JSQR = 1u << ADC_JSQR_JL_POS | ADC_CH_I_LEFT << ADC_JSQR_JSQ3_POS |
		    ADC_CH_I_RIGHT << ADC_JSQR_JSQ4_POS;
	ADC1_CR1 = ADC_CR1_SCAN;
	ADC1_CR2 = ADC_CR2_ADON;
	adc_code[0] = adc_code[1] = 2048u; /* 0 A until the first conversion */
}

/* Both conversions take 2 x (56 + 12) ADC cycles, 6 us, waited for: the tick's first reading. */
void stm32_adc_sample(void)
{
	ADC1_SR = ~(ADC_SR_JEOC | ADC_SR_JSTRT); /* rc_w0: clears only these */
	ADC1_CR2 |= ADC_CR2_JSWSTART;
	while (!(ADC1_SR & ADC_SR_JEOC))
		;
	adc_code[HAL_LEFT] = ADC1_JDR1;
	adc_code[HAL_RIGHT] = ADC1_JDR2;
}

void hal_motor_set(enum hal_side side, int16_t duty_q15)
{
	uint32_t counts = stm32_pwm_counts(duty_q15);
	uint32_t in1 = side == HAL_LEFT ? PIN_LEFT_IN1 : PIN_RIGHT_IN1;
	uint32_t in2 = side == HAL_LEFT ? PIN_LEFT_IN2 : PIN_RIGHT_IN2;

	if (duty_q15 > 0)
		GPIO_BSRR(PIN_DIR_PORT) = 1u << in1 | 1u << (in2 + 16u);
	else if (duty_q15 < 0)
		GPIO_BSRR(PIN_DIR_PORT) = 1u << (in1 + 16u) | 1u << in2;
	else
		GPIO_BSRR(PIN_DIR_PORT) = 1u << (in1 + 16u) | 1u << (in2 + 16u);
	if (side == HAL_LEFT)
		TIM_CCR1(TIM1_BASE) = counts;
	else
		TIM_CCR2(TIM1_BASE) = counts;
}

int16_t hal_motor_current_ma(enum hal_side side)
{
	return stm32_current_ma(adc_code[side]);
}
