"""A 10-point tour, stop-and-go against pass-through corners (issue 31, item 5; docs/control.md,
"Corners").

On each of N randomized robots (50), at random accepted limits, at 1 kHz on an empty table, the
same 10 random points are driven twice: stop-and-go (GOTO, wait for the end, the next GOTO), and
queued at once with APPEND | PASS_THROUGH at the default corner tolerance (SET_CORNER, 30 mm).
It prints:

- the time ratio pass-through / stop-and-go, worst and mean (goal: 0.75 or less);
- at each corner point, the larger of how close the path passed the point and how far it
  strayed from the polyline of the points around it, worst first (goal: within the
  tolerance), in the board's estimate: the estimate's own error is the error radius's,
  checked below;
- that every robot ended without PB_MOTEUR, without a contact, DONE, and with the truth within
  the error radius of the estimate;
- a bound on the ratio from the limits alone (``bound_s()``), for information: what a planner
  within the master's limits but the rotation acceleration could reach on the same tour. Its
  curves are arcs passing the whole tolerance from each point, at the whole grip (the board
  keeps a third of it across, docs/control.md "Corners") and the heading's wheel speed within
  SET_VITESSE_ROT; its lines at SET_VITESSE_TRAJ's speed and acceleration, with no clothoids
  and no settling; a corner may also stop at its point, its turn taking no time of its own (as
  a pivot's overlaps the lines' ramps), and must where no arc of 50 mm/s fits; the fastest of
  these choices. Its arcs step the heading's rate, beyond any rotation acceleration;
- the turns alone over the stop-and-go time (``turns_s()``), for information: each corner's
  heading change from rest to rest at SET_VITESSE_ROT, which a curve takes too.

``--max-turn DEG`` (60 to 180) draws tours whose corners turn by DEG at most (as a team chains
its points with PASS_THROUGH, stopping for the sharper ones), instead of any turn.

    python bench/course.py [--robots N] [--first-seed K] [--tolerance MM] [--max-turn DEG]
                           [--strict]
"""

from __future__ import annotations

import argparse
import itertools
import math
import random
import sys
from dataclasses import dataclass

import numpy as np

from asserv import codec, field, robot
from asserv._protocol import EndReason, Reject, Status
from asserv.driver import Board, OrderRejected
from asserv.goals import Goals, add_strict_flag
from asserv.sim import Simulator

APPEND, THROUGH = 0x04, 0x08
GOAL_RATIO = 0.75
_ROBOT = robot.load().values
#: The board's grip (board_config.c: mu x the drive wheels' share of the weight x g) [m/s^2], and
#: half its drive track [m]: what the board plans with, whatever the randomized robot.
GRIP_M_S2 = _ROBOT["friction_coeff"] * _ROBOT["drive_weight_share"] * 9.81
HALF_TRACK_M = _ROBOT["drive_track_mm"] / 2000


@dataclass
class Tour:
    seconds: float
    near_mm: list[float]  # each corner point (all but the last): passed at, strayed around
    ok: bool  # no PB, no contact, DONE, the error within the radius
    why: str


def segment_mm(
    px: np.ndarray, py: np.ndarray, a: tuple[float, float], b: tuple[float, float]
) -> np.ndarray:
    """The distance of each (px, py) from the segment a-b."""
    dx, dy = b[0] - a[0], b[1] - a[1]
    t = np.clip(((px - a[0]) * dx + (py - a[1]) * dy) / max(dx * dx + dy * dy, 1e-9), 0, 1)
    return np.hypot(px - a[0] - t * dx, py - a[1] - t * dy)


def turn_deg(a: tuple[float, float], b: tuple[float, float], c: tuple[float, float]) -> float:
    """The turn at b of the path a-b-c [deg], 0..180."""
    t = math.atan2(c[1] - b[1], c[0] - b[0]) - math.atan2(b[1] - a[1], b[0] - a[0])
    return abs(math.degrees((t + math.pi) % (2 * math.pi) - math.pi))


