"""``asserv view``: the robot on its field in the browser, live (simulator or board) or replayed.

One ``websockets`` server serves the page (``view_static/``: plain canvas drawing, no library,
nothing from the internet) and, on ``/ws``, its stream::

    asserv view [--port P] [SCENARIO]      # the simulator, playing a scenario file (or idle)
    asserv --bus 1 view                    # a real board, POSITION, DEBUG, CHECK_BUSY polled
    asserv view --replay RUN.mcap          # a log of asserv sim run --mcap or asserv log

The data comes from a ``Source`` (``SimSource``, ``BoardSource``, ``ReplaySource``): it says what
it shows (``info()``), gives the new rows for the wall time that has passed (``advance(dt)``, rows
of ``asserv.log.LOG_FIELDS``) and takes the page's commands (``goto``, ``pause``, ``speed``).
``BoardSource`` runs on any smbus2-like bus, so a simulated bus served by another process is one
more bus object, not a new source.

Messages on ``/ws`` are JSON. Server to page: ``{"type": "hello", "info": {...}, "access":
{"commands": bool, "drive": bool, "mode": text}}`` once, then ``{"type": "rows", "rows": [[...],
...], "state": {...}}`` about 30 times a second, and ``{"type": "refused", "why": text}`` for
a message refused. Page to
server: ``{"type": "goto", "x": mm, "y": mm}``, ``{"type": "pause", "paused": bool}``,
``{"type": "speed", "speed": 1..50}``. The simulator's and the replay's time stands still
while no page is open.

Who may do what (docs/view.md, "What is protected"): the socket takes connections only from
the page it serves (websockets' ``origins``: a page of another site is refused). Each run makes
a random token; the address printed carries it (``/?token=...``), the page passes it on when it
opens ``/ws?token=...``, and only such a connection may send commands. Without it a page on
loopback may watch, and on another host may do nothing. A real board (``--bus N``, ``--sim
HOST:PORT``) takes GOTOs from the page only with ``--control``. A message that is not a command
of the list above, or one over the rate, gets a line in the log and changes nothing.
"""

from __future__ import annotations

import argparse
import asyncio
import contextlib
import dataclasses
import json
import math
import queue
import secrets
import socket
import sys
import threading
import time
import urllib.parse
import weakref
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from . import log
from ._protocol import EndReason, OrderState, ResetCause, Status
from .field import Field

if TYPE_CHECKING:
    from websockets.typing import Origin

    from .codec import Motion
    from .driver import Board
    from .scenario import Scenario
    from .sim import Simulator

__all__ = ["BoardSource", "PageMessageError", "ReplaySource", "SimSource", "Source", "ViewServer"]

STATIC = Path(__file__).resolve().parent / "view_static"
SPEEDS = (1, 2, 5, 10, 20, 50)
FRAME_S = 1 / 30  # the stream's period, wall time
MAX_ROWS_PER_FRAME = 12  # rows sent per frame at most (the rest are skipped, not the last)
_BUSY = int(Status.BUSY_TRAJET | Status.BUSY_GOTO_PANIER)
_END_BITS = (Status.CHOC_PANIER, Status.CHOC_BORD, Status.PB_MOTEUR, Status.PB_GRAVE)
_CONTENT_TYPES = {
    ".html": "text/html; charset=utf-8",
    ".js": "text/javascript; charset=utf-8",
    ".css": "text/css; charset=utf-8",
    ".svg": "image/svg+xml",
}
MAX_MESSAGE_BYTES = 4096  # a page's command is under 100 bytes; a longer message ends the socket
RATE_HZ = 10.0  # a page's commands a second, sustained (a click, a button)
BURST = 20  # ... and at once; over that, messages are dropped with a line in the log
MAX_CLIENTS = 16  # pages open at once


def status_names(status: int) -> list[str]:
    return [str(s.name) for s in Status if s.name and status & s]


#: The end reasons the page names beside PB_MOTEUR: an order abandoned for the master's
#: silence or a reset rather than a motor problem (docs/protocol.md, DEBUG's end_reason).
_NAMED_ENDS = (EndReason.TIMEOUT, EndReason.RESET)


@dataclass
class Outcome:
    """Follows the status rows and says how the last order ended: its end bits, and DEBUG's
    end reason beside them where the rows have it and it is a timeout or a reset
    (``PB_MOTEUR (RESET)``)."""

    busy: bool = False
    last: str = ""  # "" before any order has ended
    orders: int = 0

    def update(self, status: int, end_reason: float = math.nan) -> None:
        busy = bool(status & _BUSY)
        if busy and not self.busy:
            self.orders += 1
        if self.busy and not busy:
            bits = [str(b.name) for b in _END_BITS if status & b]
            self.last = "|".join(bits) if bits else "done"
            if not math.isnan(end_reason) and int(end_reason) in set(_NAMED_ENDS):
                self.last += f" ({EndReason(int(end_reason)).name})"
        self.busy = busy


#: A Python strategy: a generator function of the board that yields how many seconds of
#: simulated time to wait before its next turn (0 or None: the next 10 ms).
Strategy = Callable[["Board"], Iterator[float | None]]


