"""The robot description file: robot/default.toml is the simulator's reference robot (through
sim/robot_default_gen.h), other files make other robots, bad files are refused by name."""

from __future__ import annotations

import sys
import tomllib
from pathlib import Path
from typing import Any

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from asserv import Board, robot, scenario
from asserv.driver import Outcome
from asserv.sim import Simulator

ROOT = Path(__file__).resolve().parents[2]


def member(cfg: Any, dotted: str) -> float:
    obj = cfg
    for part in dotted.split("."):
        obj = getattr(obj, part)
    return float(obj)


def test_the_default_file_is_the_simulators_default_robot() -> None:
    cfg = Simulator(record=False).config
    values = robot.load().values
    assert len(values) == 25
    for name, value in values.items():
        assert member(cfg, name) == value, name


def test_the_generated_header_is_current() -> None:
    sys.path.insert(0, str(ROOT / "robot"))
    try:
        import gen_robot  # type: ignore[import-not-found]
    finally:
        sys.path.pop(0)
    assert gen_robot.main(["--check"]) == 0
    assert gen_robot.render() == (ROOT / "sim" / "robot_default_gen.h").read_text()


def default_data() -> dict[str, Any]:
    with robot.DEFAULT.open("rb") as f:
        return tomllib.load(f)


@pytest.mark.parametrize(
    ("change", "message"),
    [
        (lambda d: d.pop("motor"), "[motor]: missing section"),
        (lambda d: d["drive"].pop("track_mm"), "drive.track_mm: missing"),
        (lambda d: d["drive"].update(track=1), "drive.track: unknown key"),
        (lambda d: d.update(wings={}), "wings: unknown section"),
        (lambda d: d["body"].update(mass_kg=-8), "body.mass_kg: -8 is outside"),
        (lambda d: d["body"].update(mass_kg="8"), "body.mass_kg: '8' is not a number"),
        (lambda d: d["encoders"].update(cpr=2000.5), "encoders.cpr: 2000.5 is not a whole"),
        (lambda d: d["motor"].update(gear_efficiency=1.5), "motor.gear_efficiency: 1.5"),
    ],
)
def test_bad_robot_files_are_named(change: Any, message: str) -> None:
    data = default_data()
    change(data)
    with pytest.raises(robot.RobotError) as e:
        robot.parse(data, "r.toml")
    assert str(e.value).startswith("r.toml: ") and message in str(e.value)


def test_unreadable_files(tmp_path: Path) -> None:
    with pytest.raises(robot.RobotError, match="cannot read"):
        robot.load(tmp_path / "none.toml")
    (tmp_path / "bad.toml").write_text("[body\n")
    with pytest.raises(robot.RobotError, match="not valid TOML"):
        robot.load(tmp_path / "bad.toml")


def write(tmp_path: Path, data: dict[str, Any]) -> Path:
    lines = []
    for section, table in data.items():
        lines.append(f"[{section}]")
        lines += [f"{k} = {v!r}" for k, v in table.items()]
    path = tmp_path / "mine.toml"
    path.write_text("\n".join(lines) + "\n")
    return path


@settings(
    max_examples=25,
    deadline=None,
    suppress_health_check=[HealthCheck.too_slow, HealthCheck.function_scoped_fixture],
)
@given(
    wheel=st.floats(50, 90),
    track=st.floats(120, 220),
    enc=st.floats(30, 70),
    cpr=st.integers(1000, 10000),
)
def test_robot_property_a_file_makes_its_robot(
    tmp_path: Path, wheel: float, track: float, enc: float, cpr: int
) -> None:
    """Whatever wheels and encoders a file gives, the simulator's robot has exactly them."""
    data = default_data()
    data["drive"].update(wheel_diameter_mm=wheel, track_mm=track)
    data["encoders"].update(wheel_diameter_mm=enc, cpr=cpr)
    cfg = Simulator(robot=write(tmp_path, data), record=False).config
    assert cfg.drive_radius_mm == wheel / 2 and cfg.drive_track_mm == track
    assert cfg.enc_radius_mm == enc / 2 and cfg.enc_cpr == cpr


def test_another_robot_in_a_scenario(tmp_path: Path) -> None:
    data = default_data()
    data["outline"].update(length_mm=200.0)
    data["drive"].update(wheel_diameter_mm=80.0)
    path = write(tmp_path, data)
    scn = scenario.parse(f"robot {path}\nstart -1000 -300 0\ngoto -500 -300\nwait\n", "s.txt")
    sim = scn.simulator()
    assert sim.config.outline_length_mm == 200 and sim.config.drive_radius_mm == 40
    board = Board(sim.bus)
    assert board.complete(board.goto, -500, -300, timeout_s=20) is Outcome.DONE
    with pytest.raises(scenario.ScenarioError, match=r"s\.txt:1: bad robot file"):
        scenario.parse("robot nowhere\ngoto 0 0\n", "s.txt")