def points(rng: random.Random, max_turn_deg: float | None = None) -> list[tuple[int, int]]:
    """10 points inside the table, each 300 mm or more from the last; with max_turn_deg, each
    corner (the turn at each point but the last) at most that. A tour that cannot go on within
    it (a point near a border, facing out) is drawn again."""
    out: list[tuple[int, int]] = []
    last = (0, -850)
    tries = 0
    while len(out) < 10:
        tries += 1
        if tries > 2000:
            out, last, tries = [], (0, -850), 0
        p = (rng.randint(-1100, 1100), rng.randint(-700, 700))
        if math.dist(p, last) < 300:
            continue
        if max_turn_deg is not None and out:
            before = out[-2] if len(out) > 1 else (0, -850)
            if turn_deg(before, last, p) > max_turn_deg:
                continue
        out.append(p)
        last = p
    return out


def corner_near_mm(
    px: np.ndarray, py: np.ndarray, start: tuple[float, float], pts: list[tuple[int, int]]
) -> list[float]:
    """At each corner point (all but the last) of a path (px, py) from start through pts: the
    larger of how close it passes the point and how far it strays from the polyline, over the
    ticks nearest to that point rather than to any other."""
    poly = [start, *pts]
    off = np.min([segment_mm(px, py, poly[i], poly[i + 1]) for i in range(len(pts))], axis=0)
    owner = np.argmin([np.hypot(px - x, py - y) for x, y in pts], axis=0)
    return [
        max(float(off[owner == i].max(initial=0.0)), float(np.hypot(px - x, py - y).min()))
        for i, (x, y) in enumerate(pts[:-1])
    ]


def _line_s(length: float, v0: float, v1: float, v_max: float, a: float) -> float:
    """The shortest time over a line from v0 to v1, within v_max and a [m, m/s, m/s^2]."""
    peak = math.sqrt(max(0.0, a * length + (v0 * v0 + v1 * v1) / 2))
    if peak <= v_max:
        return (2 * peak - v0 - v1) / a
    ramps = (2 * v_max * v_max - v0 * v0 - v1 * v1) / (2 * a)
    return (2 * v_max - v0 - v1) / a + (length - ramps) / v_max


def bound_s(limits: tuple[int, int, int, int], pts: list[tuple[int, int]], tolerance: int) -> float:
    """A lower bound of the pass-through tour's time from the start (0, -850) [s] (the module's
    docstring says of what): the initial turn in place, the corners, the lines between them;
    each corner an arc or a stop whose turn takes no time of its own, whichever of all these
    choices gives the shortest tour."""
    v_max, a, w_max = limits[0] / 100, limits[1] / 100, limits[2] / 100
    p = [(x / 1000, y / 1000) for x, y in [(0, -850), *pts]]
    n, tol = len(p), tolerance / 1000
    bearing = [math.atan2(p[i + 1][1] - p[i][1], p[i + 1][0] - p[i][0]) for i in range(n - 1)]
    arcs: dict[int, tuple[float, float, float]] = {}  # each arc's speed, cut and time
    for i in range(1, n - 1):
        turn = abs((bearing[i] - bearing[i - 1] + math.pi) % (2 * math.pi) - math.pi)
        c = math.cos(turn / 2)
        r = tol * c / (1 - c) if c < 1 else 1e9
        half = min(math.dist(p[i], p[i - 1]), math.dist(p[i], p[i + 1])) / 2
        cut = min(r * math.tan(turn / 2), half)
        r = cut / max(math.tan(turn / 2), 1e-9)
        v = min(v_max, math.sqrt(GRIP_M_S2 * r), w_max * r / HALF_TRACK_M)
        if v >= 0.05:
            arcs[i] = (v, cut, r * turn / v)
    first = abs((bearing[0] + math.pi) % (2 * math.pi) - math.pi)  # the start faces +x
    best = math.inf
    for picked in itertools.product((False, True), repeat=len(arcs)):
        v, cut, corner_s = [0.0] * n, [0.0] * n, [0.0] * n
        for i, arc in zip(arcs, picked, strict=True):
            if arc:
                v[i], cut[i], corner_s[i] = arcs[i]
        line = [0.0] + [math.dist(p[i], p[i - 1]) - cut[i - 1] - cut[i] for i in range(1, n)]
        for i in range(n - 2, 0, -1):  # each corner reachable from the next, then from the last
            v[i] = min(v[i], math.sqrt(v[i + 1] ** 2 + 2 * a * line[i + 1]))
        for i in range(1, n - 1):
            v[i] = min(v[i], math.sqrt(v[i - 1] ** 2 + 2 * a * line[i]))
        lines_s = sum(_line_s(line[i], v[i - 1], v[i], v_max, a) for i in range(1, n))
        best = min(best, sum(corner_s) + lines_s)
    return first * HALF_TRACK_M / w_max + best


