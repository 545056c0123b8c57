"""What the physics' substep changes (docs/simulator.md, "Speed"): the same runs with the 100 us
substep everywhere (coarse_substep_ns = 0), the simulator's default (a 1 ms step for whole ticks
away from contacts and from the grip), and finer substeps as the reference.

    python bench/substeps.py [--quick] [--strict]

Prints, in simulated figures (no timing):
  - open floor: the physics alone, open-loop, a randomized robot given ramped duties; how far
    each substep ends from 10 us substeps (position mm, heading degrees);
  - oblique shock: test_an_oblique_hit_stops_and_lets_go's run (a 150 mm disc 120 mm off the
    path, 1 m/s, 1.5 m/s^2): the time to rest after the contact (ms, slower than 10 mm/s);
  - return after a stop: test_a_shock_at_1_m_s_stops_and_lets_go's nominal run with its start
    moved by 0 to 0.3 mm along x: the most the robot comes back towards the disc (mm).

No goal is stated for these figures (docs/simulator.md weighs them; python/tests/test_sim_coarse.py
bounds the default's): the summary line says so, and --strict never fails.
"""

from __future__ import annotations

import argparse
import dataclasses
import math
import random
import sys

import numpy as np

from asserv import field
from asserv.driver import Board, Status
from asserv.goals import Goals, add_strict_flag
from asserv.sim import COARSE_SUBSTEP_NS, SPEC_START, Simulator, lib

FINE = {"coarse_substep_ns": 0}
DEFAULT: dict[str, object] = {}
REST_MM_S = 10.0


def open_floor(seed: int, duty: tuple[int, int], ms: int, cfg: dict[str, object]) -> Simulator:
    sim = Simulator(
        {"start": (0, 0, 0), "enc_noise_mm2_per_m": (0, 0), **cfg},
        seed,
        randomize=True,
        field=field.Field(borders=False),
        record=False,
    )
    for k in range(ms):
        ramp = min(1.0, k / 100)
        lib.sim_set_duty(sim._sim, round(duty[0] * 80 * ramp), round(duty[1] * 80 * ramp))
        lib.sim_advance_ns(sim._sim, 1_000_000)
    return sim


def disc_field(y_mm: float) -> field.Field:
    base = field.load(field.DEFAULT)
    disc = field.Obstacle("circle", 0, y_mm, radius_mm=150)
    return dataclasses.replace(base, obstacles=(*base.obstacles, disc))


def oblique_rest_ms(cfg: dict[str, object]) -> int:
    sim = Simulator({"start": (-900, 0, 0.0), **cfg}, field=disc_field(120))
    board = Board(sim.bus)
    board.set_vitesse_traj(100, 150)
    board.goto(600, 0)
    if board.wait_idle(20) != Status.CHOC_BORD:
        raise RuntimeError("the oblique run did not end on the disc")
    sim.advance(1.5)
    tr = sim.trace
    c = int(np.nonzero(tr["shocks"])[0][0])
    moving = np.nonzero(np.abs(tr["v_mm_s"][c:]) >= REST_MM_S)[0]
    return int(moving[-1]) + 1 if len(moving) else 0


def return_mm(cfg: dict[str, object], dx_mm: float) -> float:
    start = (SPEC_START[0] + dx_mm, SPEC_START[1], SPEC_START[2])
    sim = Simulator({"start": start, **cfg}, field=disc_field(0), board_start=SPEC_START)
    board = Board(sim.bus)
    board.set_vitesse_traj(100, 100)
    for x, y in ((-900, -300), (-900, 0)):
        board.goto(x, y)
        board.wait_idle(20)
    first = sim.ticks
    board.goto(600, 0)
    if board.wait_idle(20) != Status.CHOC_BORD:
        raise RuntimeError("the 1 m/s run did not end on the disc")
    sim.advance(2)
    tr = sim.trace[first:]
    c = int(np.nonzero(tr["shocks"])[0][0])
    along = -np.hypot(tr["x_mm"][c:], tr["y_mm"][c:])
    stopped = int(np.nonzero(tr["v_mm_s"][c:] <= 0)[0][0])
    after = along[stopped:]
    return float((after - np.minimum.accumulate(after)).max())


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawTextHelpFormatter)
    ap.add_argument("--quick", action="store_true", help="fewer cases")
    add_strict_flag(ap)
    args = ap.parse_args(argv)
    n_moves = 3 if args.quick else 8
    rng = random.Random(1)
    errs: dict[str, list[tuple[float, float]]] = {"100 us": [], "default": []}
    for _ in range(n_moves):
        duty = (rng.randint(-60, 100), rng.randint(-60, 100))
        ms, seed = rng.randint(200, 1500), rng.randint(0, 1000)
        ref = open_floor(seed, duty, ms, {"substep_ns": 10_000, **FINE}).drive_pose()
        for name, cfg in (("100 us", FINE), ("default", DEFAULT)):
            p = open_floor(seed, duty, ms, cfg).drive_pose()
            turn = (p.heading_deg - ref.heading_deg + 180) % 360 - 180
            errs[name].append((math.hypot(p.x_mm - ref.x_mm, p.y_mm - ref.y_mm), abs(turn)))
    print(f"open floor, {n_moves} randomized robots and duties, 0.2 to 1.5 s, against 10 us:")
    for name, e in errs.items():
        d, h = zip(*e, strict=True)
        print(f"  {name:8s} {min(d):.3f} to {max(d):.3f} mm, {min(h):.3f} to {max(h):.3f} degree")
    print("oblique shock (disc 120 mm off the path, 1 m/s), time to rest after the contact:")
    subs = (10_000, 50_000, 100_000) if args.quick else (10_000, 20_000, 50_000, 100_000, 200_000)
    for sub in subs:
        rest = oblique_rest_ms({"substep_ns": sub, **FINE})
        print(f"  {sub // 1000:3d} us everywhere: {rest} ms")
    print(f"  default ({COARSE_SUBSTEP_NS // 1000} us away from contacts and grip):", end="")
    print(f" {oblique_rest_ms(DEFAULT)} ms")
    shifts = (0.0, 0.03, 0.1) if args.quick else (0.0, 0.01, 0.02, 0.03, 0.05, 0.1, 0.2, 0.3)
    print("return towards the disc after the stop at 1 m/s, start moved by dx mm:")
    for name, cfg in (("100 us", FINE), ("default", DEFAULT)):
        backs = ", ".join(f"{dx:g}: {return_mm(cfg, dx):.3f}" for dx in shifts)
        print(f"  {name:8s} {backs}")
    goals = Goals("bench/substeps.py")
    print(goals.summary())
    return goals.exit_code(args.strict)


if __name__ == "__main__":
    sys.exit(main())
