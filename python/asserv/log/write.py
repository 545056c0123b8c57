"""Writing a log: the MCAP file (JSON messages, Foxglove's schemas) and the CSV, together."""

from __future__ import annotations

import csv
import dataclasses
import json
import math
import time
from collections.abc import Sequence
from pathlib import Path
from typing import IO, TYPE_CHECKING, Any

import numpy as np

from .._columns import INTEGER, LOG_FIELDS, UNITS
from ..field import Field
from .format import PROFILE, LogError, Outline, _version

if TYPE_CHECKING:
    pass

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
    from ..field import Basket, Line, Obstacle

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
