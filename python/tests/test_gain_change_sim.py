"""A change of gains while the robot moves (issue 31, item 7; docs/control.md "A change of
gains"): the step the new P and D make in the output is taken in at the grip's pace, so stiffer
gains applied in a curve do not make a wheel slip.

The reproduction an independent random master found: in a curve driven with FILTRE_SOUPLE, the
switch to FILTRE_RAIDE multiplied the angle's following error (3.3 mm, which the soft gains,
without an integral, leave) by ten at once: a third of full duty on each motor in one tick, and
a wheel slipped within 40 ms (PB_MOTEUR, no contact, no fault).
"""

from __future__ import annotations

import pytest
from hypothesis import given
from hypothesis import strategies as st

from asserv import Filtre, Status
from asserv.driver import Board
from asserv.sim import AVR_RATES, Simulator


def curve_with_new_gains(
    seed: int,
    before: Filtre,
    after: Filtre,
    change_s: float = 0.3,
    traj: tuple[int, int] = (100, 100),
    rot: tuple[int, int] = (70, 89),
    rates: bool = False,
) -> tuple[int, float]:
    """Issue 31's master: a GOTO replaced 0.25 s later by one that makes the robot curve, and
    the gains changed change_s after that, at 1 kHz or at the AVR's rates. The order's end and
    the largest contact force."""
    sim = Simulator(seed=seed, randomize=True, board_config=dict(AVR_RATES) if rates else None)
    board = Board(sim.bus)
    board.set_vitesse_traj(*traj)
    board.set_vitesse_rot(*rot)
    board.set_filtre(before)
    board.goto(-536, -400)
    sim.advance(0.25)
    board.goto(779, -400)
    sim.advance(change_s)
    board.set_filtre(after)
    end = board.wait_idle(30)
    return int(end), float(sim.trace["contact_force_N"].max())


@pytest.mark.parametrize("rates", [False, True], ids=["1kHz", "avr_rates"])
@pytest.mark.parametrize("seed", range(2, 10))
def test_stiffer_gains_in_a_curve_do_not_slip(seed: int, rates: bool) -> None:
    end, force = curve_with_new_gains(seed, Filtre.FILTRE_SOUPLE, Filtre.FILTRE_RAIDE, rates=rates)
    assert force == 0
    assert end == 0, f"ended 0x{end:02x}"


@given(
    seed=st.integers(0, 10_000),
    before=st.sampled_from(Filtre),
    after=st.sampled_from(Filtre),
    change_s=st.floats(0.0, 0.8),
    traj=st.tuples(st.integers(20, 120), st.integers(30, 150)),
    rot=st.tuples(st.integers(20, 90), st.integers(30, 120)),
    rates=st.booleans(),
)
def test_a_change_of_presets_never_slips(
    seed: int,
    before: Filtre,
    after: Filtre,
    change_s: float,
    traj: tuple[int, int],
    rot: tuple[int, int],
    rates: bool,
) -> None:
    """Any change between the presets at any moment of a replaced, curving order, on random
    robots and limits, at either rate: never a PB_MOTEUR without a contact."""
    end, force = curve_with_new_gains(seed, before, after, change_s, traj, rot, rates)
    assert force > 0 or not end & (Status.PB_MOTEUR | Status.PB_GRAVE), f"ended 0x{end:02x}"
