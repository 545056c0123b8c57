#!/usr/bin/env bash
# Every test and check of the project, as CI runs them (.ci/run calls this and nothing else).
. "$(dirname "$0")/setup.sh" test

step() { printf '\n== %s\n' "$*"; }

step "generated files: C and Python match protocol/messages.toml and field/default.toml"
python protocol/gen.py --check
python field/gen_field.py --check
python firmware/ports/host/gen_trace.py --check

step "generated files: the simulator's and the boards' robots match robot/*.toml"
python robot/gen_robot.py --check
ruff check robot
ruff format --check robot

step "style: clang-format, ruff, mypy"
mapfile -t c_files < <(git ls-files -co --exclude-standard '*.c' '*.h' |
	grep -v -e '_gen\.h$' -e 'protocol_defs\.h$' -e 'field_defs\.h$' -e 'robot_defs\.h$' -e 'protocol_table\.c$')
clang-format --dry-run --Werror "${c_files[@]}"
ruff check python protocol field bench fuzz scripts firmware/ports/host/gen_trace.py harness/avr
ruff format --check python protocol field bench fuzz scripts firmware/ports/host/gen_trace.py harness/avr
mypy

step "structure: no function of firmware/core over 80 lines (Universal Ctags)"
bash scripts/function_lengths.sh

step "C: build (AddressSanitizer + UndefinedBehaviorSanitizer) and ctest"
cmake -S . -B build -G Ninja -DASSERV_SANITIZE=ON >/dev/null
cmake --build build
ctest --test-dir build --output-on-failure

step "Python: pytest (pytest-xdist: one worker per core)"
python -m pytest -n auto

step "install: sdist and wheel built, installed outside the checkout (driver alone, no compiler; asserv[sim])"
bash scripts/check_install.sh

step "fuzz: the protocol layer and the board tick, 30 s each (libFuzzer, ASan + UBSan: fuzz/README.md)"
bash fuzz/run.sh 30

step "AVR: build the firmware, print its size, run it in simavr (and the core's Cortex-M4 size)"
cmake -S . -B build-avr -G Ninja -DASSERV_AVR_HARNESS=ON -DASSERV_TESTS=OFF \
	-DASSERV_AVR_SLOW_SHIFT=3 >/dev/null
cmake --build build-avr
cmake -S cmake/cortex-m4 -B build-avr/m4 -G Ninja -DCMAKE_TOOLCHAIN_FILE="$ROOT/cmake/arm-none-eabi.cmake" >/dev/null
cmake --build build-avr/m4
build-avr/harness/avr/bench_avr build-avr/harness/avr/firmware/asserv_avr.elf
ctest --test-dir build-avr -L avr --output-on-failure -j "$(nproc)"

step "AVR, one rate (the whole tick in the main loop, ASSERV_AVR_SLOW_SHIFT=0): the same tests"
cmake -S . -B build-avr0 -G Ninja -DASSERV_AVR_HARNESS=ON -DASSERV_TESTS=OFF \
	-DASSERV_AVR_SLOW_SHIFT=0 >/dev/null
cmake --build build-avr0
ctest --test-dir build-avr0 -L avr --output-on-failure -j "$(nproc)"

step "STM32: build the firmware and its bootloader for a Nucleo-F446RE, run the ELFs in unicorn (harness/stm32, docs/stm32.md, docs/update.md)"
cmake -S firmware/ports/stm32 -B build-stm32 -G Ninja -DCMAKE_TOOLCHAIN_FILE="$ROOT/cmake/stm32f4.cmake" >/dev/null
cmake --build build-stm32
ruff check harness/stm32
ruff format --check harness/stm32
mypy --config-file harness/stm32/mypy.ini harness/stm32 bench/stm32.py bench/update_stm32.py
# The benches run inside the tests, which check their figures against docs/stm32.md and
# docs/update.md and leave what they printed in build-stm32/bench/, shown here after them.
rm -rf build-stm32/bench
python -m pytest -p no:cacheprovider -n auto harness/stm32
cat build-stm32/bench/stm32.txt # python bench/stm32.py build-stm32/asserv_stm32.elf
grep -E 'SET_FIX|busiest period|goals met' build-stm32/bench/stm32_fixes.txt # ... --fixes
cat build-stm32/bench/update_stm32.txt # python bench/update_stm32.py build-stm32
