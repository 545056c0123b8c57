"""Honest endings (issue 18, docs/failure-model.md "How each order ends"): a setting sent during a
border push applies after it, and GOTO_PANIER that touches no basket says so.

Each reproduction of the issue is a case here, and each promise also gets a hypothesis test over
random moments, settings and robots (a few dozen examples, derandomized, so that the suite stays
within its time).
"""

from __future__ import annotations

import dataclasses
import math
import sys
from pathlib import Path
from typing import Any

import pytest
from hypothesis import HealthCheck, example, given, settings
from hypothesis import strategies as st

from asserv import EndReason, OrderState, Status, field
from asserv.driver import Board, GotoOption
from asserv.sim import AVR_RATES, Simulator

sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "bench"))
from shock_stop import SLOW_REST_MS, Stop, disc_field, hit, stop_of

MISMATCHED = {"enc_radius_error": (0.0015, -0.0015), "start": (0, -850, 1.0)}
MOTOR_BITS = Status.PB_MOTEUR | Status.PB_GRAVE
SOAK = settings(
    max_examples=12,
    deadline=None,
    derandomize=True,
    suppress_health_check=[HealthCheck.too_slow],
)


def gains(sim: Simulator) -> tuple[int, int, int]:
    """The gains the board gave the servo last (board.h: the soft ones during a border push)."""
    g = sim._h.board.planner.gains
    return (int(g.p), int(g.i), int(g.d))


def preset(sim: Simulator, n: int) -> tuple[int, int, int]:
    g = sim.board_config.control.presets[n]
    return (int(g.p), int(g.i), int(g.d))


# ---- settings sent during a push apply after it (issue 18, Why 5) -----------------------------


def border_push(seed: int = 1) -> tuple[Simulator, Board]:
    """The robot at (1200, 0), then a GOTO there with border recalibration, under way."""
    sim = Simulator(MISMATCHED, seed=seed, board_start=(0, -850, 0), start_uncertainty=(2.0, 1.2))
    board = Board(sim.bus)
    board.set_vitesse_traj(30, 50)
    board.goto(1200, 0)
    assert board.wait_idle(30) == 0
    board.goto(1200, 0, GotoOption.RECALAGE_BORD)
    return sim, board


def until_state(sim: Simulator, board: Board, state: OrderState) -> None:
    while board.debug().order_state != state:
        assert sim.time_s < 120, f"never reached {state.name}"
        sim.advance(0.005)


def check_border_end(sim: Simulator, board: Board, want: tuple[int, int, int]) -> None:
    assert board.wait_idle(30) == Status.CHOC_BORD
    assert board.debug().end_reason == EndReason.BORDER
    sim.advance(0.02)
    assert gains(sim) == want  # the setting applied after the push


def test_set_filtre_during_a_border_push_applies_after_it() -> None:
    # Issue 18's reproduction: SET_FILTRE, any preset, during the push and while squaring up;
    # it used to end with PB_MOTEUR (STD and RAIDE are too stiff against the border).
    for n in (0, 1, 2):
        for state in (OrderState.PUSH, OrderState.SQUARE):
            sim, board = border_push()
            until_state(sim, board, state)
            board.set_filtre(n)
            sim.advance(0.05)
            if state == OrderState.SQUARE:
                assert gains(sim) == preset(sim, 1)  # still the soft gains of the push
            check_border_end(sim, board, preset(sim, n))


@SOAK
@given(
    delay_ms=st.integers(0, 1500),
    raw=st.one_of(
        st.integers(0, 2).map(lambda n: ("preset", n, 0, 0)),
        st.tuples(st.just("raw"), st.integers(0, 600), st.integers(0, 1500), st.integers(0, 300)),
    ),
)
def test_any_setting_during_a_border_push_keeps_its_ending(
    delay_ms: int, raw: tuple[str, int, int, int]
) -> None:
    sim, board = border_push()
    until_state(sim, board, OrderState.PUSH)
    sim.advance(delay_ms / 1000)
    kind, p, i, d = raw
    if kind == "preset":
        board.set_filtre(p)
        want = preset(sim, p)
    else:
        board.set_filtre_raw(p, i, d)
        want = (p, i, d)
    check_border_end(sim, board, want)


# ---- GOTO_PANIER with no basket in reach (issue 18, Why 8) -------------------------------------


