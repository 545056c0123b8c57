"""The board's robot constants generated from the robot files (robot/gen_robot.py): today's
numbers, the simulated board's own derivation of the same robot, the firmware's ranges, and bad
files refused by name with exit 2."""

from __future__ import annotations

import contextlib
import io
import math
import re
import subprocess
import sys
import tomllib
from pathlib import Path
from typing import Any

import pytest
from hypothesis import HealthCheck, event, given, settings
from hypothesis import strategies as st

from asserv import robot
from asserv.sim import Simulator

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT / "robot"))
try:
    import gen_robot  # type: ignore[import-not-found]
finally:
    sys.path.pop(0)

#: the members host_board_config() (firmware/ports/host/host.c) derives from the simulator's robot
HOST_DERIVED = {
    "ROBOT_ENC_UM_PER_COUNT_Q16",
    "ROBOT_ENC_TRACK_UM",
    "ROBOT_DRIVE_TRACK_UM",
    "ROBOT_MOTOR_UM_PER_COUNT_Q16",
    "ROBOT_GRIP_UM_S2",
    "ROBOT_ROT_GRIP_Q8",
    "ROBOT_FRONT_UM",
}


def member(cfg: Any, dotted: str) -> int:
    obj = cfg
    for part in dotted.split("."):
        obj = getattr(obj, part)
    return int(obj)


def constants(path: Path | str) -> dict[str, Any]:
    return {c.macro: c for c in gen_robot.constants_of(path)}


def header_values(path: Path) -> dict[str, int]:
    """The macros of a generated header, or the member assignments of a port's function."""
    text = path.read_text()
    found = {m: int(v) for m, v in re.findall(r"#define (ROBOT_\w+) (-?\d+)", text)}
    found.update({m: int(v) for m, v in re.findall(r"cfg->([\w.]+) = (-?\d+);", text)})
    return found


def test_todays_hand_values_come_out() -> None:
    """The numbers board_default_config() and the ports stated by hand before the generator."""
    c = {k: v.value for k, v in constants(robot.DEFAULT).items()}
    assert c["ROBOT_ENC_UM_PER_COUNT_Q16"] == 5147185
    assert c["ROBOT_ENC_TRACK_UM"] == 280000
    assert c["ROBOT_DRIVE_TRACK_UM"] == 160000
    assert c["ROBOT_MOTOR_UM_PER_COUNT_Q16"] == 322692
    assert c["ROBOT_GRIP_UM_S2"] == 4707192
    assert c["ROBOT_ROT_GRIP_Q8"] == 500
    assert c["ROBOT_FRONT_UM"] == 125000
    # the tuned feed-forward of robot/default.toml's [feedforward]
    assert (c["ROBOT_FF_SPEED_Q15_PER_M_S"], c["ROBOT_FF_ACCEL_Q15_PER_M_S2"]) == (19980, 1400)
    assert c["ROBOT_FF_ANGLE_ACCEL_Q15_PER_M_S2"] == 900
    # 195 mm by hand: the corner of the 250 x 300 mm outline is 195.256 mm away
    assert c["ROBOT_REACH_UM"] == math.ceil(math.hypot(125, 150) * 1000)
    avr = constants(ROOT / "robot" / "avr.toml")
    assert avr["ROBOT_MOTOR_UM_PER_COUNT_Q16"].value == 13768191
    stm32 = {k: v.value for k, v in constants(ROOT / "robot" / "stm32.toml").items()}
    assert stm32 == c


def test_the_motor_model_gives_the_figures_of_control_md() -> None:
    """Without [feedforward], the model's values (docs/control.md: 19959 no-load, 1251 and 2355
    with the rotor's and the wheel's inertia)."""
    data = tomllib.loads((robot.DEFAULT).read_text())
    data.pop("feedforward")
    c = gen_robot.derive(robot.parse(data, "r.toml"))
    by = {x.macro: x.value for x in c}
    assert by["ROBOT_FF_SPEED_Q15_PER_M_S"] == 19959
    assert by["ROBOT_FF_ACCEL_Q15_PER_M_S2"] == 1251
    assert by["ROBOT_FF_ANGLE_ACCEL_Q15_PER_M_S2"] == 2355
    text = (ROOT / "docs" / "control.md").read_text()
    assert "1251" in text and "2355" in text


@pytest.mark.parametrize(
    ("source", "header"),
    [
        ("default.toml", "firmware/core/robot_defs.h"),
        ("avr.toml", "firmware/ports/avr/avr_robot_gen.h"),
        ("stm32.toml", "firmware/ports/stm32/stm32_robot_gen.h"),
    ],
)
def test_the_checked_in_headers_hold_the_generated_values(source: str, header: str) -> None:
    found = header_values(ROOT / header)
    for c in gen_robot.constants_of(ROOT / "robot" / source):
        if header.endswith("robot_defs.h"):
            assert found[c.macro] == c.value, c.macro
        else:
            for m in c.members:
                assert found[m] == c.value, m
    assert gen_robot.main(["--check"]) == 0


