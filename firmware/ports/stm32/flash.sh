#!/usr/bin/env bash
# Build the STM32 firmware and flash it into a Nucleo-F446RE plugged in by USB (its ST-LINK):
#   bash firmware/ports/stm32/flash.sh [F446|F401]
# The bootloader (sector 0) and slot A (sector 2 on: its header, then the application linked for
# it, asserv_stm32.bin; docs/update.md, "The flash") are written apart, so that sector 1, the odometry calibration's first log (docs/stm32.md, "The
# calibration in flash"), is kept; st-flash erases only the sectors it writes, so sector 7, its
# second log, is kept too. Sector 5, slot B, is erased by writing it a blank header: whatever an
# earlier bootloader or update left there is no longer a slot the start-up could prefer to the
# one written here (sequence 1). The slot's header is the one the bootloader writes after an
# update over I2C (docs/update.md): its CRC-32s are gzip's (RFC 1952 ends with the CRC-32 of
# the data, the same as zlib's crc32). Later updates need no ST-LINK: `asserv --bus 1 flash`.
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
for tool in arm-none-eabi-gcc cmake ninja st-flash gzip od; do
	if ! command -v "$tool" >/dev/null; then
		echo "flash.sh: $tool not found: sudo apt-get install gcc-arm-none-eabi libnewlib-arm-none-eabi cmake ninja-build stlink-tools" >&2
		exit 1
	fi
done
BUILD="$ROOT/build-stm32-$CHIP"
cmake -S "$ROOT/firmware/ports/stm32" -B "$BUILD" -G Ninja \
	-DCMAKE_TOOLCHAIN_FILE="$ROOT/cmake/stm32f4.cmake" -DSTM32_CHIP="$CHIP" >/dev/null
cmake --build "$BUILD"
# The CRC-32 of stdin, as 4 little-endian bytes (the gzip trailer's first 4).
crc32() { gzip -c | tail -c8 | head -c4; }
# A 32-bit number as 4 little-endian bytes.
le32() { printf "$(printf '\\x%02x\\x%02x\\x%02x\\x%02x' $(($1 & 255)) $(($1 >> 8 & 255)) $(($1 >> 16 & 255)) $(($1 >> 24 & 255)))"; }
IMAGE="$BUILD/asserv_stm32.bin"
LEN=$(stat -c %s "$IMAGE")
if ((LEN % 4)); then
	echo "flash.sh: $IMAGE is $LEN bytes, not a multiple of 4" >&2
	exit 1
fi
# The image's record (boot_layout.h, at offset 0x200): magic, board id, version, link.
read -r _ BOARD VERSION LINK < <(od -An -tu4 -j $((0x200)) -N 16 "$IMAGE")
{
	printf 'BOOT'
	le32 "$LEN"
	crc32 <"$IMAGE"
	le32 "$VERSION"
	le32 "$BOARD"
	le32 "$LINK"
	le32 1 # the sequence: the newest slot, with slot B's erased
} >"$BUILD/header28.bin"
{
	cat "$BUILD/header28.bin"
	crc32 <"$BUILD/header28.bin"
	head -c $((0x200 - 32)) /dev/zero | tr '\0' '\377'
	cat "$IMAGE"
} >"$BUILD/slot.bin"
head -c 512 /dev/zero | tr '\0' '\377' >"$BUILD/blank.bin"
st-flash write "$BUILD/blank.bin" 0x08020000
st-flash write "$BUILD/slot.bin" 0x08008000
st-flash --reset write "$BUILD/asserv_boot.bin" 0x08000000
