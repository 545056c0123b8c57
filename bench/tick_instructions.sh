#!/usr/bin/env bash
# Instructions per control tick of the core on the host, counted by callgrind (repeatable, unlike
# time): board_tick() inclusive, averaged over the ticks of each scenario. Prints, asserts nothing.
set -euo pipefail
ROOT=$(cd "$(dirname "$0")/.." && pwd)
BUILD=${BUILD:-$ROOT/build-bench}
cmake -S "$ROOT" -B "$BUILD" -G Ninja -DCMAKE_BUILD_TYPE=Release -DASSERV_TESTS=OFF >/dev/null
cmake --build "$BUILD" --target bench_tick >/dev/null
command -v valgrind >/dev/null || { echo "tick_instructions: valgrind is not installed" >&2; exit 1; }
echo "board_tick() instructions per control tick, x86-64, CMake Release -O3 (callgrind):"
for scenario in idle goto rotate; do
	out=$(mktemp)
	# Wait for valgrind to exit (and write its file) before reading either output.
	line=$(valgrind --tool=callgrind --callgrind-out-file="$out" \
		--toggle-collect=board_tick "$BUILD/bench/bench_tick" "$scenario" 2>/dev/null)
	ticks=${line#* }
	total=$(grep -E '^(summary|totals):' "$out" | head -1 | awk '{print $2}')
	rm -f "$out"
	printf '  %-7s %6d ticks  %8.0f instructions/tick\n' "$scenario" "$ticks" \
		"$(echo "$total / $ticks" | bc -l)"
done
