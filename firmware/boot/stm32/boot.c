/* The bootloader of the STM32F446 asserv board (docs/update.md): in flash sector 0, it starts the
 * application of the newest of its two slots (A/B) whose header and CRC are right, the other one
 * when the newest fails them, and otherwise (no valid application, or the application asked for
 * it) serves the update protocol as an I2C slave at address 2, writing the update into the slot
 * that does not run: each slot's image is linked to run where it is, so nothing is copied.
 *
 * Everything but the reset handler runs from RAM (the vector table too): while the flash erases
 * or programs, a fetch from it would stall the CPU (RM0390 3.5), and the bus would wait for the
 * whole erase, up to 2 s for a 128 KiB sector. From RAM the I2C interrupt keeps answering
 * "busy, poll again" and the main loop keeps feeding the watchdog. The clock stays the HSI's
 * 16 MHz (RM0390 6.2): the application's clock set-up finds the RCC as it is after a reset. */
#include <stddef.h>
#include <stdint.h>

#include "boot_layout.h"
#include "boot_proto.h"
#include "stm32f4_regs.h"

/* Registers the application does not use (RM0390, PM0214), so not in stm32f4_regs.h. */
#define SCB_AIRCR STM32_REG(0xE000ED0Cu) /* PM0214 4.4.5 */
#define SCB_AIRCR_SYSRESET (0x05FAu << 16 | 1u << 2)
#define NVIC_ICER(n) STM32_REG(0xE000E180u + 4u * (n)) /* PM0214 4.2.3 */
#define FLASH_CR_EOPIE (1u << 24)                      /* RM0390 3.8.5 */
#define IRQ_FLASH 4u                                   /* RM0390 Table 38 */
#define HSI_HZ 16000000u
#define BOOT_WDG_PR 3u    /* LSI / 32 */
#define BOOT_WDG_RLR 999u /* 1000 counts: 1 s at 32 kHz (0.68..1.9 s with the LSI's spread) */

extern uint32_t _sidata[], _sdata[], _edata[], _sbss[], _ebss[];
extern void _estack(void); /* a function, so that the table of them holds it (startup.c) */
void Reset_Handler(void);
void boot_main(void);
void boot_idle(void);

/* In flash, for the reset only: the stack and the reset handler (PM0214 2.3.4). */
__attribute__((section(".isr_vector"), used)) void (*const boot_reset_vectors[2])(void) = {
	_estack, Reset_Handler};

/* Runs from flash: copies the code and data into RAM (plain loops through volatile pointers, so
 * that the compiler makes no call to memcpy, which is not in RAM yet), then calls into RAM. */
__attribute__((section(".boot_reset"), used)) void Reset_Handler(void)
{
	volatile uint32_t *src = _sidata;
	volatile uint32_t *dst = _sdata;
	void (*volatile entry)(void) = boot_main;

	while (dst < _edata)
		*dst++ = *src++;
	for (dst = _sbss; dst < _ebss;)
		*dst++ = 0;
	entry();
	for (;;)
		;
}

/* ---- CRC-32 (IEEE 802.3, reflected 0xEDB88320), table in RAM ---- */
static uint32_t crc_table[256];

static void crc_init(void)
{
	for (uint32_t i = 0; i < 256u; i++) {
		uint32_t c = i;

		for (int k = 0; k < 8; k++)
			c = (c & 1u) ? 0xEDB88320u ^ (c >> 1) : c >> 1;
		crc_table[i] = c;
	}
}

static uint32_t crc32_update(uint32_t crc, const uint8_t *p, uint32_t n)
{
	crc = ~crc;
	while (n--)
		crc = crc_table[(crc ^ *p++) & 0xFFu] ^ (crc >> 8);
	return ~crc;
}

/* ---- Slots: 0 is A, 1 is B ---- */
static uint32_t slot_base(uint32_t slot)
{
	return slot ? BOOT_SLOT_B_BASE : BOOT_SLOT_A_BASE;
}

static const struct boot_header *header_at(uint32_t slot)
{
	return (const struct boot_header *)(uintptr_t)slot_base(slot);
}

static const uint8_t *image_at(uint32_t slot)
{
	return (const uint8_t *)(uintptr_t)(slot_base(slot) + BOOT_HEADER_SIZE);
}

