"""The stop after a shock (docs/failure-model.md "A stop that stops", issue 18): the robot drives
at a speed limit into a 150 mm disc at (0, 0) on the default field, from x = -900 mm (-400 mm
below 0.2 m/s) along y = 0 at 1.5 m/s^2, and 1 m/s on the randomized seed-7 robot; prints, from
the tick the shock switch closed, the speed then, the braking time the grip allows from it, the
time to rest (the last tick faster than 10 mm/s), the most it came back towards the disc once it
had first stopped, and the largest contact force from 300 ms on, in simulated ticks.

    python bench/shock_stop.py
"""

from __future__ import annotations

import dataclasses

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


def main() -> None:
    for speed in (5, 10, 20, 30, 60, 100, 150):
        print(f"limit {speed:3d} cm/s: {run(speed)}")
    print(f"seed 7, randomized, 100 cm/s: {run(100, seed=7, randomize=True)}")
    print("the AVR board's rates (AVR_RATES: the planner every 8th tick, its results 3 ticks on):")
    for speed in (10, 30, 60, 100, 150):
        print(f"limit {speed:3d} cm/s: {run(speed, slow_shift=3)}")


if __name__ == "__main__":
    main()