def wait_idle(board: Board, poll_s: float = 0.01) -> Iterator[float]:
    """For strategies: ``yield from wait_idle(board)`` waits until the order is over (the
    annex's ``while (BUSY_TRAJET)``), polling CHECK_BUSY every ``poll_s`` of simulated time."""
    while board.check_busy() & _BUSY:
        yield poll_s


class StrategyError(ValueError):
    """A strategy file that cannot be used; the message names the file."""


def load_strategy(path: str | Path) -> Strategy:
    """The ``strategy(board)`` generator function of a Python file."""
    import importlib.util
    import inspect

    p = Path(path)
    if not p.is_file():
        raise StrategyError(f"{p}: no such strategy file")
    spec = importlib.util.spec_from_file_location(f"asserv_strategy_{p.stem}", p)
    if spec is None or spec.loader is None:
        raise StrategyError(f"{p}: not a Python file")
    module = importlib.util.module_from_spec(spec)
    try:
        spec.loader.exec_module(module)
    except Exception as e:
        raise StrategyError(f"{p}: cannot load it: {type(e).__name__}: {e}") from None
    fn = getattr(module, "strategy", None)
    if not inspect.isgeneratorfunction(fn):
        raise StrategyError(
            f"{p}: needs a generator function strategy(board) that yields seconds to wait"
        )
    strategy: Strategy = fn
    return strategy


@dataclass
class Source:
    """What the view shows: the base of the three sources."""

    field: Field
    outline: log.Outline
    kind: str = "sim"
    truth: bool = True
    can_goto: bool = True
    paused: bool = False
    speed: float = 1.0
    target: tuple[float, float] | None = None
    outcome: Outcome = dataclasses.field(default_factory=Outcome)
    message: str = ""  # what the source is doing (the scenario's line, an error)
    #: Match play (issue 31): what MOTION says, the points queued by this view that the board
    #: has not reached, the lidar's hits on the field; None where the board or bus has none.
    match: MatchState | None = None
    #: RESET_INFO (issue 28): the board's last reset, as ``reset_state()`` gives it; None where
    #: the board has none or the source cannot ask (a replay).
    reset: dict[str, Any] | None = None

    def why_no_goto(self) -> str:
        """Why the page's clicks send no GOTO here ("" when they do)."""
        return "" if self.can_goto else f"a {self.kind} takes no GOTO"

    def info(self) -> dict[str, Any]:
        return {
            "kind": self.kind,
            "field": log.field_dict(self.field),
            "outline": self.outline.__dict__,
            "truth": self.truth,
            "can_goto": self.can_goto,
            "speeds": list(SPEEDS),
            "fields": list(log.LOG_FIELDS),
            "status_bits": [[str(b.name), int(b)] for b in Status if b.name],
            "order_states": {int(o): o.name for o in OrderState},
        }

    def state(self) -> dict[str, Any]:
        return {
            "paused": self.paused,
            "speed": self.speed,
            "target": self.target,
            "outcome": self.outcome.last,
            "orders": self.outcome.orders,
            "message": self.message,
            "match": None if self.match is None else self.match.as_dict(),
            "reset": self.reset,
        }

    def advance(self, dt_s: float) -> np.ndarray:
        """The rows for ``dt_s`` seconds of wall time (none while paused)."""
        raise NotImplementedError

    def goto(self, x_mm: float, y_mm: float) -> None:
        raise NotImplementedError

    def set_paused(self, paused: bool) -> None:
        self.paused = paused

    def set_speed(self, speed: float) -> None:
        if not 1 <= speed <= max(SPEEDS):
            raise ValueError(f"speed must be 1..{max(SPEEDS)}, not {speed}")
        self.speed = speed

    def close(self) -> None:
        pass


@dataclass
class MatchState:
    """The match-play part of the view's state: MOTION's pause, pending orders, braking
    distance and scale; the points this view queued (GOTO with APPEND) that are still ahead;
    the lidar's last hits on the field."""

    paused: bool = False
    pending: int = 0
    running: bool = False
    braking_mm: int = 0
    scale_percent: int = 100
    queue: list[tuple[float, float]] = dataclasses.field(default_factory=list)
    lidar: list[tuple[float, float]] = dataclasses.field(default_factory=list)

    def sent(self, x_mm: float, y_mm: float, append: bool) -> None:
        """A GOTO the view sent: queued behind the others, or replacing them."""
        self.queue = [*self.queue, (x_mm, y_mm)] if append else [(x_mm, y_mm)]

    def read(self, m: Motion) -> None:
        """MOTION read: the queue keeps the running point and those pending."""
        self.paused, self.pending, self.running = m.paused, m.pending, m.running
        self.braking_mm, self.scale_percent = m.braking_mm, m.scale_percent
        left = m.pending + 1 if m.running else 0
        self.queue = self.queue[len(self.queue) - left :] if left else []

    def as_dict(self) -> dict[str, Any]:
        return {
            "paused": self.paused,
            "pending": self.pending,
            "braking_mm": self.braking_mm,
            "scale_percent": self.scale_percent,
            "queue": [list(q) for q in self.queue],
            "lidar": [[round(x, 1), round(y, 1)] for x, y in self.lidar],
        }


