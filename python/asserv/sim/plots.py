"""Plots of a simulated run (matplotlib, written to PNG files without a display)."""

from __future__ import annotations

from collections.abc import Callable, Sequence
from pathlib import Path
from typing import TYPE_CHECKING

import matplotlib

matplotlib.use("Agg")  # files only: no display needed, on a Raspberry Pi or in CI
import matplotlib.pyplot as plt
import numpy as np
from matplotlib.axes import Axes
from matplotlib.figure import Figure
from matplotlib.patches import Circle, Polygon, Rectangle

from .._protocol import Status
from ..field import Field
from . import accuracy

if TYPE_CHECKING:
    from ..log import Outline
    from . import OdometryErrors
    from .accuracy import BenchResult, StraightRun

#: The bits that say how an order ended (docs/protocol.md): they show for as little as one tick.
END_BITS = (Status.CHOC_PANIER, Status.CHOC_BORD, Status.PB_MOTEUR, Status.PB_GRAVE)
_BUSY = int(Status.BUSY_TRAJET | Status.BUSY_GOTO_PANIER)


def outline_corners(
    x_mm: float, y_mm: float, heading_deg: float, outline: Outline
) -> list[tuple[float, float]]:
    """The four corners of the robot's rectangle at a pose, field frame, mm."""
    h = np.radians(heading_deg)
    c, s = float(np.cos(h)), float(np.sin(h))
    hl, hw = outline.length_mm / 2, outline.width_mm / 2
    out = []
    for u, v in ((hl, hw), (hl, -hw), (-hl, -hw), (-hl, hw)):
        u, v = u + outline.offset_x_mm, v + outline.offset_y_mm
        out.append((x_mm + c * u - s * v, y_mm + s * u + c * v))
    return out


def contact_rows(trace: np.ndarray) -> list[int]:
    """The ticks where the robot's outline starts touching something (a border, a basket, an
    obstacle: contact force or a shock switch), and the last tick."""
    touching = (trace["contact_force_N"] > 0) | (trace["shocks"] != 0)
    starts = np.nonzero(touching & ~np.concatenate(([False], touching[:-1])))[0]
    rows = [int(i) for i in starts]
    if len(trace) and (not rows or rows[-1] != len(trace) - 1):
        rows.append(len(trace) - 1)
    return rows


def order_ends(trace: np.ndarray) -> list[tuple[float, str]]:
    """When each order ended (the busy bits fall) and how: the end bits of that tick, or "done"
    when it has none."""
    status = trace["status"].astype(int)
    busy = (status & _BUSY) != 0
    ends = np.nonzero(~busy[1:] & busy[:-1])[0] + 1
    out = []
    for i in ends:
        bits = [str(b.name) for b in END_BITS if status[i] & b]
        out.append((float(trace["t_s"][i]), "|".join(bits) if bits else "done"))
    return out


def draw_field(ax: Axes, field: Field) -> None:
    """The table, its borders, lines and baskets, in mm (field frame)."""
    hx, hy = field.length_mm / 2, field.width_mm / 2
    ax.add_patch(
        Rectangle((-hx, -hy), field.length_mm, field.width_mm, fill=False, lw=2, color="k")
    )
    for ln in field.lines:
        ax.plot([ln.x0_mm, ln.x1_mm], [ln.y0_mm, ln.y1_mm], color="0.8", lw=1.5, zorder=0)
    for b in field.baskets:
        ax.add_patch(Circle((b.x_mm, b.y_mm), b.radius_mm, color="tab:orange", alpha=0.5))
    for o in field.obstacles:
        if o.shape == "circle":
            ax.add_patch(Circle((o.x_mm, o.y_mm), o.radius_mm, color="0.5", alpha=0.5))
        else:
            ax.add_patch(
                Rectangle(
                    (o.x_mm - o.half_x_mm, o.y_mm - o.half_y_mm),
                    2 * o.half_x_mm,
                    2 * o.half_y_mm,
                    color="0.5",
                    alpha=0.5,
                )
            )
    ax.set_aspect("equal")
    ax.set_xlim(-hx - 50, hx + 50)
    ax.set_ylim(-hy - 50, hy + 50)
    ax.set_xlabel("x [mm]")
    ax.set_ylabel("y [mm]")


