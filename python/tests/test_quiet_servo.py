"""The quiet servo (issue 32, docs/control.md "PID"): a robot cruising at constant set points
keeps its duty jitter and its motors' current within bench/quiet.py's goals, on any randomized
robot at any cruise speed, and at rest after it; the same measure on the same robots with the
derivative read raw (control.d_filter_ms 0, the AVR's build) misses them, so that it can fail.
The figures over 50 robots are bench/quiet.py's."""

from __future__ import annotations

import importlib
import sys
from pathlib import Path
from typing import Any

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from asserv._protocol import Capability
from asserv.driver import Board
from asserv.sim import AVR_RATES, Simulator

sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "bench"))
quiet = importlib.import_module("quiet")


def within_goals(w: Any) -> list[str]:
    """What of a window misses bench/quiet.py's goals: duty jitter, current."""
    out = []
    if w.jitter > quiet.JITTER_GOAL:
        out.append(f"duty jitter {w.jitter:.4f} RMS > {quiet.JITTER_GOAL}")
    goal = quiet.CURRENT_GAIN_GOAL * w.current_need_a + quiet.CURRENT_OFFSET_GOAL_A
    if w.current_rms_a > goal:
        out.append(f"current {w.current_rms_a:.3f} A RMS > {goal:.3f} A")
    return out


@settings(max_examples=10, deadline=None)
@given(seed=st.integers(0, 2**31 - 1), speed_cm_s=st.integers(10, 100))
def test_any_robot_cruising_keeps_its_duty_quiet(seed: int, speed_cm_s: int) -> None:
    run, rest = quiet.cruise(seed, speed_cm_s)
    assert within_goals(run) == [], f"seed {seed} at {speed_cm_s} cm/s, cruising"
    assert within_goals(rest) == [], f"seed {seed} at {speed_cm_s} cm/s, at rest after it"


@pytest.mark.parametrize("seed", [0, 7])
def test_the_raw_derivative_chatters(seed: int) -> None:
    """The measure is not blind: the derivative read raw misses both goals."""
    run, _ = quiet.cruise(seed, 50, quiet.RAW_D)
    assert len(within_goals(run)) == 2, f"seed {seed}: {within_goals(run)}"


def test_version_says_whether_the_servo_is_quiet() -> None:
    """QUIET_SERVO is a build's capability: set on the host build whatever its settings (the
    AVR's, which leaves it out, is test_avr_vectors')."""
    for cfg in (None, AVR_RATES):
        board = Board(Simulator(board_config=cfg).bus)
        assert Capability.QUIET_SERVO in board.version().capabilities
