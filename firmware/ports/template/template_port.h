/* What the template port's files share: the one board, and the two interrupt handlers a real
 * port attaches to its vector table. Rename the prefix (template_) to the port's name. */
#ifndef ASSERV_TEMPLATE_PORT_H
#define ASSERV_TEMPLATE_PORT_H

#include <stdint.h>

#include "board.h"

/* The board, one per chip: the control interrupt, the I2C interrupt and the main loop share it
 * (main.c). A global, so that a debugger finds it by name. */
extern struct board asserv_board;

/* The I2C slave's events as a port's peripheral reports them; a real port reads them from its
 * status register instead (the AVR's TWSR codes, the STM32's ISR flags). */
enum template_i2c_event {
	TEMPLATE_I2C_ADDR_WRITE, /* own address with the write bit (after a START or a restart) */
	TEMPLATE_I2C_RX_BYTE,    /* a data byte received (already acknowledged) */
	TEMPLATE_I2C_ADDR_READ,  /* own address with the read bit */
	TEMPLATE_I2C_TX_NEXT,    /* the master acknowledged a byte sent: it wants another */
	TEMPLATE_I2C_TX_DONE,    /* the master did not acknowledge a byte sent: the read ends */
	TEMPLATE_I2C_RESTART,    /* a repeated start (only if the hardware tells it from a STOP) */
	TEMPLATE_I2C_STOP,       /* STOP */
	TEMPLATE_I2C_ERROR,      /* bus error, arbitration lost, overrun: the transaction is cut */
};

/* The I2C interrupt (i2c.c): one bus event, with its byte for TEMPLATE_I2C_RX_BYTE. Returns the
 * byte to load into the transmit register for TEMPLATE_I2C_ADDR_READ and TEMPLATE_I2C_TX_NEXT,
 * 0xFF otherwise. */
uint8_t template_i2c_event(enum template_i2c_event ev, uint8_t byte);

/* The control interrupt (tick.c): one control period. */
void template_tick_isr(void);

/* The port's robot: the board configuration the core runs with (robot.c). */
void template_robot_config(struct board_config *cfg);

/* Why the chip started, RESET_CAUSE_*, and how long the board may have been down [ms]
 * (reset.c). */
uint8_t template_reset_cause(void);
uint16_t template_down_ms(uint8_t cause);

/* The watchdog (watchdog.c): started by main(), fed after each tick. */
void template_watchdog_start(void);
void template_watchdog_feed(void);

#endif
