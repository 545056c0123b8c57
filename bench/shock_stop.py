"""The stop after a shock (docs/failure-model.md "A stop that stops", issue 18), and the measure
python/tests/test_endings_sim.py asserts its promises on (`hit()`, `stop_of()`).

First the robot drives at each speed limit into a 150 mm disc at (0, 0) on the default field,
from x = -900 mm (-400 mm below 0.2 m/s) along y = 0 at 1.5 m/s^2, and at 1 m/s on the randomized
seed-7 robot, at 1 kHz and at the AVR's rates. Each line gives, from the first contact or switch,
the speed then, the braking time the grip allows for the speed and the spin of the first 30 ms
(SPIN_MS), the time to rest (the last tick either wheel is faster than 10 mm/s), the most it came
back towards the disc once it had first stopped, and the largest contact force from 300 ms on,
in simulated ticks.

Then, with --random N, N random hits at each rate (a wall or a disc within a switch's reach, any
start within 5 mm, speed and acceleration, nominal and randomized robots), and the worst of each
promise's measure over them.

    python bench/shock_stop.py [--random N] [--strict]

The promises' bounds (docs/failure-model.md) are its goals: at rest within 1.1 times the braking
time or SLOW_REST_MS (the AVR's rates: 1.1 times plus AVR_EXTRA_MS), never more than BACK_MM
back towards the obstacle, under FORCE_N from 300 ms on. Each line is marked met or MISSED, and
the last line sums them up; --strict exits 1 on a miss.
"""

from __future__ import annotations

import argparse
import dataclasses
import math
import random
import sys

import numpy as np

from asserv import field
from asserv.driver import Board
from asserv.goals import MET, MISSED, Goals, add_strict_flag
from asserv.sim import AVR_RATES, Simulator

#: The contact may turn the robot: the braking the grip allows is counted from the speed and
#: the spin of each of the first SPIN_MS after it.
SPIN_MS = 30
#: At rest: both wheels slower than this (a hard brake leaves the tyres relaxing at ~7 mm/s).
REST_MM_S = 10.0


#: The promise's floor (docs/failure-model.md, python/tests/test_endings_sim.py): below 0.2 m/s
#: a hard obstacle throws the robot back before it has braked, and that rebound is braked too:
#: at rest within this, whatever the braking time.
SLOW_REST_MS = 40
#: The AVR's rates: the switch seen up to 11 ms later and the set points a period at a time; the
#: rest is bounded by 1.1 times the braking time plus this.
AVR_EXTRA_MS = 120
BACK_MM = 0.2  # the most it may come back towards the obstacle once it first stopped
FORCE_N = 10.0  # the largest contact force from 300 ms after the contact on


def rest_bound_ms(braking_ms: float, rates: bool) -> float:
    """The promise's bound on the time to rest, at 1 kHz or at the AVR's rates."""
    if rates:
        return 1.1 * braking_ms + AVR_EXTRA_MS
    return max(1.1 * braking_ms, SLOW_REST_MS)


def check(goals: Goals, label: str, s: Stop, rates: bool) -> str:
    """The three promises of one stop as goals; the line's mark (met, or MISSED: which)."""
    marks = {
        "rest": goals.check(
            f"{label}: rest [ms]", s.rest_ms, "<=", rest_bound_ms(s.braking_ms, rates)
        ),
        "back": goals.check(f"{label}: back [mm]", s.back_mm, "<=", BACK_MM),
        "force": goals.check(
            f"{label}: force from 300 ms [N]", s.force_after_300_ms, "<=", FORCE_N
        ),
    }
    missed = [k for k, g in marks.items() if not g.met]
    return MET if not missed else f"{MISSED}: {', '.join(missed)}"