def read_match(board: Board, state: MatchState | None) -> MatchState | None:
    """Read MOTION into ``state`` (a new one at first); None if the board has no PAUSE."""
    from .driver import Unsupported

    try:
        m = board.motion()
    except Unsupported:
        return None
    state = state or MatchState()
    state.read(m)
    return state


def reset_state(board: Board) -> dict[str, Any] | None:
    """RESET_INFO for the page: the last reset's cause (its name), the resets since power-on,
    whether the pose was lost (motion orders refused until SET_NEW_POS) and the radius's
    widening [mm]; None on a board without RESET_INFO."""
    from .driver import Unsupported

    try:
        r = board.reset_info()
    except Unsupported:
        return None
    return {
        "cause": ResetCause(r.cause).name,
        "count": int(r.count),
        "pose_lost": bool(r.pose_lost),
        "widened_mm": int(r.widened_mm),
    }


def _decimate(rows: np.ndarray, n: int = MAX_ROWS_PER_FRAME) -> np.ndarray:
    """At most n rows, evenly spread, the last one kept (it is the pose shown)."""
    if len(rows) <= n:
        return rows
    idx = np.linspace(0, len(rows) - 1, n).round().astype(int)
    out: np.ndarray = rows[idx]
    return out


# ---- the simulator ------------------------------------------------------------------------------


def _take_trace(sim: Simulator) -> np.ndarray:
    """The trace rows recorded since the last call, and forget them (a long run would otherwise
    copy its whole trace every frame)."""
    chunks = sim._chunks  # the recorder's own list (sim.trace concatenates it)
    if not chunks:
        return sim.trace[:0]
    rows = np.concatenate(chunks) if len(chunks) > 1 else chunks[0]
    chunks.clear()
    return rows


class SimSource(Source):
    """A simulated board, playing a scenario's steps (if any) as simulated time goes on; page
    clicks send GOTOs to it. Paced by the wall clock times the speed."""

    def __init__(
        self,
        scenario: Scenario | None = None,
        sim: Simulator | None = None,
        strategy: Strategy | None = None,
    ) -> None:
        from .driver import Board
        from .sim import Simulator

        if sim is None:
            sim = scenario.simulator() if scenario is not None else Simulator()
        super().__init__(sim.field, log.Outline.of(sim), kind="sim")
        self.sim = sim
        self.board = Board(sim.bus, pec=scenario.pec if scenario is not None else False)
        self._steps = list(scenario.steps) if scenario is not None else []
        self._playing = bool(self._steps)
        self._waiting: tuple[str, float] | None = None  # ("wait" | "sleep", until sim time)
        self._gen = strategy(self.board) if strategy is not None else None
        self._resume = 0.0  # the strategy's next turn, simulated time
        self._errors = log.FollowingErrors(float(sim.config.drive_track_mm))
        self.message = f"scenario: {len(self._steps)} steps" if self._steps else "no scenario"
        if self._gen is not None:
            self.message = "strategy"

    def goto(self, x_mm: float, y_mm: float, append: bool = False) -> None:
        self.board.goto(round(x_mm), round(y_mm), append=append)
        self.target = (float(round(x_mm)), float(round(y_mm)))
        if self.match is not None:
            self.match.sent(*self.target, append)

    def _read_match(self) -> None:
        """MOTION and RESET_INFO (the view is a master on the bus, as a strategy is) and the
        lidar's hits."""
        from .driver import AsservError

        try:
            self.match = read_match(self.board, self.match)
            self.reset = reset_state(self.board)
        except AsservError:
            return
        if self.match is not None and self.sim.lidar_targets:
            self.sim.lidar()  # switched on at the first frame that has something to see
            self.match.lidar = self.sim.lidar_points()

    def _strategy(self) -> None:
        """Give the strategy its turn when its wait is over."""
        if self._gen is None or self.sim.time_s < self._resume:
            return
        try:
            wait = next(self._gen)
            self._resume = self.sim.time_s + max(0.0, float(wait or 0.0))
        except StopIteration:
            self._gen = None
            self.message = "strategy over"
        except Exception as e:  # the team's code: shown on the page, the simulator goes on
            self._gen = None
            self.message = f"strategy stopped: {type(e).__name__}: {e}"

    def _script(self) -> None:
        """Run the scenario's steps up to its next wait or sleep, or the strategy's turn."""
        from .driver import AsservError
        from .scenario import BUS_COMMANDS

        self._strategy()
        if self._waiting is not None:
            kind, until = self._waiting
            if self.sim.time_s < until:
                if kind == "sleep" or self.board.check_busy() & _BUSY:
                    return
            elif kind == "wait":
                self.message = "wait: timed out"
            self._waiting = None
        while self._steps and self._waiting is None:
            st = self._steps.pop(0)
            self.message = f"line {st.line}: {st.text}"
            try:
                if st.command == "wait":
                    timeout = st.args[0] if st.args else 30.0
                    self._waiting = ("wait", self.sim.time_s + timeout)
                elif st.command == "sleep":
                    self._waiting = ("sleep", self.sim.time_s + st.args[0])
                else:
                    getattr(self.board, BUS_COMMANDS[st.command][0])(*st.args)
                    if st.command == "goto":
                        self.target = (float(st.args[0]), float(st.args[1]))
                        if self.match is not None:
                            append = bool(st.args[2] & 4) if len(st.args) > 2 else False
                            self.match.sent(*self.target, append)
            except AsservError as e:
                self.message = f"line {st.line}: {e}"
                self._steps.clear()
        if not self._steps and self._waiting is None and self._playing:
            self._playing = False
            self.message += " (scenario over)"

    def advance(self, dt_s: float) -> np.ndarray:
        if self.paused:
            return log.empty(0)
        budget = dt_s * self.speed
        end = self.sim.time_s + budget
        if budget > 0.005:  # the MOTION read's bytes take their time within the frame's
            self._read_match()
        while self.sim.time_s < end - 1e-9:
            self._script()  # its bus transactions take simulated time too
            left = end - self.sim.time_s
            if left > 0:
                self.sim.advance(min(0.01, left))
        raw = _take_trace(self.sim)
        rows = self._rows(raw)
        for s in rows["status"]:
            self.outcome.update(int(s))  # the trace has no end reason: RESET_INFO says it
        return rows

    def _rows(self, raw: np.ndarray) -> np.ndarray:
        """Log rows, the following errors carried on from the previous chunk."""
        rows = log.empty(len(raw))
        for name in log.LOG_FIELDS:
            if name in (raw.dtype.names or ()):
                rows[name] = raw[name]
        rows["dist_err_mm"], rows["angle_err_mm"] = self._errors.update(raw)
        return rows