def no_basket_in_reach(sim: Simulator, board: Board, angle: int) -> None:
    board.goto_panier(angle)
    assert board.wait_idle(30) == Status.PB_MOTEUR  # the basket was not reached
    assert board.debug().end_reason == EndReason.NO_BASKET
    assert sim._h.board.planner.faults.cause == 0  # no check fired: not a motor fault


def test_goto_panier_without_a_basket_says_so() -> None:
    # From the power-on pose, facing +X along the end of the field: 500 mm of nothing.
    sim = Simulator()
    board = Board(sim.bus)
    x0 = sim.true_pose().x_mm
    no_basket_in_reach(sim, board, 0)
    assert math.isclose(sim.true_pose().x_mm - x0, 500, abs_tol=2)
    # Three in a row are no PB_GRAVE, and the next order runs.
    no_basket_in_reach(sim, board, 180)
    no_basket_in_reach(sim, board, 0)
    board.goto(0, -850)
    assert board.wait_idle(30) == 0


@SOAK
@given(
    x=st.integers(-600, 600),
    y=st.integers(-400, 400),
    angle=st.integers(-90, 90).map(lambda a: 2 * a),
    seed=st.integers(0, 2**16),
)
def test_goto_panier_that_touches_nothing_ends_on_pb_moteur(
    x: int, y: int, angle: int, seed: int
) -> None:
    # An empty table: nothing to touch within the push, wherever the robot stands.
    empty = field.Field(borders=False)
    sim = Simulator({"start": (x, y, 0.0)}, seed=seed, randomize=True, field=empty)
    board = Board(sim.bus)
    no_basket_in_reach(sim, board, angle)
    st_ = board.check_busy()
    assert not st_ & (Status.CHOC_PANIER | Status.CHOC_BORD | Status.BUSY_TRAJET)


# ---- a stop that stops (issue 18, Why 3) -------------------------------------------------------

BACK_MM = 0.2  # "driving back": returning towards the obstacle by more than this


def check_stop(s: Stop) -> None:
    """The promises of docs/failure-model.md: at rest within 1.1 times the grip's braking time
    from the speed and spin after the contact (at least SLOW_REST_MS), never back towards the
    obstacle, and under 10 N from 300 ms on. (A robot at rest against a wall may still touch it
    with a few newtons: the hold rocks by a count at rest, docs/failure-model.md.)"""
    assert s.rest_ms <= max(1.1 * s.braking_ms, SLOW_REST_MS), s
    assert s.back_mm < BACK_MM, s
    assert s.force_after_300_ms < 10, s


@pytest.mark.parametrize(
    ("seed", "randomize"), [pytest.param(0, False, id="nominal"), pytest.param(7, True, id="7")]
)
def test_a_shock_at_1_m_s_stops_and_lets_go(seed: int, randomize: bool) -> None:
    # Issue 18's reproduction: the hold drove the robot back at ~190 mm/s 100-150 ms after the
    # shock, then pressed it (22 N at 0.3 s, 12 N at 1 s; 21-35 N after 3 s on seed 7).
    # With the 100 us substep everywhere, as measured then: the return after the stop is a
    # lottery of the last micrometres (0.10 to 0.28 mm for starts 0 to 0.3 mm apart, with either
    # substep: docs/simulator.md "Speed"), and this start gives 0.13 mm with it.
    sim = Simulator({"coarse_substep_ns": 0}, seed=seed, randomize=randomize, field=disc_field())
    board = Board(sim.bus)
    board.set_vitesse_traj(100, 100)
    for x, y in ((-900, -300), (-900, 0)):
        board.goto(x, y)
        assert board.wait_idle(20) == 0
    start = sim.ticks
    board.goto(600, 0)
    assert board.wait_idle(20) == Status.CHOC_BORD
    sim.advance(4)
    s = stop_of(sim, start, disc=(0, 0))
    assert s.v0_mm_s > 950
    check_stop(s)
    assert s.force_last_s < 1, s  # resting clear of the disc
    assert s.rest_ms <= 0.6 * s.braking_ms  # the obstacle helps


