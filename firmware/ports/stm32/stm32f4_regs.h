/* The STM32F4 registers this port uses, and only those, written from the reference manuals:
 * RM0390 (STM32F446xx, rev 6) and, for the Cortex-M4 core peripherals, PM0214 (STM32 Cortex-M4
 * programming manual, rev 10). Each block names its manual section. The F401 (RM0368) has the
 * same addresses and bits for everything here except what stm32_clock.h switches (the PLL's R
 * divider and the over-drive of PWR_CR, which the F401 does not have). */
#ifndef ASSERV_STM32F4_REGS_H
#define ASSERV_STM32F4_REGS_H

#include <stdint.h>

#define STM32_REG(addr) (*(volatile uint32_t *)(uintptr_t)(addr))

/* ---- Memory map: RM0390 section 2.2.2, Table 1 (register boundary addresses) ---- */
#define TIM2_BASE 0x40000000u
#define TIM3_BASE 0x40000400u
#define TIM4_BASE 0x40000800u
#define TIM5_BASE 0x40000C00u
#define IWDG_BASE 0x40003000u
#define I2C1_BASE 0x40005400u
#define PWR_BASE 0x40007000u
#define TIM1_BASE 0x40010000u
#define ADC1_BASE 0x40012000u
#define ADC_COMMON_BASE 0x40012300u
#define GPIOA_BASE 0x40020000u
#define GPIOB_BASE 0x40020400u
#define GPIOC_BASE 0x40020800u
#define RCC_BASE 0x40023800u
#define FLASH_IF_BASE 0x40023C00u

/* ---- RCC: RM0390 section 6.3 ---- */
#define RCC_CR STM32_REG(RCC_BASE + 0x00u) /* 6.3.1 */
#define RCC_CR_HSEON (1u << 16)
#define RCC_CR_HSERDY (1u << 17)
#define RCC_CR_HSEBYP (1u << 18)
#define RCC_CR_PLLON (1u << 24)
#define RCC_CR_PLLRDY (1u << 25)
#define RCC_PLLCFGR STM32_REG(RCC_BASE + 0x04u) /* 6.3.2 */
#define RCC_PLLCFGR_PLLM_POS 0u                 /* 6 bits, 2..63 */
#define RCC_PLLCFGR_PLLN_POS 6u                 /* 9 bits, 50..432 */
#define RCC_PLLCFGR_PLLP_POS 16u                /* 2 bits: 0 = /2, 1 = /4, 2 = /6, 3 = /8 */
#define RCC_PLLCFGR_PLLSRC_HSE (1u << 22)
#define RCC_PLLCFGR_PLLQ_POS 24u             /* 4 bits, 2..15 */
#define RCC_PLLCFGR_PLLR_POS 28u             /* 3 bits, 2..7 (F446 only) */
#define RCC_CFGR STM32_REG(RCC_BASE + 0x08u) /* 6.3.3 */
#define RCC_CFGR_SW_MASK 3u
#define RCC_CFGR_SW_PLL 2u
#define RCC_CFGR_SWS_POS 2u
#define RCC_CFGR_PPRE1_POS 10u /* APB1 prescaler: 0xx = /1, 100 = /2, 101 = /4, 110 = /8 */
#define RCC_CFGR_PPRE2_POS 13u
#define RCC_AHB1ENR STM32_REG(RCC_BASE + 0x30u) /* 6.3.10 */
#define RCC_AHB1ENR_GPIOAEN (1u << 0)
#define RCC_AHB1ENR_GPIOBEN (1u << 1)
#define RCC_AHB1ENR_GPIOCEN (1u << 2)
#define RCC_APB1ENR STM32_REG(RCC_BASE + 0x40u) /* 6.3.13 */
#define RCC_APB1ENR_TIM2EN (1u << 0)
#define RCC_APB1ENR_TIM3EN (1u << 1)
#define RCC_APB1ENR_TIM4EN (1u << 2)
#define RCC_APB1ENR_TIM5EN (1u << 3)
#define RCC_APB1ENR_I2C1EN (1u << 21)
#define RCC_APB1ENR_PWREN (1u << 28)
#define RCC_APB2ENR STM32_REG(RCC_BASE + 0x44u) /* 6.3.14 */
#define RCC_APB2ENR_TIM1EN (1u << 0)
#define RCC_APB2ENR_ADC1EN (1u << 8)
#define RCC_CSR STM32_REG(RCC_BASE + 0x74u) /* 6.3.21: the reset flags, kept until RMVF */
#define RCC_CSR_RMVF (1u << 24)
#define RCC_CSR_BORRSTF (1u << 25) /* set with PORRSTF at a power-on, alone at a brown-out */
#define RCC_CSR_PINRSTF (1u << 26) /* set by every reset: each drives the NRST pin */
#define RCC_CSR_PORRSTF (1u << 27)
#define RCC_CSR_SFTRSTF (1u << 28)
#define RCC_CSR_IWDGRSTF (1u << 29)
#define RCC_CSR_WWDGRSTF (1u << 30)
#define RCC_CSR_LPWRRSTF (1u << 31)

