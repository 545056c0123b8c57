"""The stop after a shock (docs/failure-model.md "A stop that stops", issue 18): the robot drives
at a speed limit into a 150 mm disc at (0, 0) on the default field, from x = -900 mm (-400 mm
below 0.2 m/s) along y = 0 at 1.5 m/s^2, and 1 m/s on the randomized seed-7 robot; prints, from
the tick the shock switch closed, the speed then, the braking time the grip allows from it, the
time to rest (the last tick faster than 10 mm/s), the most it came back towards the disc once it
had first stopped, and the largest contact force from 300 ms on, in simulated ticks.

Then, with --random N, N random hits at each rate (test_endings_sim.py's `hit()`: a wall or a
disc within a switch's reach, any start within 5 mm, speed and acceleration, nominal and
randomized robots), and the worst of each promise's measure over them.

    python bench/shock_stop.py [--random N]
"""

from __future__ import annotations

import argparse
import dataclasses
import random
import sys
from pathlib import Path

import numpy as np

from asserv import field
from asserv.driver import Board
from asserv.sim import AVR_RATES, Simulator

REST_MM_S = 10.0


def run(speed_cm_s: int, seed: int = 0, randomize: bool = False, slow_shift: int = 0) -> str:
    base = field.load(field.DEFAULT)
    disc = field.Obstacle("circle", 0, 0, radius_mm=150)
    f = dataclasses.replace(base, obstacles=(*base.obstacles, disc))
    x0 = -400 if speed_cm_s < 20 else -900
    sim = Simulator(
        {"start": (x0, 0, 0.0)},
        seed=seed,
        randomize=randomize,
        field=f,
        board_config=AVR_RATES
        if slow_shift == AVR_RATES["slow_shift"]
        else {"slow_shift": slow_shift},
    )
    board = Board(sim.bus)
    board.set_vitesse_traj(speed_cm_s, 150)
    board.goto(600, 0)
    status = board.wait_idle(60)
    sim.advance(1.5)
    tr = sim.trace
    # the switch closing (the trace's switches are the board's, seen at its slow ticks) or the
    # contact, whichever came first
    c = int(np.nonzero((tr["shocks"] != 0) | (tr["contact_force_N"] > 0))[0][0])
    v = tr["v_mm_s"][c:]
    along = -np.hypot(tr["x_mm"][c:], tr["y_mm"][c:])  # towards the disc's centre
    braking_ms = float(v[0]) / (sim.board_config.orders.grip_um_s2 / 1000) * 1000
    moving = np.nonzero(np.abs(v) >= REST_MM_S)[0]
    rest_ms = int(moving[-1]) + 1 if len(moving) else 0
    after = along[int(np.nonzero(v <= 0)[0][0]) :]
    back_mm = float((after - np.minimum.accumulate(after)).max())
    force = float(tr["contact_force_N"][c + 300 :].max())
    return (
        f"{v[0]:7.0f} mm/s  braking {braking_ms:5.0f} ms  rest {rest_ms:4d} ms "
        f"({rest_ms / braking_ms:4.2f}x)  back {back_mm:5.2f} mm  {force:5.1f} N  "
        f"status 0x{int(status):02x}"
    )


def random_hits(n: int, rates: dict[str, int] | None, min_speed: int) -> str:
    sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "python" / "tests"))
    from test_endings_sim import SLOW_REST_MS, hit

    rng = random.Random(1)
    worst_ratio = worst_back = worst_force = worst_extra = 0.0
    slow_rest = 0
    back_case = ""
    for _ in range(n):
        kind = rng.choice(["wall", "disc"])
        speed, accel = rng.randint(min_speed, 150), rng.randint(30, 255)
        dx, lateral = rng.uniform(-5, 5), rng.uniform(-15, 15)
        seed, randomize = rng.randint(0, 2**16), rng.random() < 0.5
        _, s = hit(kind, speed, accel, dx, lateral, seed, randomize, rates)
        if s.braking_ms * 1.1 >= SLOW_REST_MS:
            worst_ratio = max(worst_ratio, s.rest_ms / s.braking_ms)
        else:
            slow_rest = max(slow_rest, s.rest_ms)
        worst_extra = max(worst_extra, s.rest_ms - 1.1 * s.braking_ms)
        if s.back_mm > worst_back:
            worst_back = s.back_mm
            back_case = f"{kind} {speed} cm/s {accel} cm/s^2 dx {dx:.2f} lateral {lateral:.1f}"
        worst_force = max(worst_force, s.force_after_300_ms)
    return (
        f"{n} hits: rest up to {worst_ratio:.2f}x the braking time (where 1.1x is over "
        f"{SLOW_REST_MS} ms), {slow_rest} ms below; at most {worst_extra:.0f} ms beyond 1.1x; "
        f"back {worst_back:.3f} mm at most ({back_case}); {worst_force:.1f} N at most from 300 "
        "ms on"
    )


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--random", type=int, default=0, metavar="N", help="N random hits a rate")
    args = ap.parse_args()
    if args.random < 0:
        ap.error("--random: N must be 0 or more")
    for speed in (5, 10, 20, 30, 60, 100, 150):
        print(f"limit {speed:3d} cm/s: {run(speed)}")
    print(f"seed 7, randomized, 100 cm/s: {run(100, seed=7, randomize=True)}")
    print("the AVR board's rates (AVR_RATES: the planner every 8th tick, its results 3 ticks on):")
    for speed in (10, 30, 60, 100, 150):
        print(f"limit {speed:3d} cm/s: {run(speed, slow_shift=3)}")
    if args.random:
        print(f"random, 1 kHz, 20-150 cm/s: {random_hits(args.random, None, 20)}")
        print(f"random, AVR_RATES, 10-150 cm/s: {random_hits(args.random, dict(AVR_RATES), 10)}")


if __name__ == "__main__":
    main()
