"""Resets that say so (issue 28, item 4), on the simulated board: a brown-out, a watchdog, a
reset pin or a software reset at any moment of a GOTO, with the RAM kept or scrambled. The master
learns of it at its next poll, idle or not (PB_MOTEUR, DEBUG end_reason RESET, RESET_INFO's cause
and count), and the pose is kept within the radius, or refused, never silently wrong. A power-on
is as before. The emulators' tests of the ports' own reset causes are in harness/avr and
harness/stm32 (docs/failure-model.md says which are done).
"""

from __future__ import annotations

import math

import pytest
from hypothesis import HealthCheck, Phase, event, given, settings
from hypothesis import strategies as st

from asserv import Board, EndReason, OrderRejected, Reject, ResetCause, ResetInfo, Status
from asserv.sim import Simulator

CAUSES = [c for c in ResetCause if c != ResetCause.POWER_ON]


def started(seed: int) -> tuple[Simulator, Board]:
    sim = Simulator(seed=seed, randomize=True, start_uncertainty=(3, 0.5))
    board = Board(sim.bus)
    board.set_vitesse_traj(100, 100)
    board.set_vitesse_rot(50, 100)
    return sim, board


def error_mm(sim: Simulator, board: Board) -> float:
    p, t = board.position(), sim.true_pose()
    return math.hypot(p.x_mm - t.x_mm, p.y_mm - t.y_mm)


@settings(
    max_examples=25,
    deadline=None,
    derandomize=True,
    phases=[Phase.explicit, Phase.generate],
    suppress_health_check=[HealthCheck.too_slow],
)
@given(
    seed=st.integers(0, 10_000),
    at_s=st.floats(0.05, 2.5),
    cause=st.sampled_from(CAUSES),
    keep_ram=st.booleans(),
    down_ms=st.integers(0, 200),
    twice=st.booleans(),
)
def test_a_reset_mid_goto_is_reported_and_the_pose_kept_or_refused(
    seed: int, at_s: float, cause: ResetCause, keep_ram: bool, down_ms: int, twice: bool
) -> None:
    sim, board = started(seed)
    board.goto(-200, -500)
    sim.advance(at_s)
    sim.reset(cause, keep_ram=keep_ram, down_ms=down_ms)
    if twice:  # a second reset before the master polls: the count says so
        sim.advance(0.05)
        sim.reset(cause, keep_ram=True, down_ms=0)
    # The master's next poll.
    status = board.check_busy()
    info = board.reset_info()
    assert info.cause == cause
    assert info.count == (1 + twice if keep_ram or twice else 1)
    assert info.pose_lost == (not keep_ram)
    assert status & Status.PB_MOTEUR and not status & Status.BUSY_TRAJET
    assert board.debug().end_reason == EndReason.RESET
    if keep_ram:
        # Kept: the estimate within the radius, now and after the robot has come to rest.
        assert error_mm(sim, board) <= board.position().radius_mm
        sim.advance(1.0)
        assert error_mm(sim, board) <= board.position().radius_mm
        board.goto(-200, -500)  # and the next order runs
        assert board.wait_idle(20) == 0
        assert error_mm(sim, board) <= board.position().radius_mm
    else:
        # Lost: the radius says nothing is known, and motion orders wait for the master.
        assert board.position().radius_mm == 255
        sim.advance(1.0)  # the robot, motors off, coasts to rest
        with pytest.raises(OrderRejected) as e:
            board.goto(0, 0)
        assert e.value.reason == Reject.REFUSED_NO_POSE
        board.stop()  # STOP is always taken
        t = sim.true_pose()
        board.declare_pose(round(t.x_mm), round(t.y_mm), round(t.heading_deg))
        board.goto(-200, -500)
        assert board.wait_idle(20) == 0
        assert not board.reset_info().pose_lost