/* ---- PWR: RM0390 section 5.4 ---- */
#define PWR_CR STM32_REG(PWR_BASE + 0x00u) /* 5.4.1 */
#define PWR_CR_VOS_SCALE1 (3u << 14)
#define PWR_CR_ODEN (1u << 16)
#define PWR_CR_ODSWEN (1u << 17)
#define PWR_CSR STM32_REG(PWR_BASE + 0x04u) /* 5.4.2 */
#define PWR_CSR_ODRDY (1u << 16)
#define PWR_CSR_ODSWRDY (1u << 17)

/* ---- Flash interface: RM0390 section 3.8.1 (FLASH_ACR), wait states: 3.4.1, Table 5 ---- */
#define FLASH_ACR STM32_REG(FLASH_IF_BASE + 0x00u)
#define FLASH_ACR_LATENCY_MASK 0xFu
#define FLASH_ACR_PRFTEN (1u << 8)
#define FLASH_ACR_ICEN (1u << 9)
#define FLASH_ACR_DCEN (1u << 10)

/* ---- Flash programming and erase: RM0390 sections 3.5 (unlock 3.5.1, erase 3.5.3, program
 * 3.5.4), 3.8.2-3.8.5 (registers). Sectors 1 (16 KiB at 0x0800 4000) and 7 (128 KiB at
 * 0x0806 0000; 3.3, Table 4) hold the calibration's logs (nvm.c); the linker script keeps code
 * out of them. ---- */
#define FLASH_KEYR STM32_REG(FLASH_IF_BASE + 0x04u) /* 3.8.2 */
#define FLASH_KEY1 0x45670123u                      /* 3.5.1: KEY1 then KEY2 clears LOCK */
#define FLASH_KEY2 0xCDEF89ABu
#define FLASH_SR STM32_REG(FLASH_IF_BASE + 0x0Cu) /* 3.8.4 */
#define FLASH_SR_EOP (1u << 0)
#define FLASH_SR_OPERR (1u << 1)
#define FLASH_SR_WRPERR (1u << 4)
#define FLASH_SR_PGAERR (1u << 5)
#define FLASH_SR_PGPERR (1u << 6)
#define FLASH_SR_PGSERR (1u << 7)
#define FLASH_SR_ERRORS                                                                            \
	(FLASH_SR_OPERR | FLASH_SR_WRPERR | FLASH_SR_PGAERR | FLASH_SR_PGPERR | FLASH_SR_PGSERR)
#define FLASH_SR_BSY (1u << 16)
#define FLASH_CR STM32_REG(FLASH_IF_BASE + 0x10u) /* 3.8.5 */
#define FLASH_CR_PG (1u << 0)
#define FLASH_CR_SER (1u << 1)
#define FLASH_CR_SNB_POS 3u          /* sector number, 4 bits */
#define FLASH_CR_PSIZE_X32 (2u << 8) /* 3.6.2: x32 parallelism, VDD 2.7..3.6 V */
#define FLASH_CR_STRT (1u << 16)
#define FLASH_CR_LOCK (1u << 31)

/* ---- GPIO: RM0390 section 7.4 ---- */
#define GPIO_MODER(base) STM32_REG((base) + 0x00u)  /* 7.4.1: 00 in, 01 out, 10 AF, 11 analog */
#define GPIO_OTYPER(base) STM32_REG((base) + 0x04u) /* 7.4.2: 1 open-drain */
#define GPIO_PUPDR(base) STM32_REG((base) + 0x0Cu)  /* 7.4.4: 01 pull-up, 10 pull-down */
#define GPIO_IDR(base) STM32_REG((base) + 0x10u)    /* 7.4.5 */
#define GPIO_ODR(base) STM32_REG((base) + 0x14u)    /* 7.4.6 */
#define GPIO_BSRR(base) STM32_REG((base) + 0x18u)   /* 7.4.7: set 15:0, reset 31:16 */
#define GPIO_AFRL(base) STM32_REG((base) + 0x20u)   /* 7.4.9: pins 0..7, 4 bits each */
#define GPIO_AFRH(base) STM32_REG((base) + 0x24u)   /* 7.4.10: pins 8..15 */
#define GPIO_MODE_IN 0u
#define GPIO_MODE_OUT 1u
#define GPIO_MODE_AF 2u
#define GPIO_MODE_ANALOG 3u

