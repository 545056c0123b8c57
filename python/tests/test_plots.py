"""The run plot's helpers (asserv.sim.plots): each order's end and outcome, contacts, outline."""

from __future__ import annotations

import itertools
import math
from pathlib import Path

import matplotlib.pyplot as plt
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from matplotlib.axes import Axes
from matplotlib.figure import Figure
from matplotlib.patches import Polygon

from asserv import field, log
from asserv._protocol import Status
from asserv.sim import TRACE_DTYPE, plots

BUSY = int(Status.BUSY_TRAJET)
ROOT = Path(__file__).resolve().parents[2]


def _trace(status: list[int], contact: list[float] | None = None) -> np.ndarray:
    tr = np.zeros(len(status), dtype=TRACE_DTYPE)
    tr["t_s"] = np.arange(len(status)) * 0.001
    tr["status"] = status
    if contact is not None:
        tr["contact_force_N"] = contact
    return tr


def test_an_end_bit_of_one_tick_is_the_outcome() -> None:
    tr = _trace([0, BUSY, BUSY, 0, 0, BUSY, BUSY, int(Status.CHOC_PANIER), 0])
    assert plots.order_ends(tr) == [(0.003, "done"), (0.007, "CHOC_PANIER")]


@given(st.lists(st.sampled_from([0, BUSY, BUSY | 4, 8, 16, 32, 16 | 32]), max_size=60))
def test_every_fall_of_busy_is_one_end(status: list[int]) -> None:
    tr = _trace(status)
    ends = plots.order_ends(tr)
    falls = sum(1 for a, b in itertools.pairwise(status) if a & 6 and not b & 6)
    assert len(ends) == falls
    for t, what in ends:
        s = status[round(t * 1000)]
        named = [b.name for b in plots.END_BITS if s & b]
        assert what == ("|".join(str(n) for n in named) if named else "done")


def test_contacts_start_where_the_force_rises() -> None:
    tr = _trace([0] * 8, [0, 0, 5, 6, 0, 0, 3, 0])
    assert plots.contact_rows(tr) == [2, 6, 7]


@given(
    st.floats(-2000, 2000),
    st.floats(-2000, 2000),
    st.floats(-360, 360),
    st.floats(10, 500),
    st.floats(10, 500),
)
def test_outline_is_the_rectangle_at_the_pose(
    x: float, y: float, h: float, length: float, width: float
) -> None:
    c = plots.outline_corners(x, y, h, log.Outline(length, width))
    cx = sum(p[0] for p in c) / 4
    cy = sum(p[1] for p in c) / 4
    assert math.isclose(cx, x, abs_tol=1e-6) and math.isclose(cy, y, abs_tol=1e-6)
    assert math.isclose(math.dist(c[0], c[1]), width, rel_tol=1e-9)
    assert math.isclose(math.dist(c[1], c[2]), length, rel_tol=1e-9)
    # The front edge (corners 0 and 1) is ahead along the heading.
    fx, fy = (c[0][0] + c[1][0]) / 2 - x, (c[0][1] + c[1][1]) / 2 - y
    h_rad = math.radians(h)
    assert math.isclose(fx * math.cos(h_rad) + fy * math.sin(h_rad), length / 2, rel_tol=1e-6)


def test_plot_run_writes_a_png(tmp_path: Path) -> None:
    tr = _trace([0, BUSY, BUSY, int(Status.CHOC_BORD), 0], [0, 0, 0, 4, 4])
    out = plots.plot_run(tr, field.load(), tmp_path / "run.png", targets=[(1, 2)])
    assert out.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


# What the run's PNG shows (issue 20, section 4), on its figure -------------------------------


def _status_axis(fig: Figure) -> Axes:
    return fig.axes[4]


def test_an_end_bit_of_one_tick_shows_in_its_row_and_as_the_outcome() -> None:
    """An end bit lasts one tick (1 ms of a 5 s plot): a mark where it rises on its own row, and
    the order's end named by it."""
    status = [0] * 100 + [BUSY] * 4800 + [int(Status.CHOC_BORD)] + [0] * 99
    fig = plots.figure_run(_trace(status), field.load())
    try:
        ax = _status_axis(fig)
        rows = [t.get_text() for t in ax.get_yticklabels()]
        assert rows == ["BUSY_TRAJET", "CHOC_BORD", "order ends"]
        t_end = 4.9
        marks = [ln for ln in ax.get_lines() if ln.get_marker() == "|"]
        at_row = {
            round(float(y) - 0.5): [float(x) for x in ln.get_xdata()]
            for ln in marks
            for y in set(ln.get_ydata())
        }
        assert at_row[1] == [pytest.approx(t_end)]  # CHOC_BORD's row: its one tick
        ends = [(float(a.xy[0]), a.get_text()) for a in ax.texts]
        assert ends == [(pytest.approx(t_end), "CHOC_BORD")]
    finally:
        plt.close(fig)


