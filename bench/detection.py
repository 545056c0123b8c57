"""How fast the board detects each hardware fault of docs/failure-model.md, section 2, on the
simulated reference robot: the time from the instant the fault appears to the control tick whose
status reports it, in simulated ticks of 1 ms, at several speed limits.

    python bench/detection.py [--strict]

The robot drives along a clear lane, y = -300 mm from x = -1200 towards x = 1200, at 1 m/s^2;
a fault is injected 0.1 s after the set point reaches the speed limit (a battery sag at 0.3 s,
while it accelerates), a wall stands across the lane at x = 500 mm. Each line is one row of the
table of docs/failure-model.md (the tests compare them). The goals are the bounds that
python/tests/test_faults_sim.py asserts on its own cases, here at the speeds measured; marked met
or MISSED, with a summary line; --strict exits 1 on a miss.
"""

from __future__ import annotations

import argparse
import dataclasses
import sys
from collections.abc import Callable, Sequence

import numpy as np

from asserv import Status, field
from asserv.driver import Board
from asserv.goals import Goals, add_strict_flag
from asserv.sim import Simulator

START = (-1200.0, -300.0, 0.0)
TARGET = (1200, -300)
ACCEL_CM_S2 = 100
WALL_X_MM = 500.0
MOTOR_BITS = int(Status.PB_MOTEUR | Status.PB_GRAVE)
CAUSES = ("none", "following", "overcurrent", "slip", "encoder lost", "repeated")

Fault = Callable[[Simulator], None]


def stuck(*wheels: int) -> Fault:
    def lock(sim: Simulator) -> None:
        for w in wheels:
            sim.set_motor_stuck(w, True)

    return lock


def cut(wheel: int) -> Fault:
    return lambda sim: sim.set_encoder_cut(wheel, True)


def cut_motor(wheel: int) -> Fault:
    return lambda sim: sim.set_motor_encoder_cut(wheel, True)


def sag(volts: float) -> Fault:
    return lambda sim: sim.set_battery_volts(volts)


@dataclasses.dataclass(frozen=True)
class Detection:
    """One fault's report: ms from the fault (None: never reported), the status, the check."""

    ms: int | None
    status: int
    cause: str


def _report(sim: Simulator, t0_s: float, mask: int) -> Detection:
    tr = sim.trace
    hit = np.nonzero(((tr["status"].astype(int) & mask) != 0) & (tr["t_s"] >= t0_s))[0]
    cause = CAUSES[sim._h.board.planner.faults.cause]
    if not len(hit):
        return Detection(None, int(tr["status"][-1]), cause)
    return Detection(
        round(float(tr["t_s"][hit[0]] - t0_s) * 1000), int(tr["status"][hit[0]]), cause
    )


def _drive(sim: Simulator, speed_cm_s: int) -> Board:
    board = Board(sim.bus)
    board.set_vitesse_traj(speed_cm_s, ACCEL_CM_S2)
    board.goto(*TARGET)
    return board


def _wait(sim: Simulator, board: Board) -> None:
    board.wait_idle(6.0)  # the whole lane at the lowest speed measured, and its settling


def injected(fault: Fault, speed_cm_s: int, at_s: float | None = None) -> Detection:
    """The fault injected at at_s (default: 0.1 s after the set point reaches the limit)."""
    sim = Simulator({"start": START})
    board = _drive(sim, speed_cm_s)
    t_s = speed_cm_s / ACCEL_CM_S2 + 0.1 if at_s is None else at_s
    sim.advance(t_s - sim.time_s)
    assert board.check_busy() & Status.BUSY_TRAJET, "the fault must hit a motion"
    t0 = sim.time_s
    fault(sim)
    _wait(sim, board)
    return _report(sim, t0, MOTOR_BITS)


def wall(speed_cm_s: int) -> Detection:
    """A wall across the lane and no shock sensor: from the first contact."""
    base = field.load(field.DEFAULT)
    box = field.Obstacle("box", WALL_X_MM, -300, half_x_mm=20, half_y_mm=100)
    sim = Simulator(
        {"start": START, "shock_count": 0}, field=dataclasses.replace(base, obstacles=(box,))
    )
    board = _drive(sim, speed_cm_s)
    _wait(sim, board)
    tr = sim.trace
    touched = float(tr["t_s"][np.nonzero(tr["contact_force_N"] > 0)[0][0]])
    return _report(sim, touched, MOTOR_BITS)


def shock(speed_cm_s: int) -> Detection:
    """The same wall seen by the shock sensors: from the tick the switch closes."""
    base = field.load(field.DEFAULT)
    box = field.Obstacle("box", WALL_X_MM, -300, half_x_mm=20, half_y_mm=100)
    sim = Simulator({"start": START}, field=dataclasses.replace(base, obstacles=(box,)))
    board = _drive(sim, speed_cm_s)
    _wait(sim, board)
    tr = sim.trace
    closed = float(tr["t_s"][np.nonzero(tr["shocks"])[0][0]])
    return _report(sim, closed, int(Status.CHOC_BORD))