/* 1 when the slot's header is whole, this board's, and says the image is linked for this slot
 * (END wrote it so only after the image's own record said so). */
static int header_valid(uint32_t slot)
{
	const struct boot_header *h = header_at(slot);

	if (h->magic != BOOT_HEADER_MAGIC ||
	    crc32_update(0, (const uint8_t *)h, offsetof(struct boot_header, header_crc)) !=
		    h->header_crc)
		return 0;
	return h->length != 0 && h->length <= BOOT_IMAGE_MAX && h->length % 4u == 0 &&
	       (h->board_id & 0xFFFFu) == BOOT_BOARD_ID &&
	       h->link == slot_base(slot) + BOOT_HEADER_SIZE;
}

/* 1 when the slot's header is valid and its image's CRC right. */
static int slot_valid(uint32_t slot)
{
	return header_valid(slot) &&
	       crc32_update(0, image_at(slot), header_at(slot)->length) == header_at(slot)->crc32;
}

/* The slot to start: the newest valid one (its sequence, in serial-number order, so that it may
 * wrap), else the other if it is valid; BOOT_SLOTS if neither is. The newest's CRC first: the
 * other's is computed only when the newest fails (38 ms for 56 KiB at 16 MHz). */
static uint32_t slot_to_start(void)
{
	uint32_t first = 0;

	if (header_valid(1) &&
	    (!header_valid(0) || (int32_t)(header_at(1)->sequence - header_at(0)->sequence) > 0))
		first = 1;
	if (slot_valid(first))
		return first;
	if (slot_valid(first ^ 1u))
		return first ^ 1u;
	return BOOT_SLOTS;
}

/* The application's stack pointer and reset handler, from its vector table (PM0214 2.3.4). */
__attribute__((noreturn)) static void start_application(uint32_t slot)
{
	const uint32_t *vectors = (const uint32_t *)(uintptr_t)(slot_base(slot) + BOOT_HEADER_SIZE);

	__asm__ volatile("msr msp, %0\n\tbx %1\n" ::"r"(vectors[0]), "r"(vectors[1] | 1u));
	__builtin_unreachable();
}

/* ---- The flash interface (RM0390 3.5): one operation at a time, its end an interrupt ---- */
static void flash_unlock(void)
{
	if (FLASH_CR & FLASH_CR_LOCK) {
		FLASH_KEYR = FLASH_KEY1;
		FLASH_KEYR = FLASH_KEY2;
	}
}

static void flash_erase_start(uint32_t sector)
{
	flash_unlock();
	FLASH_SR = FLASH_SR_ERRORS | FLASH_SR_EOP;
	FLASH_CR = FLASH_CR_PSIZE_X32 | FLASH_CR_EOPIE | FLASH_CR_SER | sector << FLASH_CR_SNB_POS;
	FLASH_CR |= FLASH_CR_STRT;
}

static void flash_program_start(uint32_t addr, uint32_t word)
{
	flash_unlock();
	FLASH_SR = FLASH_SR_ERRORS | FLASH_SR_EOP;
	FLASH_CR = FLASH_CR_PSIZE_X32 | FLASH_CR_EOPIE | FLASH_CR_PG;
	*(volatile uint32_t *)(uintptr_t)addr = word;
}

static int flash_busy(void)
{
	return (FLASH_SR & FLASH_SR_BSY) != 0;
}

/* After BSY clears: the errors, then PG/SER off and the lock back on. */
static uint32_t flash_finish(void)
{
	uint32_t err = FLASH_SR & FLASH_SR_ERRORS;

	FLASH_SR = err | FLASH_SR_EOP;
	FLASH_CR = FLASH_CR_LOCK;
	return err;
}

void FLASH_IRQHandler(void)
{
	FLASH_SR = FLASH_SR_EOP; /* the end wakes the main loop, which finishes the operation */
}

/* ---- The work of the main loop: flash operations, then the download's held words ---- */
struct boot_job {
	uint8_t sectors[4]; /* to erase, in order */
	uint8_t n_sectors;
	uint32_t dst;       /* then words to program from src */
	const uint8_t *src; /* RAM or flash */
	uint32_t n_words;
	uint8_t op;   /* 1 while an operation runs */
	uint8_t held; /* 1: that operation programs a word of the download held in RAM */
	uint8_t err;
};

