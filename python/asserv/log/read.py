"""Reading a log back: an MCAP file or a CSV, as the table."""

from __future__ import annotations

import csv
import json
import math
import struct
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from .._columns import LOG_FIELDS
from ..field import Field
from .format import LOG_DTYPE, LogError, Outline, empty
from .write import field_from_dict

if TYPE_CHECKING:
    pass

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
