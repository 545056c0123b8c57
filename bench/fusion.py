#!/usr/bin/env python3
"""Position fixes fused by the board (issue 28): 90 s matches on 50 randomized robots with the
start pose error, with a simulated localisation (10 Hz, 10 mm and 1 degree of noise, 100 +- 50 ms
of latency, 1 % outliers) and without. Prints each goal met or MISSED and a summary line.

    python bench/fusion.py            50 robots x 90 s (about a minute per core)
    python bench/fusion.py --quick    8 robots x 30 s
    python bench/fusion.py --strict   exit 1 when a goal is missed

Goals (issue 28): estimate error p95 <= 8 mm with fixes (16.3 mm without them on the accuracy
bench's straight), radius coverage >= 99 % of settled moments, tightness (mean radius / p99
error) <= 3, outliers rejected, few good fixes rejected (<= 1 %).
"""

from __future__ import annotations

import argparse
import math
import sys
from concurrent.futures import ProcessPoolExecutor

from asserv.fixes import FixSource
from asserv.goals import Goals, add_strict_flag
from asserv.sim.fusion import MatchResult, pool, run_match

SOURCE = dict(rate_hz=10.0, sigma_mm=10.0, sigma_deg=1.0, latency_ms=100.0, latency_jitter_ms=50.0)


def one(args: tuple[int, float, bool]) -> MatchResult:
    seed, duration_s, fixes = args
    src = FixSource(**SOURCE, outlier_rate=0.01, seed=seed) if fixes else None  # type: ignore[arg-type]
    return run_match(seed, duration_s, src)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(
        description=__doc__.split("\n\n")[0],
        epilog=__doc__.split("\n\n", 1)[1],
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    ap.add_argument("--robots", type=int, default=50, help="randomized robots (default 50)")
    ap.add_argument("--seconds", type=float, default=90.0, help="each match's length (default 90)")
    ap.add_argument("--quick", action="store_true", help="8 robots x 30 s")
    ap.add_argument("--jobs", type=int, default=2, help="processes (default 2)")
    add_strict_flag(ap)
    a = ap.parse_args(argv)
    if a.robots < 1:
        ap.error(f"--robots must be 1 or more, not {a.robots}")
    if not 0 < a.seconds < math.inf:
        ap.error(f"--seconds must be a positive number, not {a.seconds}")
    if a.jobs < 1:
        ap.error(f"--jobs must be 1 or more, not {a.jobs}")
    robots, seconds = (8, 30.0) if a.quick else (a.robots, a.seconds)
    work = [(seed, seconds, f) for seed in range(1, robots + 1) for f in (True, False)]
    with ProcessPoolExecutor(max_workers=a.jobs) as ex:
        res = list(ex.map(one, work))
    w = pool([r for r in res if r.fixes])
    wo = pool([r for r in res if not r.fixes])
    print(f"fusion: {robots} robots x {seconds:g} s, fixes 10 Hz, 10 mm, 1 deg, 100 +- 50 ms, 1 %")
    print(
        f"  without fixes: error p95 {wo.err_p95_mm:.1f} mm, worst {wo.err_max_mm:.1f} mm;"
        f" coverage {wo.coverage_pct:.2f} %, tightness {wo.tightness:.2f}"
    )
    print(f"  with fixes: error worst {w.err_max_mm:.1f} mm (no goal)")
    goals = Goals("bench/fusion.py")
    goals.check("error p95 with fixes [mm]", w.err_p95_mm, "<=", 8)
    goals.check("radius coverage of settled moments [%]", w.coverage_pct, ">=", 99)
    goals.check("radius tightness (mean / p99)", w.tightness, "<=", 3)
    outliers = 100.0 * w.outliers_rejected / w.outliers if w.outliers else 100.0
    goals.check(
        f"outliers rejected [%] ({w.outliers_rejected} of {w.outliers})", outliers, ">=", 95
    )
    good = 100.0 * w.good_rejected / w.good if w.good else 0.0
    goals.check(f"good fixes rejected [%] ({w.good_rejected} of {w.good})", good, "<=", 1)
    for line in goals.lines():
        print(line)
    print(goals.summary())
    return goals.exit_code(a.strict)


if __name__ == "__main__":
    sys.exit(main())
