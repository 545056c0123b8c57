# CMake toolchain file for the STM32F4 port (firmware/ports/stm32): Debian's gcc-arm-none-eabi and
# libnewlib-arm-none-eabi for a Cortex-M4 with the soft-float ABI. The core is integer only, so
# the port leaves the FPU off: exceptions then stack the basic 8-word frame (docs/stm32.md).
include(${CMAKE_CURRENT_LIST_DIR}/arm-none-eabi.cmake)
find_program(ARM_OBJCOPY arm-none-eabi-objcopy REQUIRED)
set(CMAKE_C_FLAGS_INIT "-mcpu=cortex-m4 -mthumb -mfloat-abi=soft")
set(CMAKE_ASM_FLAGS_INIT "-mcpu=cortex-m4 -mthumb -mfloat-abi=soft")
