"""The playing field: one description file (TOML) shared by the simulator and the board.

``field/default.toml`` is the field the C code is built with (``field/gen_field.py`` turns it into
``sim/field_default_gen.h`` and ``firmware/core/field_defs.h``); any other file describes
another field for the simulator and for the board's configuration (``asserv.sim``).

Only the standard library is used here, so that ``field/gen_field.py`` can load this module before
any virtual environment exists.
"""

from __future__ import annotations

import importlib.resources
import math
import tomllib
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any


def data_dir(name: str) -> Path:
    """The directory of the simulator's data files ``name`` ("field" or "scenarios").

    Installed, they are package data of asserv-sim (``pip install "asserv[sim]"``), found with
    importlib.resources; in a checkout without it, the repository's own directory.
    """
    try:
        packaged = importlib.resources.files("asserv_sim") / name
        if packaged.is_dir():
            return Path(str(packaged))
    except ModuleNotFoundError:
        pass
    return Path(__file__).resolve().parents[2] / name


#: The field files: field/ of the repository, installed as asserv-sim's package data.
FIELD_DIR = data_dir("field")
DEFAULT = FIELD_DIR / "default.toml"
if not DEFAULT.is_file():  # the driver alone (asserv[view] on a Pi): the default field it carries
    DEFAULT = Path(__file__).resolve().parent / "field_default.toml"

# Capacities of the C structures the description is copied into.
MAX_OBSTACLES = 16  # sim.h SIM_MAX_OBSTACLES: baskets and other obstacles together
MAX_BASKETS = 4  # orders.h ORDERS_MAX_BASKETS: the baskets the board knows
MAX_LINES = 32  # sim.h SIM_MAX_LINES
MAX_COORD_MM = 32000.0  # positions travel as signed 16-bit millimetres


class FieldError(ValueError):
    """A field file that cannot describe a field; the message names the file and the entry."""


@dataclass(frozen=True)
class Basket:
    x_mm: float
    y_mm: float
    radius_mm: float


@dataclass(frozen=True)
class Line:
    x0_mm: float
    y0_mm: float
    x1_mm: float
    y1_mm: float
    width_mm: float


@dataclass(frozen=True)
class Obstacle:
    """Something that stops the robot and presses its shock switches, but is not a basket."""

    shape: str  # "circle" (radius_mm) or "box" (axis-aligned, half_x_mm, half_y_mm)
    x_mm: float
    y_mm: float
    radius_mm: float = 0.0
    half_x_mm: float = 0.0
    half_y_mm: float = 0.0


@dataclass(frozen=True)
class Field:
    length_mm: float = 3000.0
    width_mm: float = 2100.0
    borders: bool = True
    baskets: tuple[Basket, ...] = ()
    lines: tuple[Line, ...] = ()
    obstacles: tuple[Obstacle, ...] = field(default=())
    source: str = "<built in>"


_TABLE_KEYS = {"length_mm", "width_mm", "borders"}
_BASKET_KEYS = {"x_mm", "y_mm", "radius_mm"}
_LINE_KEYS = {"x0_mm", "y0_mm", "x1_mm", "y1_mm", "width_mm"}
_OBSTACLE_KEYS = {"shape", "x_mm", "y_mm", "radius_mm", "half_x_mm", "half_y_mm"}
_TOP_KEYS = {"table", "basket", "line", "obstacle"}


class _Reader:
    def __init__(self, source: str) -> None:
        self.source = source

    def fail(self, where: str, what: str) -> FieldError:
        return FieldError(f"{self.source}: {where}: {what}")

    def keys(self, where: str, d: Any, allowed: set[str], required: set[str]) -> dict[str, Any]:
        if not isinstance(d, dict):
            raise self.fail(where, "must be a table of keys")
        unknown = sorted(set(d) - allowed)
        if unknown:
            raise self.fail(
                where, f"unknown key {unknown[0]!r} (known: {', '.join(sorted(allowed))})"
            )
        missing = sorted(required - set(d))
        if missing:
            raise self.fail(where, f"missing key {missing[0]!r}")
        return d

    def number(
        self,
        where: str,
        d: dict[str, Any],
        key: str,
        *,
        positive: bool = False,
        default: float | None = None,
    ) -> float:
        if key not in d and default is not None:
            return default
        v = d[key]
        if isinstance(v, bool) or not isinstance(v, int | float):
            raise self.fail(where, f"{key} must be a number, not {v!r}")
        x = float(v)
        if not math.isfinite(x) or abs(x) > MAX_COORD_MM:
            raise self.fail(
                where, f"{key} = {v!r} is out of range (-{MAX_COORD_MM:g}..{MAX_COORD_MM:g})"
            )
        if positive and x <= 0:
            raise self.fail(where, f"{key} must be > 0, not {v!r}")
        return x


