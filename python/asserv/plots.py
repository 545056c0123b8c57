"""Plots of a simulated run (matplotlib, written to PNG files without a display)."""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import matplotlib

matplotlib.use("Agg")  # files only: no display needed, on a Raspberry Pi or in CI
import matplotlib.pyplot as plt
import numpy as np
from matplotlib.axes import Axes
from matplotlib.patches import Circle, Rectangle

from ._protocol import Status
from .field import Field


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
) -> Path:
    """Field with the true and estimated paths, speed profiles (set-point and true) and the
    status over time, and the estimate's error beside the error radius, in one PNG.
    ``zoom`` = (xmin, xmax, ymin, ymax) limits the field view."""
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
    for x, y in targets:
        ax_map.plot(x, y, "x", color="k", ms=8)
    if len(trace):
        ax_map.plot(trace["x_mm"][0], trace["y_mm"][0], "o", color="tab:green", label="start")
    ax_map.legend(loc="upper center", ncols=3)
    ax_map.set_title("field: true path and the board's estimate (x: GOTO targets)")
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
    ax_err.set_title("position error of the estimate, and the radius the board reports")

    ax_v.plot(t, trace["v_set_mm_s"], color="k", lw=1, label="set-point")
    ax_v.plot(t, trace["v_mm_s"], color="tab:blue", lw=1, label="true")
    ax_v.set_ylabel("speed [mm/s]")
    ax_v.legend(loc="upper right")
    ax_v.set_title("speed profiles")
    ax_w.plot(t, trace["omega_set_deg_s"], color="k", lw=1, label="set-point")
    ax_w.plot(t, trace["omega_deg_s"], color="tab:blue", lw=1, label="true")
    ax_w.set_ylabel("turn rate [deg/s]")
    ax_w.legend(loc="upper right")

    status = trace["status"].astype(int)
    shown = [s for s in Status if s.name and (status & s).any()]
    for i, bit in enumerate(shown):
        on = (status & bit) != 0
        ax_s.fill_between(t, i + 0.1, i + 0.9, where=on, step="post", alpha=0.7)
    ax_s.set_yticks([i + 0.5 for i in range(len(shown))], [str(s.name) for s in shown])
    ax_s.set_ylim(0, max(1, len(shown)))
    ax_s.set_xlabel("time [s]")
    ax_s.set_title("status bits")

    out = Path(path)
    fig.savefig(out, dpi=100)
    plt.close(fig)
    return out
