/* The flash layout the bootloader and the application share on the STM32F446 (docs/update.md):
 * the sectors, the two slots' header, the image's own record of its board and version, and the word
 * in RAM by which the application asks for the bootloader. Little-endian, as the chip stores
 * words. Flash sectors: RM0390 3.3, Table 4. */
#ifndef ASSERV_BOOT_LAYOUT_H
#define ASSERV_BOOT_LAYOUT_H

#include <stdint.h>

/* Sector 0 (16 KiB): the bootloader, at the boot address. Sectors 1 and 7: the calibration's
 * logs, which the bootloader never erases nor programs. */
#define BOOT_BASE 0x08000000u
#define BOOT_SIZE 0x4000u
/* Two application slots, each run in place by an image linked for it (A/B): slot A, sectors 2,
 * 3 and 4 (16 + 16 + 64 KiB), where the bootloaders of protocol 1 and 2 keep their run slot;
 * slot B, sector 5 (128 KiB, its last 32 KiB unused: both slots take the same image). An update
 * is written into the slot that does not run; the start-up starts the newest valid one. */
#define BOOT_SLOT_A_BASE 0x08008000u
#define BOOT_SLOT_B_BASE 0x08020000u
#define BOOT_SLOT_SIZE 0x18000u
#define BOOT_SLOTS 2u
/* Each slot begins with its header, in the first of BOOT_HEADER_SIZE bytes (the vector table
 * that follows must be aligned to 512 bytes: PM0214 4.4.4); the image is linked at
 * slot + BOOT_HEADER_SIZE. */
#define BOOT_HEADER_SIZE 0x200u
#define BOOT_IMAGE_MAX (BOOT_SLOT_SIZE - BOOT_HEADER_SIZE) /* 97792 bytes */

#define BOOT_HEADER_MAGIC 0x544f4f42u /* "BOOT" */
/* A slot's header, written last: its words are programmed only once the image below it has been
 * read back and its CRC found right. A header torn by a power cut fails its own CRC. */
struct boot_header {
	uint32_t magic;
	uint32_t length;     /* [bytes] of the image, a multiple of 4 */
	uint32_t crc32;      /* of the image: CRC-32 (IEEE 802.3, zlib's crc32) */
	uint32_t version;    /* the image's (boot_app_info) */
	uint32_t board_id;   /* the image's (boot_app_info), in the low 16 bits */
	uint32_t link;       /* the image's (boot_app_info): its slot's base + BOOT_HEADER_SIZE */
	uint32_t sequence;   /* one more than the slot that ran when it was written: the newest */
	uint32_t header_crc; /* CRC-32 of the 28 bytes above */
};
#define BOOT_HEADER_WORDS 8u

/* At image offset BOOT_APP_INFO_OFFSET (after the vector table): what the image is. */
#define BOOT_APP_INFO_MAGIC 0x49505041u /* "APPI" */
#define BOOT_APP_INFO_OFFSET 0x200u
struct boot_app_info {
	uint32_t magic;
	uint32_t board_id; /* BOOT_BOARD_ID_*, low 16 bits */
	uint32_t version;
	uint32_t link; /* the address the image is linked at: its vector table's */
};
#define BOOT_BOARD_ID_F446 0xf446u /* a Nucleo-F446RE asserv board */
#define BOOT_BOARD_ID_F401 0xf401u /* a Nucleo-F401RE asserv board (its clock tree differs) */

/* The application asks for the bootloader by writing these two words at the end of RAM, which
 * no start-up clears before the bootloader reads them, then resetting the chip (SYSRESETREQ). */
#define BOOT_REQUEST_ADDR 0x2001fff8u
#define BOOT_REQUEST_MAGIC 0xb0071e57u

#endif
