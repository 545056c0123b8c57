/* hal_nvm.h on the STM32's flash (stm32_nvm.h): calib_store.h's records in two logs, sectors 1
 * and 7, written a 32-bit word at a time from the main loop.
 *
 * Flash is programmed from 1 to 0 only and erased by whole sectors (RM0390 3.5.3, 3.5.4), so
 * ports/common/nvm_bytes.c's scheme, records rewritten in place byte by byte, would need an
 * erase per calibration, during which every read of the flash, every instruction fetch of the
 * control interrupt included, stalls (RM0390 3.5: "any attempt to read the flash memory while
 * it is being written or erased causes the bus to stall"). Here each calibration takes the next
 * free 16-byte slot of the active log, its words 1, 2, 3 then 0 (the magic's): until word 0 is
 * programmed whole the slot cannot decode, and a word 0 with only part of its bits programmed
 * differs from the record's in byte 3 alone at most (magic and version checked), which the CRC
 * always catches. A power-off while a record is programmed so leaves the previous record the
 * newest valid one, or the new one whole.
 *
 * A full log is compacted into the other sector: erase it, then write the newest record there
 * with the next generation (calib_store_newer()); the full log stays untouched until the other
 * one fills in turn. A power-off during the erase, or before the record is whole, leaves the
 * full log's record the newest valid one. The start-up takes the newest valid record of both
 * logs: the higher generation, then the later slot. The erase happens at start-up (fewer than
 * STM32_NVM_START_FREE free slots) before the control starts, or at run time when a record
 * waits and no order runs, the motors off and the watchdog widened for the stall. docs/stm32.md
 * gives the figures. */
#include <string.h>

#include "calib_log.h"
#include "calib_store.h"
#include "hal.h"
#include "stm32_nvm.h"
#include "stm32_port.h"
#include "stm32f4_regs.h"

#define SLOT_WORDS (CALIB_STORE_SIZE / 4u)

static uint32_t area_base(uint8_t area)
{
	return area ? STM32_NVM_B_BASE : STM32_NVM_BASE;
}

static uint32_t area_sector(uint8_t area)
{
	return area ? STM32_NVM_B_SECTOR : STM32_NVM_SECTOR;
}

static uint32_t slot_addr(uint8_t area, uint16_t slot, uint8_t k)
{
	return area_base(area) + (uint32_t)slot * CALIB_STORE_SIZE + 4u * k;
}

static const uint8_t *slot_at(uint8_t area, uint16_t i)
{
	return (const uint8_t *)(uintptr_t)slot_addr(area, i, 0);
}

/* The word a record's step-th program writes: 1, 2, 3, then 0 (the magic's). */
static uint8_t step_word(uint8_t step)
{
	return (uint8_t)((step + 1u) & 3u);
}

/* RM0390 3.5.1: KEY1 then KEY2 opens FLASH_CR; a wrong key locks it until the next reset (and
 * a bus error), so the keys are written only while LOCK is set. */
static void flash_unlock(void)
{
	if (FLASH_CR & FLASH_CR_LOCK) {
		FLASH_KEYR = FLASH_KEY1;
		FLASH_KEYR = FLASH_KEY2;
	}
}

/* The end of an operation (BSY clear): its error flags, cleared (rc_w1), then PG/SER off and
 * the lock back on, so that no stray store can program the flash in between. */
static uint32_t flash_finish(void)
{
	uint32_t err = FLASH_SR & FLASH_SR_ERRORS;

	FLASH_SR = err | FLASH_SR_EOP;
	FLASH_CR = FLASH_CR_LOCK;
	return err;
}

/* RM0390 3.5.4: BSY clear, PG with the parallelism, then one store of that size. */
static void flash_program_start(uint32_t addr, uint32_t word)
{
	flash_unlock();
	FLASH_SR = FLASH_SR_ERRORS | FLASH_SR_EOP;
	FLASH_CR = FLASH_CR_PSIZE_X32 | FLASH_CR_PG;
	*(volatile uint32_t *)(uintptr_t)addr = word;
}

/* RM0390 3.5.3: SER and SNB, then STRT. */
static void flash_erase_start(uint32_t sector)
{
	flash_unlock();
	FLASH_SR = FLASH_SR_ERRORS | FLASH_SR_EOP;
	FLASH_CR = FLASH_CR_PSIZE_X32 | FLASH_CR_SER | sector << FLASH_CR_SNB_POS;
	FLASH_CR |= FLASH_CR_STRT;
}

/* Start-up only: the CPU stalls on its next fetch from flash until the operation ends anyway. */
static uint32_t flash_wait(void)
{
	while (FLASH_SR & FLASH_SR_BSY)
		;
	return flash_finish();
}

static uint32_t rec_word(const struct hal_nvm *s, uint8_t k)
{
	uint32_t w;

	memcpy(&w, &s->rec[4u * k], sizeof(w)); /* little-endian: the slot's bytes are rec's */
	return w;
}

/* calib_log.h's reader: the slot itself, in the flash's address space (one flash: no ctx). */
static const uint8_t *read_slot(void *ctx, uint8_t area, uint16_t i, uint8_t buf[CALIB_STORE_SIZE])
{
	(void)ctx;
	(void)buf;
	return slot_at(area, i);
}

/* Start-up: the active log is nearly full, and the control has not started. Erase the other
 * log's sector (up to 2 s: main() widened the watchdog for it), then write the installed record
 * into its slot 0, one generation on: from then on the other log is the active one. */
