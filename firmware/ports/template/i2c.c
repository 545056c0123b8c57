/* Template port: the I2C slave (hal_i2c.h). The bus's master (the robot's main computer) writes
 * orders and reads replies; the protocol layer (core/protocol.h) does everything but move the
 * bytes: the port's only job is to report each bus event to it from the I2C interrupt. */
#include "hal.h"
#include "protocol.h"
#include "template_port.h"

/* Answer at a 7-bit address (PROTO_ADDRESS, 2): set the own-address register, acknowledge every
 * byte of a write, enable the event and error interrupts, and do not answer a general call.
 * The I2C interrupt's priority is above the control tick's: it may preempt a tick, and a byte
 * must never wait for a tick to end (the clock would be held for up to a period). Called once,
 * from main(), after board_init() (the protocol layer it reports to must exist), before the
 * ticks start. */
void hal_i2c_slave_init(uint8_t address)
{
	(void)address; /* e.g. I2Cx->OAR1 = address << 1; I2Cx->CR1 = PE | ACK; event interrupts */
}

/* The one place that names where the protocol layer lives in struct board. */
static struct proto *template_proto(void)
{
	return &asserv_board.proto;
}

/* The I2C interrupt's body. Acknowledge at once, then report: the master (a Raspberry Pi among
 * them) may corrupt data when a slave stretches the clock, so the port releases the clock before
 * calling the protocol layer wherever the hardware allows it. The one place the clock is held is
 * after own address + read, until the first reply byte is in the transmit register; the reply
 * is packed earlier where the hardware reports a repeated start (proto_on_restart()), so that
 * only loading that byte remains. Every proto_on_*() call is bounded and short: they run in this
 * interrupt and never wait for the core. */
uint8_t template_i2c_event(enum template_i2c_event ev, uint8_t byte)
{
	struct proto *p = template_proto();

	switch (ev) {
	case TEMPLATE_I2C_ADDR_WRITE:
		proto_on_write_start(p);
		break;
	case TEMPLATE_I2C_RX_BYTE:
		/* Always acknowledged: a frame is judged whole at its end (a rejected frame changes
		 * nothing), never byte by byte. */
		proto_on_byte(p, byte);
		break;
	case TEMPLATE_I2C_ADDR_READ:
		proto_on_read_start(p);
		return proto_read_byte(p);
	case TEMPLATE_I2C_TX_NEXT:
		/* Past the reply and its PEC the protocol layer returns 0xFF: a master that reads
		 * too far gets that, and nothing changes. */
		return proto_read_byte(p);
	case TEMPLATE_I2C_TX_DONE:
		break; /* the STOP that follows ends the read */
	case TEMPLATE_I2C_RESTART:
		proto_on_restart(p);
		break;
	case TEMPLATE_I2C_STOP:
		proto_on_stop(p);
		break;
	case TEMPLATE_I2C_ERROR:
		/* A write cut short is rejected (REJECT_ABORTED), never applied. Clear the
		 * peripheral's error flags and let it wait for the next START. */
		proto_on_abort(p);
		break;
	}
	return 0xFFu;
}