def plot_run(
    trace: np.ndarray,
    field: Field,
    path: str | Path,
    *,
    title: str = "",
    targets: Sequence[tuple[float, float]] = (),
    zoom: tuple[float, float, float, float] | None = None,
    outline: Outline | None = None,
) -> Path:
    """Field with the true and estimated paths and the robot's outline where it touched something,
    speed profiles (set-point and true), the status bits with each order's end, and the
    estimate's error beside the error radius, in one PNG. ``zoom`` = (xmin, xmax, ymin, ymax)
    limits the field view; ``outline`` is the robot's rectangle (default: the nominal robot)."""
    fig = figure_run(trace, field, title=title, targets=targets, zoom=zoom, outline=outline)
    out = Path(path)
    fig.savefig(out, dpi=100)
    plt.close(fig)
    return out


def figure_run(
    trace: np.ndarray,
    field: Field,
    *,
    title: str = "",
    targets: Sequence[tuple[float, float]] = (),
    zoom: tuple[float, float, float, float] | None = None,
    outline: Outline | None = None,
) -> Figure:
    """``plot_run``'s figure, not saved: its axes in the order map, error, speed, turn rate,
    status (the caller closes it)."""
    from ..log import Outline

    outline = outline or Outline()
    fig = plt.figure(figsize=(15, 8.5), layout="constrained")
    grid = fig.add_gridspec(3, 2, width_ratios=(1.35, 1))
    ax_map = fig.add_subplot(grid[:2, 0])
    ax_err = fig.add_subplot(grid[2, 0])
    ax_v = fig.add_subplot(grid[0, 1])
    ax_w = fig.add_subplot(grid[1, 1], sharex=ax_v)
    ax_s = fig.add_subplot(grid[2, 1], sharex=ax_v)
    if title:
        fig.suptitle(title)

    t = trace["t_s"]
    draw_field(ax_map, field)
    ax_map.plot(trace["x_mm"], trace["y_mm"], color="tab:blue", lw=1.5, label="true path")
    ax_map.plot(trace["est_x_mm"], trace["est_y_mm"], "--", color="tab:red", lw=1, label="estimate")
    for i, (x, y) in enumerate(targets):
        ax_map.plot(x, y, "x", color="k", ms=8, label="GOTO target" if i == 0 else None)
    shown = ["true path", "estimate"] + (["GOTO targets"] if targets else [])
    if len(trace):
        ax_map.plot(trace["x_mm"][0], trace["y_mm"][0], "o", color="tab:green", label="start")
        shown.append("start")
        for k, i in enumerate(contact_rows(trace)):
            last = i == len(trace) - 1
            corners = outline_corners(
                float(trace["x_mm"][i]),
                float(trace["y_mm"][i]),
                float(trace["heading_deg"][i]),
                outline,
            )
            ax_map.add_patch(
                Polygon(
                    corners,
                    closed=True,
                    fill=False,
                    lw=1.2,
                    ls="-" if last else ":",
                    color="tab:blue" if last else "tab:purple",
                    label=(
                        "robot at the end" if last else "robot at a contact" if k == 0 else None
                    ),
                )
            )
        touched = len(contact_rows(trace)) > 1 or bool(
            (trace["contact_force_N"][-1:] > 0).any() or (trace["shocks"][-1:] != 0).any()
        )
        shown.append("outline at contacts and at the end" if touched else "outline at the end")
    ax_map.legend(loc="upper center", ncols=3, fontsize=8)
    ax_map.set_title("field: " + ", ".join(shown))
    if zoom is not None:
        ax_map.set_xlim(zoom[0], zoom[1])
        ax_map.set_ylim(zoom[2], zoom[3])

    err = np.hypot(trace["est_x_mm"] - trace["x_mm"], trace["est_y_mm"] - trace["y_mm"])
    ax_err.plot(t, err, color="tab:red", lw=1, label="|estimate - truth|")
    # Per axis too: a recalibration corrects one coordinate at a time.
    ax_err.plot(
        t, trace["est_x_mm"] - trace["x_mm"], ":", color="tab:purple", lw=1, label="x error"
    )
    ax_err.plot(t, trace["est_y_mm"] - trace["y_mm"], ":", color="tab:olive", lw=1, label="y error")
    ax_err.plot(
        t, trace["radius_mm"], color="k", lw=1, drawstyle="steps-post", label="error radius"
    )
    ax_err.set_ylabel("[mm]")
    ax_err.set_xlabel("time [s]")
    ax_err.legend(loc="upper left")
    ax_err.set_title("error of the estimate (total, x, y) and the error radius the board reports")

    ax_v.plot(t, trace["v_set_mm_s"], color="k", lw=1, label="set-point")
    ax_v.plot(t, trace["v_mm_s"], color="tab:blue", lw=1, label="true")
    ax_v.set_ylabel("speed [mm/s]")
    ax_v.legend(loc="upper right")
    ax_v.set_title("speed and turn rate: set point and true")
    ax_w.plot(t, trace["omega_set_deg_s"], color="k", lw=1, label="set-point")
    ax_w.plot(t, trace["omega_deg_s"], color="tab:blue", lw=1, label="true")
    ax_w.set_ylabel("turn rate [deg/s]")
    ax_w.legend(loc="upper right")

    _plot_status(ax_s, trace)
    return fig