static struct boot_job job;
struct boot_state boot;

/* The download's bytes from held_from to boot.next: received, held in RAM at their offset modulo
 * BOOT_BUFFER_SIZE, and programmed in order once the download slot's erase is over, while more
 * arrive (a word programs in 16 us; its 4 bytes take 90 us on the bus at 400 kHz). So the
 * master sends during the erase (1 s), until RAM is full. A power cut loses them with the rest
 * of the download: nothing of it counts before its header, written last. */
static uint8_t held[BOOT_BUFFER_SIZE] __attribute__((aligned(4), section(".boot_buffer")));
static uint32_t held_from;

static uint32_t word_of(const uint8_t *p)
{
	return (uint32_t)p[0] | (uint32_t)p[1] << 8 | (uint32_t)p[2] << 16 | (uint32_t)p[3] << 24;
}

static void set_state(uint8_t state, uint8_t result)
{
	__asm__ volatile("cpsid i" ::: "memory");
	boot.state = state;
	boot.result = result;
	__asm__ volatile("cpsie i" ::: "memory");
}

/* A word of the download that did not take (not blank, a flash error), or an erase that
 * failed: nothing more is programmed; begin again. */
static void download_failed(void)
{
	job.n_sectors = 0;
	job.n_words = 0;
	held_from = boot.next;
	set_state(BOOT_S_IDLE, BOOT_R_FLASH_ERROR);
}

/* A held word, at the flash, read back: it must be what RAM holds. */
static void held_word_done(int err)
{
	const uint8_t *at = image_at(boot.dl_slot) + held_from;

	if (err || word_of(at) != word_of(held + held_from % BOOT_BUFFER_SIZE))
		download_failed();
	else
		held_from += 4u;
}

/* The operation that ran, once it is over: its errors. */
static void op_finish(void)
{
	uint32_t err;

	if (!job.op || flash_busy())
		return;
	err = flash_finish();
	job.op = 0;
	if (job.held) {
		job.held = 0;
		held_word_done(err != 0);
	} else {
		job.err |= err != 0;
	}
}

/* The next operation: the job's erases, its words, then the download's held words. Returns 1 when
 * it moved on without starting one (an erased word skipped: the main loop goes on at once). */
static int op_start(void)
{
	uint32_t w;

	if (job.op)
		return 0;
	if (job.n_sectors) {
		flash_erase_start(job.sectors[0]);
		for (uint8_t i = 1; i < job.n_sectors; i++)
			job.sectors[i - 1] = job.sectors[i];
		job.n_sectors--;
		job.op = 1;
		return 0;
	}
	if (job.n_words) {
		/* An erased word stays erased: skipped, as programming 0xFFFFFFFF changes nothing.
		 */
		w = word_of(job.src);
		if (w != 0xFFFFFFFFu) {
			flash_program_start(job.dst, w);
			job.op = 1;
		}
		job.dst += 4u;
		job.src += 4u;
		job.n_words--;
		return !job.op;
	}
	if ((boot.state == BOOT_S_RECEIVING || boot.state == BOOT_S_CHECKING) &&
	    held_from != boot.next) {
		w = word_of(held + held_from % BOOT_BUFFER_SIZE);
		if (w == 0xFFFFFFFFu) {
			held_word_done(0);
			return 1;
		}
		flash_program_start(slot_base(boot.dl_slot) + BOOT_HEADER_SIZE + held_from, w);
		job.op = 1;
		job.held = 1;
	}
	return 0;
}

/* ---- The update (boot_proto.h) ---- */
static uint32_t hdr_words[BOOT_HEADER_WORDS];

static uint32_t be32(const uint8_t *p)
{
	return (uint32_t)p[0] << 24 | (uint32_t)p[1] << 16 | (uint32_t)p[2] << 8 | p[3];
}

/* The download's header: newer than the slot that runs, so that the next start-up starts it. */
static void make_header(uint32_t *w, uint32_t length, uint32_t crc, uint32_t version)
{
	struct boot_header h;

	h.magic = BOOT_HEADER_MAGIC;
	h.length = length;
	h.crc32 = crc;
	h.version = version;
	h.board_id = BOOT_BOARD_ID;
	h.link = slot_base(boot.dl_slot) + BOOT_HEADER_SIZE;
	h.sequence = boot.run_valid ? boot.run_sequence + 1u : 1u;
	h.header_crc =
		crc32_update(0, (const uint8_t *)&h, offsetof(struct boot_header, header_crc));
	__builtin_memcpy(w, &h, sizeof(h));
}