def _distance_to_polygon(px: float, py: float, corners: np.ndarray) -> float:
    best = math.inf
    for (ax_, ay), (bx, by) in itertools.pairwise([*corners, corners[0]]):
        dx, dy = bx - ax_, by - ay
        u = max(0.0, min(1.0, ((px - ax_) * dx + (py - ay) * dy) / (dx * dx + dy * dy)))
        best = min(best, math.hypot(px - ax_ - u * dx, py - ay - u * dy))
    return best


def test_the_outline_touches_the_basket_the_annex_robot_hits() -> None:
    """The path is the encoder axis midpoint, half a robot behind what it touched; the outline
    drawn at the contact reaches the basket."""
    from asserv import scenario

    res = scenario.play(scenario.load(ROOT / "scenarios" / "annex.txt"))
    tr, fld = res.sim.trace, res.sim.field
    fig = plots.figure_run(tr, fld, outline=log.Outline.of(res.sim))
    try:
        polys = [p for p in fig.axes[0].patches if isinstance(p, Polygon)]
        assert len(polys) == len(plots.contact_rows(tr)) >= 2
        gaps = [
            min(
                _distance_to_polygon(b.x_mm, b.y_mm, p.get_xy()[:4]) - b.radius_mm
                for b in fld.baskets
            )
            for p in polys
        ]
        assert min(gaps) == pytest.approx(0, abs=3)  # the outline at the basket's edge
        path_gap = min(
            math.hypot(tr["x_mm"][-1] - b.x_mm, tr["y_mm"][-1] - b.y_mm) - b.radius_mm
            for b in fld.baskets
        )
        assert path_gap > 100  # what the path alone would have suggested
    finally:
        plt.close(fig)


def test_the_outline_touches_the_border_the_robot_squares_on() -> None:
    """recal_border: the robot backs into the south border, then drives off; the outline at
    that contact (not at the end) reaches the border."""
    from asserv import scenario

    res = scenario.play(scenario.load(ROOT / "scenarios" / "recal_border.txt"))
    tr, fld = res.sim.trace, res.sim.field
    fig = plots.figure_run(tr, fld, outline=log.Outline.of(res.sim))
    try:
        polys = [p for p in fig.axes[0].patches if isinstance(p, Polygon)]
        rows = plots.contact_rows(tr)
        assert len(polys) == len(rows) >= 2
        first = polys[0].get_xy()[:4]
        assert rows[0] < len(tr) - 1 and polys[0].get_linestyle() == ":"
        assert first[:, 1].min() == pytest.approx(-fld.width_mm / 2, abs=3)
        assert tr["y_mm"][rows[0]] > -fld.width_mm / 2 + 50  # the path point stays off it
    finally:
        plt.close(fig)


_TITLE_TO_LABELS = {
    "true path": {"true path"},
    "estimate": {"estimate"},
    "GOTO targets": {"GOTO target"},
    "start": {"start"},
    "outline at the end": {"robot at the end"},
    "outline at contacts and at the end": {"robot at the end"},
}


@settings(max_examples=15, deadline=None)
@given(
    status=st.lists(st.sampled_from([0, BUSY, int(Status.CHOC_PANIER)]), min_size=1, max_size=30),
    contact=st.lists(st.sampled_from([0.0, 0.0, 3.0]), min_size=30, max_size=30),
    targets=st.lists(st.tuples(st.floats(-1000, 1000), st.floats(-800, 800)), max_size=3),
)
def test_the_field_title_names_only_what_is_drawn(
    status: list[int], contact: list[float], targets: list[tuple[float, float]]
) -> None:
    tr = _trace(status, contact[: len(status)])
    fig = plots.figure_run(tr, field.load(), targets=targets)
    try:
        ax = fig.axes[0]
        title = ax.get_title().removeprefix("field: ").split(", ")
        labels = {h.get_label() for h in ax.get_legend().legend_handles}
        drawn = set().union(*(_TITLE_TO_LABELS[t] for t in title))
        assert drawn <= labels, (title, labels)
        assert ("GOTO targets" in title) == bool(targets)
        touched = bool((tr["contact_force_N"] > 0).any())
        assert ("outline at contacts and at the end" in title) == touched
        polys = [p for p in ax.patches if isinstance(p, Polygon)]
        assert len(polys) == len(plots.contact_rows(tr))
        for poly, i in zip(polys, plots.contact_rows(tr), strict=True):  # at each contact
            want = plots.outline_corners(
                float(tr["x_mm"][i]),
                float(tr["y_mm"][i]),
                float(tr["heading_deg"][i]),
                log.Outline(),
            )
            np.testing.assert_allclose(poly.get_xy()[:4], want, atol=1e-9)
    finally:
        plt.close(fig)