@dataclasses.dataclass
class Stop:
    """The motion after the first shock, along the heading at the contact, signed towards the
    obstacle."""

    v0_mm_s: float  # the speed when the switch closed (first: at row start)
    braking_ms: float  # what the grip allows from the speed and spin after it (SPIN_MS)
    rest_ms: int  # from the contact to the last tick faster than REST_MM_S
    back_mm: float  # the most it came back towards the obstacle once it first stopped going there
    force_after_300_ms: float  # the largest contact force from 300 ms after the contact on
    force_last_s: float  # the largest in the last second of the trace


def stop_of(
    sim: Simulator, start: int, disc: tuple[float, float] | None = None, first: bool = False
) -> Stop:
    """The stop after the first shock from trace row start on (from row start itself if
    first); towards the obstacle is along the heading at the contact (a wall across the path),
    or towards the centre of disc."""
    tr = sim.trace[start:]
    shocked = np.nonzero(tr["shocks"])[0]
    assert len(shocked), "no shock switch closed"
    c = 0 if first else int(shocked[0])
    v = tr["v_mm_s"][c:]
    if disc is None:
        h = math.radians(float(tr["heading_deg"][c]))
        along = tr["x_mm"][c:] * math.cos(h) + tr["y_mm"][c:] * math.sin(h)
    else:  # minus the distance to the disc's centre
        along = -np.hypot(tr["x_mm"][c:] - disc[0], tr["y_mm"][c:] - disc[1])
    oc = sim.board_config.orders
    grip_mm_s2 = oc.grip_um_s2 / 1000
    # The wheels' speed of the spin (the drive track's half times the turn rate)
    spin = np.abs(np.radians(tr["omega_deg_s"][c:])) * oc.drive_track_um / 2000
    # What the grip allows to brake a speed and a spin together: a + k a' <= grip (orders.h),
    # from each of the contact's first SPIN_MS (it may turn the robot), counted from the contact.
    k = oc.rot_grip_q8 / 256
    need_ms = (np.abs(v[:SPIN_MS]) + k * spin[:SPIN_MS]) / grip_mm_s2 * 1000
    moving = np.nonzero(np.abs(v) + spin >= REST_MM_S)[0]
    stopped = int(np.nonzero(v <= 0)[0][0])
    after = along[stopped:]
    return Stop(
        v0_mm_s=float(v[0]),
        braking_ms=float((need_ms + np.arange(len(need_ms))).max()),
        rest_ms=int(moving[-1]) + 1 if len(moving) else 0,
        back_mm=float((after - np.minimum.accumulate(after)).max()),
        force_after_300_ms=float(tr["contact_force_N"][c + 300 :].max()),
        force_last_s=float(tr["contact_force_N"][-1000:].max()),
    )


def disc_field(x_mm: float = 0, y_mm: float = 0) -> field.Field:
    base = field.load(field.DEFAULT)
    disc = field.Obstacle("circle", x_mm, y_mm, radius_mm=150)
    return dataclasses.replace(base, obstacles=(*base.obstacles, disc))


def hit(
    kind: str,
    speed: int,
    accel: int,
    dx: float,
    lateral: float,
    seed: int,
    randomize: bool,
    board_config: dict[str, int] | None = None,
) -> tuple[int, Stop]:
    """A robot from x = -900 mm (-400 below 0.2 m/s) plus dx, along y = 0 at speed and accel,
    into a wall across its path (its face at x = 0) or a 150 mm disc at (0, lateral); the
    status it ended with and its stop, measured from the first contact or switch, whichever
    came first (a switch at the board's slow ticks may be seen after the contact)."""
    x0 = (-400 if speed < 20 else -900) + dx
    disc: tuple[float, float] | None = None
    if kind == "disc":
        f, disc = disc_field(0, lateral), (0, lateral)
    else:
        box = field.Obstacle("box", 20, 0, half_x_mm=20, half_y_mm=200)
        f = dataclasses.replace(field.load(field.DEFAULT), obstacles=(box,))
    sim = Simulator(
        {"start": (x0, 0, 0.0)}, seed=seed, randomize=randomize, field=f, board_config=board_config
    )
    board = Board(sim.bus)
    board.set_vitesse_traj(speed, accel)
    board.goto(600, 0)
    status = board.wait_idle(60)
    sim.advance(1.5)
    tr = sim.trace
    c = int(np.nonzero((tr["shocks"] != 0) | (tr["contact_force_N"] > 0))[0][0])
    assert tr["shocks"][c:].any(), "no switch closed"
    return int(status), stop_of(sim, c, disc, first=True)


