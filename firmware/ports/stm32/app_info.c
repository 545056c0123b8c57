/* What this image is, for the bootloader and the master's `asserv flash` (docs/update.md): at a
 * fixed offset after the vector table (stm32f446re.ld), the board it is built for and its
 * version (ASSERV_FW_VERSION, set by CMakeLists.txt); these are the first three words of
 * struct boot_app_info; the linker script writes the last, the link (the slot the image is linked
 * for), so that both slots' images come from the same object. */
#include "boot_layout.h"

#ifndef ASSERV_FW_VERSION
#define ASSERV_FW_VERSION 1u
#endif

__attribute__((section(".app_info"), used)) const uint32_t stm32_app_info[3] = {
	BOOT_APP_INFO_MAGIC,
#if defined(STM32F401)
	BOOT_BOARD_ID_F401,
#else
	BOOT_BOARD_ID_F446,
#endif
	ASSERV_FW_VERSION,
};
