"""How fast the simulated board runs through the Python API: physics and control core at 1 kHz,
with a master polling over the simulated bus, in simulated seconds per wall-clock second.

Each robot (seeds 0..N-1, randomized) plays the same tour of GOTOs with Board.complete() (a
CHECK_BUSY poll every 10 ms of simulated time), then runs 20 s of a GOTO with
Simulator.advance() alone (the drive, then holding the position); one process per core by
default (``--jobs``). The simulator's default physics takes a whole 1 ms tick as one step away
from contacts and from the tyres' grip (docs/simulator.md, "Speed"); ``--fine`` runs the 100 us
substep everywhere (coarse_substep_ns = 0), as before. Prints the speeds per process against the
process's CPU time (what the simulator costs, whatever else the machine runs: the figure to
compare, on a machine shared with other work) and against the wall clock, and the whole
machine's. Then the physics and the core at 1 kHz through Simulator.advance(), per CPU second,
against issue 4's goal of 2000x real time (bench/README.md), marked met or MISSED, and a summary
line; --strict exits 1 on a miss. The figure is this machine's: no test compares it.

    python bench/sim_speed.py [--robots N] [--jobs J] [--record] [--fine] [--strict]
"""

from __future__ import annotations

import argparse
import multiprocessing
import os
import statistics
import sys
import time

from asserv.goals import Goals, add_strict_flag

TOUR = [(600, -600), (900, 300), (200, 600), (-600, 400), (-900, -400), (0, -700)]
ADVANCE_S = 20.0
GOAL_X = 2000.0  # issue 4: simulated seconds per second of one core


Run = tuple[float, float, float, float, float, float]


def one(job: tuple[int, bool, bool]) -> Run:
    """(simulated s, wall s, CPU s) of a tour with a polling master, then of advance() alone."""
    from asserv import Board
    from asserv.sim import Simulator

    seed, record, fine = job
    config: dict[str, object] = {"start": (0, -850, 0)}
    if fine:
        config["coarse_substep_ns"] = 0
    sim = Simulator(config, seed, randomize=True, record=record)
    board = Board(sim.bus)
    board.set_vitesse_traj(100, 100)
    board.set_vitesse_rot(50, 100)
    t0, w0, c0 = sim.time_s, time.perf_counter(), time.process_time()
    for x, y in TOUR:
        board.complete(board.goto, x, y, timeout_s=20)
    tour = (sim.time_s - t0, time.perf_counter() - w0, time.process_time() - c0)
    board.goto(-900, 300)  # a long drive, then holding, while advance() runs alone
    t0, w0, c0 = sim.time_s, time.perf_counter(), time.process_time()
    sim.advance(ADVANCE_S)
    return (*tour, sim.time_s - t0, time.perf_counter() - w0, time.process_time() - c0)


def _line(label: str, sim_s: list[float], wall_s: list[float], cpu_s: list[float]) -> str:
    cpu = [s / c for s, c in zip(sim_s, cpu_s, strict=True)]
    wall = [s / w for s, w in zip(sim_s, wall_s, strict=True)]
    return (
        f"{label}: median {statistics.median(cpu):.0f}x real time per CPU second"
        f" (min {min(cpu):.0f}x, max {max(cpu):.0f}x), {statistics.median(wall):.0f}x per wall"
        " second"
    )


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawTextHelpFormatter)
    ap.add_argument("--robots", type=int, default=0, help="robots (default: 2 per process)")
    ap.add_argument("--jobs", type=int, default=os.cpu_count() or 1, help="processes (all cores)")
    ap.add_argument("--record", action="store_true", help="keep the trace of every tick")
    ap.add_argument("--fine", action="store_true", help="100 us substeps everywhere")
    add_strict_flag(ap)
    args = ap.parse_args(argv)
    if args.jobs < 1 or args.robots < 0:
        print("sim_speed: --jobs must be >= 1 and --robots >= 0", file=sys.stderr)
        return 2
    robots = args.robots or 2 * args.jobs
    w0 = time.perf_counter()
    with multiprocessing.Pool(args.jobs) as pool:
        runs = pool.map(one, [(s, args.record, args.fine) for s in range(robots)])
    wall = time.perf_counter() - w0
    sim_total = sum(r[0] + r[3] for r in runs)
    print(
        f"{robots} robots on {args.jobs} processes, trace {'kept' if args.record else 'off'},"
        f" substep {'100 us everywhere' if args.fine else '1 ms away from contacts and grip'}"
    )
    cols = list(zip(*runs, strict=True))
    print(_line("tour, Board.complete() polling every 10 ms", *map(list, cols[0:3])))
    print(_line("Simulator.advance(), a GOTO then holding ", *map(list, cols[3:6])))
    print(
        f"whole machine: {sim_total:.0f} simulated s in {wall:.1f} s of wall time:"
        f" {sim_total / wall:.0f}x real time"
    )
    per_cpu = [r[3] / r[5] for r in runs]
    speed = statistics.median(per_cpu)
    print(
        f"speed: physics and core at 1 kHz through Simulator.advance():"
        f" {speed:.0f}x real time per CPU second (median of {robots} robots)"
    )
    goals = Goals("bench/sim_speed.py")
    goals.check("Simulator.advance() per CPU second [x real time]", speed, ">=", GOAL_X)
    for line in goals.lines():
        print(line)
    print(goals.summary())
    return goals.exit_code(args.strict)


if __name__ == "__main__":
    sys.exit(main())
