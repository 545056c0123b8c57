"""PID tuning: step responses of the distance loop and the angle loop, their figures, a sweep of
P, I and D that ranks the gain sets, and SET_FILTRE_RAW of the chosen one (docs/view.md).

A step is a GOTO: straight ahead by ``size`` mm for the distance loop, or towards a point at
``size`` degrees from the heading (``ANGLE_REACH_MM`` away) for the angle loop. The response is
polled from the board (POSITION, DEBUG, CHECK_BUSY: ``asserv.log.poll_board``), the same way in
the simulator and on a real board; after each step the robot drives back to where it started.

The figures of a response (``metrics``), against the commanded step A from the start value y0:

- rise time: from the first sample at 10 % of A to the first at 90 %;
- overshoot: how far the response goes past the target, in % of A (0 when it never does);
- settling time: from the order to the last time the response is outside the band
  (2 % of A, at least the resolution of the reading) around the target;
- steady-state error: target minus the mean of the last 10 % of the window;
- largest following error: the largest |DEBUG dist_err| (or angle_err), mm at the wheels.

A gain set's cost (``cost``) is its settling time plus 20 ms per % of overshoot, 100 ms per mm
(or degree) of steady-state error and 50 ms per mm of the largest following error (with the
board's feed-forward, the trajectory sets the rise and most of the settling: the gains show in
the following error); a set that does not settle in the window ranks last.
"""

from __future__ import annotations

import argparse
import itertools
import math
import sys
from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from . import log
from .cli_args import natural, progress_bar

if TYPE_CHECKING:
    from .driver import Board

__all__ = [
    "Gains",
    "StepMetrics",
    "StepResponse",
    "cost",
    "metrics",
    "rank",
    "step",
    "sweep",
]

AXES = ("distance", "angle")
ANGLE_REACH_MM = 200  # the angle step's GOTO target is this far away
RESOLUTION = {"distance": 1.0, "angle": 0.5}  # POSITION's mm; half a degree for the heading
UNIT = {"distance": "mm", "angle": "deg"}
DEFAULT_STEP = {"distance": 200.0, "angle": 90.0}


@dataclass(frozen=True, order=True)
class Gains:
    """SET_FILTRE_RAW's gains (docs/protocol.md 5.4)."""

    p: int
    i: int
    d: int

    def __str__(self) -> str:
        return f"P={self.p} I={self.i} D={self.d}"


#: FILTRE_STD's gains (docs/control.md).
STD = Gains(205, 400, 160)


@dataclass(frozen=True)
class StepMetrics:
    rise_s: float  # NaN when the response never reaches 90 %
    overshoot_pct: float
    settling_s: float  # NaN when it is not settled at the end of the window
    steady_state_error: float  # mm or degrees
    max_following_mm: float  # NaN when unknown

    @property
    def settled(self) -> bool:
        return not math.isnan(self.settling_s)


@dataclass(frozen=True)
class StepResponse:
    axis: str
    gains: Gains | None
    size: float  # the commanded step, mm or degrees
    t_s: np.ndarray  # since the order
    y: np.ndarray  # the response, from 0 (mm along the step, or degrees turned)
    following_mm: np.ndarray
    rows: np.ndarray  # the polled log rows
    metrics: StepMetrics


