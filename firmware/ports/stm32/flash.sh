#!/usr/bin/env bash
# Build the STM32 firmware and flash it into a Nucleo-F446RE plugged in by USB (its ST-LINK):
#   bash firmware/ports/stm32/flash.sh [F446|F401]
# The vectors (sector 0) and the code (sector 2 on) are written apart, so that sector 1, the
# odometry calibration's log (docs/stm32.md, "The calibration in flash"), is kept.
# Needs Debian's gcc-arm-none-eabi, libnewlib-arm-none-eabi, cmake, ninja-build, stlink-tools.
set -euo pipefail
ROOT=$(cd "$(dirname "${BASH_SOURCE[0]}")/../../.." && pwd)
CHIP=${1:-F446}
case "$CHIP" in
F446 | F401) ;;
*)
	echo "flash.sh: chip must be F446 or F401, not '$CHIP'" >&2
	exit 2
	;;
esac
for tool in arm-none-eabi-gcc cmake ninja st-flash; do
	if ! command -v "$tool" >/dev/null; then
		echo "flash.sh: $tool not found: sudo apt-get install gcc-arm-none-eabi libnewlib-arm-none-eabi cmake ninja-build stlink-tools" >&2
		exit 1
	fi
done
BUILD="$ROOT/build-stm32-$CHIP"
cmake -S "$ROOT/firmware/ports/stm32" -B "$BUILD" -G Ninja \
	-DCMAKE_TOOLCHAIN_FILE="$ROOT/cmake/stm32f4.cmake" -DSTM32_CHIP="$CHIP" >/dev/null
cmake --build "$BUILD"
arm-none-eabi-objcopy -O binary -j .isr_vector "$BUILD/asserv_stm32.elf" "$BUILD/vectors.bin"
arm-none-eabi-objcopy -O binary -R .isr_vector "$BUILD/asserv_stm32.elf" "$BUILD/code.bin"
st-flash write "$BUILD/code.bin" 0x08008000
st-flash --reset write "$BUILD/vectors.bin" 0x08000000
