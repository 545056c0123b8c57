#!/usr/bin/env bash
# Build the fuzz targets (clang, libFuzzer, AddressSanitizer + UndefinedBehaviorSanitizer) in
# build-fuzz/ and run each for a bounded time, starting from the seeds written from
# protocol/vectors.toml and from what earlier runs found (build-fuzz/corpus/). fuzz/README.md.
#
#   bash fuzz/run.sh             30 s per target: the CI run (scripts/test.sh)
#   bash fuzz/run.sh 3600        an hour per target: the long run
#   FUZZ_JOBS=2 bash fuzz/run.sh 3600     the same with 2 workers per target (2 cores)
#   bash fuzz/run.sh 60 board    one target only
#
# Prints the executions of each target; exits 1 with the fuzzer's report and the input that
# failed (build-fuzz/crash-*) when a sanitizer or a property check fires.
set -euo pipefail
ROOT=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
cd "$ROOT"

seconds=${1:-30}
shift || true
targets=("$@")
[ ${#targets[@]} -gt 0 ] || targets=(protocol board)
jobs=${FUZZ_JOBS:-1}
out=build-fuzz

cmake -S fuzz -B "$out" -G Ninja -DCMAKE_C_COMPILER=clang >/dev/null
cmake --build "$out" -j2 >/dev/null

export UBSAN_OPTIONS="suppressions=$ROOT/fuzz/known-ub.supp"
for t in "${targets[@]}"; do
	python3 fuzz/seed_corpus.py "$t" "$out/seeds/$t" >/dev/null
	mkdir -p "$out/corpus/$t"
	log="$out/fuzz_$t.log"
	args=(-max_total_time="$seconds" -timeout=10 -max_len=1024 -print_final_stats=1
		-artifact_prefix="$out/crash-$t-")
	if [ "$jobs" -gt 1 ]; then
		args+=(-jobs="$jobs" -workers="$jobs")
	fi
	if ! "$out/fuzz_$t" "${args[@]}" "$out/corpus/$t" "$out/seeds/$t" >"$log" 2>&1; then
		tail -n 40 "$log"
		echo "fuzz_$t: FAILED; the input is $(ls -t "$out"/crash-"$t"-* 2>/dev/null | head -n 1)"
		echo "  reproduce: $out/fuzz_$t <that file>    (fuzz/README.md)"
		exit 1
	fi
	runs=$(awk '/stat::number_of_executed_units/ {s += $NF} END {print s + 0}' "$log")
	rate=$(awk '/stat::average_exec_per_sec/ {s += $NF} END {print s + 0}' "$log")
	cov=$(grep -o 'cov: [0-9]*' "$log" | tail -n 1 | cut -d' ' -f2)
	units=$(find "$out/corpus/$t" -type f | wc -l)
	printf 'fuzz_%s: %s executions in %s s (%s/s), coverage %s points, corpus %s inputs\n' \
		"$t" "$runs" "$seconds" "$rate" "${cov:-?}" "$units"
done
