"""A bus transaction runs in one call into C when no timed event falls within it
(``Simulator.i2c_write``/``i2c_read``): the same steps as byte by byte, so the same trace, the
same frames and the same replies, bit for bit."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from asserv import Board
from asserv.sim import Simulator

SLOW = settings(max_examples=10, deadline=None, suppress_health_check=[HealthCheck.too_slow])


def session(batched: bool, seed: int, bus_hz: int, waits: list[int], press_at: float | None):
    sim = Simulator({"start": (0, -600, 0)}, seed, randomize=True, bus_hz=bus_hz)
    if not batched:
        sim._in_one_call = lambda n_bytes: False  # type: ignore[method-assign]
    if press_at is not None:  # a timed event, which may fall within a transaction
        sim.at(press_at, lambda s: s.press(0b1))
        sim.at(press_at + 0.05, lambda s: s.press(0))
    board = Board(sim.bus)
    board.set_vitesse_traj(80, 100)
    board.goto(400, 200)
    replies = []
    for ms in waits:
        sim.advance(ms / 1000)
        replies.append((board.check_busy(), board.position(), board.debug()))
    return sim, replies


@SLOW
@given(
    seed=st.integers(0, 2**16),
    bus_hz=st.sampled_from([10_000, 100_000, 400_000]),
    waits=st.lists(st.integers(0, 40), min_size=1, max_size=30),
    press_at=st.one_of(st.none(), st.floats(0.0, 0.3)),
)
def test_a_transaction_in_one_call_is_the_same_as_byte_by_byte(
    seed: int, bus_hz: int, waits: list[int], press_at: float | None
) -> None:
    a, ra = session(True, seed, bus_hz, waits, press_at)
    b, rb = session(False, seed, bus_hz, waits, press_at)
    assert ra == rb
    assert a.frames == b.frames
    assert np.array_equal(a.trace, b.trace)
    assert a.time_s == b.time_s


def test_an_event_within_a_transaction_runs_byte_by_byte() -> None:
    sim = Simulator({"start": (0, -600, 0)}, record=False)
    board = Board(sim.bus)
    seen: list[float] = []
    sim.at(sim.time_s + 0.0002, lambda s: seen.append(s.time_s))  # within the next poll
    assert not sim._in_one_call(4)
    board.check_busy()
    assert seen == [pytest.approx(0.0002, abs=1e-9)]
    assert sim._in_one_call(4)
