#!/usr/bin/env bash
# Installs the package as a team would, outside the checkout, and runs it there (scripts/test.sh):
#  1. builds the sdist and the wheel of asserv (pure Python) and of asserv-sim (the C simulator);
#  2. the driver alone, from the wheel and from the sdist, on a machine with no C compiler (cc,
#     gcc and clang replaced by a command that fails and records the attempt; CC=false): it
#     installs, imports without numpy, matplotlib or cffi, and answers the CLI;
#  3. asserv[sim] from the wheels: `asserv demo`, a scenario, and the driver's tests;
#  4. asserv[view] on the driver's install (no compiler, no simulator): its page and default
#     field, and `asserv --sim ... log` of a simulator server run from the asserv[sim] install;
#  5. asserv[sim] from the sdists (the extension compiled from the C sources the sdist carries):
#     `asserv demo` and a scenario; then asserv[view] added to it.
# In each install (driver only, [view], [sim], both), scripts/check_commands.py runs `--help` of
# every subcommand and the commands that install should run: help, a run, or one line naming the
# extra to install (exit 1); never a traceback or "unrecognized arguments".
# Needs network access to PyPI for the dependencies (smbus2, numpy, matplotlib, cffi, pytest).
set -euo pipefail
ROOT=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
PYTHON=${PYTHON:-python3}
SCENARIO="$ROOT/scenarios/annex.txt"
# The dependencies at the versions the tests pin (pyproject.toml has the ranges)
export PIP_CONSTRAINT="$ROOT/constraints.txt"
WORK=$(mktemp -d)
trap 'rm -rf "$WORK"' EXIT
say() { printf -- '-- %s %s\n' "$(date +%T)" "$*"; }
fail() {
	echo "check_install: $*" >&2
	exit 1
}

say "build: sdist and wheel of asserv and asserv-sim (python -m build)"
python -m build -o "$WORK/dist" "$ROOT" >"$WORK/build.log" 2>&1 || {
	cat "$WORK/build.log"
	fail "python -m build of asserv failed"
}
python -m build -o "$WORK/dist" "$ROOT/python/asserv-sim" >>"$WORK/build.log" 2>&1 || {
	cat "$WORK/build.log"
	fail "python -m build of asserv-sim failed"
}
ls "$WORK/dist"
WHEEL=$(echo "$WORK"/dist/asserv-*-py3-none-any.whl)
SDIST=$(echo "$WORK"/dist/asserv-[0-9]*.tar.gz)
SIM_WHEEL=$(echo "$WORK"/dist/asserv_sim-*.whl)
SIM_SDIST=$(echo "$WORK"/dist/asserv_sim-*.tar.gz)
for f in "$WHEEL" "$SDIST" "$SIM_WHEEL" "$SIM_SDIST"; do [ -f "$f" ] || fail "missing $f"; done

cd "$WORK" # from here on, nothing of the checkout is on the path

# A machine without a C compiler: every compiler name runs this, which records and fails.
mkdir nocc
for cc in cc gcc c++ g++ clang clang++ x86_64-linux-gnu-gcc aarch64-linux-gnu-gcc; do
	printf '#!/bin/sh\necho "$0 $*" >>%s/compiler-calls\nexit 1\n' "$WORK" >"nocc/$cc"
	chmod +x "nocc/$cc"
done

