"""PAUSE at random moments (issue 31, item 1; docs/failure-model.md, "A pause").

On each of N randomized robots (50), at random accepted limits, at 1 kHz on an empty table, the
master reads MOTION, then sends PAUSE at a random moment of one of three kinds: on a straight, in
a turn in place, or just after a pass-through corner. From the PAUSE's last byte it measures:

- the time to rest (the last tick either drive wheel is faster than REST_MM_S) minus the braking
  time MOTION reported just before (goal: +10 ms at most);
- how far the encoder-axis midpoint got from where it was at the PAUSE, at any moment of the
  next 2 s, minus the braking distance MOTION reported (goal: +2 mm at most);

then sends RESUME and checks that the order (or the tour) arrives at its target: DONE, the truth
within the error radius of the target.

    python bench/pause.py [--robots N] [--first-seed K] [--strict]
"""

from __future__ import annotations

import argparse
import math
import random
import sys
from dataclasses import dataclass

import numpy as np

from asserv import codec, field
from asserv._protocol import EndReason
from asserv.driver import Board
from asserv.goals import Goals, add_strict_flag
from asserv.sim import Simulator

REST_MM_S = 10.0  # as bench/shock_stop.py: a braked tyre relaxes at ~7 mm/s
HALF_TRACK_MM = 80.0  # the reference robot's drive wheels (docs/control.md)
GOAL_MS, GOAL_MM = 10.0, 2.0
APPEND, THROUGH = 0x04, 0x08


@dataclass
class Pause:
    seed: int
    kind: str
    speed_mm_s: float
    braking_mm: int
    braking_ms: int
    travel_mm: float
    rest_ms: float
    arrived: bool
    why: str

    @property
    def over_ms(self) -> float:
        return self.rest_ms - self.braking_ms

    @property
    def over_mm(self) -> float:
        return self.travel_mm - self.braking_mm


def motion(board: Board) -> codec.Motion:
    return board._query("MOTION", codec.Motion)


def one(seed: int, kind: str, rng: random.Random) -> Pause:
    sim = Simulator(seed=seed, randomize=True, field=field.Field())
    board = Board(sim.bus)
    board.set_vitesse_traj(rng.randint(30, 150), rng.randint(50, 255))
    board.set_vitesse_rot(rng.randint(20, 100), rng.randint(50, 255))
    start = sim.true_pose()
    if kind == "straight":
        target = [(1100, round(start.y_mm))]
        board.goto(*target[0])
        sim.advance(rng.uniform(0.1, 1.5))
    elif kind == "turn":
        target = [(-900, round(start.y_mm) + rng.choice([100, 250]))]  # behind: a half turn
        board.goto(*target[0])
        sim.advance(rng.uniform(0.02, 0.4))
    else:
        target = [(600, -600), (600, 400), (-400, 400)]
        for x, y in target:
            board._command("GOTO", x, y, APPEND | THROUGH)
        while motion(board).running_seq < 2:
            sim.advance(0.002)
        sim.advance(rng.uniform(0.0, 0.1))
    before = motion(board)
    n = len(sim.trace)
    speed = float(abs(sim.trace["v_mm_s"][-1]))
    sim.i2c_write(bytes([17]), stop=True)  # PAUSE
    t0 = sim.time_s
    sim.advance(2.0)
    tr = sim.trace[n:]
    omega = np.radians(tr["omega_deg_s"]) * HALF_TRACK_MM
    wheel = np.maximum(np.abs(tr["v_mm_s"] + omega), np.abs(tr["v_mm_s"] - omega))
    moving = np.nonzero(wheel >= REST_MM_S)[0]
    rest_ms = 0.0 if len(moving) == 0 else (float(tr["t_s"][moving[-1]]) - t0) * 1000
    travel = float(np.hypot(tr["x_mm"] - tr["x_mm"][0], tr["y_mm"] - tr["y_mm"][0]).max())
    board._command("RESUME")
    status = board.wait_idle(40)
    m = motion(board)
    pose, radius = sim.true_pose(), board.position().radius_mm
    x, y = target[-1]
    why = f"status {int(status)}, {m}, {math.hypot(pose.x_mm - x, pose.y_mm - y):.1f} mm"
    arrived = (
        status == 0
        and m.last_end == EndReason.DONE
        and m.last_seq == len(target)
        and math.hypot(pose.x_mm - x, pose.y_mm - y) <= radius + 1
    )
    return Pause(
        seed, kind, speed, before.braking_mm, before.braking_ms, travel, rest_ms, arrived, why
    )


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--robots", type=int, default=50, help="randomized robots (50)")
    ap.add_argument("--first-seed", type=int, default=0, help="seed of the first robot (0)")
    add_strict_flag(ap)
    args = ap.parse_args(argv)
    rng = random.Random(args.first_seed)
    runs = [
        one(seed, kind, rng)
        for seed in range(args.first_seed, args.first_seed + args.robots)
        for kind in ("straight", "turn", "corner")
    ]
    print(f"PAUSE at random moments: {args.robots} randomized robots x 3 kinds, 1 kHz")
    print("rest time minus MOTION's braking time, worst first (goal: +10 ms at most):")
    print("  seed  kind      speed mm/s  braking ms  rest ms  over ms")
    for r in sorted(runs, key=lambda r: -r.over_ms)[:10]:
        print(
            f"  {r.seed:4d}  {r.kind:8s}  {r.speed_mm_s:10.0f}  {r.braking_ms:10d}"
            f"  {r.rest_ms:7.0f}  {r.over_ms:+7.0f}"
        )
    print(
        "distance from the PAUSE's point minus MOTION's braking distance, worst first"
        " (goal: +2 mm at most):"
    )
    print("  seed  kind      speed mm/s  braking mm  travel mm  over mm")
    for r in sorted(runs, key=lambda r: -r.over_mm)[:10]:
        print(
            f"  {r.seed:4d}  {r.kind:8s}  {r.speed_mm_s:10.0f}  {r.braking_mm:10d}"
            f"  {r.travel_mm:9.1f}  {r.over_mm:+7.1f}"
        )
    worst_ms = max(r.over_ms for r in runs)
    worst_mm = max(r.over_mm for r in runs)
    arrived = sum(r.arrived for r in runs)
    goals = Goals("bench/pause.py")
    goals.check("rest over the braking time, worst [ms]", worst_ms, "<=", GOAL_MS)
    goals.check("travel over the braking distance, worst [mm]", worst_mm, "<=", GOAL_MM)
    goals.check(f"RESUMEs that arrived at their target (of {len(runs)})", arrived, "==", len(runs))
    for r in runs:
        if not r.arrived:
            print(f"  seed {r.seed} {r.kind}: {r.why}")
    print(f"goals over {len(runs)} pauses:")
    for line in goals.lines():
        print(line)
    print(goals.summary())
    return goals.exit_code(args.strict)


if __name__ == "__main__":
    sys.exit(main())
