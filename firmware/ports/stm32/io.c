/* The board's inputs and outputs: the four quadrature encoders on timers in encoder mode (no
 * interrupt per edge), the motors' PWM on TIM1 and their direction pins, the current sense on
 * ADC1's injected channels, the switches and floor sensors on GPIOC. Pins: pinmap.h. */
#include "hal.h"
#include "pinmap.h"
#include "stm32_port.h"
#include "stm32f4_regs.h"

static void gpio_mode(uint32_t port, uint32_t pin, uint32_t mode)
{
	GPIO_MODER(port) = (GPIO_MODER(port) & ~(3u << (2u * pin))) | mode << (2u * pin);
}

static void gpio_af(uint32_t port, uint32_t pin, uint32_t af)
{
	if (pin < 8u)
		GPIO_AFRL(port) = (GPIO_AFRL(port) & ~(0xFu << (4u * pin))) | af << (4u * pin);
	else
		GPIO_AFRH(port) =
			(GPIO_AFRH(port) & ~(0xFu << (4u * (pin - 8u)))) | af << (4u * (pin - 8u));
	gpio_mode(port, pin, GPIO_MODE_AF);
}

static void gpio_pull_up(uint32_t port, uint32_t pin)
{
	GPIO_PUPDR(port) = (GPIO_PUPDR(port) & ~(3u << (2u * pin))) | 1u << (2u * pin);
}

/* Encoder mode 3 (RM0390 17.3.16): the counter counts up and down on both edges of both inputs,
 * x4, with no prescaler; a digital filter of 8 samples at the timer's clock (IC1F = IC2F = 3)
 * rejects glitches under 0.1 us. 16 bits, as hal_encoder.h wants. */
static void encoder_init(uint32_t tim)
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

static uint32_t adc_code[2];

void stm32_io_init(void)
{
	RCC_AHB1ENR |= RCC_AHB1ENR_GPIOAEN | RCC_AHB1ENR_GPIOBEN | RCC_AHB1ENR_GPIOCEN;
	RCC_APB1ENR |= RCC_APB1ENR_TIM2EN | RCC_APB1ENR_TIM3EN | RCC_APB1ENR_TIM4EN |
		       RCC_APB1ENR_TIM5EN | RCC_APB1ENR_I2C1EN;
	RCC_APB2ENR |= RCC_APB2ENR_TIM1EN | RCC_APB2ENR_ADC1EN;

	/* Encoders (RM0390 Table 11, alternate functions). */
	gpio_af(GPIOA_BASE, 6u, 2u);
	gpio_af(GPIOA_BASE, 7u, 2u);
	gpio_af(GPIOB_BASE, 6u, 2u);
	gpio_af(GPIOB_BASE, 7u, 2u);
	gpio_af(GPIOA_BASE, 0u, 2u);
	gpio_af(GPIOA_BASE, 1u, 2u);
	gpio_af(GPIOA_BASE, 15u, 1u);
	gpio_af(GPIOB_BASE, 3u, 1u);
	encoder_init(ENC_FREE_LEFT_TIM);
	encoder_init(ENC_FREE_RIGHT_TIM);
	encoder_init(ENC_MOTOR_LEFT_TIM);
	encoder_init(ENC_MOTOR_RIGHT_TIM);

	/* Motors: direction pins low (bridge off), then PWM mode 1 on TIM1 channels 1 and 2
	 * (RM0390 16.3.10), the compare values preloaded (taken at each update, so that a write
	 * never cuts a pulse), the main output enabled (BDTR.MOE, 16.4.18). */
	GPIO_BSRR(PIN_DIR_PORT) = 1u << (PIN_LEFT_IN1 + 16u) | 1u << (PIN_LEFT_IN2 + 16u) |
				  1u << (PIN_RIGHT_IN1 + 16u) | 1u << (PIN_RIGHT_IN2 + 16u);
	gpio_mode(PIN_DIR_PORT, PIN_LEFT_IN1, GPIO_MODE_OUT);
	gpio_mode(PIN_DIR_PORT, PIN_LEFT_IN2, GPIO_MODE_OUT);
	gpio_mode(PIN_DIR_PORT, PIN_RIGHT_IN1, GPIO_MODE_OUT);
	gpio_mode(PIN_DIR_PORT, PIN_RIGHT_IN2, GPIO_MODE_OUT);
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
	gpio_af(GPIOA_BASE, 8u, 1u);
	gpio_af(GPIOA_BASE, 9u, 1u);

	/* Current sense: ADC1 at PCLK2 / 4 = 22.5 MHz (36 MHz at most: RM0390 13.2 via the data
	 * sheet), the two channels as an injected sequence of two (JL = 1: RM0390 13.13.12 converts
	 * JSQ3 then JSQ4 into JDR1 and JDR2), 56 cycles of sampling each, scan mode. */
	gpio_mode(GPIOA_BASE, 4u, GPIO_MODE_ANALOG);
	gpio_mode(GPIOB_BASE, 0u, GPIO_MODE_ANALOG);
	ADC_CCR = 1u << ADC_CCR_ADCPRE_POS;
	ADC1_SMPR2 = 3u << (3u * ADC_CH_I_LEFT) | 3u << (3u * ADC_CH_I_RIGHT);
	ADC1_JSQR = 1u << ADC_JSQR_JL_POS | ADC_CH_I_LEFT << ADC_JSQR_JSQ3_POS |
		    ADC_CH_I_RIGHT << ADC_JSQR_JSQ4_POS;
	ADC1_CR1 = ADC_CR1_SCAN;
	ADC1_CR2 = ADC_CR2_ADON;
	adc_code[0] = adc_code[1] = 2048u; /* 0 A until the first conversion */

	/* Switches to ground with pull-ups; line sensors drive their pins. */
	for (uint32_t pin = 0; pin <= PIN_BASKET; pin++)
		gpio_pull_up(PIN_SENSOR_PORT, pin);

	GPIO_BSRR(PIN_TICK_PORT) = 1u << (PIN_TICK + 16u);
	gpio_mode(PIN_TICK_PORT, PIN_TICK, GPIO_MODE_OUT);
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

uint16_t hal_encoder_free(enum hal_side side)
{
	return (uint16_t)TIM_CNT(side == HAL_LEFT ? ENC_FREE_LEFT_TIM : ENC_FREE_RIGHT_TIM);
}

uint16_t hal_encoder_motor(enum hal_side side)
{
	return (uint16_t)TIM_CNT(side == HAL_LEFT ? ENC_MOTOR_LEFT_TIM : ENC_MOTOR_RIGHT_TIM);
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

/* The switches and line sensors are read once per tick: that sampling is their debouncing (a
 * bounce shorter than a period is seen at most once), as on the AVR. */
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
