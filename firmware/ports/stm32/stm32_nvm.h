/* hal_nvm.h on the STM32F4's flash: the odometry calibration kept across a power-off as
 * calib_store.h's 16-byte records in two flash sectors, 1 and 7, each a log written in turn
 * (nvm.c; docs/stm32.md, "The calibration in flash"). The other implementation of hal_nvm.h,
 * ports/common/nvm_bytes.h, rewrites two records in place, as an EEPROM allows; flash is erased
 * by sectors, so here a new record takes the next free slot of the active log instead, and a
 * full log is compacted into the other sector. main.c includes this header for struct hal_nvm. */
#ifndef ASSERV_STM32_NVM_H
#define ASSERV_STM32_NVM_H

#include <stdint.h>

#include "board.h"
#include "calib_store.h"
#include "hal_nvm.h"

/* The two logs (RM0390 3.3 Table 4; RM0368 3.3 Table 5): sector 1, 16 KiB, and sector 7, 128
 * KiB, of which the first 16 KiB are used, so that both logs hold as many records.
 * stm32f446re.ld keeps code out of both; neither the bootloader nor flash.sh writes them. */
#define STM32_NVM_BASE 0x08004000u /* sector 1 */
#define STM32_NVM_SECTOR 1u
#define STM32_NVM_B_BASE 0x08060000u /* sector 7 */
#define STM32_NVM_B_SECTOR 7u
#define STM32_NVM_SIZE 0x4000u                              /* [bytes] of each log */
#define STM32_NVM_SLOTS (STM32_NVM_SIZE / CALIB_STORE_SIZE) /* 1024 records */
/* At start-up the active log is compacted when fewer slots than this are left, so that a
 * run-time erase (which stalls the CPU) needs that many calibrations in one power-on. */
#define STM32_NVM_START_FREE 64u

enum stm32_nvm_op {
	STM32_NVM_OP_NONE,
	STM32_NVM_OP_PROGRAM, /* a word, 16 us typical, 100 us at most */
	STM32_NVM_OP_ERASE,   /* the other log's sector: 16 KiB 250 ms typical, 500 ms at most;
				 128 KiB 1 s typical, 2 s at most (x32) */
};

/* The implementation's state (hal_nvm.h). */
struct hal_nvm {
	struct board_calibration stored; /* the calibration of the newest record, or the one
					    being written */
	uint8_t have;                    /* stored is valid */
	uint8_t pending;                 /* stored's record is not completely written yet */
	uint8_t rec[CALIB_STORE_SIZE];   /* stored's record */
	uint8_t word;                    /* rec's words programmed (4: all, to check) */
	uint8_t op;                      /* enum stm32_nvm_op: the flash operation started */
	uint8_t area;                    /* the active log: 0 (sector 1) or 1 (sector 7) */
	uint8_t gen;                     /* the generation of its records */
	uint16_t next;                   /* its slot being written, or the first free one
					    (STM32_NVM_SLOTS: the log is full) */
	int8_t loaded;                   /* hal_nvm_load()'s result */
	uint16_t writes;                 /* records written and checked since start-up */
	uint16_t erases;                 /* sector erases since start-up */
	uint16_t errors;                 /* flash errors and failed read-backs since start-up */
};

/* hal_nvm.h's three functions, as this implementation does them:
 * - hal_nvm_load(), at start, after board_init(), before the I2C, the watchdog's 60 ms and the
 *   first tick: find the newest valid record of both logs and install it. When fewer than
 *   STM32_NVM_START_FREE slots of its log are free, erase the other log's sector and write that
 *   record there, one generation on: the start-up then takes up to 500 ms, or 2 s, more
 *   (main.c widens the watchdog for it).
 * - hal_nvm_poll(), from the main loop (thread mode): finish the flash operation that has ended,
 *   then, when the board's calibration is not the stored one, start writing its record; start
 *   at most one operation (one word, or the other sector's erase when the active log is full
 *   and no order runs) and return without waiting.
 * - hal_nvm_pending(): 1 while a record is not completely written and checked. */

#endif