# ---- a real board -------------------------------------------------------------------------------


class BoardSource(Source):
    """A board on a bus (a real one, the simulator server's ``RemoteBus``, or any smbus2-like
    bus), polled at ``hz`` in a thread; ``goto`` goes through the same thread. The page's clicks
    are GOTOs only with ``control`` (``asserv view --control``): by default the board is
    watched, not driven. Pause freezes the view (the robot goes on). The true pose is drawn
    where the bus knows it (``RemoteBus.truth``)."""

    def __init__(
        self, board: Board, hz: float = 50.0, field: Field | None = None, control: bool = False
    ) -> None:
        from . import field as fieldmod
        from .bus import SystemClock

        truth = log.bus_truth(board.bus) is not None  # the simulator server knows it
        super().__init__(
            field or fieldmod.load(), log.Outline(), kind="board", truth=truth, can_goto=control
        )
        self.board = board
        self.hz = hz
        # Paced by the simulation where this process runs it (a simulated bus), else by the
        # wall clock: a view watching the simulator server must not move its time.
        clock = log.poll_clock(board.bus)
        self._clock = clock if getattr(clock, "drives_simulation", False) else SystemClock()
        self._rows: queue.Queue[np.void] = queue.Queue()
        self._orders: queue.Queue[tuple[int, int]] = queue.Queue()
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, name="asserv-view-poll", daemon=True)
        self._thread.start()

    def _run(self) -> None:
        from .driver import AsservError

        try:
            rows = log.poll_board(self.board, self.hz, until=self._stop.is_set, clock=self._clock)
            for n, row in enumerate(rows):
                self._rows.put(row)
                if n % 5 == 0:
                    self._read_match(row)
                    self.reset = reset_state(self.board)
                while not self._orders.empty():
                    x, y = self._orders.get()
                    try:
                        self.board.goto(x, y)
                        self.target = (float(x), float(y))
                    except (AsservError, ValueError) as e:  # refused: shown, polling goes on
                        self.message = f"GOTO ({x}, {y}): {e}"
        except AsservError as e:
            self.message = f"the board stopped answering: {e}"

    def _read_match(self, row: np.void) -> None:
        """MOTION, and the lidar where the bus has one (the simulator server's), its hits put
        on the field from the board's estimate."""
        self.match = read_match(self.board, self.match)
        lidar = getattr(self.board.bus, "lidar", None)
        if self.match is not None and callable(lidar):
            try:
                scan = lidar()
            except OSError:
                return
            x, y, h = (float(row[k]) for k in ("est_x_mm", "est_y_mm", "est_heading_deg"))
            self.match.lidar = scan.points(x, y, h)

    def why_no_goto(self) -> str:
        if self.can_goto:
            return ""
        return "the board is watched, not driven: asserv view --control lets clicks drive it"

    def goto(self, x_mm: float, y_mm: float) -> None:
        """Queued for the polling thread; ``target`` shows it once the board has taken it."""
        self._orders.put((round(x_mm), round(y_mm)))

    def advance(self, dt_s: float) -> np.ndarray:
        rows = []
        while not self._rows.empty():
            rows.append(self._rows.get())
        out = np.array(rows, dtype=log.LOG_DTYPE) if rows else log.empty(0)
        for s, why in zip(out["status"], out["end_reason"], strict=True):
            self.outcome.update(int(s), float(why))
        return log.empty(0) if self.paused else out

    def close(self) -> None:
        self._stop.set()
        self._thread.join(timeout=2)


# ---- a log --------------------------------------------------------------------------------------


