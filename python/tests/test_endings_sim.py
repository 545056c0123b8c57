"""Honest endings (issue 18, docs/failure-model.md "How each order ends"): a setting sent during a
border push applies after it, and GOTO_PANIER that touches no basket says so.

Each reproduction of the issue is a case here, and each promise also gets a hypothesis test over
random moments, settings and robots (a few dozen examples, derandomized, so that the suite stays
within its time).
"""

from __future__ import annotations

import math

from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from asserv import EndReason, OrderState, Status
from asserv.driver import Board, GotoOption
from asserv.sim import Simulator

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
    g = sim._h.board.gains
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
    assert sim._h.board.faults.cause == 0  # no check fired: not a motor fault


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
    from asserv import field

    empty = field.Field(borders=False)
    sim = Simulator({"start": (x, y, 0.0)}, seed=seed, randomize=True, field=empty)
    board = Board(sim.bus)
    no_basket_in_reach(sim, board, angle)
    st_ = board.check_busy()
    assert not st_ & (Status.CHOC_PANIER | Status.CHOC_BORD | Status.BUSY_TRAJET)
