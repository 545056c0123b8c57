"""Run logs: the same values as an MCAP file (Foxglove, Lichtblick, PlotJuggler) and as CSV.

A log is a table with one row per sample and the columns ``LOG_FIELDS`` (``LOG_DTYPE``), from a
simulated run (``from_trace``: every control tick, the truth included) or from a real board polled
over I2C (``poll_board``: POSITION, DEBUG and CHECK_BUSY; the truth is unknown, NaN). A value that
is not known is NaN in the table and an empty cell in the CSV.

    sim = Simulator()
    board = Board(sim.bus)
    board.goto(500, 0)
    board.wait_idle(10)
    log.save(log.from_sim(sim), mcap="run.mcap", csv="run.csv", field=sim.field)

The MCAP file has, with JSON-encoded messages and a JSON schema per channel:

- ``/field`` (``foxglove.SceneUpdate``): the table, its borders, lines, baskets and obstacles;
- ``/robot`` (``foxglove.SceneUpdate``): the robot's outline, in the frames ``robot`` (the board's
  estimate) and ``robot_true`` (the simulated truth), as the 3D panel draws them;
- ``/tf`` (``foxglove.FrameTransform``): ``field`` to ``robot`` and to ``robot_true``;
- ``/pose/estimate`` and ``/pose/true`` (``foxglove.PoseInFrame``): the two poses;
- ``/asserv`` (``asserv.Sample``): every column of the table, for plots (mm, degrees, s).

Positions in the Foxglove messages are in metres (their convention); in ``/asserv`` and the CSV
they are in millimetres.
"""

from __future__ import annotations

import argparse
import csv
import dataclasses
import json
import math
import struct
import sys
import time
from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import IO, TYPE_CHECKING, Any

import numpy as np

from ._columns import INTEGER, LOG_FIELDS, UNITS
from .bus import Clock
from .field import Field

if TYPE_CHECKING:
    from .driver import Board
    from .sim import Simulator

__all__ = [
    "LOG_DTYPE",
    "LOG_FIELDS",
    "LogError",
    "LogWriter",
    "Outline",
    "from_sim",
    "from_trace",
    "poll_board",
    "read_csv",
    "read_mcap",
    "save",
]

#: The columns of a log, in order, what each is, and those that hold integers: one table,
#: firmware/ports/host/trace.toml, generated into _columns.py. ``dist_err_mm`` and
#: ``angle_err_mm`` are the following errors of the distance loop and of the angle loop (as the
#: arc at the drive wheels), as DEBUG reports them; ``end_reason`` is DEBUG's (the end_reason
#: table of protocol/messages.toml).
LOG_DTYPE = np.dtype([(name, "<f8") for name in LOG_FIELDS])

#: The MCAP header's profile: JSON messages with JSON schemas, Foxglove's well-known schemas and
#: asserv.Sample; times are wall-clock ns since 1970 (UTC).
PROFILE = "asserv"


def _version() -> str:
    from . import __version__

    return __version__


class LogError(ValueError):
    """A log that cannot be written or read; the message names the file."""


@dataclass(frozen=True)
class Outline:
    """The robot's rectangle in its own frame (x forward), mm: what the view and /robot draw."""

    length_mm: float = 250.0
    width_mm: float = 300.0
    offset_x_mm: float = 0.0
    offset_y_mm: float = 0.0

    @classmethod
    def of(cls, sim: Simulator) -> Outline:
        c = sim.config
        return cls(
            float(c.outline_length_mm),
            float(c.outline_width_mm),
            float(c.outline_offset_x_mm),
            float(c.outline_offset_y_mm),
        )


# ---- tables -----------------------------------------------------------------------------------


def empty(n: int = 0) -> np.ndarray:
    """A log of n rows, every value unknown (NaN)."""
    out = np.zeros(n, dtype=LOG_DTYPE)
    for name in LOG_FIELDS:
        out[name] = np.nan
    return out


#: A step of the estimate this far from the truth's step in one tick is a correction of the pose
#: (a recalibration, SET_NEW_POS), not travel: odometry errs by micrometres per tick.
CORRECTION_MM = 0.3
CORRECTION_DEG = 0.05
_BUSY_BITS = 2 | 4  # BUSY_TRAJET, BUSY_GOTO_PANIER
_REANCHOR_STATES = (6, 7)  # SQUARE, BACK_OFF (the order_state table)