class ReplaySource(Source):
    """A log read back (``asserv.log.read_mcap``), played at the speed chosen; it pauses at its
    end, and play starts it again. No GOTO."""

    def __init__(self, path: str | Path) -> None:
        from . import field as fieldmod

        got = log.read_mcap(path)
        if not len(got.rows):
            raise log.LogError(f"{path}: the log has no /asserv rows to replay")
        rows = got.rows
        super().__init__(
            got.field or fieldmod.load(),
            got.outline or log.Outline(),
            kind="replay",
            truth=not np.isnan(rows["x_mm"]).all(),
            can_goto=False,
        )
        self.rows = rows
        self.t = float(rows["t_s"][0])
        self._i = 0
        self.message = f"replay of {path}: {len(rows)} rows, {rows['t_s'][-1]:.1f} s"

    @property
    def at_end(self) -> bool:
        return self._i >= len(self.rows)

    def set_paused(self, paused: bool) -> None:
        if not paused and self.at_end:  # play at the end: from the start again
            self._i = 0
            self.t = float(self.rows["t_s"][0])
            self.outcome = Outcome()
        self.paused = paused

    def advance(self, dt_s: float) -> np.ndarray:
        if self.paused:
            return log.empty(0)
        self.t += dt_s * self.speed
        j = int(np.searchsorted(self.rows["t_s"], self.t, side="right"))
        out = self.rows[self._i : j]
        self._i = max(self._i, j)
        for s, why in zip(out["status"], out["end_reason"], strict=True):
            if not math.isnan(s):
                self.outcome.update(int(s), float(why))
        if self._i >= len(self.rows):
            self.paused = True
            self.message = "end of the log (play: from the start again)"
        return out

    def goto(self, x_mm: float, y_mm: float) -> None:
        raise ValueError("a replay takes no GOTO")


# ---- the page's messages ------------------------------------------------------------------------


class PageMessageError(ValueError):
    """A page's message that the view does not take; the text says why (it goes to the log)."""


def _short(value: Any, n: int = 40) -> str:
    """``repr(value)``, cut to ``n`` characters for a log line."""
    text = repr(value)
    return text if len(text) <= n else text[: n - 3] + "..."


def _no_constant(name: str) -> Any:
    raise PageMessageError(f"{name} is not a number of JSON")


def _number(msg: dict[str, Any], key: str, lo: float, hi: float) -> float:
    """``msg[key]`` as a float within lo..hi, or PageMessageError."""
    v = msg[key]
    if isinstance(v, bool) or not isinstance(v, int | float):
        raise PageMessageError(f"{key} must be a number, not {_short(v)}")
    if not lo <= v <= hi:  # an int of any size compares; NaN never passes
        raise PageMessageError(f"{key} {_short(v, 24)} is not within {lo:g}..{hi:g}")
    return float(v)


_KEYS = {"goto": {"type", "x", "y"}, "pause": {"type", "paused"}, "speed": {"type", "speed"}}


def parse_command(text: str | bytes, source: Source) -> dict[str, Any]:
    """The command of one message from the page, checked whole: ``{"type": "goto", "x": mm,
    "y": mm}`` on the table, ``{"type": "pause", "paused": bool}`` or ``{"type": "speed",
    "speed": 1..50}``, nothing else in them. PageMessageError says what is wrong."""
    if isinstance(text, bytes):
        raise PageMessageError("a binary message: the page sends JSON text")
    if len(text) > MAX_MESSAGE_BYTES:
        raise PageMessageError(f"a message longer than {MAX_MESSAGE_BYTES} characters")
    try:
        msg = json.loads(text, parse_constant=_no_constant)
    except PageMessageError:
        raise
    except (ValueError, RecursionError) as e:  # RecursionError: [[[[... nested too deep
        raise PageMessageError(f"not JSON: {_short(text)}: {type(e).__name__}") from None
    if not isinstance(msg, dict):
        raise PageMessageError(f"not a JSON object: {_short(msg)}")
    kind = msg.get("type")
    if not isinstance(kind, str) or kind not in _KEYS:
        raise PageMessageError(f"unknown kind {_short(kind)} (goto, pause, speed)")
    if set(msg) != _KEYS[kind]:
        want = ", ".join(sorted(_KEYS[kind] - {"type"}))
        raise PageMessageError(f"{kind} takes {want}; got {_short(sorted(msg))}")
    if kind == "goto":
        half_x, half_y = source.field.length_mm / 2, source.field.width_mm / 2
        return {
            "type": "goto",
            "x": _number(msg, "x", -half_x, half_x),
            "y": _number(msg, "y", -half_y, half_y),
        }
    if kind == "pause":
        if not isinstance(msg["paused"], bool):
            raise PageMessageError(f"paused must be true or false, not {_short(msg['paused'])}")
        return {"type": "pause", "paused": msg["paused"]}
    return {"type": "speed", "speed": _number(msg, "speed", 1, max(SPEEDS))}


# ---- the server ---------------------------------------------------------------------------------


def _row_list(row: np.void) -> list[float | None]:
    return [None if math.isnan(float(v)) else round(float(v), 4) for v in row.tolist()]


def _log_stderr(line: str) -> None:
    print(f"asserv view: {line}", file=sys.stderr, flush=True)


