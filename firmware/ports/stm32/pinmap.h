/* Pin map of the asserv board on a Nucleo-64 (STM32F446RE or F401RE): docs/stm32.md has the
 * wiring, with the Arduino and morpho connector names. Every pin here exists on both chips. */
#ifndef ASSERV_STM32_PINMAP_H
#define ASSERV_STM32_PINMAP_H

#include "stm32f4_regs.h"

/* Quadrature encoders, each on a timer in encoder mode (channel 1 = A, channel 2 = B). */
#define ENC_FREE_LEFT_TIM TIM3_BASE   /* PA6 A, PA7 B, AF2 */
#define ENC_FREE_RIGHT_TIM TIM4_BASE  /* PB6 A, PB7 B, AF2 */
#define ENC_MOTOR_LEFT_TIM TIM5_BASE  /* PA0 A, PA1 B, AF2 */
#define ENC_MOTOR_RIGHT_TIM TIM2_BASE /* PA15 A, PB3 B, AF1 (free once JTAG is off: SWD stays) */

/* Motor PWM on TIM1: channel 1 PA8 (left), channel 2 PA9 (right), AF1. Direction: IN1/IN2 of
 * each half of the dual H-bridge (IN1 high, IN2 low: forward), all on GPIOB. */
#define PIN_DIR_PORT GPIOB_BASE
#define PIN_LEFT_IN1 4u
#define PIN_LEFT_IN2 5u
#define PIN_RIGHT_IN1 13u
#define PIN_RIGHT_IN2 14u

/* Current sense: PA4 = ADC1_IN4 (left), PB0 = ADC1_IN8 (right), each from a bidirectional
 * sense amplifier: 1.65 V at 0 A, 100 mV/A (stm32_port.h). */
#define ADC_CH_I_LEFT 4u
#define ADC_CH_I_RIGHT 8u

/* Switches and floor sensors, all on GPIOC so that one IDR read samples them together:
 * PC0..PC7 the eight shock switches (to ground, internal pull-ups: low = pressed), PC8 the
 * basket contact (same), PC9..PC12 four line sensors (high = line seen). */
#define PIN_SENSOR_PORT GPIOC_BASE
#define PIN_BASKET 8u
#define PIN_LINE0 9u

/* I2C1: PB8 SCL, PB9 SDA, AF4, open-drain (the Raspberry Pi's 1.8 kOhm pull-ups). */
#define PIN_I2C_SCL 8u
#define PIN_I2C_SDA 9u

/* PA5 (the Nucleo's green LED LD2): high while the control tick runs, for a scope. */
#define PIN_TICK_PORT GPIOA_BASE
#define PIN_TICK 5u

#endif