def _plot_status(ax: Axes, trace: np.ndarray) -> None:
    """One row per status bit that was ever set (a bar while set, a tick where it rose, so that
    a bit set for one tick shows), and a row with each order's end and its outcome."""
    t = trace["t_s"]
    status = trace["status"].astype(int)
    shown = [s for s in Status if s.name and (status & s).any()]
    for i, bit in enumerate(shown):
        on = (status & bit) != 0
        color = f"C{i}"
        ax.fill_between(t, i + 0.1, i + 0.9, where=on, step="post", alpha=0.7, color=color)
        rises = np.nonzero(on & ~np.concatenate(([False], on[:-1])))[0]
        ax.plot(t[rises], np.full(len(rises), i + 0.5), "|", ms=14, mew=2, color=color)
    ends = order_ends(trace)
    row = len(shown)
    for te, what in ends:
        ax.plot(te, row + 0.5, "v", color="k", ms=7)
        ax.annotate(
            what,
            (te, row + 0.5),
            xytext=(-3, 6),
            textcoords="offset points",
            ha="right",
            fontsize=8,
        )
    labels = [str(s.name) for s in shown] + (["order ends"] if ends else [])
    ax.set_yticks([i + 0.5 for i in range(len(labels))], labels)
    ax.set_ylim(0, max(1, len(labels)) + (0.4 if ends else 0))
    ax.set_xlabel("time [s]")
    ax.set_title("status bits (|: set) and each order's end with its outcome")


_CONTROLLER_STYLE = {
    "legacy": ("legacy P-only", "tab:red"),
    "asserv": ("asserv, nominal odometry", "tab:blue"),
    "calibrated": ("asserv, calibrated", "tab:green"),
}


def plot_accuracy(res: BenchResult, out_dir: Path) -> list[Path]:
    """The accuracy bench's figures (asserv.sim.accuracy): distributions over the robots, one
    robot's runs at the top speed, and the calibration before and after. Returns the files."""
    out_dir.mkdir(parents=True, exist_ok=True)
    files = [_plot_accuracy_figures(res, out_dir / "accuracy.png")]
    if res.examples:
        files.append(_plot_accuracy_example(res, out_dir / "accuracy-run.png"))
    if any(r.after is not None for r in res.robots):
        files.append(_plot_calibration(res, out_dir / "calibration.png"))
    return files


