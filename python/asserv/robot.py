"""The robot description: one TOML file for the simulated robot's wheels, encoders, motors and
outline (robot/default.toml, the reference robot).

``robot/gen_robot.py`` turns robot/default.toml into ``sim/robot_default_gen.h``, from which
``sim_config_defaults()`` (sim/config.c) builds the simulator's robot, and into the board's
constants (``firmware/core/robot_defs.h``, and a port's from its own file, robot/avr.toml);
``load(path)`` reads any other file, and ``Robot.sim_config()`` gives the members of
``struct sim_config`` it sets, for ``Simulator(robot=path)``. A file may start from another
(``base = "default.toml"``, a path from its own folder) and restate only what differs. Only the
standard library is used, so that the generator can load this module before any virtual
environment exists.
"""

from __future__ import annotations

import math
import tomllib
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

#: The repository's robot files.
ROBOT_DIR = Path(__file__).resolve().parents[2] / "robot"
DEFAULT = ROBOT_DIR / "default.toml"


class RobotError(ValueError):
    """A robot file that cannot describe a robot; the message names the file and the key."""


# section -> key -> (struct sim_config member, scale from the file's unit, lowest, highest)
# (lowest exclusive when it is 0 and the value must be positive: see _POSITIVE)
SCHEMA: dict[str, dict[str, tuple[str, float, float, float]]] = {
    "body": {
        "mass_kg": ("mass_kg", 1.0, 0.1, 200.0),
        "yaw_inertia_kg_m2": ("yaw_inertia_kg_m2", 1.0, 1e-4, 100.0),
        "drive_weight_share": ("drive_weight_share", 1.0, 0.01, 1.0),
        "friction_coeff": ("friction_coeff", 1.0, 0.0, 5.0),
        "battery_V": ("battery_V", 1.0, 1.0, 60.0),
    },
    "drive": {
        "wheel_diameter_mm": ("drive_radius_mm", 0.5, 5.0, 500.0),
        "track_mm": ("drive_track_mm", 1.0, 20.0, 2000.0),
        "wheel_inertia_g_cm2": ("wheel_inertia_g_cm2", 1.0, 0.0, 1e6),
    },
    "motor": {
        "kv_rpm_per_V": ("motor.kv_rpm_per_V", 1.0, 1.0, 1e5),
        "kt_mNm_per_A": ("motor.kt_mNm_per_A", 1.0, 0.01, 1e4),
        "resistance_ohm": ("motor.resistance_ohm", 1.0, 1e-3, 1e3),
        "inductance_mH": ("motor.inductance_mH", 1.0, 0.0, 1e3),
        "rotor_inertia_g_cm2": ("motor.rotor_inertia_g_cm2", 1.0, 0.01, 1e5),
        "friction_mNm": ("motor.friction_mNm", 1.0, 0.0, 1e3),
        "gear_ratio": ("motor.gear_ratio", 1.0, 0.1, 1e4),
        "gear_efficiency": ("motor.gear_efficiency", 1.0, 0.01, 1.0),
        "encoder_cpr": ("motor.encoder_cpr", 1.0, 1.0, 1e7),
    },
    "encoders": {
        "wheel_diameter_mm": ("enc_radius_mm", 0.5, 5.0, 500.0),
        "track_mm": ("enc_track_mm", 1.0, 20.0, 2000.0),
        "offset_x_mm": ("enc_offset_x_mm", 1.0, -1000.0, 1000.0),
        "cpr": ("enc_cpr", 1.0, 1.0, 1e7),
    },
    "outline": {
        "length_mm": ("outline_length_mm", 1.0, 10.0, 2000.0),
        "width_mm": ("outline_width_mm", 1.0, 10.0, 2000.0),
        "offset_x_mm": ("outline_offset_x_mm", 1.0, -1000.0, 1000.0),
        "offset_y_mm": ("outline_offset_y_mm", 1.0, -1000.0, 1000.0),
    },
}
_INTEGERS = {"motor.encoder_cpr", "enc_cpr"}

#: Optional: the board's feed-forward coefficients (firmware/core/control.h) when the file states
#: them (tuned); a key left out, or "model", leaves them to the motor model of robot/gen_robot.py.
#: key -> (lowest, highest), whole numbers (control_init() refuses the rest).
FEEDFORWARD: dict[str, tuple[int, int]] = {
    "speed_q15_per_m_s": (0, 1000000),
    "accel_q15_per_m_s2": (0, 1000000),
    "angle_accel_q15_per_m_s2": (0, 1000000),
}


