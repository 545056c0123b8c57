/* The I2C slave on I2C1 (RM0390 24.3.3, slave mode), interrupt-driven, reporting each bus event to
 * the protocol layer (hal_i2c.h), the PEC summed by it. Two interrupts: events (ADDR, RXNE, BTF,
 * STOPF) and errors (AF, BERR, ARLO, OVR), at a higher priority than the control tick, so that
 * the bus never waits for a tick.
 *
 * Receiving, the buffer interrupt (ITBUFEN) is on: each byte is read at RXNE, while the master
 * sends the next one, and the clock is never held. Sending, it is off: the next byte is written
 * at BTF, once the master has acknowledged the last one (the clock is held for the interrupt's
 * entry, as the AVR's TWI holds it for each byte). Writing ahead at TXE would leave one byte in
 * DR when the master NACKs the last one, and the hardware would send it first in the next read.
 * The master's NACK ends a read (AF: the slave leaves the transfer, no STOPF follows, RM0390
 * Figure 245). The hardware does not tell a repeated start apart from a START: a new address
 * ends the write or the read that was going on, as the host port does. */
#include "hal.h"
#include "pinmap.h"
#include "stm32_port.h"
#include "stm32f4_regs.h"

void hal_i2c_slave_init(uint8_t address)
{
	RCC_AHB1ENR |= RCC_AHB1ENR_GPIOBEN;
	RCC_APB1ENR |= RCC_APB1ENR_I2C1EN;
	GPIO_OTYPER(GPIOB_BASE) |= 1u << PIN_I2C_SCL | 1u << PIN_I2C_SDA;
	GPIO_AFRH(GPIOB_BASE) = (GPIO_AFRH(GPIOB_BASE) & ~(0xFFu << (4u * (PIN_I2C_SCL - 8u)))) |
				0x44u << (4u * (PIN_I2C_SCL - 8u));
	GPIO_MODER(GPIOB_BASE) = (GPIO_MODER(GPIOB_BASE) & ~(0xFu << (2u * PIN_I2C_SCL))) |
				 (GPIO_MODE_AF | GPIO_MODE_AF << 2u) << (2u * PIN_I2C_SCL);

	I2C1_CR1 = I2C_CR1_SWRST;
	I2C1_CR1 = 0;
	I2C1_CR2 =
		(STM32_APB1_HZ / 1000000u) << I2C_CR2_FREQ_POS | I2C_CR2_ITEVTEN | I2C_CR2_ITERREN;
	I2C1_OAR1 = I2C_OAR1_BIT14 | (uint32_t)address << 1;
	I2C1_CR1 = I2C_CR1_PE;
	I2C1_CR1 = I2C_CR1_PE | I2C_CR1_ACK; /* ACK is cleared while PE is 0 (24.6.1) */

	/* PM0214 4.2.7: 4 priority bits (the upper nibble); 0x40 preempts the tick's 0xF0. */
	NVIC_IPR_BYTE(IRQ_I2C1_EV) = 0x40u;
	NVIC_IPR_BYTE(IRQ_I2C1_ER) = 0x40u;
	NVIC_ISER(IRQ_I2C1_EV / 32u) = 1u << (IRQ_I2C1_EV % 32u);
	NVIC_ISER(IRQ_I2C1_ER / 32u) = 1u << (IRQ_I2C1_ER % 32u);
}

void I2C1_EV_IRQHandler(void)
{
	struct proto *p = &asserv_board.proto;
	uint32_t sr1 = I2C1_SR1;

	if (sr1 & I2C_SR1_ADDR) {
		/* ADDR is cleared by reading SR1 (done) then SR2 (24.6.6). */
		if (I2C1_SR2 & I2C_SR2_TRA) {
			I2C1_CR2 &= ~I2C_CR2_ITBUFEN;
			proto_on_read_start(p);
			I2C1_DR = proto_read_byte(p);
		} else {
			I2C1_CR2 |= I2C_CR2_ITBUFEN;
			proto_on_write_start(p);
		}
		return;
	}
	if (sr1 & I2C_SR1_RXNE) {
		proto_on_byte(p, (uint8_t)I2C1_DR); /* reading DR clears RXNE (and BTF) */
	} else if ((sr1 & (I2C_SR1_TXE | I2C_SR1_BTF)) == (I2C_SR1_TXE | I2C_SR1_BTF)) {
		I2C1_DR = proto_read_byte(p); /* SR1 read, then DR written: BTF cleared */
	}
	if (sr1 & I2C_SR1_STOPF) {
		/* STOPF is cleared by reading SR1 (done) then writing CR1 (24.6.6); after RXNE, so
		 * that the last byte of a write comes before its STOP. */
		I2C1_CR1 = I2C1_CR1;
		proto_on_stop(p);
	}
}

void I2C1_ER_IRQHandler(void)
{
	struct proto *p = &asserv_board.proto;
	uint32_t sr1 = I2C1_SR1;

	/* The error flags are cleared by writing 0 to them (rc_w0); ones leave the others be. */
	if (sr1 & I2C_SR1_AF) {
		I2C1_SR1 = ~I2C_SR1_AF & 0xFFFFu;
		proto_on_stop(p); /* the master's NACK: its read is over */
	}
	if (sr1 & (I2C_SR1_BERR | I2C_SR1_ARLO | I2C_SR1_OVR)) {
		I2C1_SR1 = ~(I2C_SR1_BERR | I2C_SR1_ARLO | I2C_SR1_OVR) & 0xFFFFu;
		proto_on_abort(p);
	}
}