def run(
    speed_cm_s: int,
    seed: int = 0,
    randomize: bool = False,
    rates: bool = False,
    goals: Goals | None = None,
) -> str:
    cfg = dict(AVR_RATES) if rates else None
    status, s = hit("disc", speed_cm_s, 150, 0, 0, seed, randomize, cfg)
    label = f"disc {speed_cm_s} cm/s{' seed ' + str(seed) if randomize else ''}"
    mark = check(goals, f"{'AVR ' if rates else ''}{label}", s, rates) if goals else ""
    return (
        f"{s.v0_mm_s:7.0f} mm/s  braking {s.braking_ms:5.0f} ms  rest {s.rest_ms:4d} ms "
        f"({s.rest_ms / s.braking_ms:4.2f}x)  back {s.back_mm:5.2f} mm  "
        f"{s.force_after_300_ms:5.1f} N  status 0x{status:02x}  {mark}"
    ).rstrip()


def random_hits(
    n: int, rates: dict[str, int] | None, min_speed: int, goals: Goals | None = None
) -> str:
    rng = random.Random(1)
    worst_ratio = worst_back = worst_force = worst_extra = 0.0
    over_bound = -math.inf  # the most a hit's rest went past its bound [ms]
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
        over_bound = max(over_bound, s.rest_ms - rest_bound_ms(s.braking_ms, rates is not None))
    mark = ""
    if goals is not None:
        label = f"{n} random hits{' (AVR)' if rates else ''}"
        got = [
            goals.check(f"{label}: rest past its bound, worst [ms]", over_bound, "<=", 0),
            goals.check(f"{label}: back, worst [mm]", worst_back, "<=", BACK_MM),
            goals.check(f"{label}: force from 300 ms, worst [N]", worst_force, "<=", FORCE_N),
        ]
        mark = f"; {MET if all(g.met for g in got) else MISSED}"
    return (
        f"{n} hits: rest up to {worst_ratio:.2f}x the braking time (where 1.1x is over "
        f"{SLOW_REST_MS} ms), {slow_rest} ms below; at most {worst_extra:.0f} ms beyond 1.1x; "
        f"back {worst_back:.3f} mm at most ({back_case}); {worst_force:.1f} N at most from 300 "
        f"ms on{mark}"
    )


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--random", type=int, default=0, metavar="N", help="N random hits a rate")
    add_strict_flag(ap)
    args = ap.parse_args(argv)
    if args.random < 0:
        ap.error("--random: N must be 0 or more")
    goals = Goals("bench/shock_stop.py")
    for speed in (5, 10, 20, 30, 60, 100, 150):
        print(f"limit {speed:3d} cm/s: {run(speed, goals=goals)}")
    print(f"seed 7, randomized, 100 cm/s: {run(100, seed=7, randomize=True, goals=goals)}")
    print("the AVR board's rates (AVR_RATES: the planner every 8th tick, its results 3 ticks on):")
    for speed in (10, 30, 60, 100, 150):
        print(f"limit {speed:3d} cm/s: {run(speed, rates=True, goals=goals)}")
    if args.random:
        print(f"random, 1 kHz, 20-150 cm/s: {random_hits(args.random, None, 20, goals)}")
        avr = random_hits(args.random, dict(AVR_RATES), 10, goals)
        print(f"random, AVR_RATES, 10-150 cm/s: {avr}")
    print(goals.summary())
    return goals.exit_code(args.strict)


if __name__ == "__main__":
    sys.exit(main())