class FollowingErrors:
    """The distance loop's and the angle loop's following errors, mm, rebuilt from a simulator
    trace, chunk after chunk (``update``): the set point's travel (its speed summed over the
    ticks) minus the estimate's travel (along its heading, and its heading's change times half
    the drive track).

    - The board's loops follow the odometry's travel, which a correction of the pose does not
      move: in a tick where the estimate jumps (``CORRECTION_MM``, ``CORRECTION_DEG``), the
      truth's step stands for the travel.
    - Each order counts from zero: the board's error is continuous there but settled (hundredths
      of a mm), and this keeps what a rebuild misses from piling up over a match.
    - The border recalibration re-anchors the set points (SQUARE, BACK_OFF): unknown (NaN) from
      there to the next order.
    """

    def __init__(self, drive_track_mm: float) -> None:
        self.half_track_mm = drive_track_mm / 2
        self._prev: np.ndarray | None = None  # the last row seen
        self._sums = (0.0, 0.0)  # the running values after it
        self._busy = False
        self._unknown = False

    def update(self, trace: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        n = len(trace)
        if n == 0:
            return np.zeros(0), np.zeros(0)
        first = trace[:1] if self._prev is None else self._prev

        def steps(prefix: str) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
            x = np.concatenate((first[prefix + "x_mm"], trace[prefix + "x_mm"]))
            y = np.concatenate((first[prefix + "y_mm"], trace[prefix + "y_mm"]))
            h = np.unwrap(
                np.radians(
                    np.concatenate((first[prefix + "heading_deg"], trace[prefix + "heading_deg"]))
                )
            )
            return np.diff(x), np.diff(y), np.diff(h)

        t = np.concatenate((first["t_s"], trace["t_s"]))
        dt = np.diff(t)
        dx, dy, dh = steps("est_")
        tx, ty, th = steps("")
        jump = (np.hypot(dx - tx, dy - ty) > CORRECTION_MM) | (
            np.abs(dh - th) > np.radians(CORRECTION_DEG)
        )
        jump &= ~np.isnan(tx)  # no truth: no way to tell
        dx, dy, dh = (np.where(jump, b, a) for a, b in ((dx, tx), (dy, ty), (dh, th)))
        h = np.radians(trace["est_heading_deg"])
        inc_d = trace["v_set_mm_s"] * dt - (dx * np.cos(h) + dy * np.sin(h))
        inc_t = (np.radians(trace["omega_set_deg_s"]) * dt - dh) * self.half_track_mm

        busy = (np.nan_to_num(trace["status"]).astype(int) & _BUSY_BITS) != 0
        rise = busy & ~np.concatenate(([self._busy], busy[:-1]))
        starts = np.nonzero(rise)[0]
        seg = np.searchsorted(starts, np.arange(n), side="right")  # 0: before a new order
        out = []
        for inc, carried in ((inc_d, self._sums[0]), (inc_t, self._sums[1])):
            c = np.cumsum(inc) + carried
            before = np.where(starts > 0, c[np.maximum(starts - 1, 0)], carried)
            out.append(c - np.concatenate(([0.0], before))[seg])
        dist, turn = out
        self._sums = (float(dist[-1]), float(turn[-1]))

        lost = np.isin(np.nan_to_num(trace["order_state"]).astype(int), _REANCHOR_STATES)
        unknown = np.zeros(n, dtype=bool)
        bounds = [0, *starts.tolist(), n]
        flag = self._unknown
        for k in range(len(bounds) - 1):
            lo, hi = bounds[k], bounds[k + 1]
            if k > 0 or (len(starts) and starts[0] == 0):
                flag = False  # a new order
            hits = np.nonzero(lost[lo:hi])[0]
            if flag:
                unknown[lo:hi] = True
            elif len(hits):
                unknown[lo + hits[0] : hi] = True
                flag = True
        self._unknown = flag
        self._busy = bool(busy[-1])
        self._prev = trace[-1:].copy()
        return np.where(unknown, np.nan, dist), np.where(unknown, np.nan, turn)


def following_errors(trace: np.ndarray, drive_track_mm: float) -> tuple[np.ndarray, np.ndarray]:
    """``FollowingErrors`` over a whole trace."""
    return FollowingErrors(drive_track_mm).update(trace)


def from_trace(trace: np.ndarray, drive_track_mm: float = 160.0) -> np.ndarray:
    """A log from a simulator trace (asserv.sim.TRACE_FIELDS): every tick, the truth included;
    the following errors rebuilt (``following_errors``); end_reason unknown (NaN)."""
    out = empty(len(trace))
    for name in LOG_FIELDS:
        if name in (trace.dtype.names or ()):
            out[name] = trace[name]
    out["dist_err_mm"], out["angle_err_mm"] = following_errors(trace, drive_track_mm)
    return out


def from_sim(sim: Simulator) -> np.ndarray:
    """The log of a simulated run so far (``Simulator(record=True)``, the default)."""
    return from_trace(sim.trace, float(sim.config.drive_track_mm))


# ---- writing ----------------------------------------------------------------------------------


def _ns(t_s: float, start_ns: int = 0) -> int:
    """The wall-clock time of the log's time ``t_s``: its start, plus ``t_s`` (ns)."""
    return start_ns + max(0, round(t_s * 1e9))


def _stamp(t_s: float, start_ns: int = 0) -> dict[str, int]:
    ns = _ns(t_s, start_ns)
    return {"sec": ns // 1_000_000_000, "nsec": ns % 1_000_000_000}


def _quat(heading_deg: float) -> dict[str, float]:
    h = math.radians(heading_deg) / 2
    return {"x": 0.0, "y": 0.0, "z": math.sin(h), "w": math.cos(h)}


def _num(v: float) -> float | None:
    return None if math.isnan(v) else float(v)


def _obj(props: dict[str, Any], required: Sequence[str] | None = None) -> dict[str, Any]:
    return {
        "type": "object",
        "properties": props,
        "required": list(props if required is None else required),
    }


_NUM = {"type": "number"}
_TIME = _obj({"sec": {"type": "integer"}, "nsec": {"type": "integer"}})
_VEC3 = _obj({"x": _NUM, "y": _NUM, "z": _NUM})
_QUAT = _obj({"x": _NUM, "y": _NUM, "z": _NUM, "w": _NUM})
_POSE = _obj({"position": _VEC3, "orientation": _QUAT})
_COLOR = _obj({"r": _NUM, "g": _NUM, "b": _NUM, "a": _NUM})
_PRIMITIVE = {"type": "array", "items": {"type": "object"}}

#: JSON schemas of the Foxglove well-known message types this log uses, as the fields they are
#: written with (Foxglove's documentation lists the full types).
SCHEMAS: dict[str, dict[str, Any]] = {
    "foxglove.PoseInFrame": _obj(
        {"timestamp": _TIME, "frame_id": {"type": "string"}, "pose": _POSE}
    ),
    "foxglove.FrameTransform": _obj(
        {
            "timestamp": _TIME,
            "parent_frame_id": {"type": "string"},
            "child_frame_id": {"type": "string"},
            "translation": _VEC3,
            "rotation": _QUAT,
        }
    ),
    "foxglove.SceneUpdate": _obj(
        {
            "deletions": {"type": "array", "items": {"type": "object"}},
            "entities": {
                "type": "array",
                "items": _obj(
                    {
                        "timestamp": _TIME,
                        "frame_id": {"type": "string"},
                        "id": {"type": "string"},
                        "lifetime": _TIME,
                        "frame_locked": {"type": "boolean"},
                        "metadata": {"type": "array", "items": {"type": "object"}},
                        "arrows": _PRIMITIVE,
                        "cubes": _PRIMITIVE,
                        "spheres": _PRIMITIVE,
                        "cylinders": _PRIMITIVE,
                        "lines": _PRIMITIVE,
                        "triangles": _PRIMITIVE,
                        "texts": _PRIMITIVE,
                        "models": _PRIMITIVE,
                    }
                ),
            },
        }
    ),
    "asserv.Sample": _obj(
        {
            name: {
                "type": ["integer" if name in INTEGER else "number", "null"],
                "description": UNITS[name],
            }
            for name in LOG_FIELDS
        }
    ),
}

#: topic: schema name.
TOPICS = {
    "/field": "foxglove.SceneUpdate",
    "/robot": "foxglove.SceneUpdate",
    "/tf": "foxglove.FrameTransform",
    "/pose/estimate": "foxglove.PoseInFrame",
    "/pose/true": "foxglove.PoseInFrame",
    "/asserv": "asserv.Sample",
}


def _pose(x_mm: float, y_mm: float, z_mm: float, heading_deg: float) -> dict[str, Any]:
    return {
        "position": {"x": x_mm / 1000, "y": y_mm / 1000, "z": z_mm / 1000},
        "orientation": _quat(heading_deg),
    }


def _entity(
    frame: str, ident: str, t_s: float, start_ns: int = 0, **prims: list[dict[str, Any]]
) -> dict[str, Any]:
    e: dict[str, Any] = {
        "timestamp": _stamp(t_s, start_ns),
        "frame_id": frame,
        "id": ident,
        "lifetime": {"sec": 0, "nsec": 0},
        "frame_locked": True,
        "metadata": [],
    }
    for kind in ("arrows", "cubes", "spheres", "cylinders", "lines", "triangles", "texts"):
        e[kind] = prims.get(kind, [])
    e["models"] = []
    return e


def _color(r: float, g: float, b: float, a: float = 1.0) -> dict[str, float]:
    return {"r": r, "g": g, "b": b, "a": a}


def field_dict(field: Field) -> dict[str, Any]:
    """The field as plain data (the view's and the MCAP metadata's form)."""
    d = dataclasses.asdict(field)
    d.pop("source", None)
    return d


def field_from_dict(d: dict[str, Any]) -> Field:
    """The inverse of ``field_dict``."""
    from .field import Basket, Line, Obstacle

    return Field(
        length_mm=float(d["length_mm"]),
        width_mm=float(d["width_mm"]),
        borders=bool(d["borders"]),
        baskets=tuple(Basket(**b) for b in d["baskets"]),
        lines=tuple(Line(**ln) for ln in d["lines"]),
        obstacles=tuple(Obstacle(**o) for o in d["obstacles"]),
        source="<MCAP log>",
    )


def field_scene(field: Field, t_s: float = 0.0, start_ns: int = 0) -> dict[str, Any]:
    """The field as a foxglove.SceneUpdate in the frame ``field`` (metres), stamped at the log's
    start ``start_ns`` (ns since 1970, UTC) plus ``t_s``."""
    hx, hy = field.length_mm / 2, field.width_mm / 2
    corners = [(-hx, -hy), (hx, -hy), (hx, hy), (-hx, hy), (-hx, -hy)]
    border = {
        "type": 0,  # LINE_STRIP
        "pose": _pose(0, 0, 0, 0),
        "thickness": 0.02,
        "scale_invariant": False,
        "points": [{"x": x / 1000, "y": y / 1000, "z": 0.0} for x, y in corners],
        "color": _color(0.1, 0.1, 0.1),
        "colors": [],
        "indices": [],
    }
    lines = [
        {
            "type": 2,  # LINE_LIST (0 LINE_STRIP, 1 LINE_LOOP)
            "pose": _pose(0, 0, 0, 0),
            "thickness": ln.width_mm / 1000,
            "scale_invariant": False,
            "points": [
                {"x": ln.x0_mm / 1000, "y": ln.y0_mm / 1000, "z": 0.001},
                {"x": ln.x1_mm / 1000, "y": ln.y1_mm / 1000, "z": 0.001},
            ],
            "color": _color(0.2, 0.2, 0.2),
            "colors": [],
            "indices": [],
        }
        for ln in field.lines
    ]
    cylinders = [
        {
            "pose": _pose(b.x_mm, b.y_mm, 50, 0),
            "size": {"x": b.radius_mm / 500, "y": b.radius_mm / 500, "z": 0.1},
            "bottom_scale": 1.0,
            "top_scale": 1.0,
            "color": _color(1.0, 0.5, 0.05, 0.7),
        }
        for b in field.baskets
    ]
    cubes = []
    for o in field.obstacles:
        if o.shape == "circle":
            cylinders.append(
                {
                    "pose": _pose(o.x_mm, o.y_mm, 50, 0),
                    "size": {"x": o.radius_mm / 500, "y": o.radius_mm / 500, "z": 0.1},
                    "bottom_scale": 1.0,
                    "top_scale": 1.0,
                    "color": _color(0.5, 0.5, 0.5, 0.7),
                }
            )
        else:
            cubes.append(
                {
                    "pose": _pose(o.x_mm, o.y_mm, 50, 0),
                    "size": {"x": o.half_x_mm / 500, "y": o.half_y_mm / 500, "z": 0.1},
                    "color": _color(0.5, 0.5, 0.5, 0.7),
                }
            )
    table = {
        "pose": _pose(0, 0, -5, 0),
        "size": {"x": field.length_mm / 1000, "y": field.width_mm / 1000, "z": 0.01},
        "color": _color(0.85, 0.9, 0.85, 1.0),
    }
    entity = _entity(
        "field",
        "field",
        t_s,
        start_ns,
        lines=[border, *lines],
        cylinders=cylinders,
        cubes=[table, *cubes],
    )
    return {"deletions": [], "entities": [entity]}


def robot_scene(
    outline: Outline, frames: Sequence[str], t_s: float = 0.0, start_ns: int = 0
) -> dict[str, Any]:
    """The robot's outline as a box in each of ``frames`` (``robot``, ``robot_true``)."""
    colors = {"robot": _color(0.85, 0.1, 0.1, 0.5), "robot_true": _color(0.1, 0.3, 0.9, 0.5)}
    entities = [
        _entity(
            frame,
            frame,
            t_s,
            start_ns,
            cubes=[
                {
                    "pose": _pose(outline.offset_x_mm, outline.offset_y_mm, 60, 0),
                    "size": {
                        "x": outline.length_mm / 1000,
                        "y": outline.width_mm / 1000,
                        "z": 0.12,
                    },
                    "color": colors.get(frame, _color(0.5, 0.5, 0.5, 0.5)),
                }
            ],
        )
        for frame in frames
    ]
    return {"deletions": [], "entities": entities}


def sample_json(row: np.void | dict[str, float]) -> dict[str, float | int | None]:
    """One row as the /asserv message (NaN as null; the INTEGER columns as integers)."""
    out: dict[str, float | int | None] = {}
    for name in LOG_FIELDS:
        v = float(row[name])
        out[name] = None if math.isnan(v) else _integer(name, v) if name in INTEGER else v
    return out


def _integer(name: str, v: float) -> int:
    if not v.is_integer():
        raise LogError(f"the column {name} holds integers, not {v!r}")
    return int(v)


def _cell(name: str, v: float) -> str:
    """A CSV cell: empty for NaN, an integer column as an integer, else the float in full."""
    if math.isnan(v):
        return ""
    return str(_integer(name, v)) if name in INTEGER else repr(v)


def _mcap_writer() -> Any:
    try:
        from mcap.writer import Writer
    except ImportError:
        raise LogError(
            "MCAP needs the mcap package: pip install 'asserv[view]' (pyproject.toml)"
        ) from None
    return Writer


def _open(path: str | Path, what: str) -> IO[Any]:
    p = Path(path)
    try:
        return p.open("wb" if what == "mcap" else "w", newline="" if what == "csv" else None)
    except OSError as e:
        raise LogError(f"cannot write the {what} file {p}: {e.strerror}") from None


class LogWriter:
    """Writes rows to an MCAP file and/or a CSV file as they come (a board polled live), or all at
    once (``save``). ``close()`` (or ``with``) ends the files; a file that is not closed is lost
    for MCAP (no summary) but its CSV rows up to the last one are there."""

    def __init__(
        self,
        mcap: str | Path | None = None,
        csv_path: str | Path | None = None,
        *,
        field: Field | None = None,
        outline: Outline | None = None,
        truth: bool = True,
        start_ns: int | None = None,
    ) -> None:
        if mcap is None and csv_path is None:
            raise LogError("nothing to write: give an MCAP file, a CSV file or both")
        self._truth = truth
        #: The wall-clock time of the log's t_s = 0 (ns since 1970, UTC): the MCAP's times are
        #: this plus each row's t_s, so that a viewer dates the recording right.
        self.start_ns = time.time_ns() if start_ns is None else int(start_ns)
        self._mcap_file: IO[Any] | None = None
        self._csv_file: IO[Any] | None = None
        self._writer: Any = None
        self._csv: Any = None
        self._channels: dict[str, int] = {}
        self._seq = 0
        try:
            if mcap is not None:
                Writer = _mcap_writer()  # noqa: N806 (a class)
                self._mcap_file = _open(mcap, "mcap")
                self._writer = Writer(self._mcap_file)
                self._writer.start(profile=PROFILE, library=f"asserv {_version()}")
                schema_ids = {
                    name: self._writer.register_schema(
                        name=name,
                        encoding="jsonschema",
                        data=json.dumps(schema).encode(),
                    )
                    for name, schema in SCHEMAS.items()
                }
                for topic, schema in TOPICS.items():
                    if topic == "/pose/true" and not truth:
                        continue
                    self._channels[topic] = self._writer.register_channel(
                        topic=topic, message_encoding="json", schema_id=schema_ids[schema]
                    )
                meta = {
                    "outline": json.dumps(dataclasses.asdict(outline or Outline())),
                    "start_ns": str(self.start_ns),
                }
                if field is not None:
                    meta["field"] = json.dumps(field_dict(field))
                self._writer.add_metadata("asserv", meta)
                if field is not None:
                    self._write("/field", 0.0, field_scene(field, 0.0, self.start_ns))
                frames = ["robot", "robot_true"] if truth else ["robot"]
                scene = robot_scene(outline or Outline(), frames, 0.0, self.start_ns)
                self._write("/robot", 0.0, scene)
            if csv_path is not None:
                self._csv_file = _open(csv_path, "csv")
                self._csv = csv.writer(self._csv_file)
                self._csv.writerow(LOG_FIELDS)
        except BaseException:
            self._close_files()
            raise

    def _write(self, topic: str, t_s: float, msg: dict[str, Any]) -> None:
        ns = _ns(t_s, self.start_ns)
        self._seq += 1
        self._writer.add_message(
            channel_id=self._channels[topic],
            log_time=ns,
            publish_time=ns,
            sequence=self._seq,
            data=json.dumps(msg, separators=(",", ":")).encode(),
        )

    def add(self, row: np.void | dict[str, float]) -> None:
        """One row (a record of LOG_DTYPE, or a dict with every column)."""
        t = float(row["t_s"])
        if self._writer is not None:
            stamp = _stamp(t, self.start_ns)
            est = (float(row["est_x_mm"]), float(row["est_y_mm"]), float(row["est_heading_deg"]))
            tru = (float(row["x_mm"]), float(row["y_mm"]), float(row["heading_deg"]))
            poses = [("estimate", "robot", est)]
            if self._truth and not any(math.isnan(v) for v in tru):
                poses.append(("true", "robot_true", tru))
            for name, frame, (x, y, h) in poses:
                if any(math.isnan(v) for v in (x, y, h)):
                    continue
                self._write(
                    f"/pose/{name}",
                    t,
                    {"timestamp": stamp, "frame_id": "field", "pose": _pose(x, y, 0, h)},
                )
                self._write(
                    "/tf",
                    t,
                    {
                        "timestamp": stamp,
                        "parent_frame_id": "field",
                        "child_frame_id": frame,
                        "translation": {"x": x / 1000, "y": y / 1000, "z": 0.0},
                        "rotation": _quat(h),
                    },
                )
            self._write("/asserv", t, sample_json(row))
        if self._csv is not None:
            self._csv.writerow(_cell(n, float(row[n])) for n in LOG_FIELDS)

    def flush(self) -> None:
        if self._csv_file is not None:
            self._csv_file.flush()

    def close(self) -> None:
        try:
            if self._writer is not None:
                self._writer.finish()
                self._writer = None
        finally:
            self._close_files()

    def _close_files(self) -> None:
        for f in (self._mcap_file, self._csv_file):
            if f is not None:
                f.close()
        self._mcap_file = self._csv_file = None

    def __enter__(self) -> LogWriter:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


def save(
    rows: np.ndarray,
    *,
    mcap: str | Path | None = None,
    csv: str | Path | None = None,
    field: Field | None = None,
    outline: Outline | None = None,
    every: int = 1,
    start_ns: int | None = None,
) -> None:
    """Write a whole log (``from_sim``, ``from_trace``, ``poll_board``) to MCAP and/or CSV.
    ``every`` keeps one row in that many (1: all; the simulator records 1000 rows a second).
    ``start_ns``: the wall-clock time of the rows' t_s = 0 (ns since 1970; default now)."""
    if every < 1:
        raise LogError(f"every must be at least 1, not {every}")
    truth = bool(len(rows)) and not np.isnan(rows["x_mm"]).all()
    with LogWriter(mcap, csv, field=field, outline=outline, truth=truth, start_ns=start_ns) as w:
        for row in rows[::every]:
            w.add(row)


# ---- reading ----------------------------------------------------------------------------------


@dataclass
class McapLog:
    """What ``read_mcap`` found: the rows of /asserv, the schemas by topic, the field's scene."""

    rows: np.ndarray
    schemas: dict[str, str]  # topic: schema name
    encodings: dict[str, tuple[str, str]]  # topic: (schema encoding, message encoding)
    messages: dict[str, list[dict[str, Any]]]  # topic: decoded messages (all but /asserv)
    field: Field | None = None  # from the metadata "asserv"
    outline: Outline | None = None
    start_ns: int | None = None  # the wall-clock time of t_s = 0 (ns since 1970, UTC)
    profile: str = ""  # the header's


def read_mcap(path: str | Path) -> McapLog:
    """Read a log written by ``LogWriter`` back (with the ``mcap`` library)."""
    from mcap.exceptions import McapError
    from mcap.reader import make_reader

    p = Path(path)
    rows: list[tuple[float, ...]] = []
    schemas: dict[str, str] = {}
    encodings: dict[str, tuple[str, str]] = {}
    messages: dict[str, list[dict[str, Any]]] = {}
    fld: Field | None = None
    outline: Outline | None = None
    start_ns: int | None = None
    profile = ""
    try:
        with p.open("rb") as f:
            reader = make_reader(f)
            profile = reader.get_header().profile
            for meta in reader.iter_metadata():
                if meta.name == "asserv":
                    if "start_ns" in meta.metadata:
                        start_ns = int(meta.metadata["start_ns"])
                    if "field" in meta.metadata:
                        fld = field_from_dict(json.loads(meta.metadata["field"]))
                    if "outline" in meta.metadata:
                        outline = Outline(**json.loads(meta.metadata["outline"]))
            f.seek(0)
            for schema, channel, message in make_reader(f).iter_messages():
                name = schema.name if schema is not None else ""
                schemas[channel.topic] = name
                encodings[channel.topic] = (
                    schema.encoding if schema is not None else "",
                    channel.message_encoding,
                )
                msg = json.loads(message.data)
                if channel.topic == "/asserv":
                    rows.append(
                        tuple(math.nan if msg[n] is None else float(msg[n]) for n in LOG_FIELDS)
                    )
                else:
                    messages.setdefault(channel.topic, []).append(msg)
    except OSError as e:
        raise LogError(f"cannot read the MCAP file {p}: {e.strerror}") from None
    except (McapError, ValueError, KeyError, EOFError, TypeError, struct.error) as e:
        raise LogError(f"{p} is not an asserv MCAP log: {e}") from None
    out = np.array(rows, dtype=LOG_DTYPE) if rows else empty(0)
    return McapLog(out, schemas, encodings, messages, fld, outline, start_ns, profile)


def read_csv(path: str | Path) -> np.ndarray:
    """Read a CSV log back (empty cells as NaN)."""
    p = Path(path)
    try:
        with p.open(newline="") as f:
            reader = csv.reader(f)
            header = next(reader, None)
            if header is None or tuple(header) != LOG_FIELDS:
                raise LogError(f"{p}: not an asserv CSV log (its header is not LOG_FIELDS)")
            data = [tuple(math.nan if c == "" else float(c) for c in r) for r in reader]
    except OSError as e:
        raise LogError(f"cannot read the CSV file {p}: {e.strerror}") from None
    except ValueError as e:
        if isinstance(e, LogError):
            raise
        raise LogError(f"{p}: a cell is not a number: {e}") from None
    return np.array(data, dtype=LOG_DTYPE) if data else empty(0)


# ---- a real board -----------------------------------------------------------------------------


def board_row(
    board: Board, t_s: float, truth: Callable[[], tuple[float, float, float, float]] | None = None
) -> np.void:
    """One row from a board: POSITION, DEBUG and CHECK_BUSY read now. The truth is unknown
    (NaN) unless ``truth()`` gives it (``RemoteBus.truth``: the simulator server's robot)."""
    pose = board.position()
    d = board.debug()
    status = board.check_busy()
    row: np.void = empty(1)[0]
    row["t_s"] = t_s
    if truth is not None:
        _, row["x_mm"], row["y_mm"], row["heading_deg"] = truth()
    # POSITION's angle is in 2-degree steps; DEBUG's heading is finer: take DEBUG's.
    row["est_x_mm"], row["est_y_mm"] = pose.x_mm, pose.y_mm
    row["est_heading_deg"] = d.heading_cdeg / 100
    row["radius_mm"] = pose.radius_mm
    row["v_mm_s"] = d.speed_mm_s
    row["omega_deg_s"] = d.turn_rate_cdeg_s / 100
    row["dist_err_mm"] = d.dist_err_um / 1000
    row["angle_err_mm"] = d.angle_err_um / 1000
    row["duty_left"] = d.duty_left_q15 / 32767
    row["duty_right"] = d.duty_right_q15 / 32767
    row["current_left_A"] = d.current_left_ma / 1000
    row["current_right_A"] = d.current_right_ma / 1000
    row["status"] = int(status)
    row["order_state"] = int(d.order_state)
    row["end_reason"] = int(d.end_reason)
    return row


def poll_clock(bus: Any) -> Clock:
    """Time for polling a board on ``bus``: its own clock (``asserv.bus.clock_of``: a simulated
    bus's, the simulator server's) or the system's."""
    from .bus import clock_of

    return clock_of(bus)


def bus_truth(bus: Any) -> Callable[[], tuple[float, float, float, float]] | None:
    """The bus's ``truth()`` (the simulator server's true pose: ``RemoteBus``), or None."""
    truth = getattr(bus, "truth", None)
    return truth if callable(truth) else None


def poll_board(
    board: Board,
    hz: float = 50.0,
    *,
    duration_s: float | None = None,
    until: Callable[[], bool] | None = None,
    on_row: Callable[[np.void], None] | None = None,
    clock: Clock | None = None,
) -> Iterator[np.void]:
    """Poll the board at ``hz`` rows a second (each row: POSITION, DEBUG, CHECK_BUSY, and the
    truth where the bus knows it) for ``duration_s`` (None: until ``until()`` says so, or
    forever); yields the rows. ``clock`` paces it (default ``poll_clock(board.bus)``). A row is
    38 bytes on the bus (44 with PEC), 3.4 ms at 100 kHz: up to about 290 rows a second fit
    (``bench/poll_rate.py`` prints it; a real adapter adds its own time per transaction)."""
    if not hz > 0:
        raise ValueError(f"hz must be > 0, not {hz}")
    clock = clock or poll_clock(board.bus)
    truth = bus_truth(board.bus)
    period = 1.0 / hz
    t0 = clock.monotonic()
    next_t = t0
    while True:
        now = clock.monotonic()
        if duration_s is not None and now - t0 >= duration_s:
            return
        if until is not None and until():
            return
        row = board_row(board, now - t0, truth)
        if on_row is not None:
            on_row(row)
        yield row
        next_t += period
        wait = next_t - clock.monotonic()
        if wait > 0:
            clock.sleep(wait)
        else:
            next_t = clock.monotonic()


# ---- the command line -------------------------------------------------------------------------


def check_output(path: str | Path, what: str) -> str | None:
    """Why ``path`` cannot be written as the ``what`` file ("MCAP", "CSV", "PNG": its name must
    end so) (None: it can), checked before a run by creating it (and removing it again), so
    that a bad path changes nothing and a long run does not end on it."""
    from .cli_args import UsageError, check_output_file

    try:
        check_output_file(str(path), (f".{what.lower()}",))
    except UsageError as e:
        return f"the {what} file {e}"
    return None


def write_outputs(
    prog: str,
    rows: np.ndarray,
    mcap: str | None,
    csv_path: str | None,
    field: Field | None,
    outline: Outline | None,
    start_ns: int | None = None,
) -> int:
    """Write a whole log for a command; prints what was written; returns an exit code."""
    try:
        save(rows, mcap=mcap, csv=csv_path, field=field, outline=outline, start_ns=start_ns)
    except LogError as e:
        print(f"{prog}: {e}", file=sys.stderr)
        return 2
    for kind, p in (("mcap", mcap), ("csv", csv_path)):
        if p:
            print(f"{kind}: {p} ({len(rows)} rows)")
    return 0


BusFactory = Callable[[int], Any]


def _smbus(number: int) -> Any:
    import smbus2

    return smbus2.SMBus(number)


#: How ``asserv --bus N log`` opens bus N (tests put a simulated bus here).
BUS_FACTORY: BusFactory = _smbus


def bus_options(parser: argparse.ArgumentParser) -> None:
    """``--bus``, ``--sim``, ``--address``, ``--pec`` after the subcommand too (the main parser
    has them before it: asserv --bus 1 log ..., asserv --sim :5021 view), with its names."""
    parser.add_argument("--bus", metavar="N", default=argparse.SUPPRESS, help="I2C bus number")
    parser.add_argument(
        "--sim",
        dest="bus_sim",
        metavar="HOST:PORT",
        default=argparse.SUPPRESS,
        help="the simulated board of `asserv sim serve` instead of an I2C bus",
    )
    parser.add_argument(
        "--address", dest="bus_address", metavar="ADDR", default=argparse.SUPPRESS, help="7-bit"
    )
    parser.add_argument("--pec", dest="bus_pec", action="store_true", default=argparse.SUPPRESS)


def wants_board(args: argparse.Namespace) -> bool:
    """True if the command line names a board: ``--bus N`` or ``--sim HOST:PORT``."""
    return getattr(args, "bus", None) is not None or getattr(args, "bus_sim", None) is not None


def board_where(args: argparse.Namespace) -> str:
    """The board of the command line, in words."""
    if getattr(args, "bus_sim", None) is not None:
        return f"the simulator server at {args.bus_sim}"
    return f"the board on bus {args.bus}"


def open_board(args: argparse.Namespace, prog: str) -> tuple[Board, Any] | int:
    """The board of ``--bus N`` (or ``--sim HOST:PORT``) ``--address A --pec``, and its bus to
    close; or an exit code (2: a bad argument, 1: the bus cannot be opened), the message
    printed. Every argument is checked before anything is opened."""
    from .cli_args import UsageError
    from .cli_bus import open_error, parse_address, parse_bus
    from .driver import Board
    from .server import RemoteBus
    from .server import parse_address as parse_sim_address

    remote = getattr(args, "bus_sim", None)
    try:
        if remote is not None:
            if getattr(args, "bus", None) is not None:
                raise UsageError("give --bus N or --sim HOST:PORT, not both")
            try:
                host, port = parse_sim_address(str(remote))
            except ValueError as e:
                raise UsageError(f"--sim {e}") from None
        else:
            number = parse_bus(str(args.bus))
        address = parse_address(str(getattr(args, "bus_address", "2")))
    except UsageError as e:
        print(f"{prog}: {e}", file=sys.stderr)
        return 2
    try:
        bus = RemoteBus(host, port) if remote is not None else BUS_FACTORY(number)
    except OSError as e:
        why = e.strerror or str(e) if remote is not None else open_error(number, e)
        print(f"{prog}: {why}", file=sys.stderr)
        return 1
    return Board(bus, address, pec=bool(getattr(args, "bus_pec", False))), bus


def _log_command(args: argparse.Namespace) -> int:
    from .driver import AsservError

    prog = "asserv log"
    if not wants_board(args):
        print(
            f"{prog}: --bus N (or --sim HOST:PORT) is required: asserv --bus 1 log ...",
            file=sys.stderr,
        )
        return 2
    if args.mcap is None and args.csv is None:
        print(f"{prog}: give --mcap FILE, --csv FILE or both", file=sys.stderr)
        return 2
    if not args.hz > 0 or (args.duration is not None and not args.duration > 0):
        print(f"{prog}: --hz and --duration must be > 0", file=sys.stderr)
        return 2
    for kind, p in (("MCAP", args.mcap), ("CSV", args.csv)):
        if p is not None and (why := check_output(p, kind)):
            print(f"{prog}: {why}", file=sys.stderr)
            return 2
    from . import field as fieldmod

    try:
        fld = fieldmod.load(args.field or fieldmod.DEFAULT)
    except fieldmod.FieldError as e:
        print(f"{prog}: {e}", file=sys.stderr)
        return 2
    opened = open_board(args, prog)
    if isinstance(opened, int):
        return opened
    board, bus = opened
    n = 0
    try:
        truth = bus_truth(bus) is not None
        with LogWriter(args.mcap, args.csv, truth=truth, field=fld) as w:
            print(f"{prog}: polling at {args.hz:g} Hz (Ctrl-C ends the log)", file=sys.stderr)
            for row in poll_board(board, args.hz, duration_s=args.duration):
                w.add(row)
                n += 1
                if n % 50 == 0:
                    w.flush()
    except AsservError as e:
        print(f"{prog}: {e} (the log so far, {n} rows, is written)", file=sys.stderr)
        return 1
    except KeyboardInterrupt:
        pass
    except LogError as e:
        print(f"{prog}: {e}", file=sys.stderr)
        return 2
    finally:
        close = getattr(bus, "close", None)
        if callable(close):
            close()
    for kind, p in (("mcap", args.mcap), ("csv", args.csv)):
        if p:
            print(f"{kind}: {p} ({n} rows)")
    return 0


def register(sub: Any) -> None:
    """Add ``asserv log`` to the main CLI's subcommands."""
    p = sub.add_parser(
        "log",
        help="record a real board (POSITION, DEBUG, CHECK_BUSY polled) to MCAP and/or CSV",
        description="Poll a board over I2C and record its estimate, following errors, duties,"
        " currents and status as an MCAP file (Foxglove, PlotJuggler) and/or CSV (docs/view.md)."
        " Ctrl-C ends the log.",
    )
    bus_options(p)
    p.add_argument("--mcap", metavar="FILE", help="MCAP file to write")
    p.add_argument("--csv", metavar="FILE", help="CSV file to write")
    p.add_argument("--hz", type=float, default=50.0, help="rows a second (default 50)")
    p.add_argument("--duration", type=float, help="seconds (default: until Ctrl-C)")
    p.add_argument("--field", help="field file drawn in the MCAP (default field/default.toml)")
    p.set_defaults(run=_log_command)
