/* The I2C slave on the ATmega's TWI, interrupt-driven, reporting each bus event to the protocol
 * layer (hal_i2c.h). While TWINT is set the TWI holds SCL low, so each case releases TWINT
 * first and only then calls the protocol layer: the clock is held only for the interrupt's
 * entry, except after the own address with the read bit, where the first reply byte must be in
 * TWDR before the release. The reply is packed before that when it can be: at the repeated start
 * that ends the selecting write (proto_on_restart(), while the master sends the address), so
 * that proto_on_read_start() only starts the PEC; the PEC is then summed as the bytes go out.
 * Later reply bytes are fetched one ahead, while the master clocks the previous one out. */
#include <avr/interrupt.h>
#include <avr/io.h>

#include "avr_port.h"
#include "hal.h"
#include "pinmap.h"

/* Release the bus (TWINT), keep acknowledging our address and bytes, keep the interrupt. */
#define TWCR_GO (_BV(TWINT) | _BV(TWEA) | _BV(TWEN) | _BV(TWIE))

/* TWSR status codes (ATmega1284P datasheet, slave receiver and transmitter tables). */
#define TW_SR_SLA_ACK 0x60u
#define TW_SR_ARB_LOST_SLA_ACK 0x68u
#define TW_SR_DATA_ACK 0x80u
#define TW_SR_DATA_NACK 0x88u
#define TW_SR_STOP 0xA0u
#define TW_ST_SLA_ACK 0xA8u
#define TW_ST_ARB_LOST_SLA_ACK 0xB0u
#define TW_ST_DATA_ACK 0xB8u
#define TW_ST_DATA_NACK 0xC0u
#define TW_ST_LAST_DATA 0xC8u
#define TW_BUS_ERROR 0x00u

static uint8_t tx_next; /* the reply byte after the one in TWDR */

void hal_i2c_slave_init(uint8_t address)
{
	TWAR = (uint8_t)(address << 1); /* no general call */
	TWCR = TWCR_GO;
}

ISR(TWI_vect)
{
	struct proto *p = &asserv_board.proto;
	uint8_t scl = PINC & _BV(PIN_SCL_BIT); /* first: see TW_SR_STOP */
	uint8_t data;

	switch (TWSR & 0xF8u) {
	case TW_SR_SLA_ACK:
	case TW_SR_ARB_LOST_SLA_ACK:
		TWCR = TWCR_GO;
		proto_on_write_start(p);
		break;
	case TW_SR_DATA_ACK:
	case TW_SR_DATA_NACK:
		data = TWDR;
		TWCR = TWCR_GO;
		proto_on_byte(p, data);
		break;
	case TW_SR_STOP:
		/* The TWI gives the same status for a STOP and a repeated start. After a STOP the
		 * bus is idle, SCL high; a repeated start is followed by the next address, whose
		 * clock the TWI holds low until this release. After a repeated start the write is
		 * judged here, while the master sends the next address, so that a read that follows
		 * only has to start sending; its PEC still covers the write. */
		TWCR = TWCR_GO;
		if (scl)
			proto_on_stop(p);
		else
			proto_on_restart(p);
		break;
	case TW_ST_SLA_ACK:
	case TW_ST_ARB_LOST_SLA_ACK:
		proto_on_read_start(p);
		TWDR = proto_read_byte(p);
		TWCR = TWCR_GO;
		tx_next = proto_read_byte(p);
		break;
	case TW_ST_DATA_ACK:
		TWDR = tx_next;
		TWCR = TWCR_GO;
		tx_next = proto_read_byte(p);
		break;
	case TW_ST_DATA_NACK:
	case TW_ST_LAST_DATA:
		/* The master took its last byte: the TWI leaves the addressed state, so no
		 * TW_SR_STOP follows. The read is over here. */
		TWCR = TWCR_GO;
		proto_on_stop(p);
		break;
	case TW_BUS_ERROR:
		proto_on_abort(p);
		TWCR = TWCR_GO | _BV(TWSTO); /* releases the lines, not a STOP on the bus */
		break;
	default:
		TWCR = TWCR_GO;
		break;
	}
}