/* ---- Timers. Advanced-control TIM1: RM0390 section 16.4; general-purpose TIM2..TIM5:
 * section 17.4. The offsets and bits used here are the same in both. ---- */
#define TIM_CR1(base) STM32_REG((base) + 0x00u) /* 16.4.1, 17.4.1 */
#define TIM_CR1_CEN (1u << 0)
#define TIM_CR1_DIR (1u << 4) /* read-only in encoder mode: 1 = counting down */
#define TIM_CR1_ARPE (1u << 7)
#define TIM_SMCR(base) STM32_REG((base) + 0x08u) /* 16.4.3, 17.4.3 */
#define TIM_SMCR_SMS_ENCODER3 3u                 /* counts on TI1 and TI2 edges (x4) */
#define TIM_SR(base) STM32_REG((base) + 0x10u)   /* 16.4.5, 17.4.5 */
#define TIM_EGR(base) STM32_REG((base) + 0x14u)  /* 16.4.6, 17.4.6 */
#define TIM_EGR_UG (1u << 0)
#define TIM_CCMR1(base) STM32_REG((base) + 0x18u) /* 16.4.7, 17.4.7 */
#define TIM_CCMR1_CC1S_TI1 (1u << 0)              /* input capture 1 on TI1 */
#define TIM_CCMR1_CC2S_TI2 (1u << 8)              /* input capture 2 on TI2 */
#define TIM_CCMR1_OC1PE (1u << 3)
#define TIM_CCMR1_OC1M_PWM1 (6u << 4)
#define TIM_CCMR1_OC2PE (1u << 11)
#define TIM_CCMR1_OC2M_PWM1 (6u << 12)
#define TIM_CCMR1_IC1F_POS 4u /* input filter, 4 bits */
#define TIM_CCMR1_IC2F_POS 12u
#define TIM_CCER(base) STM32_REG((base) + 0x20u) /* 16.4.9, 17.4.9 */
#define TIM_CCER_CC1E (1u << 0)
#define TIM_CCER_CC1P (1u << 1) /* encoder mode: TI1 inverted (counting direction) */
#define TIM_CCER_CC2E (1u << 4)
#define TIM_CCER_CC2P (1u << 5)
#define TIM_CNT(base) STM32_REG((base) + 0x24u)  /* 16.4.10, 17.4.10 */
#define TIM_PSC(base) STM32_REG((base) + 0x28u)  /* 16.4.11, 17.4.11 */
#define TIM_ARR(base) STM32_REG((base) + 0x2Cu)  /* 16.4.12, 17.4.12 */
#define TIM_CCR1(base) STM32_REG((base) + 0x34u) /* 16.4.14, 17.4.13 */
#define TIM_CCR2(base) STM32_REG((base) + 0x38u) /* 16.4.15, 17.4.14 */
#define TIM1_BDTR STM32_REG(TIM1_BASE + 0x44u)   /* 16.4.18 */
#define TIM_BDTR_MOE (1u << 15)

/* ---- ADC1: RM0390 section 13.13 ---- */
#define ADC1_SR STM32_REG(ADC1_BASE + 0x00u) /* 13.13.1 */
#define ADC_SR_JEOC (1u << 2)
#define ADC_SR_JSTRT (1u << 3)
#define ADC1_CR1 STM32_REG(ADC1_BASE + 0x04u) /* 13.13.2 */
#define ADC_CR1_SCAN (1u << 8)
#define ADC1_CR2 STM32_REG(ADC1_BASE + 0x08u) /* 13.13.3 */
#define ADC_CR2_ADON (1u << 0)
#define ADC_CR2_JSWSTART (1u << 22)
#define ADC1_SMPR1 STM32_REG(ADC1_BASE + 0x0Cu) /* 13.13.4: channels 10..18 */
#define ADC1_SMPR2 STM32_REG(ADC1_BASE + 0x10u) /* 13.13.5: channels 0..9, 3 bits each */
#define ADC1_JSQR STM32_REG(ADC1_BASE + 0x38u)  /* 13.13.12 */
#define ADC_JSQR_JL_POS 20u
#define ADC_JSQR_JSQ3_POS 10u
#define ADC_JSQR_JSQ4_POS 15u
#define ADC1_JDR1 STM32_REG(ADC1_BASE + 0x3Cu) /* 13.13.13 */
#define ADC1_JDR2 STM32_REG(ADC1_BASE + 0x40u)
#define ADC_CCR STM32_REG(ADC_COMMON_BASE + 0x04u) /* 13.13.16 */
#define ADC_CCR_ADCPRE_POS 16u                     /* PCLK2 / 2, 4, 6, 8 */

