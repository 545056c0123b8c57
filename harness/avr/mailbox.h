/* A test binary in simavr driven through a mailbox in its RAM (fixmath_avr/, control_avr/): the
 * binary signals FXA_READY in GPIOR0 with the mailbox's address in GPIOR1..2, then runs each
 * operation the host writes there. Shared by test_avr_fixmath and test_avr_control. */
#ifndef ASSERV_HARNESS_MAILBOX_H
#define ASSERV_HARNESS_MAILBOX_H

#include <stdint.h>

#include <simavr/sim_avr.h>
#include <simavr/sim_elf.h>

struct mailbox {
	elf_firmware_t fw;
	avr_t *avr;
	uint16_t box; /* the mailbox's address in the AVR's data space */
};

/* Loads the ELF on an ATmega1284P at 16 MHz and runs it until it is ready. Returns 0 or -1. */
int mailbox_open(struct mailbox *mb, const char *elf_path);

/* Runs the AVR until the byte at addr equals want. Returns 0, or -1 (crash, or more than
 * max_cycles). */
int mailbox_run_until(struct mailbox *mb, uint16_t addr, uint8_t want, uint64_t max_cycles);

#endif
