"""Issue 31, item 6: the friction circle everywhere. A random master plays a match on a randomized
robot at random accepted limits: orders that replace the running one, APPEND and PASS_THROUGH
orders, pauses and resumes, speed scales, corner tolerances, STOP, all at random moments. At
every 5 ms the simulator's truth is read:

- no drive wheel slips beyond the tyre's grip: its surface speed against the ground (the
  simulator's ``slip_mm_s``) stays below SLIP_MM_S. A tyre within its grip creeps: 3 mm/s on
  the issue's seed 2, up to 71 mm/s on plain GOTOs of seed 0 at 30 cm/s^2; beyond it the wheel
  spins: 371 mm/s in the issue's reproduction of item 7;
- the board never reports PB_MOTEUR (nor PB_GRAVE) without a contact: there is none on an empty
  table and no fault is injected, so PB_MOTEUR is never right;
- every order ends, and MOTION's last ending is one the master's actions explain.

The draws that also change the gains at random moments are a second test, at one rate. Issue
31's item 7 (a change to stiffer gains mid-curve slipped) needs soft gains, a replacement that
curves and the change within a few hundred ms: these draws have not hit it; its regression and
its own soak are test_gain_change_sim.py. At the AVR's rates these draws found a slip without
any gain change, older than issue 31: the last test keeps it.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from asserv import codec, field
from asserv._protocol import EndReason, Status
from asserv.driver import Board
from asserv.sim import AVR_RATES, Simulator
from asserv.sim._core import ffi, lib

SLIP_MM_S = 150.0
STEP_S = 0.005
APPEND, THROUGH = 0x04, 0x08

SOAK = settings(
    max_examples=30, deadline=None, derandomize=True, suppress_health_check=[HealthCheck.too_slow]
)


def truth_slip_mm_s(sim: Simulator) -> tuple[float, float]:
    t = ffi.new("struct sim_truth *")
    lib.sim_get_truth(sim._sim, t)
    return float(t.slip_mm_s[0]), float(t.slip_mm_s[1])


@dataclass
class Watch:
    sim: Simulator
    slip_mm_s: float = 0.0

    def run(self, seconds: float) -> None:
        for _ in range(max(1, round(seconds / STEP_S))):
            self.sim.advance(STEP_S)
            self.slip_mm_s = max(self.slip_mm_s, max(abs(s) for s in truth_slip_mm_s(self.sim)))


point = st.tuples(st.integers(-1100, 1100), st.integers(-750, 750))
action = st.one_of(
    st.tuples(st.just("goto"), point, st.sampled_from([0, APPEND, APPEND | THROUGH, THROUGH])),
    st.tuples(st.just("reverse"), st.integers(0, 200), st.sampled_from([0, APPEND])),
    st.tuples(st.just("pause"), st.none(), st.none()),
    st.tuples(st.just("resume"), st.none(), st.none()),
    st.tuples(st.just("scale"), st.integers(0, 100), st.none()),
    st.tuples(st.just("corner"), st.integers(1, 255), st.none()),
    st.tuples(st.just("stop"), st.none(), st.none()),
)
gain_action = st.tuples(st.just("filtre"), st.integers(0, 2), st.none())


def play(
    seed: int,
    avr: bool,
    traj: tuple[int, int],
    rot: tuple[int, int],
    actions: list[tuple[str, object, object]],
    waits: list[float],
) -> None:
    # Speeds the motors carry (1.5 m/s: above it the following error is the limit,
    # docs/failure-model.md), on an empty table inside its borders.
    sim = Simulator(
        seed=seed, randomize=True, field=field.Field(), board_config=AVR_RATES if avr else None
    )
    board = Board(sim.bus)
    board.set_vitesse_traj(*traj)
    board.set_vitesse_rot(*rot)
    watch = Watch(sim)
    for (kind, a, b), wait in zip(actions, waits, strict=False):
        if kind == "goto":
            assert isinstance(a, tuple) and isinstance(b, int)
            board._command("GOTO", a[0], a[1], b)
        elif kind == "reverse":
            assert isinstance(a, int) and isinstance(b, int)
            board._command("GOTO_REVERSE", a, b)
        elif kind == "pause":
            board._command("PAUSE")
        elif kind == "resume":
            board._command("RESUME")
        elif kind == "scale":
            assert isinstance(a, int)
            board._command("SET_SPEED_SCALE", a)
        elif kind == "corner":
            assert isinstance(a, int)
            board._command("SET_CORNER", a)
        elif kind == "filtre":
            assert isinstance(a, int)
            board.set_filtre(a)
        else:
            board.stop()
        watch.run(wait)
    board._command("SET_SPEED_SCALE", 100)
    board._command("RESUME")
    for _ in range(400):  # at most 20 s for what is queued
        if not board.check_busy() & Status.BUSY_TRAJET:
            break
        watch.run(0.05)
    status = board.check_busy()
    m = board._query("MOTION", codec.Motion)
    trace_status = sim.trace["status"].astype(int)
    assert watch.slip_mm_s < SLIP_MM_S
    assert not np.any(trace_status & int(Status.PB_MOTEUR | Status.PB_GRAVE))
    assert sim.trace["contact_force_N"].max() == 0  # inside the borders: no contact
    assert not status & Status.BUSY_TRAJET and m.pending == 0
    assert m.last_end in (EndReason.NONE, EndReason.DONE, EndReason.STOPPED)


def draws(
    actions: st.SearchStrategy[tuple[str, object, object]], avr: st.SearchStrategy[bool]
) -> dict[str, object]:
    return dict(
        seed=st.integers(0, 2**16),
        avr=avr,
        traj=st.tuples(st.integers(30, 150), st.integers(30, 255)),
        rot=st.tuples(st.integers(20, 150), st.integers(30, 255)),
        actions=st.lists(actions, min_size=3, max_size=10),
        waits=st.lists(st.sampled_from([0.0, 0.02, 0.1, 0.3, 0.8]), min_size=10, max_size=10),
    )


@SOAK
@given(**draws(action, st.booleans()))  # type: ignore[arg-type]
def test_no_master_makes_a_wheel_slip_or_a_motor_fault(
    seed: int,
    avr: bool,
    traj: tuple[int, int],
    rot: tuple[int, int],
    actions: list[tuple[str, object, object]],
    waits: list[float],
) -> None:
    play(seed, avr, traj, rot, actions, waits)


@SOAK
# At one rate: at the AVR's, these draws find test_a_plain_goto_at_avr_rates_... first.
@given(**draws(st.one_of(action, gain_action, gain_action), st.just(False)))  # type: ignore[arg-type]
def test_nor_with_gain_changes_at_random_moments(
    seed: int,
    avr: bool,
    traj: tuple[int, int],
    rot: tuple[int, int],
    actions: list[tuple[str, object, object]],
    waits: list[float],
) -> None:
    play(seed, avr, traj, rot, actions, waits)


@pytest.mark.xfail(
    strict=True,
    reason="found by the soak above, not issue 31's: at the AVR's rates a plain GOTO of this "
    "randomized robot slips and ends PB_MOTEUR (the 2002 path is bit-identical to ab41e8a's)",
)
def test_a_plain_goto_at_avr_rates_keeps_seed_0_within_its_grip() -> None:
    play(0, True, (30, 30), (45, 167), [("goto", (0, 0), 0)], [0.0])
