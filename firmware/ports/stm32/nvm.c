/* The odometry calibration kept in flash (stm32_nvm.h): an append-only log of calib_store.h
 * records in sector 1, written a 32-bit word at a time from the main loop.
 *
 * Flash is programmed from 1 to 0 only and erased by whole sectors (RM0390 3.5.3, 3.5.4), so
 * ports/common/port_nvm.c's scheme, one record rewritten in place byte by byte, would need an
 * erase per calibration: 250 ms (typical; 500 ms at most, x32) during which every read of the
 * flash, every instruction fetch of the control interrupt included, stalls (RM0390 3.5: "any
 * attempt to read the flash memory while it is being written or erased causes the bus to
 * stall"). Here each calibration takes the next free 16-byte slot; the start-up takes the last
 * slot that decodes (magic, version, CRC: calib_store_decode()). A power-off while a record is
 * programmed leaves that slot torn, which does not decode: the previous record stays the last
 * valid one. The sector is erased only when the log is (nearly) full: at start-up before the
 * control starts, or at run time when a record waits and no order runs, the motors off and the
 * watchdog widened for the stall. docs/stm32.md gives the figures. */
#include <string.h>

#include "calib_store.h"
#include "hal.h"
#include "stm32_nvm.h"
#include "stm32_port.h"
#include "stm32f4_regs.h"

#define SLOT_WORDS (CALIB_STORE_SIZE / 4u)

static const uint8_t *slot_at(uint16_t i)
{
	return (const uint8_t *)(uintptr_t)(STM32_NVM_BASE + (uint32_t)i * CALIB_STORE_SIZE);
}

static int blank(const uint8_t *p)
{
	for (uint8_t i = 0; i < CALIB_STORE_SIZE; i++)
		if (p[i] != 0xFFu)
			return 0;
	return 1;
}

static int same(const struct board_calibration *a, const struct board_calibration *b)
{
	return a->ratio_ppm == b->ratio_ppm && a->scale_ppm == b->scale_ppm &&
	       a->track_10um == b->track_10um;
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
static void flash_erase_start(void)
{
	flash_unlock();
	FLASH_SR = FLASH_SR_ERRORS | FLASH_SR_EOP;
	FLASH_CR = FLASH_CR_PSIZE_X32 | FLASH_CR_SER | STM32_NVM_SECTOR << FLASH_CR_SNB_POS;
	FLASH_CR |= FLASH_CR_STRT;
}

/* Start-up only: the CPU stalls on its next fetch from flash until the operation ends anyway. */
static uint32_t flash_wait(void)
{
	while (FLASH_SR & FLASH_SR_BSY)
		;
	return flash_finish();
}

static uint32_t rec_word(const struct stm32_nvm *s, uint8_t k)
{
	uint32_t w;

	memcpy(&w, &s->rec[4u * k], sizeof(w)); /* little-endian: the slot's bytes are rec's */
	return w;
}

static uint32_t slot_addr(uint16_t slot, uint8_t k)
{
	return STM32_NVM_BASE + (uint32_t)slot * CALIB_STORE_SIZE + 4u * k;
}

int stm32_nvm_load(struct stm32_nvm *s, struct board *b)
{
	struct board_calibration cal;
	int err = CALIB_STORE_BLANK;

	memset(s, 0, sizeof(*s));
	s->word = SLOT_WORDS;
	for (uint16_t i = 0; i < STM32_NVM_SLOTS; i++) {
		const uint8_t *p = slot_at(i);
		int e;

		if (blank(p))
			continue;
		s->next = (uint16_t)(i + 1u); /* after the last slot ever written, torn ones too */
		e = calib_store_decode(p, &cal);
		if (e == 0 || err != 0)
			err = e; /* the last valid record, or the last refusal if none */
		if (e == 0) {
			s->stored = cal;
			s->have = 1;
		}
	}
	if (s->have) {
		err = board_set_calibration(b, &s->stored);
		if (err != 0)
			s->have = 0; /* refused: the board's next calibration is written */
	}
	if (STM32_NVM_SLOTS - s->next < STM32_NVM_START_FREE) {
		/* Nearly full, and the control has not started: erase now (up to 500 ms), then
		 * write the installed record back in slot 0. */
		flash_erase_start();
		s->erases++;
		s->errors += flash_wait() != 0;
		s->next = 0;
		if (s->have) {
			calib_store_encode(&s->stored, s->rec);
			for (uint8_t k = 0; k < SLOT_WORDS; k++) {
				flash_program_start(slot_addr(0, k), rec_word(s, k));
				s->errors += flash_wait() != 0;
			}
			s->next = 1;
			s->writes++;
		}
	}
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

/* The run-time erase. The control ticks stall with the fetches, and nothing feeds the watchdog,
 * for up to 500 ms: the watchdog's window is widened first (restored at the erase's end), and
 * the motors are switched off for the stall, as the tick could not drive them (the hold's duty
 * comes back at the first tick after it). Under PRIMASK, so that no tick comes between the
 * motors' stop and the erase's start. */
static void erase_when_idle(void)
{
	stm32_watchdog_set(STM32_WDG_ERASE_PR, STM32_WDG_ERASE_RLR);
	__asm__ volatile("cpsid i" ::: "memory");
	hal_motor_set(HAL_LEFT, 0);
	hal_motor_set(HAL_RIGHT, 0);
	flash_erase_start();
	__asm__ volatile("cpsie i" ::: "memory");
}

void stm32_nvm_poll(struct stm32_nvm *s, const struct board *b)
{
	struct board_calibration cal;
	uint8_t idle;

	if (s->op != STM32_NVM_OP_NONE) {
		uint32_t err;

		if (FLASH_SR & FLASH_SR_BSY)
			return;
		err = flash_finish();
		s->errors += err != 0;
		if (s->op == STM32_NVM_OP_ERASE) {
			stm32_watchdog_set(STM32_WDG_PR, STM32_WDG_RLR);
			s->next = 0;
			s->word = 0;
		} else {
			/* A failed word: the slot is spoilt, its check below moves to the next. */
			s->word = err ? SLOT_WORDS : (uint8_t)(s->word + 1u);
		}
		s->op = STM32_NVM_OP_NONE;
	}
	if (board_snapshot(b, &cal, &idle) && (!s->have || !same(&cal, &s->stored))) {
		if (s->pending && s->word > 0 && s->next < STM32_NVM_SLOTS)
			s->next++; /* a record half written: left torn, the new one after it */
		s->stored = cal;
		s->have = 1;
		s->pending = 1;
		s->word = 0;
		calib_store_encode(&s->stored, s->rec);
	}
	if (!s->pending)
		return;
	if (s->word == SLOT_WORDS) {
		/* Read back: a slot that does not hold the record (a flash error, a word that was
		 * not blank) is left behind, and the record goes to the next. */
		if (memcmp(slot_at(s->next), s->rec, CALIB_STORE_SIZE) == 0) {
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
		erase_when_idle();
		s->op = STM32_NVM_OP_ERASE;
		s->erases++;
		return;
	}
	flash_program_start(slot_addr(s->next, s->word), rec_word(s, s->word));
	s->op = STM32_NVM_OP_PROGRAM;
}

uint8_t stm32_nvm_pending(const struct stm32_nvm *s)
{
	return s->pending;
}