@settings(SOAK, max_examples=30)
@given(
    seed=st.integers(0, 2**16),
    speed=st.integers(3, 255),
    accel=st.integers(30, 255),
    gap=st.integers(100, 700),
    lateral=st.integers(-60, 60),
    axis=st.sampled_from([(1, 0), (-1, 0), (0, 1), (0, -1)]),
)
def test_any_shock_stops_within_the_grip_and_lets_go(
    seed: int, speed: int, accel: int, gap: int, lateral: int, axis: tuple[int, int]
) -> None:
    # A randomized robot drives from the middle of the field towards a wall across its path
    # (a box 400 mm wide, its face gap mm ahead of the front edge), at any accepted limits.
    ux, uy = axis
    heading = math.degrees(math.atan2(uy, ux))
    x0, y0 = -ux * 200 + uy * lateral, -uy * 200 + ux * lateral
    face = 125 + gap  # from the robot's axis
    cx, cy = x0 + ux * (face + 20), y0 + uy * (face + 20)
    box = field.Obstacle("box", cx, cy, half_x_mm=20 if ux else 200, half_y_mm=200 if ux else 20)
    f = dataclasses.replace(field.load(field.DEFAULT), obstacles=(box,))
    sim = Simulator({"start": (x0, y0, heading)}, seed=seed, randomize=True, field=f)
    board = Board(sim.bus)
    board.set_vitesse_traj(speed, accel)
    board.goto(round(x0 + ux * 900), round(y0 + uy * 900))
    assert board.wait_idle(60) == Status.CHOC_BORD
    sim.advance(1.5)
    check_stop(stop_of(sim, 0))


# ---- grip: no accepted limits make a nominal robot slip (issue 18, Why 6) ----------------------


def test_limits_at_the_edge_of_the_grip_do_not_slip() -> None:
    # Issue 18's reproduction: translating while the turn still braked, the wheels asked for
    # more than the grip; PB_MOTEUR twice, then PB_GRAVE. The board now shares the grip.
    sim = Simulator(seed=4)
    board = Board(sim.bus)
    board.set_vitesse_traj(120, 200)
    board.set_vitesse_rot(100, 150)
    for x, y in ((0, -200), (0, -100), (239, 464)):
        board.goto(x, y)
        assert board.wait_idle(20) == 0
        assert board.debug().end_reason == EndReason.DONE


@SOAK
@given(
    seed=st.integers(0, 2**16),
    traj=st.tuples(st.integers(20, 150), st.integers(1, 255)),
    rot=st.tuples(st.integers(10, 150), st.integers(1, 255)),
    targets=st.lists(
        st.tuples(st.integers(-1000, 1000), st.integers(-600, 600)), min_size=2, max_size=3
    ),
)
def test_any_accepted_accelerations_keep_a_nominal_robot_within_its_grip(
    seed: int,
    traj: tuple[int, int],
    rot: tuple[int, int],
    targets: list[tuple[int, int]],
) -> None:
    # Any accelerations the protocol accepts, at speeds the motors carry (1.5 m/s: above their
    # top speed the following error is the limit, docs/failure-model.md), on an empty table.
    sim = Simulator(seed=seed, field=field.Field())
    board = Board(sim.bus)
    board.set_vitesse_traj(*traj)
    board.set_vitesse_rot(*rot)
    for x, y in targets:
        board.goto(x, y)
        assert board.wait_idle(120) == 0
    assert sim.trace["contact_force_N"].max() == 0


# ---- slip detection while accelerating (issue 18, Why 7) ---------------------------------------


def slip_latency_ms(scale: float, wheel: int, at_s: float, seed: int = 0) -> int | None:
    from slip_latency import latency_ms

    return latency_ms(scale, wheel, at_s, seed)


@pytest.mark.parametrize("scale", [0.0, 0.05, 0.10])
@pytest.mark.parametrize("wheel", [0, 1])
def test_slip_while_accelerating_is_detected_within_100_ms(scale: float, wheel: int) -> None:
    # Issue 18: 92, 105 and 125 ms at 0, 5 and 10 % of the grip (bench/slip_latency.py);
    # each wheel's own slip is now checked: 65, 75 and 89 ms.
    ms = slip_latency_ms(scale, wheel, 0.3)
    assert ms is not None and ms <= 100


@SOAK
@given(
    scale=st.floats(0.0, 0.10),
    wheel=st.integers(0, 1),
    at_s=st.floats(0.05, 0.8),
    seed=st.integers(0, 2**16),
)
def test_slip_up_to_10_percent_grip_is_detected_within_100_ms(
    scale: float, wheel: int, at_s: float, seed: int
) -> None:
    # Any moment of the acceleration (1 m/s at 1 m/s^2: 0 to 1 s), either wheel, 0 to 10 %.
    ms = slip_latency_ms(scale, wheel, at_s, seed)
    assert ms is not None and ms <= 100