static void cmd_begin(const uint8_t *a)
{
	uint32_t length = be32(a), crc = be32(a + 4), version = be32(a + 8);
	uint32_t board = (uint32_t)a[12] << 8 | a[13];

	if (board != BOOT_BOARD_ID) {
		set_state(boot.state, BOOT_R_WRONG_BOARD);
		return;
	}
	if (length == 0 || length > BOOT_IMAGE_MAX || length % 4u != 0) {
		set_state(boot.state, BOOT_R_TOO_LARGE);
		return;
	}
	boot.length = length;
	boot.crc = crc;
	boot.version = version;
	boot.next = 0;
	held_from = 0;
	/* The download's slot, its header's sector first: from then on it is not valid. Slot A's
	 * sectors 3 and 4 only when the image reaches them. */
	if (boot.dl_slot) {
		job.sectors[0] = 5u;
		job.n_sectors = 1;
	} else {
		uint32_t end = BOOT_SLOT_A_BASE + BOOT_HEADER_SIZE + length;

		job.sectors[0] = 2u;
		job.n_sectors = 1;
		if (end > 0x0800C000u)
			job.sectors[job.n_sectors++] = 3u;
		if (end > 0x08010000u)
			job.sectors[job.n_sectors++] = 4u;
	}
	job.n_words = 0;
	job.err = 0;
	set_state(BOOT_S_ERASING, BOOT_R_OK);
}

/* BEGIN sent again while its erase runs (its acknowledge was lost): the same download. */
static int same_begin(const uint8_t *a)
{
	return be32(a) == boot.length && be32(a + 4) == boot.crc && be32(a + 8) == boot.version &&
	       ((uint32_t)a[12] << 8 | a[13]) == BOOT_BOARD_ID;
}

/* A byte of the download received: in RAM while held, else in the download slot (no operation
 * runs when this is called: the main loop takes no frame while a held word programs). */
static uint8_t received(uint32_t off)
{
	return off < held_from ? image_at(boot.dl_slot)[off] : held[off % BOOT_BUFFER_SIZE];
}

static void cmd_data(const uint8_t *a, uint32_t n)
{
	uint32_t off = be32(a);
	const uint8_t *d = a + 4;
	uint32_t i;

	if (boot.state != BOOT_S_RECEIVING && boot.state != BOOT_S_ERASING) {
		set_state(boot.state, BOOT_R_NOT_BEGUN);
		return;
	}
	if (n == 0 || n % 4u != 0 || off % 4u != 0 || off > boot.next || off + n > boot.length) {
		set_state(boot.state, BOOT_R_BAD_OFFSET);
		return;
	}
	if (off < boot.next) {
		/* Sent again (its reply was lost): what was received must be this chunk. */
		uint32_t have = boot.next - off < n ? boot.next - off : n;

		for (i = 0; i < have; i++)
			if (received(off + i) != d[i]) {
				set_state(boot.state, BOOT_R_MISMATCH);
				return;
			}
		if (have == n) {
			set_state(boot.state, BOOT_R_OK);
			return;
		}
		d += have;
		off += have;
		n -= have;
	}
	if (off + n - held_from > BOOT_BUFFER_SIZE) {
		/* RAM is full (the erase is not over): not taken; the master polls, sends again. */
		set_state(boot.state, BOOT_R_BUSY);
		return;
	}
	for (i = 0; i < n; i++)
		held[(off + i) % BOOT_BUFFER_SIZE] = d[i];
	__asm__ volatile("cpsid i" ::: "memory");
	boot.next = off + n;
	boot.result = BOOT_R_OK;
	__asm__ volatile("cpsie i" ::: "memory");
}