@dataclass(frozen=True)
class Robot:
    """A robot file's values, by ``struct sim_config`` member (SI as in sim/sim.h)."""

    source: str
    values: dict[str, float]
    #: the [feedforward] values the file states (key of FEEDFORWARD -> value)
    feedforward: dict[str, int] = field(default_factory=dict)

    def sim_config(self) -> dict[str, Any]:
        """The ``config`` overrides of ``asserv.sim.Simulator`` that make this robot."""
        return {k: (int(v) if k in _INTEGERS else v) for k, v in self.values.items()}


def parse(data: dict[str, Any], source: str = "<robot>") -> Robot:
    """Check a loaded TOML document; RobotError names the first bad entry."""

    def fail(where: str, what: str) -> RobotError:
        return RobotError(f"{source}: {where}: {what}")

    values: dict[str, float] = {}
    unknown = set(data) - set(SCHEMA) - {"feedforward"}
    if unknown:
        raise fail(sorted(unknown)[0], f"unknown section (known: {', '.join(SCHEMA)})")
    for section, keys in SCHEMA.items():
        table = data.get(section)
        if not isinstance(table, dict):
            raise fail(f"[{section}]", "missing section" if table is None else "not a table")
        extra = set(table) - set(keys)
        if extra:
            raise fail(f"{section}.{sorted(extra)[0]}", f"unknown key (known: {', '.join(keys)})")
        for key, (member, scale, low, high) in keys.items():
            where = f"{section}.{key}"
            if key not in table:
                raise fail(where, "missing")
            v = table[key]
            if isinstance(v, bool) or not isinstance(v, int | float) or not math.isfinite(v):
                raise fail(where, f"{v!r} is not a number")
            if member in _INTEGERS and not float(v).is_integer():
                raise fail(where, f"{v!r} is not a whole number")
            if not low <= v <= high:
                raise fail(where, f"{v!r} is outside {low:g}..{high:g}")
            values[member] = float(v) * scale
    return Robot(source, values, _feedforward(data.get("feedforward", {}), fail))


def _feedforward(table: Any, fail: Callable[[str, str], RobotError]) -> dict[str, int]:
    if not isinstance(table, dict):
        raise fail("[feedforward]", "not a table")
    extra = set(table) - set(FEEDFORWARD)
    if extra:
        known = ", ".join(FEEDFORWARD)
        raise fail(f"feedforward.{sorted(extra)[0]}", f"unknown key (known: {known})")
    out: dict[str, int] = {}
    for key, (low, high) in FEEDFORWARD.items():
        v = table.get(key, "model")
        if v == "model":
            continue
        where = f"feedforward.{key}"
        if isinstance(v, bool) or not isinstance(v, int):
            raise fail(where, f'{v!r} is not a whole number (or "model")')
        if not low <= v <= high:
            raise fail(where, f"{v!r} is outside {low}..{high}")
        out[key] = v
    return out


def _merged(base: dict[str, Any], over: dict[str, Any]) -> dict[str, Any]:
    """base with over's sections laid on it key by key."""
    out = {k: dict(v) if isinstance(v, dict) else v for k, v in base.items()}
    for k, v in over.items():
        if isinstance(v, dict) and isinstance(out.get(k), dict):
            out[k].update(v)
        else:
            out[k] = v
    return out


def _read(p: Path, chain: tuple[Path, ...] = ()) -> dict[str, Any]:
    """The TOML document of p, with its ``base`` file (and that one's) under it."""
    try:
        with p.open("rb") as f:
            data = tomllib.load(f)
    except OSError as e:
        raise RobotError(f"{p}: cannot read the robot file: {e.strerror}") from None
    except tomllib.TOMLDecodeError as e:
        raise RobotError(f"{p}: not valid TOML: {e}") from None
    if "base" not in data:
        return data
    base = data.pop("base")
    if not isinstance(base, str):
        raise RobotError(f"{p}: base: {base!r} is not a file name")
    bp = p.parent / base
    if bp.resolve() in (*chain, p.resolve()):
        raise RobotError(f"{p}: base: {base!r} leads back to itself")
    try:
        under = _read(bp, (*chain, p.resolve()))
    except RobotError as e:
        raise RobotError(f"{p}: base: {e}") from None
    return _merged(under, data)


def load(path: str | Path = DEFAULT) -> Robot:
    """Read and check a robot file (and its ``base``, if it names one)."""
    p = Path(path)
    return parse(_read(p), str(p))