def _plot_accuracy_figures(res: BenchResult, path: Path) -> Path:
    fig, axs = plt.subplots(2, 2, figsize=(14, 9), layout="constrained")
    fig.suptitle(
        f"asserv bench accuracy: {len(res.robots)} robots, 1.8 m straight, 1 m/s^2"
        " (boxes: quartiles, whiskers 5-95 %)"
    )
    ctls = [c for c in _CONTROLLER_STYLE if any(res.runs(c, v) for v in res.speeds)]

    def panel(
        ax: Axes,
        value: Callable[[StraightRun], float],
        *,
        log: bool,
        goal: float,
        spec: tuple[float, str] | None,
        ylabel: str,
        title: str,
    ) -> None:
        """Boxes per speed and controller, the goal (dotted) and the specification (dashed)."""
        width = 0.8 / len(ctls)
        for i, c in enumerate(ctls):
            label, color = _CONTROLLER_STYLE[c]
            data = [[value(r) for r in res.runs(c, v) if r.finished] for v in res.speeds]
            pos = [k + (i - (len(ctls) - 1) / 2) * width for k in range(len(res.speeds))]
            bp = ax.boxplot(
                data,
                positions=pos,
                widths=width * 0.9,
                whis=(5, 95),
                showfliers=False,
                patch_artist=True,
            )
            for b in bp["boxes"]:
                b.set_facecolor(color)
                b.set_alpha(0.6)
            ax.plot([], [], "s", color=color, alpha=0.6, label=label)
        ax.set_xticks(range(len(res.speeds)), [f"{v / 100:.1f} m/s" for v in res.speeds])
        if log:
            ax.set_yscale("log")
        ax.axhline(goal, color="tab:green", ls=":", lw=1)
        if spec is not None:
            ax.axhline(spec[0], color="k", ls="--", lw=1)
            ax.text(
                0.99,
                spec[0] * 1.03,
                spec[1],
                fontsize=8,
                ha="right",
                transform=ax.get_yaxis_transform(),
            )
        ax.grid(True, axis="y", alpha=0.3)
        ax.legend(loc="upper left", fontsize=8)
        ax.set_ylabel(ylabel)
        ax.set_title(title)

    panel(
        axs[0, 0],
        lambda r: max(r.arrival_est_mm, 1e-3),
        log=True,
        goal=2.0,
        spec=(70.0, "spec 2002: +/-70 mm at 1 m/s"),
        ylabel="|target - estimate| when finished [mm]",
        title="arrival error, as the board knows it",
    )
    panel(
        axs[0, 1],
        lambda r: r.odometry_own_mm,
        log=False,
        goal=5.0,
        spec=(20.0, "spec 2002: +/-20 mm"),
        ylabel="|estimate - truth|, start error taken out [mm]",
        title="odometry error over 1.8 m",
    )
    panel(
        axs[1, 0],
        lambda r: r.time_s / accuracy.time_bound_s(r.speed_cm_s),
        log=False,
        goal=1.05,
        spec=None,
        ylabel="trajectory time / time-optimal bound",
        title="time until the board reports the move finished",
    )

    ax = axs[1, 1]
    v = max(res.speeds)
    for c in ("asserv", "calibrated"):
        runs = [r for r in res.runs(c, v) if r.finished]
        if not runs:
            continue
        label, color = _CONTROLLER_STYLE[c]
        ax.scatter(
            [r.radius_mm for r in runs],
            [r.odometry_own_mm for r in runs],
            s=10,
            color=color,
            alpha=0.6,
            label=label,
        )
    lim = ax.get_xlim()[1]
    ax.plot([0, lim], [0, lim], color="k", lw=1, label="error = radius")
    ax.set_xlabel("error radius reported when finished [mm]")
    ax.set_ylabel("true odometry error [mm]")
    ax.set_title(f"error radius against the true error ({v / 100:.1f} m/s)")
    ax.legend(loc="upper left", fontsize=8)
    fig.savefig(path, dpi=90)
    plt.close(fig)
    return path