@dataclass
class _Access:
    """What one connection to ``/ws`` may do, and its share of the message rate."""

    peer: str
    commands: bool  # it gave this run's token
    why: str = ""  # why not, when it may not
    allowance: float = BURST
    last: float = dataclasses.field(default_factory=time.monotonic)
    dropped: int = 0
    dropped_logged: float = 0.0

    def spend(self) -> bool:
        """One message's share of the rate: False if the page is over it."""
        now = time.monotonic()
        self.allowance = min(BURST, self.allowance + (now - self.last) * RATE_HZ)
        self.last = now
        if self.allowance < 1:
            return False
        self.allowance -= 1
        return True


class ViewServer:
    """The page and its stream for one source, on ``host:port`` (port 0: any free one).

    ``url`` is the page's address with this run's token (``token``, random unless given): the
    address to open. A connection to ``/ws`` without it may watch on loopback and do nothing
    elsewhere; only the page's own origin may connect. ``log`` takes a line for each connection
    or message refused (by default: stderr)."""

    def __init__(
        self,
        source: Source,
        host: str = "127.0.0.1",
        port: int = 8765,
        token: str | None = None,
        log: Callable[[str], None] | None = None,
    ) -> None:
        from .server import is_loopback

        self.source = source
        self.host = host
        self.port = port
        self.token = token if token is not None else secrets.token_urlsafe(24)
        self.loopback = is_loopback(host)
        self.log = log or _log_stderr
        self._clients: set[Any] = set()
        self._access: weakref.WeakKeyDictionary[Any, _Access] = weakref.WeakKeyDictionary()
        self._commands: queue.Queue[dict[str, Any]] = queue.Queue()
        self._server: Any = None
        self.origins: list[Origin | None] = []
        self.base_url = ""
        self.url = ""

    @property
    def ws_url(self) -> str:
        """The stream's address with this run's token (a Python client's)."""
        return f"{self.base_url.replace('http', 'ws', 1)}ws?token={self.token}"

    # -- who may connect

    def _token_of(self, path: str) -> str | None:
        values = urllib.parse.parse_qs(urllib.parse.urlsplit(path).query).get("token")
        return values[0] if values else None

    def _admit(self, connection: Any, request: Any) -> Any:
        """The checks of a ``/ws`` handshake: None lets it go on (websockets then checks the
        Origin against ``origins``), a response refuses it."""
        from websockets.exceptions import InvalidHandshake
        from websockets.typing import Origin

        peer = "{}:{}".format(*connection.remote_address[:2])
        if not self.loopback:
            # Another host: the page's own origin is the address it was opened at (the Host
            # header). A page of another site that resolves to this machine passes this check,
            # which is why the token is required here for everything.
            hosts = request.headers.get_all("Host")
            host = hosts[0] if len(hosts) == 1 else ""  # two Host headers: no origin passes
            connection.protocol.origins = [*self.origins, Origin(f"http://{host}")]
        try:
            connection.protocol.process_origin(request.headers)
        except InvalidHandshake:
            origin = request.headers.get_all("Origin")
            self.log(
                f"refused a connection from {peer} with Origin {', '.join(origin)}: only the page"
                f" that this view serves ({self.base_url}) may connect"
            )
            return None  # websockets answers 403 Forbidden
        if len(self._clients) >= MAX_CLIENTS:
            self.log(f"refused a connection from {peer}: {MAX_CLIENTS} pages are open already")
            return connection.respond(503, f"{MAX_CLIENTS} pages are open already\n")
        given = self._token_of(request.path)
        good = given is not None and secrets.compare_digest(
            given.encode("utf-8", "replace"), self.token.encode()
        )
        why = ""
        if not good:
            why = (
                "this address has no token"
                if given is None
                else "the token in this address is not this run's"
            )
            why += ": open the address that asserv view printed to send commands"
            if not self.loopback:
                self.log(f"refused a connection from {peer}: {why.split(':')[0]}")
                return connection.respond(403, f"{why}\n")
            self.log(f"a page at {peer} watches without the token ({why.split(':')[0]})")
        self._access[connection] = _Access(peer, good, why)
        return None

    def _http(self, connection: Any, request: Any) -> Any:
        from websockets.datastructures import Headers
        from websockets.http11 import Response

        path = request.path.split("?", 1)[0]
        if path == "/ws":
            return self._admit(connection, request)
        name = "index.html" if path in ("/", "/index.html") else path.lstrip("/")
        f = STATIC / name
        if "/" in name or not f.is_file() or f.suffix not in _CONTENT_TYPES:
            return connection.respond(404, f"no {path} here: open /\n")
        body = f.read_bytes()
        headers = Headers(
            [
                ("Content-Type", _CONTENT_TYPES[f.suffix]),
                ("Content-Length", str(len(body))),
                ("Cache-Control", "no-store"),
                ("Referrer-Policy", "no-referrer"),  # the token stays off other sites' logs
            ]
        )
        return Response(200, "OK", headers, body)

    # -- what a connection may send

    def access_of(self, access: _Access) -> dict[str, Any]:
        """What the page is told it may do, and the mode it shows."""
        src = self.source
        drive = access.commands and src.can_goto
        if not access.commands:
            mode = f"watching only: {access.why}"
        elif src.kind == "replay":
            mode = "replay"
        elif not src.can_goto:
            mode = f"watching: {src.why_no_goto()}"
        elif src.kind == "board":
            mode = "driving the board: a click sends a GOTO"
        else:
            mode = "driving the simulator: a click sends a GOTO"
        return {"commands": access.commands, "drive": drive, "mode": mode}

    def receive(self, access: _Access, text: str | bytes) -> str:
        """Take one message of a page: queue its command, or return why not ("" if taken).
        Every refusal, and the first of a flood's dropped messages each second, is logged."""
        if not access.spend():
            access.dropped += 1
            now = time.monotonic()
            if now - access.dropped_logged >= 1:
                self.log(
                    f"dropped {access.dropped} message(s) of {access.peer}: over"
                    f" {RATE_HZ:g} a second"
                )
                access.dropped_logged, access.dropped = now, 0
            return "over the rate"
        try:
            cmd = parse_command(text, self.source)
            if not access.commands:
                raise PageMessageError(
                    f"{cmd['type']}: commands need this run's token ({access.why})"
                )
            if cmd["type"] == "goto" and not self.source.can_goto:
                raise PageMessageError(f"goto: {self.source.why_no_goto()}")
        except PageMessageError as e:
            self.log(f"refused a message of {access.peer}: {e}")
            return str(e)
        self._commands.put(cmd)
        return ""

    async def _client(self, ws: Any) -> None:
        from websockets.exceptions import ConnectionClosed

        access = self._access.get(ws)
        if access is None:  # not through _admit: never
            await ws.close(1008, "not admitted")
            return
        self._clients.add(ws)
        try:
            hello = {"type": "hello", "info": self.source.info(), "access": self.access_of(access)}
            await ws.send(json.dumps(hello))
            async for text in ws:
                why = self.receive(access, text)
                if why and why != "over the rate":
                    await ws.send(json.dumps({"type": "refused", "why": why}))
        except ConnectionClosed as e:
            if e.sent is not None and e.sent.code == 1009:
                self.log(f"closed the connection of {access.peer}: {e.sent.reason}")
        finally:
            self._clients.discard(ws)

    def _apply(self, cmd: dict[str, Any]) -> None:
        """A command that ``parse_command`` checked."""
        src = self.source
        try:
            if cmd["type"] == "goto":
                src.goto(cmd["x"], cmd["y"])
            elif cmd["type"] == "pause":
                src.set_paused(cmd["paused"])
            elif cmd["type"] == "speed":
                src.set_speed(cmd["speed"])
        except Exception as e:  # the driver's errors: shown, the view goes on
            src.message = f"{cmd['type']}: {type(e).__name__}: {e}"

    def _tick(self, dt: float) -> np.ndarray:
        while not self._commands.empty():
            self._apply(self._commands.get())
        try:
            return self.source.advance(dt)
        except Exception as e:  # shown on the page; the view goes on
            self.source.message = f"{type(e).__name__}: {e}"
            self.source.paused = True
            return log.empty(0)

    async def _pump(self) -> None:
        import websockets

        last = time.monotonic()
        while True:
            await asyncio.sleep(FRAME_S)
            now = time.monotonic()
            dt, last = min(now - last, 0.2), now
            if not self._clients and self.source.kind != "board":
                continue  # the simulator's and the replay's time waits for a page
            rows = await asyncio.to_thread(self._tick, dt)
            if not self._clients:
                continue
            msg = json.dumps(
                {
                    "type": "rows",
                    "rows": [_row_list(r) for r in _decimate(rows)],
                    "state": self.source.state(),
                }
            )
            websockets.broadcast(self._clients, msg)

    def _listen(self) -> socket.socket:
        """The listening socket, bound first: the page's origins name its port."""
        family, _, _, _, addr = socket.getaddrinfo(
            self.host, self.port, type=socket.SOCK_STREAM, flags=socket.AI_PASSIVE
        )[0]
        sock = socket.create_server(addr[:2], family=family)
        self.port = int(sock.getsockname()[1])
        return sock

    async def run(self, ready: threading.Event | None = None) -> None:
        from websockets.asyncio.server import serve
        from websockets.typing import Origin

        sock = self._listen()
        host = f"[{self.host}]" if ":" in self.host else self.host
        self.base_url = f"http://{host}:{self.port}/"
        self.url = f"{self.base_url}?token={self.token}"
        # The page's own origins (a browser opened at one of these names, or at the address
        # printed: --host 127.0.0.2 is loopback too); None: a client that is no browser
        # (Python's websockets), which no web page can make.
        names = list(dict.fromkeys(["127.0.0.1", "localhost", "[::1]", host]))
        self.origins = [None, *(Origin(f"http://{n}:{self.port}") for n in names)]
        async with serve(
            self._client,
            sock=sock,
            process_request=self._http,
            origins=self.origins,
            max_size=MAX_MESSAGE_BYTES,
        ) as server:
            self._server = server
            if ready is not None:
                ready.set()
            await self._pump()

    def start_thread(self) -> threading.Thread:
        """Run in a thread (tests, notebooks); returns once the server listens."""
        ready = threading.Event()
        self._loop = asyncio.new_event_loop()

        def main() -> None:
            with contextlib.suppress(asyncio.CancelledError):
                self._loop.run_until_complete(self._task_main(ready))

        th = threading.Thread(target=main, name="asserv-view", daemon=True)
        th.start()
        if not ready.wait(10):
            raise RuntimeError("the view server did not start")
        self._thread = th
        return th

    async def _task_main(self, ready: threading.Event) -> None:
        self._task = asyncio.current_task()
        await self.run(ready)

    def stop(self) -> None:
        """Stop a server started by ``start_thread``."""
        loop = getattr(self, "_loop", None)
        task = getattr(self, "_task", None)
        if loop is not None and task is not None:
            loop.call_soon_threadsafe(task.cancel)
            self._thread.join(timeout=5)
        self.source.close()


