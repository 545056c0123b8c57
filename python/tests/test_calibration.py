"""The odometry calibration procedure (asserv.calibration) on simulated robots: it brings the
wheel ratio, the track and the scale within the goals of issue 7, writes them with
SET_ODOMETRIE, and says what went wrong when it cannot run."""

from __future__ import annotations

import pytest

from asserv import Board
from asserv.calibration import (
    CalibrationError,
    Geometry,
    OdometrySetting,
    Plan,
    calibrate,
)
from asserv.cli import main
from asserv.sim import Simulator, accuracy


def robot(seed: int, start: tuple[float, float, float] = accuracy.CALIBRATION_START) -> Simulator:
    return Simulator({"start": start}, seed=seed, randomize=True, record=False)


@pytest.mark.parametrize("seed", [7, 69])
def test_calibration_meets_the_goals(seed: int) -> None:
    # Seed 7: 0.25 % ratio error, track -0.7 mm, the noisiest wheels (0.25 mm^2/m each).
    # Seed 69: 0.56 % ratio error, the largest of the first 200 robots.
    sim = robot(seed)
    before = sim.odometry_errors()
    assert abs(before.ratio) > 0.002
    lines: list[str] = []
    res = calibrate(Board(sim.bus), Geometry(), Plan(), log=lines.append)
    sim.advance(0.002)  # the tick that applies the last SET_ODOMETRIE
    after = sim.odometry_errors()
    assert abs(after.ratio) <= 0.0005  # 0.05 %
    assert abs(after.track_mm) <= 0.1
    assert abs(after.scale) <= 0.0006
    # what the board runs with is what the procedure computed
    cfg = sim._h.board.servo.counter.cfg
    assert cfg.track_um == res.after.track_10um * 10
    assert [s.true_turn_deg for s in res.segments] == [360, 3600, 0, 0, 0]
    assert sum("flat on the east border" in line for line in lines) == 3
    assert lines[-1].startswith("  result: SET_ODOMETRIE ratio")


def test_dry_run_leaves_the_setting() -> None:
    sim = robot(3)
    before = sim.odometry_errors()
    res = calibrate(
        Board(sim.bus), plan=Plan(turns=2, round_trips=2), write=False, log=lambda _: None
    )
    sim.advance(0.002)
    assert sim.odometry_errors() == before
    assert res.after != res.before == OdometrySetting()


def test_no_border_behind_is_an_error() -> None:
    sim = robot(1, start=(-500.0, -300.0, 0.0))  # 875 mm from the west border
    with pytest.raises(CalibrationError, match="west border was not found behind the rear"):
        calibrate(Board(sim.bus), log=lambda _: None)


def test_calibrate_command_on_a_simulated_robot(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["calibrate", "--seed", "3", "--turns", "2", "--round-trips", "2"]) == 0
    out = capsys.readouterr().out
    assert "simulated robot 3: free wheels" in out
    assert "2 full turns in place" in out and "round trip 2 of 2" in out
    assert "result: SET_ODOMETRIE ratio" in out
    assert "the simulated robot's true errors" in out and "after: wheel ratio" in out
    assert main(["calibrate", "--round-trips", "1"]) == 2
    assert "--round-trips: '1' must be at least 2" in capsys.readouterr().err