def metrics(
    t: Sequence[float] | np.ndarray,
    y: Sequence[float] | np.ndarray,
    target: float,
    *,
    start: float = 0.0,
    band: float | None = None,
    following: Sequence[float] | np.ndarray | None = None,
) -> StepMetrics:
    """The figures of a step response ``y(t)`` from ``start`` to ``target`` (t from the order).
    ``band``: the settling band's half width (default 2 % of the step)."""
    t_a = np.asarray(t, dtype=float)
    y_a = np.asarray(y, dtype=float)
    if len(t_a) != len(y_a) or len(t_a) < 2:
        raise ValueError("a step response needs at least two samples of t and y")
    amp = target - start
    if amp == 0:
        raise ValueError("the step is zero: nothing to measure")
    e = (y_a - start) / amp  # 0 at the start, 1 at the target

    def first(level: float) -> float:
        idx = np.nonzero(e >= level)[0]
        return float(t_a[idx[0]]) if len(idx) else math.nan

    rise = first(0.9) - first(0.1)
    overshoot = max(0.0, float(e.max()) - 1.0) * 100
    half = abs(amp) * 0.02 if band is None else band
    outside = np.nonzero(np.abs(y_a - target) > half)[0]
    if not len(outside):
        settling = float(t_a[0])
    elif outside[-1] == len(t_a) - 1:
        settling = math.nan
    else:
        settling = float(t_a[outside[-1] + 1])
    tail = y_a[len(y_a) - max(1, len(y_a) // 10) :]
    sse = float(target - tail.mean())
    if following is None or not len(following):
        fmax = math.nan
    else:
        fmax = float(np.nanmax(np.abs(np.asarray(following, dtype=float))))
    return StepMetrics(rise, overshoot, settling, sse, fmax)


def cost(m: StepMetrics) -> float:
    """Lower is better; infinite when the response did not settle in the window."""
    if not m.settled:
        return math.inf
    follow = 0.0 if math.isnan(m.max_following_mm) else m.max_following_mm
    return m.settling_s + 0.02 * m.overshoot_pct + 0.1 * abs(m.steady_state_error) + 0.05 * follow


def rank(results: Iterable[tuple[Gains, Sequence[StepMetrics]]]) -> list[tuple[Gains, float]]:
    """Gain sets with their metrics (one per axis measured), best first: by the sum of the
    costs; ties in the order given."""
    scored = [(g, sum(cost(m) for m in ms)) for g, ms in results]
    return sorted(scored, key=lambda gc: gc[1])


# ---- measuring --------------------------------------------------------------------------------


def _unwrap_deg(a: np.ndarray) -> np.ndarray:
    return np.asarray(np.degrees(np.unwrap(np.radians(a))), dtype=float)


def step(
    board: Board,
    axis: str,
    size: float,
    *,
    gains: Gains | None = None,
    window_s: float = 2.0,
    hz: float = 200.0,
    go_back: bool = True,
    limits: tuple[int, int] | None = None,
) -> StepResponse:
    """One step of ``axis`` ("distance" or "angle") on a board at rest, polled at ``hz`` for
    ``window_s``; with ``gains``, SET_FILTRE_RAW first; with ``limits`` (cm/s, cm/s^2),
    SET_VITESSE_TRAJ and SET_VITESSE_ROT first. Then (``go_back``) the robot returns to
    where it started and the call waits for it."""
    if axis not in AXES:
        raise ValueError(f"axis must be distance or angle, not {axis!r}")
    if gains is not None:
        board.set_filtre_raw(gains.p, gains.i, gains.d)
    if limits is not None:
        board.set_vitesse_traj(*limits)
        board.set_vitesse_rot(*limits)
    first = log.board_row(board, 0.0)
    x0, y0 = float(first["est_x_mm"]), float(first["est_y_mm"])
    h0 = float(first["est_heading_deg"])
    if axis == "distance":
        heading, reach = h0, size
    else:
        heading, reach = h0 + size, ANGLE_REACH_MM
    hr = math.radians(heading)
    board.goto(round(x0 + reach * math.cos(hr)), round(y0 + reach * math.sin(hr)))
    rows = np.array(list(log.poll_board(board, hz, duration_s=window_s)), dtype=log.LOG_DTYPE)
    if go_back:  # back where it started, facing the same way
        board.wait_idle(30)
        board.goto_reverse(round(reach))
        board.wait_idle(30)
        if axis == "angle":
            back = math.radians(h0)
            reach = ANGLE_REACH_MM
            board.goto(round(x0 + reach * math.cos(back)), round(y0 + reach * math.sin(back)))
            board.wait_idle(30)
            board.goto_reverse(reach)
            board.wait_idle(30)
    t = rows["t_s"]
    if axis == "distance":
        c, s = math.cos(math.radians(h0)), math.sin(math.radians(h0))
        y = (rows["est_x_mm"] - x0) * c + (rows["est_y_mm"] - y0) * s
        following = rows["dist_err_mm"]
    else:
        y = _unwrap_deg(np.concatenate(([h0], rows["est_heading_deg"])))[1:] - h0
        following = rows["angle_err_mm"]
    m = metrics(t, y, size, band=max(abs(size) * 0.02, RESOLUTION[axis]), following=following)
    return StepResponse(axis, gains, size, t, y, following, rows, m)


def sim_board(seed: int = 0) -> tuple[Any, Board]:
    """A simulated board at rest in the middle of the field, facing +x (room for the steps)."""
    from .driver import Board
    from .sim import Simulator

    sim = Simulator({"start": (-300.0, 0.0, 0.0)}, seed, record=False)
    return sim, Board(sim.bus)


def sweep(
    board_for: Callable[[Gains], Board],
    gain_sets: Sequence[Gains],
    axes: Sequence[str],
    steps: dict[str, float],
    *,
    window_s: float = 2.0,
    hz: float = 200.0,
    limits: tuple[int, int] | None = None,
    progress: Callable[[Gains, StepResponse], None] | None = None,
) -> dict[Gains, list[StepResponse]]:
    """Step each axis with each gain set; ``board_for(gains)`` gives the board to use (a fresh
    simulated one, or the same real one)."""
    out: dict[Gains, list[StepResponse]] = {}
    for g in gain_sets:
        board = board_for(g)
        out[g] = []
        for axis in axes:
            r = step(board, axis, steps[axis], gains=g, window_s=window_s, hz=hz, limits=limits)
            out[g].append(r)
            if progress is not None:
                progress(g, r)
    return out


# ---- report -----------------------------------------------------------------------------------


def _f(v: float, spec: str) -> str:
    """``v`` formatted, or "-" at the same width when it is not known (NaN)."""
    return f"{'-':>{len(format(0.0, spec))}}" if math.isnan(v) else format(v, spec)


def table(results: dict[Gains, list[StepResponse]]) -> list[str]:
    """The ranked table, one line per gain set and axis."""
    ranked = rank((g, [r.metrics for r in rs]) for g, rs in results.items())
    lines = [
        f"{'rank':>4}  {'gains':<22} {'axis':<8} {'overshoot':>9} {'rise':>7} {'settling':>8}"
        f" {'ss error':>10} {'max follow':>10}  cost"
    ]
    for k, (g, c) in enumerate(ranked, 1):
        for j, r in enumerate(results[g]):
            m = r.metrics
            u = UNIT[r.axis]
            lines.append(
                f"{k if j == 0 else '':>4}  {str(g) if j == 0 else '':<22} {r.axis:<8}"
                f" {m.overshoot_pct:8.1f}% {_f(m.rise_s, '6.3f')}s {_f(m.settling_s, '7.3f')}s"
                f" {m.steady_state_error:+7.2f} {u:<3}{_f(m.max_following_mm, '7.2f')} mm"
                + (f"  {c:.3f}" if j == 0 else "")
            )
    return lines


def plot(results: dict[Gains, list[StepResponse]], path: str | Path, top: int = 5) -> Path:
    """The step responses of the best ``top`` gain sets, one panel per axis, with the metrics
    of the best in the legend."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    ranked = rank((g, [r.metrics for r in rs]) for g, rs in results.items())[:top]
    axes_names = [r.axis for r in next(iter(results.values()))]
    fig, axs = plt.subplots(
        2, len(axes_names), figsize=(7 * len(axes_names), 7), squeeze=False, layout="constrained"
    )
    for col, axis in enumerate(axes_names):
        ax, axf = axs[0, col], axs[1, col]
        size = 0.0
        for k, (g, _) in enumerate(ranked):
            r = results[g][col]
            m = r.metrics
            size = r.size
            label = (
                f"#{k + 1} {g}: overshoot {m.overshoot_pct:.1f} %, rise {_f(m.rise_s, '.2f')} s,"
                f" settling {_f(m.settling_s, '.2f')} s, ss {m.steady_state_error:+.1f}"
            )
            ax.plot(r.t_s, r.y, lw=1.5 if k == 0 else 1, label=label)
            axf.plot(r.t_s, r.following_mm, lw=1.5 if k == 0 else 1, label=f"#{k + 1} {g}")
        if size:
            ax.axhline(size, color="k", lw=0.8, ls="--")
            for f in (0.98, 1.02):
                ax.axhline(size * f, color="0.6", lw=0.6, ls=":")
        ax.set_title(f"{axis} loop: step of {size:g} {UNIT[axis]} (dotted: the 2 % band)")
        ax.set_ylabel(f"response [{UNIT[axis]}]")
        ax.legend(fontsize=7, loc="lower right")
        axf.set_title(f"{axis} loop: following error (DEBUG)")
        axf.set_ylabel("[mm at the wheels]")
        axf.set_xlabel("time since the order [s]")
        axf.legend(fontsize=7, loc="upper right")
    out = Path(path)
    fig.savefig(out, dpi=90)
    plt.close(fig)
    return out


# ---- the command line -------------------------------------------------------------------------


def _ints(text: str, what: str) -> list[int]:
    try:
        values = [int(w, 0) for w in text.split(",") if w.strip()]
    except ValueError:
        raise ValueError(f"{what} takes integers separated by commas, not {text!r}") from None
    if not values or not all(0 <= v <= 65535 for v in values):
        raise ValueError(f"{what} takes values 0..65535, not {text!r}")
    return values


def _command(args: argparse.Namespace) -> int:
    from .driver import AsservError

    prog = "asserv tune"

    def usage(msg: str) -> int:
        print(f"{prog}: {msg}", file=sys.stderr)
        return 2

    try:
        ps = _ints(args.p, "--p")
        is_ = _ints(args.i, "--i")
        ds = _ints(args.d, "--d")
    except ValueError as e:
        return usage(str(e))
    axes = AXES if args.axis == "both" else (args.axis,)
    steps = dict(DEFAULT_STEP)
    if args.step is not None:
        if len(axes) != 1:
            return usage("--step needs one --axis (distance or angle)")
        steps[axes[0]] = args.step
    if not 40 <= steps["distance"] <= 250:
        return usage(
            "the distance step must be 40..250 mm (a GOTO of less than 30 mm does not turn;"
            " the robot comes back by GOTO_REVERSE, at most 255 mm)"
        )
    if not 5 <= abs(steps["angle"]) <= 170:
        return usage("the angle step must be 5..170 degrees")
    if not 0.2 <= args.window <= 30 or not 10 <= args.hz <= 1000:
        return usage("--window takes 0.2..30 s and --hz 10..1000")
    if not (1 <= args.speed <= 255 and 1 <= args.accel <= 255):
        return usage("--speed and --accel take 1..255 (cm/s, cm/s^2)")
    if args.png is not None and (why := log.check_output(args.png, "PNG")):
        return usage(why)
    gain_sets = [Gains(p, i, d) for p, i, d in itertools.product(ps, is_, ds)]
    if len(gain_sets) > 200:
        return usage(f"{len(gain_sets)} gain sets: at most 200 (fewer values in --p --i --d)")

    real = log.wants_board(args)
    bus: Any = None
    if real:
        opened = log.open_board(args, prog)
        if isinstance(opened, int):
            return opened
        board, bus = opened

        def board_for(g: Gains) -> Board:
            return board
    else:

        def board_for(g: Gains) -> Board:
            return sim_board(args.seed)[1]

    bar = progress_bar(len(gain_sets) * len(axes), "steps")

    def progress(g: Gains, r: StepResponse) -> None:
        bar.set_postfix_str(f"{g} {r.axis}", refresh=False)
        bar.update(1)

    where = log.board_where(args) if real else f"the simulated robot {args.seed}"
    print(f"{prog}: {len(gain_sets)} gain set(s) x {', '.join(axes)} on {where}", file=sys.stderr)
    try:
        with bar:
            results = sweep(
                board_for,
                gain_sets,
                axes,
                steps,
                window_s=args.window,
                hz=args.hz,
                limits=(args.speed, args.accel),
                progress=progress,
            )
        best = rank((g, [r.metrics for r in rs]) for g, rs in results.items())[0][0]
        for line in table(results):
            print(line)
        if args.apply:
            board_for(best).set_filtre_raw(best.p, best.i, best.d)
            print(f"applied: SET_FILTRE_RAW {best.p} {best.i} {best.d}")
        else:
            print(f"best: {best} (--apply writes it with SET_FILTRE_RAW)")
            if real:
                board_for(best).set_filtre(0)
                print("the board is back on FILTRE_STD")
    except AsservError as e:
        print(f"{prog}: {e}", file=sys.stderr)
        return 1
    except KeyboardInterrupt:
        print(f"{prog}: interrupted (the robot may still be moving: `stop`)", file=sys.stderr)
        return 130
    finally:
        if bus is not None and callable(getattr(bus, "close", None)):
            bus.close()
    if args.png:
        print(f"plot: {plot(results, args.png)}")
    return 0


def register(sub: Any) -> None:
    """Add ``asserv tune`` to the main CLI's subcommands."""
    p = sub.add_parser(
        "tune",
        help="step responses of the distance and angle loops, a P/I/D sweep, SET_FILTRE_RAW",
        description="Step the distance loop (a GOTO straight ahead) and the angle loop (a GOTO"
        " towards a point at an angle), print overshoot, rise time, settling time and"
        " steady-state error for each gain set of the sweep, rank them, and with --apply write"
        " the best with SET_FILTRE_RAW. Simulated robot by default; --bus N for a real one"
        " (it drives: give it room; docs/view.md), --sim HOST:PORT for `asserv sim serve`.",
    )
    log.bus_options(p)
    p.add_argument("--axis", choices=("distance", "angle", "both"), default="both")
    p.add_argument("--step", type=float, help="step size: mm (distance) or degrees (angle)")
    p.add_argument("--p", default=str(STD.p), help="P values, comma separated (default 205)")
    p.add_argument("--i", default=str(STD.i), help="I values (default 400)")
    p.add_argument("--d", default=str(STD.d), help="D values (default 160)")
    p.add_argument("--speed", type=int, default=50, help="cm/s, both loops (default 50)")
    p.add_argument("--accel", type=int, default=100, help="cm/s^2, both loops (default 100)")
    p.add_argument("--window", type=float, default=2.0, help="seconds per step (default 2)")
    p.add_argument("--hz", type=float, default=200.0, help="polls a second (default 200)")
    p.add_argument("--seed", type=natural, default=0, help="the simulated robot (default 0)")
    p.add_argument("--png", help="plot of the best responses")
    p.add_argument("--apply", action="store_true", help="write the best set (SET_FILTRE_RAW)")
    p.set_defaults(func=_command)
