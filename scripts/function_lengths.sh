#!/usr/bin/env bash
# The core's functions over 80 lines, counted by Universal Ctags (issue "Structure"): prints each
# with its length and exits 1 if there is one. Tables and generated files are left out:
# protocol_table.c (generated from protocol/messages.toml).
set -euo pipefail
cd "$(dirname "$0")/.."
limit=${1:-80}
ctags --output-format=json --fields=+ne --kinds-C=f -o - firmware/core/*.c |
	python3 -c '
import json, sys
limit = int(sys.argv[1])
skip = {"firmware/core/protocol_table.c"}
tags = [json.loads(line) for line in sys.stdin]
funcs = [t for t in tags if t.get("kind") == "function" and t["path"] not in skip]
long = sorted(((t["end"] - t["line"] + 1, t["path"], t["name"]) for t in funcs), reverse=True)
over = [f for f in long if f[0] > limit]
for n, path, name in over:
    print(f"{path}: {name}: {n} lines (over {limit})")
print(f"function lengths: {len(funcs)} functions in firmware/core, the longest "
      f"{long[0][2]} ({long[0][0]} lines); {len(over)} over {limit}")
sys.exit(1 if over else 0)
' "$limit"
