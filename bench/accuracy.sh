#!/usr/bin/env bash
# The accuracy bench of issue 7 (bench/README.md): the specification's "Performances" experiment
# on 200 randomized simulated robots, beside the legacy P-only baseline on the same robots, with
# the odometry calibration; prints the table and writes PNGs to bench-out/. Arguments go to
# `asserv bench accuracy` (--robots N, --jobs N, --out DIR, --no-png, --strict: exit 1 when a
# goal is missed, ...).
# The arguments are the bench's: setup.sh, sourced, would take the first as its profile.
args=("$@")
set --
. "$(dirname "$0")/../scripts/setup.sh" demo
exec asserv bench accuracy "${args[@]}"
