/* Porting contract: the I2C slave. */
#ifndef ASSERV_HAL_I2C_H
#define ASSERV_HAL_I2C_H

#include <stdint.h>

/* Start answering at a 7-bit address. From then on, the port's I2C interrupt reports every bus
 * event to the protocol layer (core/protocol.h): own address + write -> proto_on_write_start(),
 * each data byte received -> proto_on_byte() then ACK, own address + read -> proto_on_read_start()
 * then send proto_read_byte(), each data byte ACKed by the master -> send proto_read_byte(),
 * STOP -> proto_on_stop(), bus error -> proto_on_abort(); a repeated start -> proto_on_restart(),
 * where the hardware tells it apart from a STOP (optional: it packs the reply early, so that the
 * clock held after own address + read only covers loading the first byte). The port acknowledges
 * every byte at once: it never holds the clock beyond the hardware's own ACK handling (Raspberry Pi
 * masters corrupt data when a slave stretches the clock).
 * May be called from an interrupt: no (once, at start-up). */
void hal_i2c_slave_init(uint8_t address);

#endif
