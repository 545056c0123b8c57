"""One clock for the strategy: Board.now()/sleep() follow the bus's clock (simulated time on a
simulated bus, the wall clock on a real one), and the match timer stops the robot at its end."""

from __future__ import annotations

import contextlib
import time

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from smbus2 import i2c_msg

from asserv import Board, BoardTimeout, Status, VirtualBus, codec
from asserv.bus import SystemClock, clock_of
from asserv.driver import MatchOver
from asserv.match import MatchTimer
from asserv.sim import Simulator

SLOW = settings(max_examples=15, deadline=None, suppress_health_check=[HealthCheck.too_slow])


def test_board_now_is_the_simulated_time() -> None:
    sim = Simulator(record=False)
    board = Board(sim.bus)
    sim.advance(0.25)
    assert board.now() == sim.time_s
    board.sleep(1.5)
    assert sim.time_s == pytest.approx(1.75, abs=1e-6)


def test_a_bus_without_a_clock_gets_the_wall_clock() -> None:
    class Plain:  # what smbus2.SMBus offers
        def i2c_rdwr(self, *msgs: i2c_msg) -> None:
            pass

    board = Board(Plain())
    assert isinstance(board.clock, SystemClock)
    before = time.monotonic()
    board.sleep(0.02)
    assert board.now() - before >= 0.02


def test_clock_of_prefers_the_bus_clock() -> None:
    sim = Simulator(record=False)
    assert clock_of(sim.bus) is sim
    assert isinstance(clock_of(object()), SystemClock)


@SLOW
@given(st.lists(st.floats(min_value=0.0, max_value=0.05), min_size=1, max_size=8))
def test_sleep_advances_the_simulated_clock_by_its_argument(sleeps: list[float]) -> None:
    sim = Simulator(record=False)
    board = Board(sim.bus)
    for s in sleeps:
        before = board.now()
        board.sleep(s)
        assert board.now() - before == pytest.approx(s, abs=1e-6)


def test_sleep_rejects_bad_durations() -> None:
    board = Board(Simulator(record=False).bus)
    for bad in (-1.0, float("nan"), float("inf")):
        with pytest.raises(ValueError):
            board.sleep(bad)


def _writes_after(sim: Simulator, t: float) -> list[str]:
    names = []
    for f in sim.frames:
        if f.kind == "W" and f.t_s > t and f.data:
            names.append(codec.message(f.data[0]).name)
    return names


def test_match_timer_stops_the_robot_at_the_end_of_the_match() -> None:
    sim = Simulator()
    board = Board(sim.bus)
    reached = False
    with MatchTimer(board, duration_s=1.0) as match:
        board.goto(1000, 0)  # ~2.3 m away: longer than the match
        board.wait_idle(timeout_s=30)
        reached = True
    assert not reached
    assert match.over
    end = match.start_s + 1.0  # type: ignore[operator]
    assert sim.time_s == pytest.approx(end, abs=0.002)
    stops = [f.t_s for f in sim.frames if f.kind == "W" and f.data and f.data[0] == 12]
    assert stops and stops[0] == pytest.approx(end, abs=0.002)
    board.sleep(3.0)  # after the match: the robot comes to rest where STOP left it
    assert not board.check_busy() & Status.BUSY_TRAJET
    assert abs(sim.true_pose().x_mm - 1000) > 300
    assert board.deadline is None


def test_transactions_after_the_deadline_raise_and_stop() -> None:
    sim = Simulator(record=False)
    board = Board(sim.bus)
    timer = MatchTimer(board, duration_s=0.1, stop_on_exit=False).start()
    sim.advance(0.2)  # the strategy computed for too long without a call to the board
    with pytest.raises(MatchOver):
        board.goto(100, 0)
    with pytest.raises(MatchOver):
        board.position()
    board.stop()  # STOP always goes through
    assert timer.over


def test_a_match_timer_starts_once_and_checks_its_duration() -> None:
    board = Board(Simulator(record=False).bus)
    timer = MatchTimer(board, 1.0).start()
    with pytest.raises(RuntimeError):
        timer.start()
    for bad in (0.0, -1.0, float("nan"), float("inf")):
        with pytest.raises(ValueError):
            MatchTimer(board, bad)


def test_the_strategy_ending_early_stops_the_robot() -> None:
    sim = Simulator()
    board = Board(sim.bus)
    with MatchTimer(board, duration_s=100.0) as match:
        board.goto(1000, 0)
        board.sleep(0.3)
    assert not match.over
    assert _writes_after(sim, 0.0)[-1] == "STOP"


@SLOW
@given(
    duration=st.floats(min_value=0.01, max_value=0.6),
    poll=st.floats(min_value=0.001, max_value=0.2),
)
def test_match_timer_property_no_order_after_the_deadline(duration: float, poll: float) -> None:
    """Whatever the match length and the polling period: STOP is sent within a tick of the
    deadline, and no write but STOP reaches the board after it."""
    sim = Simulator(record=False)
    board = Board(sim.bus)
    with MatchTimer(board, duration_s=duration, stop_on_exit=False) as match:
        while True:
            board.goto(800, 300)
            with contextlib.suppress(BoardTimeout):
                board.wait_idle(timeout_s=poll)  # MatchOver at the end
    start = match.start_s
    assert start is not None
    late = [f for f in sim.frames if f.kind == "W" and f.t_s > start + duration + 0.001]
    assert all(f.data[0] == 12 for f in late)
    assert any(f.data[0] == 12 for f in sim.frames)
    assert sim.time_s <= start + duration + 0.002


def test_the_protocol_doc_example_runs_on_the_simulator() -> None:
    """docs/protocol.md 12.2's class on a simulated bus: its waits follow the simulated time."""
    import re
    from pathlib import Path

    text = (Path(__file__).resolve().parents[2] / "docs" / "protocol.md").read_text()
    section = text[text.index("### 12.2") : text.index("### 12.3")]
    code = re.findall(r"```python\n(.*?)```", section, re.S)[0]
    assert "time.sleep" not in code and "time.monotonic" not in code
    sim = Simulator(record=False)
    code = code.replace("with SMBus(1) as bus:", "with VirtualBus_ as bus:")
    env = {"__name__": "example", "VirtualBus_": sim.bus}
    exec(compile(code, "protocol.md", "exec"), env)
    assert sim.time_s > 0.5  # the GOTO ran its course in simulated time
    assert isinstance(sim.bus, VirtualBus)
