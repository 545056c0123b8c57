"""A quiet servo (issue 32): how much the control chatters where the motion is steady.

On N randomized robots (seeds 0..N-1, `--robots`, 50 by default), at 1 kHz:

- cruise: a 2.2 m straight at 0.2, 0.5 and 1 m/s (1 m/s^2), measured over the ticks where the
  distance set point's speed is the cruise speed, from CRUISE_SETTLE_S after it is reached;
- rest, free: REST_S after that straight has ended, held where it stopped;
- rest, against a wall: driven at 0.2 m/s into a wall across its path (a shock switch stops it,
  docs/failure-model.md "A stop that stops"), REST_S from WALL_SETTLE_S after the contact.

For each, over both motors:

- duty jitter: the RMS of the duty [full duty] around its own centred 50 ms average;
- current: its RMS [A] against the current the motion needs, the magnitude of its mean over the
  window (what a steady duty giving the same torque would draw);
- following error at cruise: the RMS of the distance loop's following error [mm], rebuilt from
  the trace (asserv.log.following_errors);
- contact force against the wall [N], the largest over the window.

Each figure is the worst over the robots, beside its goal (issue 32) and the figure the commit
before the quiet servo printed (BEFORE): duty jitter 0.01 RMS or
less, current RMS at most 1.5 times the needed current + 0.1 A, contact force under 1 N, and the
following error at cruise at most 1.2 times the figure of the commit before the quiet servo
(FOLLOWING_BEFORE_MM). Each goal is marked met or MISSED; the last line sums them up
(``bench/quiet.py: goals met: N of M``), and --strict exits 1 on a miss.

--raw-d runs the same robots with the PIDs' derivative read raw, the difference of two ticks'
errors (control.d_filter_ms 0: the AVR's build, docs/avr.md), to see what the low-pass buys on
today's board.

    python bench/quiet.py [--robots N] [--jobs J] [--raw-d] [--strict]
"""

from __future__ import annotations

import argparse
import dataclasses
import multiprocessing
import sys

import numpy as np

from asserv import field
from asserv.driver import Board
from asserv.goals import Goals, add_strict_flag
from asserv.log import following_errors
from asserv.sim import Simulator

SPEEDS_CM_S = (20, 50, 100)
ACCEL_CM_S2 = 100
START_X_MM, END_X_MM = -1100, 1100
WALL_SPEED_CM_S = 20
#: Ticks of a cruise that still carry the end of the acceleration: left out.
CRUISE_SETTLE_S = 0.1
REST_S = 1.0
WALL_SETTLE_S = 0.3
AVERAGE_S = 0.05
TICK_S = 1e-3

JITTER_GOAL = 0.01  # [full duty] RMS around the 50 ms average
CURRENT_GAIN_GOAL, CURRENT_OFFSET_GOAL_A = 1.5, 0.1
FORCE_GOAL_N = 1.0
FOLLOWING_GROWTH_GOAL = 1.2
#: The worst RMS following error at each cruise speed over the 50 robots before issue 32
#: (`python bench/quiet.py` on main at ab41e8a, and the same at 70f9445) [mm].
FOLLOWING_BEFORE_MM = {20: 0.024, 50: 0.034, 100: 0.059}
#: What `python bench/quiet.py` printed on main at 70f9445, the commit before the quiet servo:
#: each case's worst duty jitter [RMS] and current [A RMS], and the contact force [N].
BEFORE: dict[str, tuple[float, float, float | None]] = {
    "cruise 0.2 m/s": (0.0834, 0.88, None),
    "rest after 0.2 m/s": (0.1026, 1.05, None),
    "cruise 0.5 m/s": (0.0774, 0.81, None),
    "rest after 0.5 m/s": (0.1023, 1.06, None),
    "cruise 1.0 m/s": (0.0763, 0.80, None),
    "rest after 1.0 m/s": (0.1010, 1.05, None),
    "rest against a wall": (0.0576, 0.57, 7.4),
}
#: The board's settings of --raw-d: the derivative without its low-pass.
RAW_D = {"control.d_filter_ms": 0}