def _plot_accuracy_example(res: BenchResult, path: Path) -> Path:
    fig, (ax_v, ax_l, ax_e) = plt.subplots(3, 1, figsize=(11, 10), layout="constrained")
    rob = res.robots[0]
    fig.suptitle(
        f"robot {rob.seed}, the 1.8 m straight at {max(res.speeds) / 100:.1f} m/s\n"
        f"{rob.description}",
        fontsize=10,
    )
    for c, tr in res.examples.items():
        label, color = _CONTROLLER_STYLE[c]
        busy = (tr["status"].astype(int) & Status.BUSY_TRAJET) != 0
        idx = np.nonzero(busy)[0]
        if not len(idx):
            continue
        i0 = idx[0]
        i1 = i0 + int(np.argmin(busy[i0:])) if not busy[i0:].all() else len(tr) - 1
        seg = tr[i0 : min(len(tr), i1 + 300)]
        t = seg["t_s"] - seg["t_s"][0]
        ax_v.plot(t, seg["v_set_mm_s"], color=color, lw=1, ls="--")
        ax_v.plot(t, seg["v_mm_s"], color=color, lw=1.2, label=f"{label} (dashed: set point)")
        ax_l.plot(t, accuracy.following_lag_mm(seg), color=color, lw=1.2, label=label)
        err = np.hypot(seg["est_x_mm"] - accuracy.TARGET[0], seg["est_y_mm"] - accuracy.TARGET[1])
        ax_e.plot(t, err, color=color, lw=1.2, label=label)
        te = t[i1 - i0]
        for ax in (ax_v, ax_l, ax_e):
            ax.axvline(te, color=color, lw=0.8, ls=":")
    ax_v.set_ylabel("speed [mm/s]")
    ax_v.legend(loc="upper right", fontsize=8)
    ax_v.set_title("speed (dotted lines: when the board reports the move finished)")
    ax_l.set_ylabel("set point - estimate [mm]")
    ax_l.set_title("lag behind the set point: v / Kp for P-only")
    ax_l.legend(loc="upper right", fontsize=8)
    ax_e.set_yscale("log")
    ax_e.set_ylim(1e-2, 3e3)
    ax_e.set_ylabel("|target - estimate| [mm]")
    ax_e.set_xlabel("time since the GOTO [s]")
    ax_e.set_title("distance to the target, as the board sees it")
    ax_e.legend(loc="upper right", fontsize=8)
    fig.savefig(path, dpi=90)
    plt.close(fig)
    return path


def _plot_calibration(res: BenchResult, path: Path) -> Path:
    ok = [r for r in res.robots if r.after is not None and r.before is not None]
    fig, axs = plt.subplots(1, 3, figsize=(15, 4.8), layout="constrained")
    fig.suptitle(f"odometry calibration on {len(ok)} robots: before (grey) and after (green)")
    items: list[tuple[str, Callable[[OdometryErrors], float], float]] = [
        ("wheel ratio error [%]", lambda e: e.ratio * 100, 0.05),
        ("track error [mm]", lambda e: e.track_mm, 0.1),
        ("wheel scale error [%]", lambda e: e.scale * 100, 0.0),
    ]
    for ax, (name, f, goal) in zip(axs, items, strict=True):
        before = [f(r.before) for r in ok if r.before is not None]
        after = [f(r.after) for r in ok if r.after is not None]
        lo, hi = min(before + after), max(before + after)
        bins = np.linspace(lo, hi, 60)
        ax.hist(before, bins=bins, color="0.6", label="before")
        ax.hist(after, bins=bins, color="tab:green", label="after")
        if goal:
            for g in (-goal, goal):
                ax.axvline(g, color="k", ls=":", lw=1)
        ax.set_xlabel(name)
        ax.set_ylabel("robots")
        ax.legend(fontsize=8)
    fig.savefig(path, dpi=90)
    plt.close(fig)
    return path
