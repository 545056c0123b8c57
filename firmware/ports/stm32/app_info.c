/* What this image is, for the bootloader and the master's `asserv flash` (docs/update.md): at a
 * fixed offset after the vector table (stm32f446re.ld), the board it is built for and its
 * version (ASSERV_FW_VERSION, set by CMakeLists.txt). */
#include "boot_layout.h"

#ifndef ASSERV_FW_VERSION
#define ASSERV_FW_VERSION 1u
#endif

__attribute__((section(".app_info"), used)) const struct boot_app_info stm32_app_info = {
	.magic = BOOT_APP_INFO_MAGIC,
#if defined(STM32F401)
	.board_id = BOOT_BOARD_ID_F401,
#else
	.board_id = BOOT_BOARD_ID_F446,
#endif
	.version = ASSERV_FW_VERSION,
};
