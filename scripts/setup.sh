# Sourced by scripts/demo.sh and scripts/test.sh: installs what the project needs, idempotently.
#   . scripts/setup.sh demo    what the simulator needs: a C compiler and Python (scripts/demo.sh)
#   . scripts/setup.sh [test]  everything the tests and checks use: CMake, the sanitizers, clang,
#                              valgrind, the AVR and ARM toolchains, simavr (scripts/test.sh)
#  - Debian packages: with apt-get when run as root, otherwise a message naming the missing ones.
#  - A Python virtual environment in .venv with the package, its simulator (python/asserv-sim,
#    compiled from the C sources) and, for `test`, the dev tools (pip).
# After it: ROOT is the repository, the venv is active, and build/ is the CMake build directory.

set -euo pipefail
ROOT=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
cd "$ROOT"

SETUP_PROFILE=${1:-test}
# The simulator: a C compiler and the Python headers for the cffi extension, and the venv.
DEBIAN_PACKAGES=(build-essential python3 python3-venv python3-dev)
case "$SETUP_PROFILE" in
demo) PIP_EXTRAS=sim ;;
test)
	PIP_EXTRAS=dev,sim
	DEBIAN_PACKAGES+=(
		cmake ninja-build pkg-config libcmocka-dev clang-format valgrind clang libclang-rt-14-dev
		universal-ctags # scripts/function_lengths.sh
		gcc-avr avr-libc simavr libsimavr-dev libelf-dev bc gcc-arm-none-eabi
		libnewlib-arm-none-eabi
		chromium # asserv view's browser tests (Playwright drives it: no browser download)
	)
	# the reference MCAP reader (@mcap/core) reads the logs in python/tests/test_log_mcap_js.py
	command -v npm >/dev/null || DEBIAN_PACKAGES+=(nodejs npm)
	;;
*)
	echo "setup: unknown profile '$SETUP_PROFILE' (demo or test)" >&2
	exit 2
	;;
esac

missing=()
for pkg in "${DEBIAN_PACKAGES[@]}"; do
	dpkg-query -W -f='${Status}' "$pkg" 2>/dev/null | grep -q "install ok installed" || missing+=("$pkg")
done
if [ ${#missing[@]} -gt 0 ]; then
	if [ "$(id -u)" = 0 ]; then
		echo "setup: installing Debian packages: ${missing[*]}"
		export DEBIAN_FRONTEND=noninteractive
		apt-get update -qq
		apt-get install -y -qq "${missing[@]}" >/dev/null
	else
		echo "setup: missing Debian packages: ${missing[*]}" >&2
		echo "setup: install them with: sudo apt-get install ${missing[*]}" >&2
		exit 1
	fi
fi

if [ ! -x .venv/bin/python ]; then
	echo "setup: creating the Python virtual environment .venv"
	python3 -m venv .venv
fi
# shellcheck disable=SC1091
. .venv/bin/activate
# pip runs only when what it builds from changed since the last set-up of this profile: the
# packaging files, this script, the pins, and the C sources of the simulator's extension (the
# asserv package itself is installed editable: its Python files need no reinstall).
setup_stamp() {
	{
		echo "$SETUP_PROFILE"
		git ls-files -co --exclude-standard -- scripts/setup.sh pyproject.toml constraints.txt \
			python/asserv-sim firmware sim field robot protocol | grep -v -e '\.so$' -e '/build/' |
			LC_ALL=C sort | xargs -d '\n' sha256sum 2>/dev/null || true # (links to folders: no sum)
	} | sha256sum | cut -d' ' -f1
}
STAMP=.venv/.asserv-setup-$SETUP_PROFILE
stamp=$(setup_stamp)
if [ "$(cat "$STAMP" 2>/dev/null)" != "$stamp" ]; then
	PIP_LOG=.venv/pip-setup.log
	# pip and the build backends speak to the log; it is shown only if a step fails
	quiet_pip() {
		python -m pip "$@" >"$PIP_LOG" 2>&1 || {
			cat "$PIP_LOG" >&2
			echo "setup: pip $* failed (the log above: $PIP_LOG)" >&2
			exit 1
		}
	}
	# The test profile installs the exact versions of constraints.txt (what CI runs); the
	# demo takes the ranges of pyproject.toml, as a user's pip install does.
	PIN=()
	[ "$SETUP_PROFILE" = test ] && PIN=(-c constraints.txt)
	quiet_pip install -q --upgrade pip
	# The extension used to be built into python/asserv/; a stale copy there would shadow _core.py.
	rm -f python/asserv/_core.*.so python/asserv/_core.c
	echo "setup: building the simulator (python/asserv-sim) into .venv (pip)"
	quiet_pip install -q "${PIN[@]}" -e python/asserv-sim
	echo "setup: installing the asserv package ($PIP_EXTRAS) into .venv (pip)"
	quiet_pip install -q "${PIN[@]}" -e ".[$PIP_EXTRAS]"
	echo "$stamp" >"$STAMP"
fi
if [ "$SETUP_PROFILE" = test ]; then
	# The npm packages of the tests, at the exact versions of their package-lock.json.
	NPM_DIR=python/tests/mcap_js
	npm_stamp=$(sha256sum "$NPM_DIR/package-lock.json" | cut -d' ' -f1)
	if [ "$(cat "$NPM_DIR/node_modules/.asserv-setup" 2>/dev/null)" != "$npm_stamp" ]; then
		echo "setup: installing the reference MCAP reader (@mcap/core) into $NPM_DIR (npm ci)"
		npm ci --prefix "$NPM_DIR" --no-audit --no-fund --loglevel=error >/dev/null
		echo "$npm_stamp" >"$NPM_DIR/node_modules/.asserv-setup"
	fi
fi