/* The image read back: its CRC, and its own record of board, version and link. */
static uint8_t check_stage(void)
{
	const uint8_t *img = image_at(boot.dl_slot);
	const struct boot_app_info *info;

	if (boot.next != boot.length)
		return BOOT_R_INCOMPLETE;
	if (crc32_update(0, img, boot.length) != boot.crc)
		return BOOT_R_BAD_CRC;
	if (boot.length < BOOT_APP_INFO_OFFSET + sizeof(*info))
		return BOOT_R_WRONG_BOARD; /* too short to hold its record */
	info = (const struct boot_app_info *)(const void *)(img + BOOT_APP_INFO_OFFSET);
	if (info->magic != BOOT_APP_INFO_MAGIC || (info->board_id & 0xFFFFu) != BOOT_BOARD_ID)
		return BOOT_R_WRONG_BOARD;
	if (info->version != boot.version)
		return BOOT_R_BAD_VERSION;
	if (info->link != slot_base(boot.dl_slot) + BOOT_HEADER_SIZE)
		return BOOT_R_WRONG_SLOT; /* it would run at the other slot's addresses */
	return BOOT_R_OK;
}

/* END: CHECKING until the main loop has programmed what RAM holds, then end_check(). */
static void cmd_end(void)
{
	if (boot.state != BOOT_S_RECEIVING) {
		set_state(boot.state, boot.state == BOOT_S_READY ? BOOT_R_OK : BOOT_R_NOT_BEGUN);
		return;
	}
	if (boot.next != boot.length) {
		set_state(boot.state, BOOT_R_INCOMPLETE);
		return;
	}
	set_state(BOOT_S_CHECKING, BOOT_R_OK);
}

/* The whole download programmed: read back, then its header written, last. */
static void end_check(void)
{
	uint8_t r = check_stage();

	if (r != BOOT_R_OK) {
		set_state(BOOT_S_RECEIVING, r);
		return;
	}
	make_header(hdr_words, boot.length, boot.crc, boot.version);
	job.dst = slot_base(boot.dl_slot);
	job.src = (const uint8_t *)hdr_words;
	job.n_words = BOOT_HEADER_WORDS;
	job.err = 0;
	set_state(BOOT_S_WRITING_HEADER, BOOT_R_OK);
}

static void system_reset(void)
{
	__asm__ volatile("dsb" ::: "memory");
	SCB_AIRCR = SCB_AIRCR_SYSRESET;
	for (;;)
		;
}

/* A frame the I2C interrupt took (boot_i2c.c): its PEC and length already checked. */
static void run_command(const uint8_t *f, uint8_t n)
{
	uint8_t erasing = boot.state == BOOT_S_ERASING;

	/* While the download slot erases, DATA is held in RAM and BEGIN may come again; anything
	 * else waits for the erase. */
	if (boot_busy(boot.state) &&
	    !(erasing && (f[0] == BOOT_CMD_DATA || f[0] == BOOT_CMD_BEGIN))) {
		set_state(boot.state, BOOT_R_BUSY); /* not applied: poll, then send it again */
		return;
	}
	switch (f[0]) {
	case BOOT_CMD_BEGIN:
		if (n != BOOT_LEN_BEGIN)
			set_state(boot.state, BOOT_R_BAD_LENGTH);
		else if (erasing) /* another download's: not taken before this erase ends */
			set_state(boot.state, same_begin(f + 1) ? BOOT_R_OK : BOOT_R_BUSY);
		else
			cmd_begin(f + 1);
		break;
	case BOOT_CMD_DATA:
		if (n < 1u + 4u + 4u)
			set_state(boot.state, BOOT_R_BAD_LENGTH);
		else
			cmd_data(f + 1, (uint32_t)n - 5u);
		break;
	case BOOT_CMD_END:
		cmd_end();
		break;
	case BOOT_CMD_START:
		if (boot.state == BOOT_S_READY || boot.run_valid)
			system_reset(); /* the start-up starts the newest valid slot */
		set_state(boot.state, BOOT_R_NO_APPLICATION);
		break;
	default:
		set_state(boot.state, BOOT_R_UNKNOWN);
		break;
	}
}

/* The end of the job the state started. */
static void job_done(void)
{
	switch (boot.state) {
	case BOOT_S_ERASING:
		/* The result stays the last write's: a chunk held meanwhile, or refused. */
		if (job.err)
			download_failed();
		else
			set_state(BOOT_S_RECEIVING, boot.result);
		break;
	case BOOT_S_WRITING_HEADER:
		set_state(job.err || !slot_valid(boot.dl_slot) ? BOOT_S_IDLE : BOOT_S_READY,
			  job.err ? BOOT_R_FLASH_ERROR : BOOT_R_OK);
		break;
	default:
		break;
	}
}