for kind in wheel sdist; do
	if [ $kind = wheel ]; then pkg=$WHEEL; else pkg=$SDIST; fi
	say "driver only, from the $kind, no compiler: pip install asserv"
	"$PYTHON" -m venv "drv-$kind"
	(
		export PATH="$WORK/nocc:$WORK/drv-$kind/bin:$PATH" CC=false CXX=false
		pip install -q "$pkg"
		if pip show -q cffi 2>/dev/null; then fail "the driver-only install pulled in cffi"; fi
		python - <<-'EOF'
			import sys
			import asserv, asserv.cli, asserv.cli_bus, asserv.driver, asserv.codec
			loaded = {"numpy", "matplotlib", "cffi", "asserv_sim"} & set(sys.modules)
			assert not loaded, f"the driver imports {loaded}"
			print(f"import asserv {asserv.__version__}: without numpy, matplotlib, cffi")
		EOF
		asserv --version
		[ "$(asserv encode goto 200 100 0)" = "00 00 c8 00 64 00" ] || fail "asserv encode"
		set +e
		asserv --bus 1 goto 40000 0 2>err.txt
		rc=$?
		asserv demo --no-png 2>demo-err.txt
		rc_demo=$?
		set -e
		[ $rc = 2 ] && grep -q OUT_OF_RANGE err.txt || fail "goto 40000 0: exit $rc, $(cat err.txt)"
		[ $rc_demo = 1 ] && grep -q 'pip install "asserv\[sim\]"' demo-err.txt ||
			fail "asserv demo without the simulator: exit $rc_demo, $(cat demo-err.txt)"
		cat demo-err.txt
		python "$ROOT/scripts/check_commands.py" driver "$SCENARIO" || fail "the driver's commands ($kind)"
	)
	[ ! -s compiler-calls ] || fail "a compiler was called: $(cat compiler-calls)"
done

say "asserv[sim] from the wheels: demo, a scenario, the driver's tests"
"$PYTHON" -m venv sim-wheel
(
	. sim-wheel/bin/activate
	pip install -q "$SIM_WHEEL"
	pip install -q "$WHEEL[sim]" pytest hypothesis
	asserv demo --png demo.png | tail -n 3
	[ -s demo.png ] || fail "asserv demo wrote no plot"
	asserv sim run annex --png annex.png | tail -n 2
	asserv sim run recal_border | tail -n 1
	mkdir tests
	cp "$ROOT"/python/tests/test_{driver,bus,codec,cli_bus}.py tests/
	python -m pytest -q -p no:cacheprovider tests
	python "$ROOT/scripts/check_commands.py" sim "$SCENARIO" || fail "asserv[sim]'s commands"
)

say "asserv[view] without the simulator (a Pi beside the robot): log a served simulator"
(
	export PATH="$WORK/nocc:$WORK/drv-wheel/bin:$PATH" CC=false CXX=false
	pip install -q "$WHEEL[view]"
	python -c 'from asserv import field, view; field.load(); assert (view.STATIC / "index.html").is_file()'
	if pip show -q cffi 2>/dev/null; then fail "asserv[view] pulled in cffi"; fi
	python "$ROOT/scripts/check_commands.py" view "$SCENARIO" || fail "asserv[view]'s commands"
)
[ ! -s compiler-calls ] || fail "a compiler was called: $(cat compiler-calls)"
PORT=$((20000 + RANDOM % 20000))
sim-wheel/bin/asserv sim serve --port "$PORT" --speed 0 --duration 300 >serve.log 2>&1 &
SERVE=$!
for _ in $(seq 100); do grep -q listening serve.log && break || sleep 0.1; done
set +e
drv-wheel/bin/asserv --sim "127.0.0.1:$PORT" log --mcap served.mcap --duration 1
rc=$?
set -e
kill "$SERVE"
wait "$SERVE" || true
[ $rc = 0 ] || fail "asserv --sim log from the driver's install: exit $rc, $(cat serve.log)"
drv-wheel/bin/python - <<-'EOF'
	from asserv import log
	got = log.read_mcap("served.mcap")
	assert got.field is not None and len(got.rows) >= 45, (got.field, len(got.rows))
	assert "/field" in got.schemas and "/pose/true" in got.schemas
	print(f"served.mcap: {len(got.rows)} rows, the field and the truth")
EOF

say "asserv[sim] from the sdists: the extension compiled from the sources the sdist carries"
"$PYTHON" -m venv sim-sdist
(
	. sim-sdist/bin/activate
	pip install -q "$SIM_SDIST"
	pip install -q "$SDIST[sim]"
	python -c 'import asserv_sim._core, sys; print("built:", asserv_sim._core.__file__)'
	asserv demo --no-png | tail -n 2
	asserv sim run recal_line | tail -n 1
	say "asserv[sim] and asserv[view] together"
	pip install -q "$SDIST[view]"
	python "$ROOT/scripts/check_commands.py" both "$SCENARIO" || fail "asserv[sim,view]'s commands"
)
say "install checks passed"