def cut_then_order(wheel: int, speed_cm_s: int, at_s: float) -> tuple[Detection, Detection]:
    """A free wheel's wire cut at at_s: the suspicion (PB_MOTEUR), then 0.5 s later an order
    500 mm ahead: from its write to PB_GRAVE."""
    sim = Simulator({"start": START})
    board = _drive(sim, speed_cm_s)
    sim.advance(at_s - sim.time_s)
    assert board.check_busy() & Status.BUSY_TRAJET, "the cut must hit a motion"
    t0 = sim.time_s
    cut(wheel)(sim)
    _wait(sim, board)
    first = _report(sim, t0, MOTOR_BITS)
    sim.advance(0.5)
    x, y, _ = sim.true_pose()
    t1 = sim.time_s
    board.goto(round(x) + 500, round(y))
    _wait(sim, board)
    return first, _report(sim, t1, int(Status.PB_GRAVE))


def _speed(cm_s: int) -> str:
    return f"{cm_s / 100:g} m/s"


def _ms(d: Detection) -> str:
    return "none" if d.ms is None else f"{d.ms} ms"


def _row(goals: Goals, key: str, cells: str, bound: tuple[str, float, float] | None) -> None:
    """Print one row; bound: (what, the largest figure it applies to, the bound in ms)."""
    mark = ""
    if bound is not None:
        what, value, limit = bound
        goal = goals.check(f"{key}: {what} [ms]", value, "<=", limit)
        mark = f"   (goal: {what} <= {limit:g} ms: {goal.mark})"
    print(f"{key}: {cells}{mark}")


def _worst(ds: Sequence[Detection], status: int) -> float:
    """The longest detection, NaN (a miss) if any went unreported or reported another status."""
    if any(d.ms is None or not d.status & status for d in ds):
        return float("nan")
    return float(max(d.ms for d in ds if d.ms is not None))


SPEEDS = (30, 60, 100)
WALL_SPEEDS = (30, 60, 100, 150)
# The cuts' moments [s]: accelerating at every speed at first, cruising at 0.3 m/s from 0.3 s.
CUT_AT_S = (0.05, 0.1, 0.2, 0.35, 0.5, 0.7, 0.9, 1.2)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    add_strict_flag(ap)
    args = ap.parse_args(argv)
    goals = Goals("bench/detection.py")
    moteur = int(Status.PB_MOTEUR)
    print("fault: detected within, at each speed limit (the check that fired)")

    d = [shock(v) for v in SPEEDS]
    _row(
        goals,
        "shock sensor",
        ", ".join(f"{_ms(x)} at {_speed(v)}" for x, v in zip(d, SPEEDS, strict=True)),
        ("the same tick", _worst(d, int(Status.CHOC_BORD)), 0),
    )

    d = [wall(v) for v in WALL_SPEEDS]
    _row(
        goals,
        "wall, no shock sensor",
        ", ".join(f"{_ms(x)} at {_speed(v)}" for x, v in zip(d, WALL_SPEEDS, strict=True))
        + f" (from the first contact; {d[0].cause})",
        ("at 1 m/s", _worst(d[2:3], moteur), 15),
    )

    motor_faults: list[tuple[str, Fault, float | None, str | None]] = [
        ("stalled motor", stuck(0), 35, "at 1 m/s"),
        ("both drive wheels jammed", stuck(0, 1), 90, "at 0.3 m/s"),
        ("motor-encoder wire cut", cut_motor(0), 32, "at 1 m/s"),
    ]
    for key, fault, limit, where in motor_faults:
        d = [injected(fault, v) for v in SPEEDS]
        cells = ", ".join(
            f"{_ms(x)} at {_speed(v)} ({x.cause})" for x, v in zip(d, SPEEDS, strict=True)
        )
        at = {"at 1 m/s": d[2:3], "at 0.3 m/s": d[0:1]}[where or ""]
        _row(goals, key, cells, None if limit is None else (where or "", _worst(at, moteur), limit))

    d = [injected(cut(0), v) for v in SPEEDS]
    swept = [cut_then_order(w, v, at) for w in (0, 1) for v in SPEEDS for at in CUT_AT_S]
    first_ms = [f.ms for f, _ in swept if f.ms is not None]
    cells = ", ".join(f"{_ms(x)} at {_speed(v)}" for x, v in zip(d, SPEEDS, strict=True))
    _row(
        goals,
        "free-wheel encoder wire cut",
        f"{cells} ({d[2].cause}); {min(first_ms)} to {max(first_ms)} ms over {len(swept)} cuts, "
        "accelerating or cruising",
        ("at 1 m/s", _worst(d[2:3], moteur), 10),
    )
    graves = [g for _, g in swept]
    grave_ms = [g.ms for g in graves if g.ms is not None]
    _row(
        goals,
        "the next order after a free-wheel cut",
        f"PB_GRAVE {min(grave_ms)} to {max(grave_ms)} ms after the order ({len(graves)} orders)",
        ("after the order", _worst(graves, int(Status.PB_GRAVE)), 120),
    )

    sags = [(8.0, 100), (12.0, 100), (18.0, 100), (18.0, 150)]
    d = [injected(sag(volts), v, at_s=0.3) for volts, v in sags]
    cells = "; ".join(
        f"at {volts:g} V, {_ms(x)} at {_speed(v)}" for (volts, v), x in zip(sags, d, strict=True)
    )
    _row(
        goals,
        "battery sag",
        f"{cells} ({d[0].cause})",
        ("at 8 V", _worst(d[0:1], moteur), 500),
    )
    print(goals.summary())
    return goals.exit_code(args.strict)


if __name__ == "__main__":
    sys.exit(main())