def parse(data: dict[str, Any], source: str = "<field>") -> Field:
    """Check a decoded field description and build the Field; FieldError names what is wrong."""
    r = _Reader(source)
    unknown = sorted(set(data) - _TOP_KEYS)
    if unknown:
        raise r.fail(
            "top level", f"unknown table {unknown[0]!r} (known: {', '.join(sorted(_TOP_KEYS))})"
        )
    t = r.keys("[table]", data.get("table", {}), _TABLE_KEYS, set())
    length = r.number("[table]", t, "length_mm", positive=True, default=3000.0)
    width = r.number("[table]", t, "width_mm", positive=True, default=2100.0)
    borders = t.get("borders", True)
    if not isinstance(borders, bool):
        raise r.fail("[table]", f"borders must be true or false, not {borders!r}")

    def entries(name: str) -> list[Any]:
        v = data.get(name, [])
        if not isinstance(v, list):
            raise r.fail(f"[[{name}]]", f"must be an array of tables ([[{name}]] entries)")
        return v

    baskets = []
    for i, b in enumerate(entries("basket"), 1):
        where = f"basket {i}"
        r.keys(where, b, _BASKET_KEYS, _BASKET_KEYS)
        baskets.append(
            Basket(
                r.number(where, b, "x_mm"),
                r.number(where, b, "y_mm"),
                r.number(where, b, "radius_mm", positive=True),
            )
        )
    lines = []
    for i, ln in enumerate(entries("line"), 1):
        where = f"line {i}"
        r.keys(where, ln, _LINE_KEYS, _LINE_KEYS)
        lines.append(
            Line(
                r.number(where, ln, "x0_mm"),
                r.number(where, ln, "y0_mm"),
                r.number(where, ln, "x1_mm"),
                r.number(where, ln, "y1_mm"),
                r.number(where, ln, "width_mm", positive=True),
            )
        )
    obstacles = []
    for i, o in enumerate(entries("obstacle"), 1):
        where = f"obstacle {i}"
        r.keys(where, o, _OBSTACLE_KEYS, {"shape", "x_mm", "y_mm"})
        shape = o["shape"]
        if shape == "circle":
            r.keys(where, o, {"shape", "x_mm", "y_mm", "radius_mm"}, {"radius_mm"})
            obstacles.append(
                Obstacle(
                    "circle",
                    r.number(where, o, "x_mm"),
                    r.number(where, o, "y_mm"),
                    radius_mm=r.number(where, o, "radius_mm", positive=True),
                )
            )
        elif shape == "box":
            r.keys(
                where,
                o,
                {"shape", "x_mm", "y_mm", "half_x_mm", "half_y_mm"},
                {"half_x_mm", "half_y_mm"},
            )
            obstacles.append(
                Obstacle(
                    "box",
                    r.number(where, o, "x_mm"),
                    r.number(where, o, "y_mm"),
                    half_x_mm=r.number(where, o, "half_x_mm", positive=True),
                    half_y_mm=r.number(where, o, "half_y_mm", positive=True),
                )
            )
        else:
            raise r.fail(where, f'shape must be "circle" or "box", not {shape!r}')
    if len(baskets) > MAX_BASKETS:
        raise r.fail("[[basket]]", f"{len(baskets)} baskets: the board knows at most {MAX_BASKETS}")
    if len(baskets) + len(obstacles) > MAX_OBSTACLES:
        raise r.fail(
            "[[obstacle]]",
            f"{len(baskets) + len(obstacles)} baskets and obstacles: the simulator holds at most "
            f"{MAX_OBSTACLES}",
        )
    if len(lines) > MAX_LINES:
        raise r.fail("[[line]]", f"{len(lines)} lines: the simulator holds at most {MAX_LINES}")
    return Field(length, width, borders, tuple(baskets), tuple(lines), tuple(obstacles), source)


def load(path: str | Path = DEFAULT) -> Field:
    """Read and check a field file. Raises FieldError (syntax errors give the line and column)."""
    p = Path(path)
    try:
        with p.open("rb") as f:
            data = tomllib.load(f)
    except OSError as e:
        raise FieldError(f"{p}: cannot read the field file: {e.strerror}") from None
    except tomllib.TOMLDecodeError as e:
        raise FieldError(f"{p}: not valid TOML: {e}") from None
    return parse(data, str(p))
