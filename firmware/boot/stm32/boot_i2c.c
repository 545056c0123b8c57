/* The bootloader's I2C slave on I2C1, PB8 SCL / PB9 SDA (RM0390 24.3.3), as the application's
 * (firmware/ports/stm32/i2c.c) but for its own protocol (boot_proto.h). The interrupt never holds
 * the clock for longer than its own entry: it checks a write's PEC and length at its STOP, hands
 * a flash command to the main loop, and answers reads from RAM only (the flash may be erasing:
 * a read of it would stall the bus). A write that comes while the main loop has not handled the
 * last one, or while an operation runs (but the download slot's erase, during which DATA is
 * taken), is answered busy. */
#include "boot_layout.h"
#include "boot_proto.h"
#include "stm32f4_regs.h"

#define RCC_APB1ENR_I2C1 (1u << 21)
#define RCC_AHB1ENR_GPIOB (1u << 1)
#define I2C_SCL 8u
#define I2C_SDA 9u
#define APB1_MHZ 16u /* the HSI, no prescaler */

static uint8_t rx[BOOT_FRAME_MAX];
static uint8_t rx_len, rx_over, in_write, pec;
static uint8_t reply[BOOT_INFO_LEN + 1u];
static uint8_t reply_len, reply_pos;
static uint8_t select_info;
static volatile uint8_t queued; /* 1: q_frame holds a frame the main loop has not handled */
static uint8_t q_frame[BOOT_FRAME_MAX];
static uint8_t q_len;

static uint8_t crc8(uint8_t crc, uint8_t b)
{
	crc ^= b;
	for (int i = 0; i < 8; i++)
		crc = (crc & 0x80u) ? (uint8_t)((crc << 1) ^ 0x07u) : (uint8_t)(crc << 1);
	return crc;
}

void boot_i2c_init(void)
{
	RCC_AHB1ENR |= RCC_AHB1ENR_GPIOB;
	RCC_APB1ENR |= RCC_APB1ENR_I2C1;
	GPIO_OTYPER(GPIOB_BASE) |= 1u << I2C_SCL | 1u << I2C_SDA;
	GPIO_AFRH(GPIOB_BASE) = (GPIO_AFRH(GPIOB_BASE) & ~(0xFFu << (4u * (I2C_SCL - 8u)))) |
				0x44u << (4u * (I2C_SCL - 8u));
	GPIO_MODER(GPIOB_BASE) = (GPIO_MODER(GPIOB_BASE) & ~(0xFu << (2u * I2C_SCL))) |
				 (GPIO_MODE_AF | GPIO_MODE_AF << 2u) << (2u * I2C_SCL);
	I2C1_CR1 = I2C_CR1_SWRST;
	I2C1_CR1 = 0;
	I2C1_CR2 = APB1_MHZ << I2C_CR2_FREQ_POS | I2C_CR2_ITEVTEN | I2C_CR2_ITERREN;
	I2C1_OAR1 = I2C_OAR1_BIT14 | BOOT_I2C_ADDRESS << 1;
	I2C1_CR1 = I2C_CR1_PE;
	I2C1_CR1 = I2C_CR1_PE | I2C_CR1_ACK;
	NVIC_IPR_BYTE(IRQ_I2C1_EV) = 0x40u;
	NVIC_IPR_BYTE(IRQ_I2C1_ER) = 0x40u;
	NVIC_ISER(IRQ_I2C1_EV / 32u) = 1u << (IRQ_I2C1_EV % 32u);
	NVIC_ISER(IRQ_I2C1_ER / 32u) = 1u << (IRQ_I2C1_ER % 32u);
}

uint8_t boot_i2c_take(uint8_t *f)
{
	uint8_t n;

	if (!queued)
		return 0;
	n = q_len;
	for (uint8_t i = 0; i < n; i++)
		f[i] = q_frame[i];
	return n;
}

void boot_i2c_done(void)
{
	queued = 0;
}

static void put32(uint8_t *p, uint32_t v)
{
	p[0] = (uint8_t)(v >> 24);
	p[1] = (uint8_t)(v >> 16);
	p[2] = (uint8_t)(v >> 8);
	p[3] = (uint8_t)v;
}