static void watchdog_start(void)
{
	IWDG_KR = IWDG_KR_START;
	IWDG_KR = IWDG_KR_ACCESS;
	IWDG_PR = BOOT_WDG_PR;
	IWDG_RLR = BOOT_WDG_RLR;
	while (IWDG_SR != 0)
		;
	IWDG_KR = IWDG_KR_RELOAD;
}

/* The vector table in RAM: 16 + 97 entries, aligned to 512 bytes (PM0214 4.4.4). */
static void (*ram_vectors[128])(void) __attribute__((aligned(512)));

void SysTick_Handler(void)
{
	/* Wakes the main loop each millisecond: it feeds the watchdog. */
}

static void unused_handler(void)
{
	for (;;)
		; /* the watchdog resets the chip */
}

void boot_main(void)
{
	volatile uint32_t *request = (volatile uint32_t *)(uintptr_t)BOOT_REQUEST_ADDR;
	int asked = request[0] == BOOT_REQUEST_MAGIC && request[1] == ~BOOT_REQUEST_MAGIC;
	uint32_t run;

	request[0] = 0;
	request[1] = 0;
	watchdog_start();
	crc_init();
	run = slot_to_start();
	if (run < BOOT_SLOTS && !asked)
		start_application(run);

	for (uint32_t i = 0; i < 128u; i++)
		ram_vectors[i] = unused_handler;
	ram_vectors[15] = SysTick_Handler;
	ram_vectors[16 + IRQ_FLASH] = FLASH_IRQHandler;
	ram_vectors[16 + IRQ_I2C1_EV] = I2C1_EV_IRQHandler;
	ram_vectors[16 + IRQ_I2C1_ER] = I2C1_ER_IRQHandler;
	SCB_VTOR = (uint32_t)(uintptr_t)ram_vectors;

	boot.state = BOOT_S_IDLE;
	boot.result = BOOT_R_OK;
	boot.run_valid = run < BOOT_SLOTS;
	/* The download goes into the slot that does not run (slot A when none does): what runs
	 * stays whole until the next start-up finds the download's header. */
	boot.run_slot = (uint8_t)(run < BOOT_SLOTS ? run : 1u);
	boot.dl_slot = boot.run_slot ^ 1u;
	if (boot.run_valid) {
		/* Kept in RAM: the I2C interrupt must not read the flash while it erases. */
		boot.run_version = header_at(run)->version;
		boot.run_length = header_at(run)->length;
		boot.run_crc = header_at(run)->crc32;
		boot.run_sequence = header_at(run)->sequence;
	}
	boot_i2c_init();
	NVIC_IPR_BYTE(IRQ_FLASH) = 0x80u;
	NVIC_ISER(IRQ_FLASH / 32u) = 1u << (IRQ_FLASH % 32u);
	SCB_SHPR3 = (SCB_SHPR3 & 0x00FFFFFFu) | 0xF0u << 24;
	SYST_RVR = HSI_HZ / 1000u - 1u;
	SYST_CVR = 0;
	SYST_CSR = SYST_CSR_ENABLE | SYST_CSR_TICKINT | SYST_CSR_CLKSOURCE;

	for (;;) {
		uint8_t n;
		int again;

		op_finish();
		/* A frame, but not while a held word programs (16 us): a chunk sent again may be
		 * compared with the flash, whose reads stall the CPU meanwhile. */
		if (!job.held) {
			n = boot_i2c_take(boot.frame);
			if (n) {
				run_command(boot.frame, n);
				boot_i2c_done();
			}
		}
		again = op_start();
		if (!job.op && !job.n_sectors && !job.n_words) {
			if (boot.state == BOOT_S_CHECKING && held_from == boot.next) {
				end_check();
				again = 1;
			} else if (boot.state == BOOT_S_ERASING ||
				   boot.state == BOOT_S_WRITING_HEADER) {
				job_done();
				again = 1;
			}
		}
		IWDG_KR = IWDG_KR_RELOAD;
		if (!again)
			boot_idle();
	}
}

/* One sleep of the main loop: the harness knows the CPU asleep at this wfi (as stm32_idle). */
__attribute__((naked)) void boot_idle(void)
{
	__asm__ volatile("wfi\n\tbx lr\n");
}
