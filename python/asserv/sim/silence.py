"""A master whose order thread hangs while its polling thread lives on (issue 28, item 5): the
sessions that ``python/tests/test_timeout_sim.py`` plays on the simulator and
``harness/stm32/test_timeout.py`` on the STM32 binary, and the promise every poll checks.

A session: SET_TIMEOUT of ``timeout_ms``, then a slow GOTO that outlasts it, then the order
thread's accepted writes (HEARTBEAT, or a setting sent again), each after a gap; the session
ends with a gap longer than the timeout (the order thread hangs) or after the last write. In
every gap the polling thread reads (CHECK_BUSY, then DEBUG: its designation is a write too) at
its own period, and the master sends writes the board rejects (a frame cut short). Only the
accepted writes feed the timeout (docs/protocol.md 5.7), so at every poll, ``t`` ms after the
last accepted write:

- ``t < timeout_ms - EARLY_MS``: the order runs (BUSY_TRAJET, not STOPPING, no PB_MOTEUR);
- ``t >= timeout_ms + late_ms``: it has been stopped: STOPPING while it brakes, then at rest
  PB_MOTEUR with DEBUG end_reason TIMEOUT, never the ``00`` of a finished order.

``late_ms`` is what the target adds between the timeout and the poll that sees it: the write
taken at the next planner period, the timeout rounded up to periods, the snapshot published a
tick later (a few ms at 1 kHz). After a hang the master's next order runs again.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import TYPE_CHECKING

from .._protocol import EndReason, OrderState, Status
from ..driver import Board

if TYPE_CHECKING:
    from hypothesis.strategies import SearchStrategy

__all__ = ["BUS_MS", "EARLY_MS", "Gap", "Session", "play", "sessions"]

#: A poll this close under the timeout may already see it (a write's bus time).
EARLY_MS = 2
SPEED_CM_S = 20  # the GOTO: 1.7 m at 0.2 m/s, over 8 s, longer than any session
START = (-900, -300, 0)
TARGET = (800, -300)
#: A poll's transactions take about this long at 100 kHz (DEBUG's 22 bytes).
BUS_MS = 4
#: A write the board rejects (SET_TIMEOUT cut short: BAD_LENGTH); it must not feed the timeout.
CUT_SHORT = bytes([15, 0x01])


@dataclass(frozen=True)
class Gap:
    """From one accepted write to the next: ``ms`` long; the polling thread reads every
    ``poll_ms`` from ``poll_phase_ms`` on; rejected writes at ``rejected_ms`` into it; the
    write that ends it (``setting``: SET_VITESSE_TRAJ again, else HEARTBEAT), none for a
    hang."""

    ms: int
    poll_ms: int
    poll_phase_ms: int = 0
    rejected_ms: tuple[int, ...] = ()
    setting: bool = False
    hang: bool = False


@dataclass(frozen=True)
class Session:
    timeout_ms: int
    gaps: tuple[Gap, ...]  # a hang, if any, is the last

    def __post_init__(self) -> None:
        if not 1 <= self.timeout_ms <= 65535:
            raise ValueError(f"Session: timeout_ms={self.timeout_ms} must be 1..65535")
        for i, g in enumerate(self.gaps):
            if g.hang and i != len(self.gaps) - 1:
                raise ValueError("Session: only the last gap may be a hang")
            if g.ms < 1 or g.poll_ms < 1 or g.poll_phase_ms < 0:
                raise ValueError(f"Session: gap {i}: ms, poll_ms must be >= 1, phase >= 0")


def sessions(
    late_ms: int,
    max_timeout_ms: int = 600,
    max_writes: int = 8,
    max_hang_ms: int = 400,
    max_poll_ms: int = 60,
    max_rejected: int = 3,
) -> SearchStrategy[Session]:
    """The hypothesis strategy of sessions that the tests play (hypothesis, a test dependency,
    is imported here only): a timeout of 50 to ``max_timeout_ms``, up to ``max_writes`` gaps
    under it, then maybe a hang of ``late_ms`` + 10 to ``max_hang_ms`` over it; polls every 5
    to ``max_poll_ms`` ms, up to ``max_rejected`` rejected writes a gap."""
    from hypothesis import strategies as st

    @st.composite
    def draw_session(draw: st.DrawFn) -> Session:
        timeout = draw(st.integers(50, max_timeout_ms))
        n = draw(st.integers(0, max_writes))
        hang = draw(st.booleans())
        gaps = []
        for i in range(n + hang):
            is_hang = i == n
            ms = (
                draw(st.integers(timeout + late_ms + 10, timeout + max_hang_ms))
                if is_hang
                else draw(st.integers(1, timeout - 8))
            )
            poll = draw(st.integers(5, max_poll_ms))
            gaps.append(
                Gap(
                    ms,
                    poll,
                    draw(st.integers(0, poll - 1)),
                    tuple(draw(st.lists(st.integers(0, ms), max_size=max_rejected))),
                    draw(st.booleans()),
                    is_hang,
                )
            )
        return Session(timeout, tuple(gaps))

    return draw_session()


def play(
    board: Board, write_raw: Callable[[bytes, bool], None], s: Session, late_ms: float
) -> list[str]:
    """Play ``s`` on the board at rest at ``START`` (``write_raw(data, stop)``: the device's
    raw write, for the rejected frames). Returns what broke the promise, one line each (empty:
    kept)."""
    problems: list[str] = []

    def poll(last: float) -> None:
        t = (board.now() - last) * 1000
        status = board.check_busy() & ~Status.COMMANDE_REJETEE
        t_debug = (board.now() - last) * 1000
        d = board.debug()
        if t < s.timeout_ms - EARLY_MS and status != Status.BUSY_TRAJET:
            problems.append(f"{t:.1f} ms after a write: status {status!r}, not running")
        if t_debug < s.timeout_ms - EARLY_MS and (
            d.order_state == OrderState.STOPPING or d.end_reason == EndReason.TIMEOUT
        ):  # DEBUG is the plain snapshot: IDLE until the GOTO is taken
            problems.append(f"{t_debug:.1f} ms after a write: order state {d.order_state!r}")
        if t >= s.timeout_ms + late_ms and not (
            status == Status.PB_MOTEUR or status & Status.BUSY_TRAJET
        ):
            problems.append(f"{t:.1f} ms after a write: status {status!r}, not stopped")
        if t_debug >= s.timeout_ms + late_ms and not (
            d.order_state == OrderState.STOPPING
            or (d.order_state == OrderState.IDLE and d.end_reason == EndReason.TIMEOUT)
        ):
            problems.append(
                f"{t_debug:.1f} ms after a write: {d.order_state!r}, {d.end_reason!r}: not"
                " stopped by the timeout"
            )

    board.set_vitesse_traj(SPEED_CM_S, 100)
    board.set_timeout(s.timeout_ms)
    board.goto(*TARGET)
    last = board.now()
    for g in s.gaps:
        events = [(ms, True) for ms in range(g.poll_phase_ms, g.ms, g.poll_ms)]
        events += [(ms, False) for ms in g.rejected_ms if ms < g.ms]
        for at_ms, is_poll in sorted(events):
            if not g.hang and board.now() >= last + (g.ms - BUS_MS) / 1000:
                break  # the polls ran late: the write keeps its time
            board.sleep(max(0.0, last + at_ms / 1000 - board.now()))
            if is_poll:
                poll(last)
            else:
                write_raw(CUT_SHORT, True)
        board.sleep(max(0.0, last + g.ms / 1000 - board.now()))
        if g.hang:
            poll(last)
            end = board.wait_idle(10) & ~Status.COMMANDE_REJETEE
            d = board.debug()
            if end != Status.PB_MOTEUR or d.end_reason != EndReason.TIMEOUT:
                problems.append(f"after a hang: status {end!r}, {d.end_reason!r}")
            board.goto(*START[:2])  # the next order runs, PB_MOTEUR cleared
            status = board.check_busy()
            if status & Status.PB_MOTEUR or not status & Status.BUSY_TRAJET:
                problems.append(f"the order after a hang: status {status!r}")
            board.stop()
            return problems
        if g.setting:
            board.set_vitesse_traj(SPEED_CM_S, 100)
        else:
            board.heartbeat()
        last = board.now()
    poll(last)
    board.stop()
    return problems
