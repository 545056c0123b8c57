"""Scenarios as a team's tests: expectations, unexpected faults, the busy warning, the start and
the targets checked against the field, opponents and timed events."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from asserv import scenario
from asserv.cli import main
from asserv.driver import Outcome

SLOW = settings(max_examples=15, deadline=None, suppress_health_check=[HealthCheck.too_slow])
LANE = "start -1000 -300 0\n"


def run(text: str) -> tuple[bool, list[str]]:
    scn = scenario.parse(text, "s.txt")
    lines: list[str] = []
    res = scenario.play(scn, lines.append)
    return res.ok, lines


@dataclass
class Ran:
    returncode: int
    stdout: str
    stderr: str


@pytest.fixture
def cli(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> Callable[[str], Ran]:
    """``asserv sim run`` on a scenario text (in this process)."""

    def run_cli(text: str) -> Ran:
        path = tmp_path / "s.txt"
        path.write_text(text)
        code = main(["sim", "run", str(path)])
        out = capsys.readouterr()
        return Ran(code, out.out, out.err)

    return run_cli


def test_the_opponent_scenario_passes() -> None:
    scn = scenario.load(scenario.SCENARIO_DIR / "opponent.txt")
    lines: list[str] = []
    assert scenario.play(scn, lines.append).ok, "\n".join(lines)
    assert sum("expect" in ln and ": ok" in ln for ln in lines) == 5


def test_a_failing_assertion_with_an_opponent_exits_1(cli: Callable[[str], Ran]) -> None:
    text = (
        LANE + "opponent -400 500 150 400 -400 -300\n"
        "goto 200 -300\nwait\nexpect done\n"  # the opponent is in the way: a shock
    )
    r = cli(text)
    assert r.returncode == 1, r.stdout + r.stderr
    assert "s.txt:5: expectation failed: expected done, the order ended: shock" in r.stdout


def test_a_failing_pose_assertion(cli: Callable[[str], Ran]) -> None:
    r = cli(LANE + "goto -500 -300\nwait\nexpect pose -400 -300 20\n")
    assert r.returncode == 1
    assert "s.txt:4: expectation failed: the robot is at (-500.0, -300.0)" in r.stdout


def test_an_unexpected_fault_exits_1_an_expected_one_passes(cli: Callable[[str], Ran]) -> None:
    fault = LANE + "at 1 stick_motor left\ngoto 200 -300\nwait\n"
    r = cli(fault)
    assert r.returncode == 1
    assert "s.txt:4: the order ended in a fault the scenario does not expect: motor" in r.stdout
    assert "add 'expect motor'" in r.stdout
    r = cli(fault + "expect motor\n")
    assert r.returncode == 0, r.stdout


def test_a_scenario_ending_busy_warns(cli: Callable[[str], Ran]) -> None:
    r = cli(LANE + "goto 200 -300\nsleep 0.5\n")
    assert r.returncode == 0
    assert "warning: " in r.stdout and "still busy (BUSY_TRAJET)" in r.stdout


@pytest.mark.parametrize(
    ("text", "line", "message"),
    [
        ("start 5000 0 0\ngoto 0 0\n", 1, "off the table"),
        ("start 1200 -750 0\ngoto 0 0\n", 1, "inside the basket at (1200, -750)"),
        ("start -1400 0 0\ngoto 0 0\n", 1, "off the table"),  # the outline crosses the border
        (LANE + "goto 1600 0\n", 2, "the target (1600, 0) is off the table"),
        (LANE + "goto 1200 -700\n", 2, "the target (1200, -700) is inside the basket"),
        (LANE + "goto 0 0\nwait\nexpect maybe\n", 4, "expect takes"),
        (LANE + "expect done\ngoto 0 0\n", 2, "expect follows a wait"),
        (LANE + "at x press 1\ngoto 0 0\n", 2, "not a number of seconds"),
        (LANE + "at 1 fly\ngoto 0 0\n", 2, "unknown event 'fly'"),
        (LANE + "at 1 press 300\ngoto 0 0\n", 2, "press MASK"),
        (LANE + "at 1 stick_motor middle\ngoto 0 0\n", 2, "stick_motor left|right"),
        (LANE + "at 1 move_obstacle 7 0 0\ngoto 0 0\n", 2, "no obstacle 7"),
        (LANE + "opponent 0 0 150\ngoto 0 0\n", 2, "opponent takes"),
        (LANE + "opponent 0 0 150 300 9000 0\ngoto 0 0\n", 2, "is off the table"),
        (LANE + "opponent 0 0 150 300 10\ngoto 0 0\n", 2, "pairs of numbers"),
    ],
)
def test_bad_lines_are_named_exit_2(text: str, line: int, message: str) -> None:
    with pytest.raises(scenario.ScenarioError) as e:
        scenario.parse(text, "s.txt")
    assert str(e.value).startswith(f"s.txt:{line}: "), str(e.value)
    assert message in str(e.value)


def test_the_cli_exits_2_on_a_start_off_the_table(cli: Callable[[str], Ran]) -> None:
    r = cli("start 5000 0 0\ngoto 0 0\nwait\n")
    assert r.returncode == 2
    assert r.stdout == "" and "s.txt:1: start: the robot at (5000, 0, 0 deg)" in r.stderr


@SLOW
@given(x=st.integers(-1700, 1700), y=st.integers(-1200, 1200), h=st.integers(-180, 180))
def test_start_check_property(x: int, y: int, h: int) -> None:
    """A start is accepted exactly when the whole outline is on the table, off the baskets:
    then the simulated robot touches nothing (no contact force, no shock switch)."""
    text = f"start {x} {y} {h}\ncheck_busy\n"
    try:
        scn = scenario.parse(text, "s.txt")
    except scenario.ScenarioError as e:
        assert str(e).startswith("s.txt:1: start: ")
        return
    sim = scn.simulator()
    sim.advance(0.05)
    assert sim.trace["contact_force_N"].max() == 0
    assert sim.trace["shocks"].max() == 0


def test_expect_names_every_outcome_but_timeout() -> None:
    assert set(scenario.OUTCOMES.values()) == set(Outcome) - {Outcome.TIMEOUT}