# ---- the command line ---------------------------------------------------------------------------


def _command(args: argparse.Namespace) -> int:
    from . import field as fieldmod
    from . import scenario

    prog = "asserv view"

    def usage(msg: str) -> int:
        print(f"{prog}: {msg}", file=sys.stderr)
        return 2

    if not 0 <= args.port <= 65535:
        return usage(f"--port must be 0..65535, not {args.port}")
    real = log.wants_board(args)
    if sum((real, args.replay is not None, args.scenario is not None)) > 1:
        return usage("give one of SCENARIO, --replay FILE, --bus N or --sim HOST:PORT")
    if not 1 <= args.hz <= 500:
        return usage("--hz takes 1..500 polls a second")
    if args.control and not real:
        return usage(
            "--control lets the page drive a board (--bus N or --sim HOST:PORT); the"
            " simulator of the view is always driven, a replay never"
        )
    bus: Any = None
    source: Source
    try:
        if args.replay is not None:
            source = ReplaySource(args.replay)
        elif real:
            fld = fieldmod.load(args.field) if args.field else None
            opened = log.open_board(args, prog)
            if isinstance(opened, int):
                return opened
            board, bus = opened
            source = BoardSource(board, args.hz, fld, control=args.control)
            source.message = f"polling {log.board_where(args)} at {args.hz:g} Hz"
        else:
            if args.scenario and args.scenario.endswith(".py"):
                source = SimSource(strategy=load_strategy(args.scenario))
            else:
                scn = scenario.load(args.scenario) if args.scenario else None
                source = SimSource(scn)
    except (log.LogError, scenario.ScenarioError, fieldmod.FieldError, StrategyError) as e:
        return usage(str(e))
    server = ViewServer(source, args.host, args.port)

    async def main() -> None:
        task = asyncio.create_task(server.run())
        while not server.url and not task.done():
            await asyncio.sleep(0.05)
        if server.url:
            print(f"{prog}: open {server.url}  (Ctrl-C stops)", flush=True)
            if not server.loopback:
                print(
                    f"{prog}: {args.host} is not loopback: the robot's control is exposed to"
                    " every machine that reaches this port; the page needs the token of the"
                    " address above to watch or drive: give it to the team only",
                    file=sys.stderr,
                    flush=True,
                )
            if isinstance(source, BoardSource) and not source.can_goto:
                print(f"{prog}: {source.why_no_goto()}", flush=True)
        await task

    try:
        asyncio.run(main())
    except KeyboardInterrupt:
        pass
    except OSError as e:
        print(f"{prog}: cannot listen on {args.host}:{args.port}: {e.strerror}", file=sys.stderr)
        return 1
    finally:
        source.close()
        if bus is not None and callable(getattr(bus, "close", None)):
            bus.close()
    return 0