/* The reply of the read that starts, from RAM; then its PEC, over the whole transaction. */
static void build_reply(void)
{
	uint8_t state = queued ? (uint8_t)BOOT_S_QUEUED : boot.state;

	if (select_info) {
		reply[0] = 'B';
		reply[1] = 'L';
		reply[2] = BOOT_PROTO_VERSION;
		reply[3] = (uint8_t)(BOOT_BOARD_ID >> 8);
		reply[4] = (uint8_t)BOOT_BOARD_ID;
		reply[5] = boot.run_valid;
		put32(reply + 6, boot.run_version);
		put32(reply + 10, boot.run_length);
		put32(reply + 14, boot.run_crc);
		put32(reply + 18, BOOT_IMAGE_MAX);
		reply[22] = state;
		reply[23] = boot.dl_slot;
		reply_len = BOOT_INFO_LEN;
	} else {
		reply[0] = state;
		reply[1] = boot.result;
		put32(reply + 2, boot.next);
		reply_len = BOOT_STATUS_LEN;
	}
	for (uint8_t i = 0; i < reply_len; i++)
		pec = crc8(pec, reply[i]);
	reply[reply_len] = pec;
	reply_pos = 0;
}

static uint8_t next_reply_byte(void)
{
	return reply_pos <= reply_len ? reply[reply_pos++] : 0xFFu;
}

/* A whole write: checked here, then selected, queued, or refused, never half applied. */
static void end_write(void)
{
	uint8_t n = rx_len;

	in_write = 0;
	if (n == 0)
		return; /* a quick write, or the address of a read that follows */
	if (rx_over) {
		boot.result = BOOT_R_BAD_LENGTH;
		return;
	}
	if (n < 2u || pec != 0) {
		boot.result = BOOT_R_BAD_PEC; /* the PEC over the frame and itself leaves 0 */
		return;
	}
	n--;
	if (n == 1u && (rx[0] == BOOT_CMD_INFO || rx[0] == BOOT_CMD_STATUS)) {
		select_info = rx[0] == BOOT_CMD_INFO;
		return;
	}
	if (queued || (boot_busy(boot.state) && boot.state != BOOT_S_ERASING)) {
		boot.result = BOOT_R_BUSY;
		return;
	}
	for (uint8_t i = 0; i < n; i++)
		q_frame[i] = rx[i];
	q_len = n;
	queued = 1;
}

void I2C1_EV_IRQHandler(void)
{
	uint32_t sr1 = I2C1_SR1;

	if (sr1 & I2C_SR1_ADDR) {
		if (I2C1_SR2 & I2C_SR2_TRA) {
			I2C1_CR2 &= ~I2C_CR2_ITBUFEN;
			if (in_write)
				end_write(); /* a repeated start: the PEC runs on over the read */
			else
				pec = 0;
			pec = crc8(pec, (uint8_t)(BOOT_I2C_ADDRESS << 1 | 1u));
			build_reply();
			I2C1_DR = next_reply_byte();
		} else {
			I2C1_CR2 |= I2C_CR2_ITBUFEN;
			if (in_write)
				end_write();
			in_write = 1;
			rx_len = 0;
			rx_over = 0;
			pec = crc8(0, (uint8_t)(BOOT_I2C_ADDRESS << 1));
		}
		return;
	}
	if (sr1 & I2C_SR1_RXNE) {
		uint8_t b = (uint8_t)I2C1_DR;

		if (rx_len < sizeof(rx))
			rx[rx_len++] = b;
		else
			rx_over = 1;
		pec = crc8(pec, b);
	} else if ((sr1 & (I2C_SR1_TXE | I2C_SR1_BTF)) == (I2C_SR1_TXE | I2C_SR1_BTF)) {
		I2C1_DR = next_reply_byte();
	}
	if (sr1 & I2C_SR1_STOPF) {
		I2C1_CR1 = I2C1_CR1;
		if (in_write)
			end_write();
	}
}

void I2C1_ER_IRQHandler(void)
{
	uint32_t sr1 = I2C1_SR1;

	if (sr1 & I2C_SR1_AF)
		I2C1_SR1 = ~I2C_SR1_AF & 0xFFFFu; /* the master's NACK ends its read */
	if (sr1 & (I2C_SR1_BERR | I2C_SR1_ARLO | I2C_SR1_OVR)) {
		I2C1_SR1 = ~(I2C_SR1_BERR | I2C_SR1_ARLO | I2C_SR1_OVR) & 0xFFFFu;
		in_write = 0; /* a write cut short is dropped whole */
	}
}