def turns_s(limits: tuple[int, int, int, int], pts: list[tuple[int, int]]) -> float:
    """The turns alone [s]: the start's and each corner's heading change, from rest to rest at
    SET_VITESSE_ROT's wheel speed and acceleration. A curve turns its heading from the line's
    rate of nought to nought again within that acceleration (docs/control.md "Corners"), as a
    turn in place does: whatever the line does meanwhile, each corner takes this long in either
    mode."""
    w_max, a_rot = limits[2] / 100, limits[3] / 100
    p = [(0, -850), *pts]
    turns = [abs(math.atan2(p[1][1] - p[0][1], p[1][0] - p[0][0]))]  # the start faces +x
    turns += [math.radians(turn_deg(*p[i - 1 : i + 2])) for i in range(1, len(p) - 1)]
    return sum(_line_s(t * HALF_TRACK_M, 0.0, 0.0, w_max, a_rot) for t in turns)


def robot(seed: int, limits: tuple[int, int, int, int], tolerance: int) -> tuple[Simulator, Board]:
    """Randomized robot ``seed`` on an empty table, at the limits (SET_VITESSE_TRAJ's speed and
    acceleration, SET_VITESSE_ROT's) and the corner tolerance (SET_CORNER) [mm]."""
    sim = Simulator(seed=seed, randomize=True, field=field.Field())
    board = Board(sim.bus)
    board.set_vitesse_traj(limits[0], limits[1])
    board.set_vitesse_rot(limits[2], limits[3])
    board._command("SET_CORNER", tolerance)
    return sim, board