@pytest.mark.parametrize("lateral", [-140, -120, 120, 140])
def test_an_oblique_hit_stops_and_lets_go(lateral: int) -> None:
    # A disc off the robot's centre line, where a corner switch meets it at 1 m/s: the contact
    # turns the robot by about 30 degrees, and holding the heading back presses the corner into
    # the disc (a first version of the stop, holding it: 26 N from 300 ms on, 1.1 s to rest).
    sim = Simulator({"start": (-900, 0, 0.0)}, field=disc_field(0, lateral))
    board = Board(sim.bus)
    board.set_vitesse_traj(100, 150)
    board.goto(600, 0)
    assert board.wait_idle(20) == Status.CHOC_BORD
    sim.advance(1.5)
    s = stop_of(sim, 0, disc=(0, lateral))
    check_stop(s)
    assert s.force_last_s < 1, s  # resting clear of the disc


def hits(min_speed_cm_s: int) -> dict[str, st.SearchStrategy[Any]]:
    """hit()'s arguments at random: a wall or a disc within a switch's reach, any start within 5
    mm, any accepted speed from min_speed_cm_s and acceleration, nominal and randomized robots."""
    return {
        "kind": st.sampled_from(["wall", "disc"]),
        "speed": st.integers(min_speed_cm_s, 150),
        "accel": st.integers(30, 255),
        "dx": st.floats(-5, 5),
        "lateral": st.floats(-15, 15),
        "seed": st.integers(0, 2**16),
        "randomize": st.booleans(),
    }


@settings(SOAK, max_examples=30)
@given(**hits(20))
@example(kind="wall", speed=138, accel=255, dx=-4.0, lateral=0.0, seed=2190, randomize=True)
@example(kind="wall", speed=54, accel=132, dx=4.400390625, lateral=0.0, seed=8738, randomize=True)
def test_any_hit_from_any_start_stops_within_the_grip(
    kind: str, speed: int, accel: int, dx: float, lateral: float, seed: int, randomize: bool
) -> None:
    # The stop's promises at 1 kHz for hits from any start (the return after the stop was a
    # lottery of the last micrometres: 0.10 to 0.28 mm for starts 0.3 mm apart), on nominal and
    # randomized robots, into a wall or a disc within a switch's reach. The examples are what
    # this soak found first: a hold point that followed the robot back towards the wall while
    # the heading's hold turned it (0.31 mm back; 6.1 N resting against the wall).
    status, s = hit(kind, speed, accel, dx, lateral, seed, randomize)
    assert status == Status.CHOC_BORD
    check_stop(s)


#: At the AVR's rates (AVR_RATES) the switch is seen up to 11 ms after it closes, and the
#: planner's set points reach the servo a period at a time: at rest within 1.1 times the
#: braking time plus this.
AVR_REST_EXTRA_MS = 120


@pytest.mark.parametrize("speed", [10, 30, 60, 100, 150])
def test_the_stop_at_the_avr_s_rate(speed: int) -> None:
    # The planner every 8th tick, its results 3 ticks on (the AVR board): the robot meets the
    # disc at speed and is thrown back at up to 0.5 m/s; the hold brakes that along its motion.
    status, s = hit("disc", speed, 150, 0, 0, 0, False, dict(AVR_RATES))
    assert status == Status.CHOC_BORD
    assert s.back_mm < BACK_MM, s
    assert s.force_after_300_ms < 10 and s.force_last_s < 1, s
    assert s.rest_ms <= 1.1 * s.braking_ms + AVR_REST_EXTRA_MS, s


@settings(SOAK, max_examples=15)
@given(**hits(10))
def test_any_hit_at_the_avr_s_rates_stops(
    kind: str, speed: int, accel: int, dx: float, lateral: float, seed: int, randomize: bool
) -> None:
    status, s = hit(kind, speed, accel, dx, lateral, seed, randomize, dict(AVR_RATES))
    assert status == Status.CHOC_BORD
    assert s.rest_ms <= 1.1 * s.braking_ms + AVR_REST_EXTRA_MS, s
    assert s.back_mm < BACK_MM, s
    assert s.force_after_300_ms < 10, s
