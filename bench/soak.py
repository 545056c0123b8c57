"""The soak of the board's promises (asserv.sim.soak) over many matches: prints their figures.

    python bench/soak.py [--matches N] [--seconds S] [--first-seed K] [--jobs J] [--no-faults]

Each match is a random robot (calibrated or not, half each), a random master and injected faults
for S simulated seconds; match k draws everything from random.Random(first_seed + k). Prints the
error radius's coverage at settled ticks and at order ends, for calibrated and uncalibrated
robots apart, the worst error/radius ratio, and the endings whose status disagreed with DEBUG's
end reason. docs/failure-model.md quotes its figures. The promises are its goals, each marked
met or MISSED, with a summary line; --strict exits 1 on a miss.
"""

from __future__ import annotations

import argparse
import os
import random
import sys
import time
from concurrent.futures import ProcessPoolExecutor

from asserv.goals import Goals, add_strict_flag
from asserv.sim.soak import MatchResult, play_match


def _match(args: tuple[int, float, bool]) -> MatchResult:
    seed, seconds, faults = args
    return play_match(random.Random(seed), duration_s=seconds, faults=faults)


def _parse(argv: list[str]) -> argparse.Namespace:
    p = argparse.ArgumentParser(prog="bench/soak.py", description=__doc__.split("\n")[0])
    p.add_argument("--matches", type=int, default=64, help="matches to play (64)")
    p.add_argument("--seconds", type=float, default=90.0, help="simulated seconds each (90)")
    p.add_argument("--first-seed", type=int, default=0, help="seed of the first match (0)")
    p.add_argument("--jobs", type=int, default=os.cpu_count() or 1, help="processes (all cores)")
    p.add_argument("--no-faults", action="store_true", help="no injected faults")
    add_strict_flag(p)
    a = p.parse_args(argv)
    if a.matches < 1:
        p.error(f"--matches must be at least 1, not {a.matches}")
    if not 1.0 <= a.seconds <= 3600.0:
        p.error(f"--seconds must be 1..3600, not {a.seconds}")
    if a.first_seed < 0:
        p.error(f"--first-seed must be 0 or more, not {a.first_seed}")
    if a.jobs < 1:
        p.error(f"--jobs must be at least 1, not {a.jobs}")
    return a


def main(argv: list[str]) -> int:
    a = _parse(argv)
    t0 = time.monotonic()
    work = [(a.first_seed + k, a.seconds, not a.no_faults) for k in range(a.matches)]
    with ProcessPoolExecutor(a.jobs) as pool:
        results = list(pool.map(_match, work))
    print(
        f"soak: {a.matches} matches of {a.seconds:g} s (seeds {a.first_seed}.."
        f"{a.first_seed + a.matches - 1}), faults {'off' if a.no_faults else 'on'}"
    )
    print(
        f"{'robots':<14}{'matches':>8}{'settled ticks':>15}{'covered':>9}{'order ends':>12}"
        f"{'covered':>9}{'worst e/r':>10}"
    )
    goals = Goals("bench/soak.py")
    for label, cal in (("uncalibrated", False), ("calibrated", True), ("all", None)):
        rs = [r for r in results if cal is None or r.calibrated == cal]
        if not rs:
            continue
        settled = sum(r.settled_ticks for r in rs)
        s_cov = sum(r.settled_covered for r in rs)
        ends = sum(r.order_ends for r in rs)
        e_cov = sum(r.ends_covered for r in rs)
        worst = max(r.worst_settled_ratio for r in rs)
        print(
            f"{label:<14}{len(rs):>8}{settled:>15}{100 * s_cov / max(settled, 1):>8.2f}%"
            f"{ends:>12}{100 * e_cov / max(ends, 1):>8.2f}%{worst:>10.2f}"
        )
        if cal is None:  # the promise: the error within the radius at every one of them
            goals.check(
                "settled ticks within the radius [%]", 100 * s_cov / max(settled, 1), "==", 100
            )
            goals.check("order ends within the radius [%]", 100 * e_cov / max(ends, 1), "==", 100)
    bad = [(k, b) for k, r in enumerate(results) for b in r.bad_endings]
    print(f"endings whose status disagreed with DEBUG's end reason: {len(bad)}")
    for k, b in bad[:10]:
        print(f"  match {a.first_seed + k}: {b}")
    goals.check("endings whose status disagreed with DEBUG", len(bad), "==", 0)
    print("goals (docs/failure-model.md, section 4):")
    for line in goals.lines():
        print(line)
    print(f"wall time: {time.monotonic() - t0:.1f} s on {a.jobs} processes")
    print(goals.summary())
    return goals.exit_code(a.strict)


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