def tour(
    seed: int,
    limits: tuple[int, int, int, int],
    pts: list[tuple[int, int]],
    through: bool,
    tolerance: int,
) -> Tour:
    sim, board = robot(seed, limits, tolerance)
    n, t0 = len(sim.trace), sim.time_s
    status = Status(0)
    if through:
        for x, y in pts:  # 1 runs and 8 wait: the tenth waits for room
            while True:
                try:
                    board._command("GOTO", x, y, APPEND | THROUGH)
                    break
                except OrderRejected as e:
                    if e.reason != Reject.MOTION_QUEUE_FULL:
                        raise
                    sim.advance(0.01)
        status = board.wait_idle(120)
    else:
        for x, y in pts:
            board.goto(x, y)
            status |= board.wait_idle(60)
    seconds = sim.time_s - t0
    tr = sim.trace[n:]
    # In the board's estimate: its own error is the error radius's, checked at the end.
    ex, ey = tr["est_x_mm"], tr["est_y_mm"]
    near = corner_near_mm(ex, ey, (float(ex[0]), float(ey[0])), pts)
    m = board._query("MOTION", codec.Motion)
    pos, truth = board.position(), sim.true_pose()
    err = math.hypot(pos.x_mm - truth.x_mm, pos.y_mm - truth.y_mm)
    contact = float(tr["contact_force_N"].max())
    bad = status & (Status.PB_MOTEUR | Status.PB_GRAVE) or np.any(
        tr["status"].astype(int) & int(Status.PB_MOTEUR | Status.PB_GRAVE)
    )
    ok = not bad and contact == 0 and m.last_end == EndReason.DONE and err <= pos.radius_mm + 1
    why = f"status {int(status)}, contact {contact:.0f} N, {m.last_end.name}, error {err:.1f} mm"
    return Tour(seconds, near, ok, why + f" / radius {pos.radius_mm} mm")


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--robots", type=int, default=50, help="randomized robots (50)")
    ap.add_argument("--first-seed", type=int, default=0, help="seed of the first robot (0)")
    ap.add_argument("--tolerance", type=int, default=30, help="SET_CORNER [mm] (30)")
    ap.add_argument(
        "--max-turn",
        type=float,
        default=None,
        metavar="DEG",
        help="corners of at most DEG degrees, 60..180 (any turn)",
    )
    add_strict_flag(ap)
    args = ap.parse_args(argv)
    if args.max_turn is not None and not 60 <= args.max_turn <= 180:
        ap.error(f"--max-turn: {args.max_turn:g} degrees: give 60 to 180")
    rng = random.Random(args.first_seed)
    ratios, nears, bad, bounds, turns = [], [], [], [], []
    for seed in range(args.first_seed, args.first_seed + args.robots):
        limits = (
            rng.randint(50, 150),
            rng.randint(50, 200),
            rng.randint(30, 100),
            rng.randint(50, 200),
        )
        pts = points(rng, args.max_turn)
        stop = tour(seed, limits, pts, False, args.tolerance)
        thru = tour(seed, limits, pts, True, args.tolerance)
        ratios.append((thru.seconds / stop.seconds, seed, stop.seconds, thru.seconds))
        bounds.append(bound_s(limits, pts, args.tolerance) / stop.seconds)
        turns.append(turns_s(limits, pts) / stop.seconds)
        nears += [(d, seed, i) for i, d in enumerate(thru.near_mm)]
        bad += [
            (seed, kind, t.why)
            for kind, t in (("stop-and-go", stop), ("through", thru))
            if not t.ok
        ]
    kind = "any corner" if args.max_turn is None else f"corners of {args.max_turn:g} deg at most"
    print(
        f"10-point tours ({kind}): {args.robots} randomized robots, 1 kHz,"
        f" corner tolerance {args.tolerance} mm"
    )
    print("time pass-through / stop-and-go, worst first (goal: 0.75 or less):")
    print("  seed  stop-and-go s  through s  ratio")
    for r, seed, a, b in sorted(ratios, reverse=True)[:8]:
        print(f"  {seed:4d}  {a:13.2f}  {b:9.2f}  {r:5.3f}")
    worst_ratio = max(r[0] for r in ratios)
    mean_ratio = sum(r[0] for r in ratios) / len(ratios)
    print(
        "each corner: the path's distance from the point, or from the polyline around it if"
        " larger, worst first (goal: the tolerance):"
    )
    for d, seed, i in sorted(nears, reverse=True)[:8]:
        print(f"  seed {seed:4d} corner {i + 1}: {d:.1f} mm")
    for seed, kind, why in bad:
        print(f"  seed {seed} {kind}: {why}")
    worst_near = max(d for d, _, _ in nears)
    print(
        "for information, a bound on the ratio from the limits alone (bound_s(): arcs at the"
        " whole tolerance and grip, the rotation limit, no clothoids, no settling, or stops whose"
        " turns take no time):"
        f" worst {max(bounds):.3f}, mean {sum(bounds) / len(bounds):.3f}"
    )
    print(
        "for information, the turns alone over the stop-and-go time (turns_s(): each corner's"
        " heading from rest to rest at SET_VITESSE_ROT, as a curve turns it too):"
        f" worst {max(turns):.3f}, mean {sum(turns) / len(turns):.3f}"
    )
    goals = Goals("bench/course.py")
    goals.check(f"time ratio, worst (mean {mean_ratio:.3f})", worst_ratio, "<=", GOAL_RATIO)
    goals.check(
        "corners: distance from the point or the polyline, worst [mm]",
        worst_near,
        "<=",
        args.tolerance,
    )
    goals.check(
        f"tours with a PB, a contact, no DONE or an error beyond the radius (of {2 * args.robots})",
        len(bad),
        "==",
        0,
    )
    print(f"goals over {args.robots} robots:")
    for line in goals.lines():
        print(line)
    print(goals.summary())
    return goals.exit_code(args.strict)


if __name__ == "__main__":
    sys.exit(main())
