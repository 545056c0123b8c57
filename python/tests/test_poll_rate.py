"""``asserv --bus N view`` and ``log`` poll POSITION, DEBUG and CHECK_BUSY at 50 Hz or more on a
100 kHz bus: checked against the bus's bytes, counted, at 9 bit times a byte (the simulated
bus's model), never against the wall clock (bench/poll_rate.py prints the figures)."""

from __future__ import annotations

import time
from typing import Any

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from smbus2 import i2c_msg

from asserv import Board, log
from asserv.sim import Simulator

BUS_HZ = 100_000


class CountingBus:
    """The simulated bus, counting an address byte per message and its data bytes."""

    def __init__(self, sim: Simulator) -> None:
        self.inner = sim.bus
        self.clock = sim
        self.bytes = 0

    def i2c_rdwr(self, *msgs: i2c_msg) -> None:
        self.bytes += sum(1 + int(m.len) for m in msgs)
        self.inner.i2c_rdwr(*msgs)

    def __getattr__(self, name: str) -> Any:
        return getattr(self.inner, name)


def _row_bytes(pec: bool) -> tuple[int, float]:
    """The bytes of one polled row, and the simulated time it took."""
    sim = Simulator(record=False)
    bus = CountingBus(sim)
    board = Board(bus, pec=pec)
    t0 = sim.time_s
    log.board_row(board, 0.0)
    return bus.bytes, sim.time_s - t0


@pytest.mark.parametrize("pec", [False, True])
def test_a_row_fits_50_times_a_second_on_a_100_khz_bus(pec: bool) -> None:
    n, took = _row_bytes(pec)
    # POSITION, DEBUG and CHECK_BUSY: each a designation written and a reply read (and PECs).
    assert 30 <= n <= 60
    # The simulated bus charges what the bytes take at 100 kHz, no more, no less.
    assert took == pytest.approx(n * 9 / BUS_HZ, abs=1e-9)
    # 50 rows a second need at most 20 ms of bus a row; there is room for 250.
    assert n * 9 / BUS_HZ <= 1 / 50
    assert n * 9 / BUS_HZ <= 1 / 250


@settings(max_examples=12, deadline=None)
@given(hz=st.floats(10, 600), pec=st.booleans(), seconds=st.floats(0.3, 1.0))
def test_polls_come_at_the_rate_asked_or_the_bus_limit(
    hz: float, pec: bool, seconds: float
) -> None:
    """On the simulated clock (the bytes' time included), rows come every 1/hz, or as fast as
    the bytes of a row allow when hz asks for more: never slower."""
    n, _ = _row_bytes(pec)
    row_s = n * 9 / BUS_HZ
    sim = Simulator(record=False)
    board = Board(sim.bus, pec=pec)
    rows = np.array(list(log.poll_board(board, hz, duration_s=seconds)), dtype=log.LOG_DTYPE)
    gaps = np.diff(rows["t_s"])
    expected = max(1 / hz, row_s)
    np.testing.assert_allclose(gaps, expected, atol=2e-6)
    assert len(rows) == pytest.approx(seconds / expected, abs=1.5)
    if hz >= 50:
        assert len(rows) / seconds >= 50 - 1 / seconds  # 50 Hz or more, as asked


def test_the_view_polls_a_board_at_50_hz_of_the_bus_clock() -> None:
    """BoardSource (``asserv --bus N view``) on the simulated 100 kHz bus: rows every 20 ms of
    the bus's clock, each with POSITION's estimate and DEBUG's values."""
    from asserv import view

    sim = Simulator(record=False)
    src = view.BoardSource(Board(sim.bus), hz=50)
    try:
        got: list[np.ndarray] = []
        while sum(len(g) for g in got) < 60:
            got.append(src.advance(0.02))
            time.sleep(0.005)  # the polling thread's turn
    finally:
        src.close()
    rows = np.concatenate(got)
    np.testing.assert_allclose(np.diff(rows["t_s"]), 0.02, atol=2e-6)
    assert not np.isnan(rows["est_x_mm"]).any() and not np.isnan(rows["duty_left"]).any()
