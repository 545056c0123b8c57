#!/usr/bin/env bash
# Every test and check of the project, as CI runs them (.ci/run calls this and nothing else).
. "$(dirname "$0")/setup.sh"

step() { printf '\n== %s\n' "$*"; }

step "protocol: generated C and Python match protocol/messages.toml"
python protocol/gen.py --check

step "style: clang-format, ruff, mypy"
mapfile -t c_files < <(git ls-files -co --exclude-standard '*.c' '*.h' |
	grep -v -e '_gen\.h$' -e 'protocol_defs\.h$' -e 'protocol_table\.c$')
clang-format --dry-run --Werror "${c_files[@]}"
ruff check python protocol bench
ruff format --check python protocol bench
mypy

step "C: build (AddressSanitizer + UndefinedBehaviorSanitizer) and ctest"
cmake -S . -B build -G Ninja -DASSERV_SANITIZE=ON >/dev/null
cmake --build build
ctest --test-dir build --output-on-failure

step "Python: pytest"
python -m pytest
