"""``asserv bench accuracy``: the specification's "Performances" experiment on simulated robots.

The 2002 specification measured, on a 1.8 m straight, "+/-2 cm" of odometry error nearly
independent of the speed, and an arrival error of "+/-7 cm" at 1 m/s and 1 m/s^2 (none below
0.2 m/s). This bench drives the same straight at 0.2, 0.5 and 1 m/s with 1 m/s^2 on robots drawn
at random (wheel mismatch, track error, encoder noise, start pose error: ``sim_config_randomize``)
and, on the same robots in the same run:

- **legacy**: what the 2002 board is thought to have been (docs/physics-sources.md): a P-only
  position loop (Kp 15 /s), no feed-forward, the move declared finished when the set point
  ends. It is this board's code with that configuration (``LEGACY_CONFIG``, ``LEGACY_P``), so
  it has the same odometry, profiles and error radius;
- **asserv**: this board as it powers on, its odometry on the nominal wheel values;
- **asserv calibrated**: the same, after the calibration procedure of ``calibration.py`` has
  run on that robot and written SET_ODOMETRIE.

Figures, each over all robots (docs/calibration.md and bench/README.md define them): odometry
error (estimate vs truth, with and without the start pose error), arrival error (target vs
estimate, target vs truth) when the board reports the move finished, trajectory time over the
time-optimal bound, and the error radius's coverage and tightness. The simulator is driven in
steps of 0.5 s (``Simulator.advance``) and the figures read from its trace.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Iterable, Sequence
from concurrent.futures import ProcessPoolExecutor
from dataclasses import dataclass, field

import numpy as np

from .._protocol import Status
from ..calibration import (
    Calibration,
    CalibrationError,
    Geometry,
    OdometrySetting,
    Plan,
    calibrate,
)
from ..driver import AsservError, Board
from ..goals import MET, MISSED, Goals
from . import OdometryErrors, Simulator

__all__ = ["BenchResult", "RobotResult", "StraightRun", "bench", "report", "run_robot"]

SPEEDS_CM_S = (20, 50, 100)
ACCEL_CM_S2 = 100
ROT_CM_S, ROT_CM_S2 = 50, 100
DISTANCE_MM = 1800.0
START = (-900.0, 0.0, 0.0)  # along the field's X axis, clear of the baskets
TARGET = (START[0] + DISTANCE_MM, START[1])
CALIBRATION_START = (-1370.0, -300.0, 0.0)  # rear 5 mm from the west border

# The legacy baseline: P only, Kp = 15 /s (physics.md). The P gain is in 2^-12 of full duty
# per mm; full duty drives the reference robot at 1.64 m/s, so Kp = 1640 p / 4096 per second.
LEGACY_P = 37
_BIG = 2**31 - 1
LEGACY_CONFIG: dict[str, int] = {
    "control.ff_speed_q15_per_m_s": 0,  # no feed-forward
    "control.ff_accel_q15_per_m_s2": 0,
    "control.ff_angle_accel_q15_per_m_s2": 0,
    # finished on the first tick after both set points end (1 kHz): the robot anywhere, and no
    # set point "nearly done" before it ends (slower than an arrival speed of 0)
    "orders.settle_ms": 1,
    "orders.arrive_window_um": _BIG,
    "orders.arrive_speed_um_s": 0,
    "faults.following_max_um": _BIG,  # a lag of 67 mm at 1 m/s is its normal behaviour
}

CONTROLLERS = ("legacy", "asserv", "calibrated")
_CHUNK_S = 0.5  # the simulator is advanced by this much at a time
_TIMEOUT_S = 30.0
AFTER_S = 0.5  # how long after "finished" the arrival error is watched


def following_lag_mm(seg: np.ndarray) -> np.ndarray:
    """How far the estimate is behind the distance set point along a straight, tick by tick,
    from a trace that starts when the GOTO is taken (the set point rebuilt from its speed)."""
    set_pos = np.cumsum(seg["v_set_mm_s"]) * 1e-3
    moved = np.hypot(seg["est_x_mm"] - seg["est_x_mm"][0], seg["est_y_mm"] - seg["est_y_mm"][0])
    return np.asarray(set_pos - moved)


def time_bound_s(speed_cm_s: int, accel_cm_s2: int = ACCEL_CM_S2) -> float:
    """The time-optimal trapezoid over DISTANCE_MM (physics.md): d/v + v/a, or 2 sqrt(d/a)."""
    d, v, a = DISTANCE_MM / 1000, speed_cm_s / 100, accel_cm_s2 / 100
    return d / v + v / a if d >= v * v / a else 2 * math.sqrt(d / a)


@dataclass(frozen=True)
class StraightRun:
    """One 1.8 m straight, read when the board reports it finished (BUSY_TRAJET cleared)."""

    controller: str
    speed_cm_s: int
    finished: bool  # within the timeout, with no other status bit
    time_s: float  # from the tick that took the GOTO to the one that cleared BUSY_TRAJET
    odometry_mm: float  # |estimate - truth|
    odometry_own_mm: float  # the same with the start pose error taken out
    arrival_est_mm: float  # |target - estimate|
    arrival_after_mm: float  # the largest |target - estimate| over the next AFTER_S
    arrival_true_mm: float  # |target - truth|
    radius_mm: float  # the board's error radius then
    max_lag_mm: float  # largest distance of the estimate behind the set point, along the path


@dataclass
class RobotResult:
    seed: int
    description: str
    noise: tuple[float, float]  # encoder noise k of each wheel [mm^2/m]
    runs: list[StraightRun] = field(default_factory=list)
    before: OdometryErrors | None = None
    after: OdometryErrors | None = None
    setting: OdometrySetting | None = None
    calibration_error: str = ""


def straight(
    seed: int,
    controller: str,
    speed_cm_s: int,
    setting: OdometrySetting | None = None,
    *,
    keep_trace: bool = False,
) -> tuple[StraightRun, np.ndarray | None]:
    """Drive the straight on the robot of ``seed`` with one controller and one speed."""
    legacy = controller == "legacy"
    sim = Simulator(
        {"start": START},
        seed=seed,
        randomize=True,
        board_config=LEGACY_CONFIG if legacy else None,
    )
    board = Board(sim.bus)
    if setting is not None:
        board.set_odometrie(setting.ratio_ppm, setting.track_10um, setting.scale_ppm)
    board.set_vitesse_traj(speed_cm_s, ACCEL_CM_S2)
    board.set_vitesse_rot(ROT_CM_S, ROT_CM_S2)
    if legacy:
        board.set_filtre_raw(LEGACY_P, 0, 0)
    n0 = sim.ticks
    board.goto(round(TARGET[0]), round(TARGET[1]))
    first = end = -1
    while sim.time_s < _TIMEOUT_S:
        sim.advance(_CHUNK_S)
        busy = (sim.trace["status"][n0:].astype(np.int64) & Status.BUSY_TRAJET) != 0
        if first < 0 and busy.any():
            first = int(np.argmax(busy))
        if first >= 0 and not busy[first:].all():
            end = first + int(np.argmin(busy[first:]))
            break
    if end >= 0:  # and what the robot does in the next AFTER_S, where the master reads it
        sim.advance(max(0.0, (n0 + end) * 1e-3 + AFTER_S - sim.time_s + 1e-3))
    tr = sim.trace
    row = tr[n0 + end] if end >= 0 else tr[-1]
    status = int(row["status"])
    finished = end >= 0 and status & ~int(Status.BUSY_TRAJET) == 0
    t0 = tr[0]
    est = np.array([row["est_x_mm"], row["est_y_mm"]])
    true = np.array([row["x_mm"], row["y_mm"]])
    # The odometry's own error: the true motion since the start, seen from the start pose the
    # board believes (its estimate before moving) instead of the true one.
    a = math.radians(t0["est_heading_deg"] - t0["heading_deg"])
    c, s = math.cos(a), math.sin(a)
    d = true - np.array([t0["x_mm"], t0["y_mm"]])
    ideal = np.array([t0["est_x_mm"], t0["est_y_mm"]]) + np.array(
        [c * d[0] - s * d[1], s * d[0] + c * d[1]]
    )
    target = np.array(TARGET)
    seg = tr[n0 + max(first, 0) : n0 + end + 1 if end >= 0 else len(tr)]
    lag = following_lag_mm(seg)
    after = tr[n0 + end : n0 + end + round(AFTER_S * 1000)] if end >= 0 else tr[-1:]
    drift = np.hypot(after["est_x_mm"] - target[0], after["est_y_mm"] - target[1])
    run = StraightRun(
        controller,
        speed_cm_s,
        finished,
        (end - first) * 1e-3 if end >= 0 else math.nan,
        float(np.hypot(*(est - true))),
        float(np.hypot(*(est - ideal))),
        float(np.hypot(*(target - est))),
        float(drift.max()),
        float(np.hypot(*(target - true))),
        float(row["radius_mm"]),
        float(lag.max()) if len(lag) else math.nan,
    )
    return run, (tr.copy() if keep_trace else None)


def calibrate_robot(seed: int, plan: Plan | None = None) -> tuple[Calibration, Simulator]:
    """Run the calibration procedure on the robot of ``seed``, standing at the west border."""
    sim = Simulator({"start": CALIBRATION_START}, seed=seed, randomize=True, record=False)
    geometry = Geometry(
        table_length_mm=sim.field.length_mm,
        robot_length_mm=float(sim.config.outline_length_mm),
    )
    result = calibrate(Board(sim.bus), geometry, plan, _nominal(sim), log=lambda _: None)
    sim.advance(0.002)  # the tick that applies SET_ODOMETRIE
    return result, sim


def _nominal(sim: Simulator) -> OdometrySetting:
    return OdometrySetting(0, round(sim.board_config.odometry.track_um / 10), 0)


def run_robot(
    seed: int, speeds: Sequence[int] = SPEEDS_CM_S, plan: Plan | None = None
) -> RobotResult:
    """Everything the bench does with one robot: calibrate it, then drive the straights."""
    probe = Simulator({"start": START}, seed=seed, randomize=True, record=False)
    k = probe.config.enc_noise_mm2_per_m
    res = RobotResult(seed, probe.describe_robot(), (k[0], k[1]), before=probe.odometry_errors())
    try:
        cal, sim = calibrate_robot(seed, plan)
        res.setting = cal.after
        res.after = sim.odometry_errors()
    except (CalibrationError, AsservError) as e:  # reported under the table
        res.calibration_error = f"{type(e).__name__}: {e}"
    for v in speeds:
        res.runs.append(straight(seed, "legacy", v)[0])
        res.runs.append(straight(seed, "asserv", v)[0])
        if res.setting is not None:
            res.runs.append(straight(seed, "calibrated", v, res.setting)[0])
    return res


@dataclass
class BenchResult:
    robots: list[RobotResult]
    speeds: tuple[int, ...]
    wall_s: float
    plan: Plan
    examples: dict[str, np.ndarray] = field(default_factory=dict)

    def runs(self, controller: str, speed: int) -> list[StraightRun]:
        return [
            r
            for rob in self.robots
            for r in rob.runs
            if r.controller == controller and r.speed_cm_s == speed
        ]


def bench(
    n_robots: int = 200,
    first_seed: int = 0,
    *,
    speeds: Sequence[int] = SPEEDS_CM_S,
    plan: Plan | None = None,
    jobs: int = 1,
    examples: bool = True,
    progress: Callable[[int, int], None] | None = None,
) -> BenchResult:
    """Run the bench on robots ``first_seed .. first_seed + n_robots - 1``."""
    plan = plan or Plan()
    t0 = time.perf_counter()
    seeds = range(first_seed, first_seed + n_robots)
    robots: list[RobotResult] = []
    if jobs > 1:
        with ProcessPoolExecutor(max_workers=jobs) as ex:
            futures = [ex.submit(run_robot, s, tuple(speeds), plan) for s in seeds]
            for i, f in enumerate(futures):
                robots.append(f.result())
                if progress:
                    progress(i + 1, n_robots)
    else:
        for i, s in enumerate(seeds):
            robots.append(run_robot(s, speeds, plan))
            if progress:
                progress(i + 1, n_robots)
    out = BenchResult(robots, tuple(speeds), 0.0, plan)
    if examples and robots:
        v = max(speeds)
        setting = robots[0].setting
        for ctl in CONTROLLERS:
            if ctl == "calibrated" and setting is None:
                continue
            _, tr = straight(
                first_seed, ctl, v, setting if ctl == "calibrated" else None, keep_trace=True
            )
            assert tr is not None
            out.examples[ctl] = tr
    out.wall_s = time.perf_counter() - t0
    return out


# ---- the report -----------------------------------------------------------------------------


def _p(values: Iterable[float], q: float) -> float:
    v = [x for x in values if math.isfinite(x)]
    return float(np.percentile(v, q)) if v else math.nan


def _f(x: float, digits: int = 1) -> str:
    return "-" if not math.isfinite(x) else f"{x:.{digits}f}"


def noise_floor_mm(res: BenchResult, q: float = 95.0, samples: int = 4000) -> float:
    """The q-th percentile of the position error that the encoder noise alone gives over the
    straight, on these robots: per robot sigma_long^2 = (kL + kR) L / 4 and sigma_lat^2 =
    (kL + kR) L^3 / (3 b^2) (Chong and Kleeman 1997; docs/odometry.md), sampled (fixed seed)."""
    rng = np.random.default_rng(0)
    length_m, b_m = DISTANCE_MM / 1000, 0.28
    errs = []
    for rob in res.robots:
        k = sum(rob.noise)  # mm^2/m
        lon = rng.normal(0, math.sqrt(k * length_m / 4), samples)
        lat = rng.normal(0, math.sqrt(k * length_m**3 / (3 * b_m**2)), samples)
        errs.append(np.hypot(lon, lat))
    return float(np.percentile(np.concatenate(errs), q)) if errs else math.nan


_LABEL, _COL, _GOAL = 44, 11, 26

#: The calibrated odometry's goal, as a ratio to what the encoder noise alone gives over the
#: straight on the same robots (``noise_floor_mm``): no calibration removes that part, so the
#: goal is that the calibration's residuals add at most a fifth to it.
ODOMETRY_OVER_NOISE = 1.2


def report(res: BenchResult, goals: Goals | None = None) -> list[str]:
    """The bench's table, beside the specification's figures and the goals of issue 7, each
    goal marked met or MISSED (and recorded in ``goals``), and a summary line at the end."""
    goals = goals if goals is not None else Goals("asserv bench accuracy")
    n = len(res.robots)
    floor = noise_floor_mm(res)
    ctls = [c for c in CONTROLLERS if any(res.runs(c, v) for v in res.speeds)]
    heads = {
        "legacy": ("legacy", "P-only"),
        "asserv": ("asserv", "nominal"),
        "calibrated": ("asserv", "calibrated"),
    }
    lines = [
        f"asserv bench accuracy: {n} robots (seeds {res.robots[0].seed}.."
        f"{res.robots[-1].seed}), a {DISTANCE_MM / 1000:.1f} m straight at"
        f" {ACCEL_CM_S2 / 100:g} m/s^2, read when the board reports it finished",
        "",
        " " * _LABEL
        + f"{'spec 2002':>{_COL}}"
        + "".join(f"{heads[c][0]:>{_COL}}" for c in ctls)
        + f"{'goal':>{_GOAL}}",
        " " * _LABEL + " " * _COL + "".join(f"{heads[c][1]:>{_COL}}" for c in ctls),
    ]

    def row(label: str, spec: str, cells: Iterable[str], goal: str = "") -> None:
        lines.append(
            label.ljust(_LABEL)
            + f"{spec:>{_COL}}"
            + "".join(f"{c:>{_COL}}" for c in cells)
            + f"{goal:>{_GOAL}}"
        )

    def block(
        title: str,
        cell: Callable[[list[StraightRun]], str],
        spec: Callable[[int], str] = lambda v: "",
        goal: Callable[[int], str] = lambda v: "",
        speed_label: Callable[[int], str] = lambda v: f"  {v / 100:.1f} m/s",
        limit: tuple[str, float, tuple[str, ...]] | None = None,
    ) -> None:
        """A block of rows, one a speed; ``limit`` (op, value, controllers): the goal of the
        rows that have one, checked on those controllers' cells and marked."""
        lines.append(title)
        for v in res.speeds:
            cells = [cell(res.runs(c, v)) for c in ctls]
            text = goal(v)
            if text and limit is not None:
                op, bound, which = limit
                name = f"{title.strip()}, {speed_label(v).strip()}"
                text = f"{text} {mark(name, cells, op, bound, which)}"
            row(speed_label(v), spec(v), cells, text)

    def mark(name: str, cells: list[str], op: str, bound: float, which: tuple[str, ...]) -> str:
        """Check the cells of the controllers ``which``; the worst decides (a '-' is a miss)."""
        marks = []
        for c, text in zip(ctls, cells, strict=True):
            if c in which:
                value = float(text) if text != "-" else math.nan
                marks.append(goals.check(f"{name} ({c})", value, op, bound).mark)
        return MISSED if MISSED in marks else MET

    def p95(attr: str, digits: int = 1) -> Callable[[list[StraightRun]], str]:
        return lambda runs: _f(_p((getattr(r, attr) for r in runs if r.finished), 95), digits)

    def time_ratio(runs: list[StraightRun]) -> str:
        t = [r.time_s / time_bound_s(r.speed_cm_s) for r in runs if r.finished]
        return f"{_p(t, 95):.3f}" if t else "-"

    def coverage(runs: list[StraightRun]) -> str:
        ok = [r for r in runs if r.finished and r.controller != "legacy"]
        if not ok:
            return "-"
        return f"{100 * sum(r.odometry_own_mm <= r.radius_mm for r in ok) / len(ok):.1f}"

    def tightness(runs: list[StraightRun]) -> str:
        ok = [r for r in runs if r.finished and r.controller != "legacy"]
        p99 = _p((r.odometry_own_mm for r in ok), 99)
        if not ok or not p99 > 0:
            return "-"
        return f"{float(np.mean([r.radius_mm for r in ok])) / p99:.2f}"

    def over_noise(runs: list[StraightRun]) -> str:
        own = _p((r.odometry_own_mm for r in runs if r.finished), 95)
        return f"{own / floor:.2f}" if math.isfinite(own) and floor > 0 else "-"

    both = ("asserv", "calibrated")
    block("odometry error |estimate - truth|, p95 [mm]", p95("odometry_mm"), lambda v: "+/-20")
    block("  without the start pose error [mm]", p95("odometry_own_mm"))
    block(
        f"  the same / the encoder noise alone ({floor:.1f} mm)",
        over_noise,
        goal=lambda v: f"<= {ODOMETRY_OVER_NOISE:g} calibrated",
        limit=("<=", ODOMETRY_OVER_NOISE, ("calibrated",)),
    )
    block(
        "arrival error |target - estimate|, p95 [mm]",
        p95("arrival_est_mm", 2),
        lambda v: "0" if v <= 20 else ("+/-70" if v >= 100 else ""),
        lambda v: "<= 2" if v >= 100 else "",
        limit=("<=", 2.0, both),
    )
    block(
        f"  the largest in the next {AFTER_S:g} s [mm]",
        p95("arrival_after_mm", 2),
        goal=lambda v: "<= 2" if v >= 100 else "",
        limit=("<=", 2.0, both),
    )
    block("arrival error |target - truth|, p95 [mm]", p95("arrival_true_mm"))
    block("largest lag behind the set point, p95 [mm]", p95("max_lag_mm"))
    block(
        "trajectory time / time-optimal bound, p95",
        time_ratio,
        goal=lambda v: "<= 1.05",
        speed_label=lambda v: f"  {v / 100:.1f} m/s (bound {time_bound_s(v):.2f} s)",
        limit=("<=", 1.05, both),
    )
    worst = {
        c: max(
            (
                r.time_s / time_bound_s(r.speed_cm_s)
                for v in res.speeds
                for r in res.runs(c, v)
                if r.finished
            ),
            default=math.nan,
        )
        for c in ctls
    }
    worst_cells = [f"{worst[c]:.3f}" for c in ctls]
    worst_mark = mark("trajectory time / bound, the largest", worst_cells, "<=", 1.05, both)
    row("  the largest, any speed", "", worst_cells, f"<= 1.05 {worst_mark}")
    block(
        "error radius: coverage of the error [%]",
        coverage,
        goal=lambda v: ">= 99",
        limit=(">=", 99.0, both),
    )
    block(
        "error radius: mean radius / true p99",
        tightness,
        goal=lambda v: "<= 3",
        limit=("<=", 3.0, both),
    )
    lines.append(
        f"encoder noise alone over {DISTANCE_MM / 1000:.1f} m on these robots, p95:"
        f" {floor:.1f} mm (sigma_lat^2 = (kL + kR) L^3 / (3 b^2))"
    )
    unfinished = [
        f"{r.controller} {r.speed_cm_s} cm/s seed {rob.seed}"
        for rob in res.robots
        for r in rob.runs
        if not r.finished
    ]
    tail = f" ({', '.join(unfinished[:5])}{', ...' if len(unfinished) > 5 else ''})"
    lines.append(f"runs not finished cleanly: {len(unfinished)}" + (tail if unfinished else ""))
    lines += ["", *calibration_report(res, goals), "", f"wall time: {res.wall_s:.1f} s"]
    lines.append(goals.summary())
    return lines