@dataclasses.dataclass
class Window:
    """The figures of one robot in one steady case."""

    jitter: float  # [full duty] the larger motor's
    current_rms_a: float  # the motor whose RMS is furthest above its goal
    current_need_a: float  # and its need
    following_mm: float  # RMS; NaN where not measured
    force_n: float  # largest contact force; 0 off a wall


def jitter_of(duty: np.ndarray) -> float:
    n = round(AVERAGE_S / TICK_S)
    avg = np.convolve(duty, np.ones(n) / n, mode="valid")
    lo = (n - 1) // 2
    return float(np.sqrt(np.mean((duty[lo : lo + len(avg)] - avg) ** 2)))


def window_of(tr: np.ndarray, following: np.ndarray | None = None) -> Window:
    jitter = max(jitter_of(tr["duty_left"]), jitter_of(tr["duty_right"]))
    excess, rms, need = -np.inf, 0.0, 0.0
    for col in ("current_left_A", "current_right_A"):
        r = float(np.sqrt(np.mean(tr[col] ** 2)))
        m = float(abs(np.mean(tr[col])))
        e = r - (CURRENT_GAIN_GOAL * m + CURRENT_OFFSET_GOAL_A)
        if e > excess:
            excess, rms, need = e, r, m
    f = float(np.sqrt(np.mean(following**2))) if following is not None else float("nan")
    return Window(jitter, rms, need, f, float(tr["contact_force_N"].max()))


def cruise(
    seed: int, speed_cm_s: int, board_config: dict[str, int] | None = None
) -> tuple[Window, Window]:
    """A straight at speed: its cruise, then the rest after it."""
    sim = Simulator(
        {"start": (START_X_MM, 0, 0.0)}, seed=seed, randomize=True, board_config=board_config
    )
    board = Board(sim.bus)
    board.set_vitesse_traj(speed_cm_s, ACCEL_CM_S2)
    board.goto(END_X_MM, 0)
    board.wait_idle(30)
    end = len(sim.trace)
    sim.advance(REST_S + 0.5)
    tr = sim.trace
    dist, _ = following_errors(tr, sim.board_config.orders.drive_track_um / 1000)
    at = np.nonzero(tr["v_set_mm_s"] == 10 * speed_cm_s)[0]
    first = at[0] + round(CRUISE_SETTLE_S / TICK_S)
    run = slice(first, at[-1] + 1)
    rest = slice(end + round(0.5 / TICK_S), None)
    return window_of(tr[run], dist[run]), window_of(tr[rest])


def wall(seed: int, board_config: dict[str, int] | None = None) -> Window:
    """Driven into a wall at WALL_SPEED_CM_S, then at rest against it."""
    box = field.Obstacle("box", 20, 0, half_x_mm=20, half_y_mm=200)
    f = dataclasses.replace(field.load(field.DEFAULT), obstacles=(box,))
    sim = Simulator(
        {"start": (-400, 0, 0.0)}, seed=seed, randomize=True, field=f, board_config=board_config
    )
    board = Board(sim.bus)
    board.set_vitesse_traj(WALL_SPEED_CM_S, ACCEL_CM_S2)
    board.goto(600, 0)
    board.wait_idle(30)
    sim.advance(WALL_SETTLE_S + REST_S)
    tr = sim.trace
    hit = np.nonzero((tr["shocks"] != 0) | (tr["contact_force_N"] > 0))[0]
    if not len(hit):
        raise RuntimeError(f"seed {seed}: the robot never reached the wall")
    c = int(hit[0]) + round(WALL_SETTLE_S / TICK_S)
    return window_of(tr[c : c + round(REST_S / TICK_S)])


def robot(seed: int, board_config: dict[str, int] | None = None) -> dict[str, Window]:
    out: dict[str, Window] = {}
    for v in SPEEDS_CM_S:
        out[f"cruise {v / 100:.1f} m/s"], out[f"rest after {v / 100:.1f} m/s"] = cruise(
            seed, v, board_config
        )
    out["rest against a wall"] = wall(seed, board_config)
    return out


