#!/usr/bin/env bash
# Real-time factor of the physics and the control core on one core (bench_realtime.c): builds it
# as a Release build with link-time optimisation in build-realtime/ (or $BUILD) and runs it;
# arguments go to the program (the number of runs). Prints, asserts nothing.
set -euo pipefail
ROOT=$(cd "$(dirname "$0")/.." && pwd)
BUILD=${BUILD:-$ROOT/build-realtime}
cmake -S "$ROOT" -B "$BUILD" -G Ninja -DCMAKE_BUILD_TYPE=Release -DASSERV_TESTS=OFF \
	-DCMAKE_INTERPROCEDURAL_OPTIMIZATION=ON >/dev/null
cmake --build "$BUILD" --target bench_realtime >/dev/null
"$BUILD/bench/bench_realtime" "$@"
