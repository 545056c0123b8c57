"""SET_TIMEOUT fed by accepted writes only (issue 28, item 5), as a property on the simulated
board: a master whose order thread writes after random gaps, under or over the timeout, while
its polling thread reads at its own period and rejected writes come between; at every poll the
order runs or has been stopped as the last accepted write says (asserv.sim.silence). The same
sessions run on the STM32 binary (harness/stm32/test_timeout.py) and on the AVR's
(harness/avr/test_avr_timeout.c); test_faults_sim.py has the fixed cases.
"""

from __future__ import annotations

import threading

from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from asserv import Board, EndReason, Status
from asserv.sim import Simulator
from asserv.sim.silence import START, TARGET, Gap, Session, play, sessions

LATE_MS = 5  # 1 kHz: the write's period, the rounding, the snapshot


@settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(s=sessions(LATE_MS), seed=st.integers(0, 10_000))
def test_only_accepted_writes_feed_the_timeout(s: Session, seed: int) -> None:
    sim = Simulator({"start": START}, seed=seed, randomize=True)
    assert play(Board(sim.bus), sim.i2c_write, s, LATE_MS) == []


def test_a_session_that_breaks_the_promise_is_caught() -> None:
    """The check can fail: a master that reads the board as idle too early (a timeout of 0, off,
    played as if it were 100 ms) sees an order that runs on after its hang."""
    sim = Simulator({"start": START})

    class Off(Board):
        def set_timeout(self, timeout_ms: int) -> None:
            super().set_timeout(0)

    problems = play(Off(sim.bus), sim.i2c_write, Session(100, (Gap(300, 20, hang=True),)), LATE_MS)
    assert any("not stopped" in p for p in problems), problems


def test_a_polling_thread_does_not_keep_a_hung_order_thread_alive() -> None:
    """Two threads on one Board, as a master runs them: the order thread sends its GOTO and
    hangs (it never writes again); the polling thread reads CHECK_BUSY and DEBUG every 10 ms
    (as `asserv view`) until the order ends. It ends 200 ms after the GOTO, PB_MOTEUR."""
    sim = Simulator({"start": START})
    board = Board(sim.bus)
    board.set_vitesse_traj(50, 100)
    board.set_timeout(200)
    sent = threading.Event()
    at: list[float] = []
    polls: list[tuple[float, Status, EndReason]] = []

    def order_thread() -> None:
        board.goto(*TARGET)
        at.append(board.now())
        sent.set()  # then it hangs

    def polling_thread() -> None:
        sent.wait()
        while True:
            t, s, d = board.now(), board.check_busy(), board.debug()
            polls.append((t, s, d.end_reason))
            if not s & Status.BUSY_TRAJET or t > at[0] + 5:
                return
            board.sleep(0.01)

    threads = [threading.Thread(target=f) for f in (order_thread, polling_thread)]
    for th in threads:
        th.start()
    for th in threads:
        th.join(30)
    t_end, status, why = polls[-1]
    assert (status, why) == (Status.PB_MOTEUR, EndReason.TIMEOUT)
    assert len(polls) > 15  # it polled all along
    assert 0.2 <= t_end - at[0] <= 0.2 + 0.6  # the timeout, then braking from 0.5 m/s