def register(sub: Any) -> None:
    """Add ``asserv view`` to the main CLI's subcommands."""
    p = sub.add_parser(
        "view",
        help="the robot on its field in the browser: simulator, --bus N, --sim HOST:PORT or"
        " --replay RUN.mcap",
        description="Serve a page that shows the field, the robot (estimate and, simulated, the"
        " truth), the error radius, the path, the target, the status and scrolling plots;"
        " play/pause, speed x1..x50, a click on the field sends a GOTO (docs/view.md). Open"
        " the address it prints: its token lets the page send commands.",
    )
    log.bus_options(p)
    p.add_argument(
        "scenario",
        nargs="?",
        help="a scenario file, or a Python file with a strategy(board) generator (simulator)",
    )
    p.add_argument("--replay", metavar="RUN.mcap", help="replay a log instead")
    p.add_argument("--port", type=int, default=8765, help="TCP port (default 8765; 0: any)")
    p.add_argument("--host", default="127.0.0.1", help="address to listen on (default 127.0.0.1)")
    p.add_argument("--hz", type=float, default=50.0, help="board polls a second (default 50)")
    p.add_argument("--field", help="field file (a real board; default field/default.toml)")
    p.add_argument(
        "--control",
        action="store_true",
        help="let the page's clicks send GOTOs to the board of --bus N or --sim HOST:PORT"
        " (without it the board is watched, not driven)",
    )
    p.set_defaults(func=_command)