def robot_raw_d(seed: int) -> dict[str, Window]:
    return robot(seed, RAW_D)


def report(results: list[dict[str, Window]], goals: Goals, raw_d: bool = False) -> None:
    n = len(results)
    how = "the derivative read raw (control.d_filter_ms 0)" if raw_d else "the quiet servo"
    print(f"{n} randomized robots (seeds 0..{n - 1}), 1 kHz, {how}; the worst robot of each case")
    print(
        f"{'case':<22} {'jitter':>8} {'goal':>6}   {'I rms':>7} {'need':>7} {'goal':>7}   "
        f"{'follow':>7} {'goal':>7}   {'force':>6} {'goal':>5}"
    )
    for case in results[0]:
        ws = [r[case] for r in results]
        jit = max(w.jitter for w in ws)
        worst_i = max(
            ws,
            key=lambda w: w.current_rms_a - CURRENT_GAIN_GOAL * w.current_need_a,
        )
        i_goal = CURRENT_GAIN_GOAL * worst_i.current_need_a + CURRENT_OFFSET_GOAL_A
        ok_j = goals.check(f"{case}: duty jitter [RMS]", jit, "<=", JITTER_GOAL)
        ok_i = goals.check(f"{case}: current [A RMS]", worst_i.current_rms_a, "<=", i_goal)
        line = (
            f"{case:<22} {jit:8.4f} {JITTER_GOAL:6.3f} {ok_j.mark:>6}  "
            f"{worst_i.current_rms_a:5.2f} A {worst_i.current_need_a:5.3f} A {i_goal:5.2f} A "
            f"{ok_i.mark:>6}"
        )
        if case.startswith("cruise"):
            v = round(float(case.split()[1]) * 100)
            fol = max(w.following_mm for w in ws)
            before = FOLLOWING_BEFORE_MM[v]
            goal = FOLLOWING_GROWTH_GOAL * before
            if before > 0:
                ok_f = goals.check(f"{case}: following error [mm]", fol, "<=", goal)
                line += f"  {fol:6.3f} mm {goal:6.3f} mm {ok_f.mark:>6}"
            else:
                line += f"  {fol:6.3f} mm  (none)          "
        if case.endswith("wall"):
            force = max(w.force_n for w in ws)
            ok_c = goals.check(f"{case}: contact force [N]", force, "<", FORCE_GOAL_N)
            line += f"{'':>27}{force:5.1f} N {FORCE_GOAL_N:4.1f} N {ok_c.mark}"
        print(line)
    print("before the quiet servo (what this bench printed at 70f9445):")
    for case, (j_before, i_before, f_before) in BEFORE.items():
        tail = f"   force {f_before:4.1f} N" if f_before is not None else ""
        print(f"  {case:<20} jitter {j_before:6.4f}   I rms {i_before:4.2f} A{tail}")


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawTextHelpFormatter)
    ap.add_argument("--robots", type=int, default=50, help="randomized robots (50)")
    ap.add_argument("--jobs", type=int, default=1, help="processes (1)")
    ap.add_argument(
        "--raw-d",
        action="store_true",
        help="the derivative read raw (control.d_filter_ms 0, the AVR's build)",
    )
    add_strict_flag(ap)
    args = ap.parse_args(argv)
    if args.robots < 1:
        ap.error(f"--robots: {args.robots} robots: give 1 or more")
    if args.jobs < 1:
        ap.error(f"--jobs: {args.jobs} processes: give 1 or more")
    seeds = range(args.robots)
    run = robot_raw_d if args.raw_d else robot
    if args.jobs > 1:
        with multiprocessing.Pool(args.jobs) as pool:
            results = pool.map(run, seeds)
    else:
        results = [run(s) for s in seeds]
    goals = Goals("bench/quiet.py")
    report(results, goals, args.raw_d)
    print(goals.summary())
    return goals.exit_code(args.strict)


if __name__ == "__main__":
    sys.exit(main())
