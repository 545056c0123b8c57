"""The slip detection's latency curve (docs/failure-model.md, issue 18): the left or right drive
wheel's grip drops to a fraction of normal while the robot accelerates to 1 m/s at 1 m/s^2, and
the board reports PB_MOTEUR; prints the time from the drop to the report, in simulated ticks.

    python bench/slip_latency.py
"""

from __future__ import annotations

import numpy as np

from asserv import Status
from asserv.driver import Board
from asserv.sim import Simulator

START = (-1000.0, -300.0, 0.0)
SCALES = (0.0, 0.05, 0.10, 0.15, 0.20, 0.30)


def latency_ms(scale: float, wheel: int, at_s: float, seed: int = 0) -> int | None:
    """Milliseconds from the grip drop at at_s to PB_MOTEUR (None: the robot got through)."""
    sim = Simulator({"start": START}, seed=seed)
    board = Board(sim.bus)
    board.set_vitesse_traj(100, 100)
    board.goto(1000, -300)
    sim.advance(at_s - sim.time_s)
    t0 = sim.time_s
    sim.set_friction_scale(wheel, scale)
    while board.check_busy() & Status.BUSY_TRAJET and sim.time_s < t0 + 3:
        sim.advance(0.001)
    tr = sim.trace
    mask = int(Status.PB_MOTEUR | Status.PB_GRAVE)
    hit = np.nonzero(((tr["status"].astype(int) & mask) != 0) & (tr["t_s"] >= t0))[0]
    return round(float(tr["t_s"][hit[0]] - t0) * 1000) if len(hit) else None


def main() -> None:
    print("grip  latency [ms] (left, right wheel; drop at 0.2 s and 0.5 s, accelerating)")
    for scale in SCALES:
        cells = [latency_ms(scale, w, at) for w in (0, 1) for at in (0.2, 0.5)]
        text = ", ".join("through" if c is None else str(c) for c in cells)
        print(f"{scale * 100:4.0f} %  {text}")


if __name__ == "__main__":
    main()
