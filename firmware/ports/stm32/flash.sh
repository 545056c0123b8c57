#!/usr/bin/env bash
# Build the STM32 firmware and flash it into a Nucleo-F446RE plugged in by USB (its ST-LINK):
#   bash firmware/ports/stm32/flash.sh [F446|F401]
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
st-flash --reset write "$BUILD/asserv_stm32.bin" 0x08000000