@settings(
    max_examples=30,
    deadline=None,
    derandomize=True,
    phases=[Phase.explicit, Phase.generate],
    suppress_health_check=[HealthCheck.too_slow],
)
@given(
    seed=st.integers(0, 10_000),
    order=st.sampled_from([None, (-200, -500), (0, -750)]),
    at_s=st.floats(0.0, 4.0),
    cause=st.sampled_from(CAUSES),
    keep_ram=st.booleans(),
    down_ms=st.integers(0, 200),
)
def test_any_reset_but_a_power_on_shows_at_the_first_poll(
    seed: int,
    order: tuple[int, int] | None,
    at_s: float,
    cause: ResetCause,
    keep_ram: bool,
    down_ms: int,
) -> None:
    """At a random moment, idle (no order yet, or one finished) or moving, RAM kept or
    scrambled: the master's first CHECK_BUSY after the reset reads PB_MOTEUR, not busy, and
    RESET_INFO names the cause, so a master that only polls learns that its settings are back
    at their power-on values. It reads so until the next order: the settings sent again do not
    clear it, the order does."""
    sim, board = started(seed)
    board.set_timeout(500)  # settings the reset will undo
    board.heartbeat()
    if order is not None:
        board.goto(*order)
    left = at_s
    while left > 0:  # the master alive until the reset
        sim.advance(min(0.2, left))
        board.heartbeat()
        left -= 0.2
    before = board.check_busy()
    assert not before & Status.PB_MOTEUR  # nothing ended badly before the reset
    busy = bool(before & Status.BUSY_TRAJET)
    event("moving" if busy else "idle, no order yet" if order is None else "idle, order done")
    sim.reset(cause, keep_ram=keep_ram, down_ms=down_ms)

    status = board.check_busy()  # the master's first poll
    assert status & Status.PB_MOTEUR and not status & Status.BUSY_TRAJET, status
    info = board.reset_info()
    assert (info.cause, info.count, info.pose_lost) == (cause, 1, not keep_ram)
    assert board.debug().end_reason == EndReason.RESET

    # The master sends its settings again: the reset still shows, until the next order.
    board.set_vitesse_traj(100, 100)
    board.set_vitesse_rot(50, 100)
    board.set_timeout(500)
    if not keep_ram:
        t = sim.true_pose()
        board.declare_pose(round(t.x_mm), round(t.y_mm), round(t.heading_deg))
    sim.advance(0.1)
    assert board.check_busy() & Status.PB_MOTEUR
    assert board.debug().end_reason == EndReason.RESET
    board.heartbeat()
    board.goto(-200, -600)
    status = board.check_busy()
    assert not status & Status.PB_MOTEUR
    while status & Status.BUSY_TRAJET:  # the order runs to its end, the timeout fed
        assert sim.time_s < 60
        sim.advance(0.1)
        board.heartbeat()
        status = board.check_busy()
    assert status == 0 and board.debug().end_reason == EndReason.DONE


def test_a_power_on_is_as_before() -> None:
    sim, board = started(1)
    board.goto(-200, -500)
    sim.advance(0.8)
    sim.power_cycle()
    assert board.check_busy() == 0
    assert board.reset_info() == ResetInfo(ResetCause.POWER_ON, 0, False, 0)
    assert board.debug().end_reason == EndReason.NONE
    p = board.position()
    assert (p.x_mm, p.y_mm, p.angle_deg) == (0, -850, 0)  # the specification's start, believed


def test_the_radius_widens_by_the_travel_while_down() -> None:
    """Driving, 200 ms down: what the robot may have travelled at its speed, unseen; the radius
    takes it."""
    sim, board = started(2)
    board.goto(1000, -850)
    sim.advance(1.6)  # cruising
    sim.reset("BROWN_OUT", keep_ram=True, down_ms=200)
    info = board.reset_info()
    assert 40 <= info.widened_mm <= 255, info
    assert error_mm(sim, board) <= board.position().radius_mm


def test_the_simulator_refuses_a_bad_reset() -> None:
    sim, board = started(3)
    with pytest.raises(ValueError, match=r"no cause 'UNPLUGGED' \(the causes: POWER_ON, BROWN_OUT"):
        sim.reset("UNPLUGGED")
    with pytest.raises(ValueError, match="no cause 9 "):
        sim.reset(9)
    with pytest.raises(ValueError):
        sim.reset("WATCHDOG", down_ms=1001)
    assert board.reset_info() == ResetInfo(ResetCause.POWER_ON, 0, False, 0)  # nothing done