static void compact_at_start(struct hal_nvm *s)
{
	s->area ^= 1u;
	s->gen++;
	flash_erase_start(area_sector(s->area));
	s->erases++;
	s->errors += flash_wait() != 0;
	s->next = 0;
	if (!s->have)
		return;
	calib_store_encode(&s->stored, s->gen, s->rec);
	for (uint8_t i = 0; i < SLOT_WORDS; i++) {
		uint8_t k = step_word(i);

		flash_program_start(slot_addr(s->area, 0, k), rec_word(s, k));
		s->errors += flash_wait() != 0;
	}
	s->next = 1;
	s->writes++;
}

int hal_nvm_load(struct hal_nvm *s, struct board *b)
{
	struct calib_log_area l[CALIB_LOG_AREAS];
	int err;

	memset(s, 0, sizeof(*s));
	s->word = SLOT_WORDS;
	calib_log_scan(read_slot, NULL, 0, STM32_NVM_SLOTS, &l[0]);
	calib_log_scan(read_slot, NULL, 1, STM32_NVM_SLOTS, &l[1]);
	s->area = calib_log_pick(l); /* the newer generation's log, or the emptier */
	s->gen = l[s->area].gen;
	s->next = l[s->area].next;
	err = l[s->area].err;
	if (l[s->area].found) {
		s->stored = l[s->area].cal;
		err = board_set_calibration(b, &s->stored);
		s->have = err == 0; /* refused: the board's next calibration is written */
	}
	if (STM32_NVM_SLOTS - s->next < STM32_NVM_START_FREE)
		compact_at_start(s);
	s->loaded = (int8_t)(err < -128 ? -128 : err);
	return err;
}

/* What the main loop reads of the board, under PRIMASK: the slow steps (SET_ODOMETRIE, the
 * order's end) run in the SysTick interrupt and could otherwise change it between two of its
 * fields, and a torn calibration would be stored as a valid record. Idle: no order runs. */
static uint8_t board_snapshot(const struct board *b, struct board_calibration *cal, uint8_t *idle)
{
	uint8_t on;

	__asm__ volatile("cpsid i" ::: "memory");
	on = b->planner.calibrated;
	*cal = b->planner.calibration;
	*idle = !orders_busy(&b->planner.orders);
	__asm__ volatile("cpsie i" ::: "memory");
	return on;
}

/* The run-time erase of the other log's sector. The control ticks stall with the fetches, and
 * nothing feeds the watchdog, for up to 2 s: the watchdog's window is widened first (restored
 * at the erase's end), and the motors are switched off for the stall, as the tick could not
 * drive them (the hold's duty comes back at the first tick after it). Under PRIMASK, so that no
 * tick comes between the motors' stop and the erase's start. */
static void erase_when_idle(uint32_t sector)
{
	stm32_watchdog_set(STM32_WDG_ERASE_PR, STM32_WDG_ERASE_RLR);
	__asm__ volatile("cpsid i" ::: "memory");
	hal_motor_set(HAL_LEFT, 0);
	hal_motor_set(HAL_RIGHT, 0);
	flash_erase_start(sector);
	__asm__ volatile("cpsie i" ::: "memory");
}

/* The flash operation that has ended: its result into the state. */
static void finish_op(struct hal_nvm *s)
{
	uint32_t err = flash_finish();

	s->errors += err != 0;
	if (s->op == STM32_NVM_OP_ERASE) {
		/* The other log is blank: it becomes the active one, one generation on. The full
		 * log keeps the newest record until the first record here is whole. */
		stm32_watchdog_set(STM32_WDG_PR, STM32_WDG_RLR);
		s->area ^= 1u;
		s->gen++;
		s->next = 0;
		s->word = 0;
	} else {
		/* A failed word: the slot is spoilt, its check moves to the next. */
		s->word = err ? SLOT_WORDS : (uint8_t)(s->word + 1u);
	}
	s->op = STM32_NVM_OP_NONE;
}

void hal_nvm_poll(struct hal_nvm *s, const struct board *b)
{
	struct board_calibration cal;
	uint8_t idle;

	if (s->op != STM32_NVM_OP_NONE) {
		if (FLASH_SR & FLASH_SR_BSY)
			return;
		finish_op(s);
	}
	if (board_snapshot(b, &cal, &idle) && (!s->have || !calib_store_same(&cal, &s->stored))) {
		if (s->pending && s->word > 0 && s->next < STM32_NVM_SLOTS)
			s->next++; /* a record half written: left torn, the new one after it */
		s->stored = cal;
		s->have = 1;
		s->pending = 1;
		s->word = 0;
	}
	if (!s->pending)
		return;
	if (s->word == SLOT_WORDS) {
		/* Read back: a slot that does not hold the record (a flash error, a word that was
		 * not blank) is left behind, and the record goes to the next. */
		if (memcmp(slot_at(s->area, s->next), s->rec, CALIB_STORE_SIZE) == 0) {
			s->pending = 0;
			s->writes++;
		} else {
			s->errors++;
			s->word = 0;
		}
		s->next++;
		return;
	}
	if (s->next >= STM32_NVM_SLOTS) {
		if (!idle)
			return; /* the erase would stall the control: not while an order runs */
		erase_when_idle(area_sector(s->area ^ 1u));
		s->op = STM32_NVM_OP_ERASE;
		s->erases++;
		return;
	}
	if (s->word == 0) /* the generation of the log it goes into */
		calib_store_encode(&s->stored, s->gen, s->rec);
	flash_program_start(slot_addr(s->area, s->next, step_word(s->word)),
			    rec_word(s, step_word(s->word)));
	s->op = STM32_NVM_OP_PROGRAM;
}

uint8_t hal_nvm_pending(const struct hal_nvm *s)
{
	return s->pending;
}
