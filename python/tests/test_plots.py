"""The run plot's helpers (asserv.plots): each order's end and outcome, contacts, the outline."""

from __future__ import annotations

import itertools
import math
from pathlib import Path

import numpy as np
from hypothesis import given
from hypothesis import strategies as st

from asserv import field, log, plots
from asserv._protocol import Status
from asserv.sim import TRACE_DTYPE

BUSY = int(Status.BUSY_TRAJET)


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