def test_check_names_a_stale_file(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    stale = tmp_path / "robot_defs.h"
    stale.write_text(gen_robot.render_core().replace("5147185", "5147186"))
    monkeypatch.setattr(gen_robot, "OUT_CORE", stale)
    err = io.StringIO()
    with contextlib.redirect_stderr(err):
        assert gen_robot.main(["--check"]) == 1
    assert str(stale) in err.getvalue()
    assert "5147186" in stale.read_text()  # --check writes nothing


def simulated_board(path: Path) -> dict[str, int]:
    """What host_board_config() derives from the simulator's robot of that file."""
    bc = Simulator(robot=path, record=False).board_config
    out = {}
    for c in gen_robot.constants_of(path):
        if c.macro in HOST_DERIVED:
            values = {member(bc, m) for m in c.members}
            assert len(values) == 1, c.members
            out[c.macro] = values.pop()
    return out


@pytest.mark.parametrize("name", ["default.toml", "avr.toml", "stm32.toml"])
def test_the_simulated_board_derives_the_same(name: str) -> None:
    path = ROOT / "robot" / name
    want = {k: c.value for k, c in constants(path).items() if k in HOST_DERIVED}
    assert simulated_board(path) == want


def write(tmp_path: Path, data: dict[str, Any], name: str = "mine.toml") -> Path:
    lines = []
    for section, table in data.items():
        if not isinstance(table, dict):
            lines.insert(0, f"{section} = {table!r}")
            continue
        lines.append(f"[{section}]")
        lines += [f"{k} = {v!r}" for k, v in table.items()]
    path = tmp_path / name
    path.write_text("\n".join(lines) + "\n")
    return path


def default_data() -> dict[str, Any]:
    with robot.DEFAULT.open("rb") as f:
        return tomllib.load(f)


@settings(
    max_examples=30,
    deadline=None,
    suppress_health_check=[HealthCheck.too_slow, HealthCheck.function_scoped_fixture],
)
@given(
    wheel=st.floats(30, 120),
    track=st.floats(100, 400),
    enc=st.floats(20, 80),
    enc_track=st.floats(100, 500),
    cpr=st.integers(1000, 100000),
    motor_cpr=st.integers(256, 100000),
    gear=st.floats(10, 100),
    offsets=st.tuples(st.floats(-50, 50), st.floats(-50, 50)),
    mu=st.floats(0.1, 1.5),
)
def test_robot_gen_property_agrees_with_the_simulated_board(
    tmp_path: Path,
    wheel: float,
    track: float,
    enc: float,
    enc_track: float,
    cpr: int,
    motor_cpr: int,
    gear: float,
    offsets: tuple[float, float],
    mu: float,
) -> None:
    """For any robot, the generator and host_board_config() (C, from the simulator's robot)
    derive the same geometry constants, to the unit."""
    data = default_data()
    data["drive"].update(wheel_diameter_mm=wheel, track_mm=track)
    data["encoders"].update(
        wheel_diameter_mm=enc, track_mm=enc_track, cpr=cpr, offset_x_mm=offsets[0]
    )
    data["motor"].update(encoder_cpr=motor_cpr, gear_ratio=gear)
    data["outline"].update(offset_x_mm=offsets[1])
    data["body"].update(friction_coeff=mu)
    path = write(tmp_path, data)
    want = {k: c.value for k, c in constants(path).items() if k in HOST_DERIVED}
    assert simulated_board(path) == want


def any_robot() -> st.SearchStrategy[dict[str, Any]]:
    """Any robot file the schema of asserv.robot takes: half of them with each value anywhere in
    its range, half near the reference robot (each value 0.6..1.6 times it, within the range)."""
    ref = default_data()

    def value(section: str, key: str, near: bool) -> st.SearchStrategy[Any]:
        name, _scale, low, high = robot.SCHEMA[section][key]
        if near:
            r = ref[section][key]
            lo, hi = sorted((max(low, r * 0.6), min(high, r * 1.6)))
            if r == 0:
                lo, hi = max(low, -20.0), min(high, 20.0)
        else:
            lo, hi = low, min(high, 1e7)
        if name in robot._INTEGERS:
            return st.integers(math.ceil(lo), math.floor(hi))
        return st.floats(lo, hi, allow_nan=False)

    def whole(near: bool) -> st.SearchStrategy[dict[str, Any]]:
        sections: dict[str, st.SearchStrategy[Any]] = {
            section: st.fixed_dictionaries({k: value(section, k, near) for k in keys})
            for section, keys in robot.SCHEMA.items()
        }
        sections["feedforward"] = st.fixed_dictionaries(
            {}, optional={k: st.integers(lo, hi) for k, (lo, hi) in robot.FEEDFORWARD.items()}
        )
        return st.fixed_dictionaries(sections)

    return st.booleans().flatmap(whole)


@settings(
    max_examples=60,
    deadline=None,
    suppress_health_check=[HealthCheck.too_slow, HealthCheck.function_scoped_fixture],
)
@given(data=any_robot())
def test_robot_gen_property_in_range_or_named(tmp_path: Path, data: dict[str, Any]) -> None:
    """Any valid robot file gives constants the board takes (board_init() accepts them), or
    exit 2 with a message that names the file and a key of it, and no traceback."""
    path = write(tmp_path, data)
    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        code = gen_robot.main(["--show", str(path)])
    event(f"exit {code}")
    if code == 2:
        msg = err.getvalue()
        assert msg.startswith(f"gen_robot.py: {path}: ") and "Traceback" not in msg
        named = msg.split(": ")[2].split(", ")
        assert named and all(k.split(".")[0] in data for k in named), msg
        assert "outside the firmware's" in msg
        return
    assert code == 0 and err.getvalue() == ""
    found = {m: int(v) for m, v in re.findall(r"#define (ROBOT_\w+) (-?\d+)", out.getvalue())}
    cs = gen_robot.constants_of(path)
    assert found == {c.macro: c.value for c in cs}
    # the reference robot's physics, this file's constants: the board must accept them all
    overrides = {m: c.value for c in cs for m in c.members}
    Simulator(record=False, board_config=overrides)  # raises if board_init() refuses


@pytest.mark.parametrize(
    ("change", "keys"),
    [
        (lambda d: d["drive"].update(track_mm=1500.0), "drive.track_mm"),
        (lambda d: d["encoders"].update(cpr=1), "encoders.wheel_diameter_mm, encoders.cpr"),
        (lambda d: d["body"].update(friction_coeff=0.0), "body.friction_coeff"),
        (lambda d: d["outline"].update(offset_x_mm=-300.0), "outline.length_mm"),
        (lambda d: d["feedforward"].update(speed_q15_per_m_s=-1), "feedforward.speed_q15_per_m_s"),
        (lambda d: d["motor"].update(encoder_cpr=0), "motor.encoder_cpr"),
    ],
)
def test_bad_files_exit_2_naming_the_file_and_key(tmp_path: Path, change: Any, keys: str) -> None:
    data = default_data()
    change(data)
    path = write(tmp_path, data)
    r = subprocess.run(
        [sys.executable, str(ROOT / "robot" / "gen_robot.py"), "--show", str(path)],
        capture_output=True,
        text=True,
        check=False,
    )
    assert r.returncode == 2 and r.stdout == ""
    assert r.stderr.startswith(f"gen_robot.py: {path}: {keys}") or (
        r.stderr.startswith(f"gen_robot.py: {path}: ") and keys in r.stderr
    ), r.stderr
    assert "Traceback" not in r.stderr


def test_a_file_on_a_base(tmp_path: Path) -> None:
    """A port's file restates only what differs; a bad base is named."""
    (tmp_path / "base.toml").write_text(robot.DEFAULT.read_text())
    mine = tmp_path / "mine.toml"
    mine.write_text('base = "base.toml"\n[motor]\nencoder_cpr = 48\n')
    got = robot.load(mine)
    ref = robot.load(robot.DEFAULT)
    assert got.values == {**ref.values, "motor.encoder_cpr": 48.0}
    assert got.feedforward == ref.feedforward
    mine.write_text('base = "mine.toml"\n')
    with pytest.raises(robot.RobotError, match="leads back to itself"):
        robot.load(mine)
    mine.write_text('base = "none.toml"\n')
    with pytest.raises(robot.RobotError, match=r"mine\.toml: base: .*none\.toml: cannot read"):
        robot.load(mine)
    mine.write_text("base = 3\n")
    with pytest.raises(robot.RobotError, match="is not a file name"):
        robot.load(mine)
    mine.write_text('base = "base.toml"\n[feedforward]\nspeed_q15_per_m_s = "fast"\n')
    with pytest.raises(robot.RobotError, match=r"feedforward\.speed_q15_per_m_s: 'fast'"):
        robot.load(mine)


def test_the_avr_file_simulates_its_encoders() -> None:
    sim = Simulator(robot=ROOT / "robot" / "avr.toml", record=False)
    assert sim.config.motor.encoder_cpr == 48
    assert sim.board_config.faults.motor_um_per_count_q16 == 13768191