/* ---- Independent watchdog: RM0390 section 19.4, on the LSI (about 32 kHz) ---- */
#define IWDG_KR STM32_REG(IWDG_BASE + 0x00u) /* 19.4.1 */
#define IWDG_KR_START 0xCCCCu
#define IWDG_KR_ACCESS 0x5555u /* PR and RLR writable until the next key */
#define IWDG_KR_RELOAD 0xAAAAu
#define IWDG_PR STM32_REG(IWDG_BASE + 0x04u)  /* 19.4.2: LSI / (4 << PR) */
#define IWDG_RLR STM32_REG(IWDG_BASE + 0x08u) /* 19.4.3: 12 bits */
#define IWDG_SR STM32_REG(IWDG_BASE + 0x0Cu)  /* 19.4.4: PVU, RVU: an update in progress */

/* ---- I2C1: RM0390 section 24.6 ---- */
#define I2C1_CR1 STM32_REG(I2C1_BASE + 0x00u) /* 24.6.1 */
#define I2C_CR1_PE (1u << 0)
#define I2C_CR1_ACK (1u << 10)
#define I2C_CR1_SWRST (1u << 15)
#define I2C1_CR2 STM32_REG(I2C1_BASE + 0x04u) /* 24.6.2 */
#define I2C_CR2_FREQ_POS 0u                   /* APB1 clock [MHz], 2..50 */
#define I2C_CR2_ITERREN (1u << 8)
#define I2C_CR2_ITEVTEN (1u << 9)
#define I2C_CR2_ITBUFEN (1u << 10)
#define I2C1_OAR1 STM32_REG(I2C1_BASE + 0x08u) /* 24.6.3 */
#define I2C_OAR1_BIT14 (1u << 14)              /* "must be kept at 1 by software" */
#define I2C1_DR STM32_REG(I2C1_BASE + 0x10u)   /* 24.6.5 */
#define I2C1_SR1 STM32_REG(I2C1_BASE + 0x14u)  /* 24.6.6 */
#define I2C_SR1_ADDR (1u << 1)
#define I2C_SR1_BTF (1u << 2)
#define I2C_SR1_STOPF (1u << 4)
#define I2C_SR1_RXNE (1u << 6)
#define I2C_SR1_TXE (1u << 7)
#define I2C_SR1_BERR (1u << 8)
#define I2C_SR1_ARLO (1u << 9)
#define I2C_SR1_AF (1u << 10)
#define I2C_SR1_OVR (1u << 11)
#define I2C1_SR2 STM32_REG(I2C1_BASE + 0x18u) /* 24.6.7 */
#define I2C_SR2_TRA (1u << 2)

/* ---- Cortex-M4 core peripherals: PM0214 ---- */
#define SYST_CSR STM32_REG(0xE000E010u) /* 4.5.1 */
#define SYST_CSR_ENABLE (1u << 0)
#define SYST_CSR_TICKINT (1u << 1)
#define SYST_CSR_CLKSOURCE (1u << 2)                   /* 1: the processor clock */
#define SYST_RVR STM32_REG(0xE000E014u)                /* 4.5.2 */
#define SYST_CVR STM32_REG(0xE000E018u)                /* 4.5.3 */
#define NVIC_ISER(n) STM32_REG(0xE000E100u + 4u * (n)) /* 4.2.2 */
#define NVIC_IPR_BYTE(irq) (*(volatile uint8_t *)(uintptr_t)(0xE000E400u + (irq))) /* 4.2.7 */
#define SCB_VTOR STM32_REG(0xE000ED08u)                                            /* 4.4.4 */
#define SCB_SHPR3 STM32_REG(0xE000ED20u) /* 4.4.8: SysTick priority in bits 31:24 */

/* Interrupt numbers: RM0390 section 10.2, Table 38 (vector table). */
#define IRQ_I2C1_EV 31u
#define IRQ_I2C1_ER 32u

#endif
