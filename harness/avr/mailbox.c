/* See mailbox.h. */
#include "mailbox.h"

#include <stdio.h>
#include <string.h>

#include "fixmath_avr/fixmath_avr.h"

/* simavr's sleep callback would wait in real time: these binaries never need to. */
static void no_sleep(struct avr_t *avr, avr_cycle_count_t howlong)
{
	(void)avr;
	(void)howlong;
}

int mailbox_run_until(struct mailbox *mb, uint16_t addr, uint8_t want, uint64_t max_cycles)
{
	uint64_t start = mb->avr->cycle;

	while (mb->avr->data[addr] != want) {
		int st = avr_run(mb->avr);

		if (st == cpu_Done || st == cpu_Crashed || mb->avr->cycle - start > max_cycles)
			return -1;
	}
	return 0;
}

int mailbox_open(struct mailbox *mb, const char *elf_path)
{
	memset(mb, 0, sizeof(*mb));
	if (elf_read_firmware(elf_path, &mb->fw))
		return -1;
	snprintf(mb->fw.mmcu, sizeof(mb->fw.mmcu), "atmega1284p");
	mb->fw.frequency = 16000000u;
	mb->avr = avr_make_mcu_by_name(mb->fw.mmcu);
	if (!mb->avr)
		return -1;
	avr_init(mb->avr);
	mb->avr->log = LOG_ERROR;
	mb->avr->sleep = no_sleep;
	avr_load_firmware(mb->avr, &mb->fw);
	if (mailbox_run_until(mb, FXA_GPIOR0, FXA_READY, 10000000u))
		return -1;
	mb->box = (uint16_t)(mb->avr->data[FXA_GPIOR1] | mb->avr->data[FXA_GPIOR2] << 8);
	return 0;
}
