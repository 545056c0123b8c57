"""The log's table: its columns and types, the rows of a simulated run, and the names every
part of asserv.log shares."""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from .._columns import LOG_FIELDS

if TYPE_CHECKING:
    from ..sim import Simulator

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
    from .. import __version__

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