def calibration_report(res: BenchResult, goals: Goals | None = None) -> list[str]:
    """Before and after the calibration procedure, over all robots; the goals on the largest
    error after it, marked (and recorded in ``goals``)."""
    goals = goals if goals is not None else Goals("asserv bench accuracy")
    p = res.plan
    ok = [r for r in res.robots if r.after is not None and r.before is not None]
    failed = [r for r in res.robots if r.calibration_error]
    lines = [
        f"odometry calibration ({p.turns} turns, {p.round_trips} round trips wall to wall,"
        f" docs/calibration.md) on {len(ok)} robots",
        f"{'':32}{'before p95':>12}{'max':>9}{'after p95':>12}{'max':>9}{'goal (max)':>18}",
    ]
    rows: list[tuple[str, Callable[[OdometryErrors], float], float | None]] = [
        ("wheel ratio error [%]", lambda e: abs(e.ratio) * 100, 0.05),
        ("track error [mm]", lambda e: abs(e.track_mm), 0.1),
        ("wheel scale error [%]", lambda e: abs(e.scale) * 100, None),
    ]
    for name, f, limit in rows:
        b = [f(r.before) for r in ok if r.before]
        a = [f(r.after) for r in ok if r.after]
        if not a:
            continue
        goal = ""
        if limit is not None:
            g = goals.check(f"calibration: {name} after, max", max(a), "<=", limit)
            goal = f"<= {limit:g} {g.mark}"
        lines.append(
            f"  {name:30}{_p(b, 95):>12.3f}{max(b):>9.3f}{_p(a, 95):>12.3f}{max(a):>9.3f}{goal:>18}"
        )
    if failed:
        lines.append(
            f"calibration failed on {len(failed)} robots: "
            + "; ".join(f"seed {r.seed}: {r.calibration_error}" for r in failed[:3])
        )
    return lines
