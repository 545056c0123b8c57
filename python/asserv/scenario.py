"""Scenario files: orders and waits played by the master driver on the simulated board.

A scenario is a text file, one command a line, ``#`` starts a comment::

    # the specification's annex session
    field annex              # field/annex.toml (or a path to a field file)
    set_vitesse_traj 100     # cm/s (an optional second number: cm/s^2)
    set_vitesse_rot 50
    goto 200 100             # x_mm y_mm [options: ligne, bord, ligne+bord or a number]
    wait                     # poll CHECK_BUSY until the order ends [timeout_s, default 30]
    goto_panier 44           # degrees, sent in 2-degree steps

Setup lines come first: ``field NAME|PATH``, ``seed N``, ``randomize`` (a robot drawn from the
seed: wheel mismatch, track error, noise, start error), ``start X_MM Y_MM HEADING_DEG`` (the
true start pose, which the board also believes), ``config KEY VALUE...`` (a member of
``struct sim_config``, e.g. ``config enc_radius_error 0.003 -0.003``), ``bus_hz N``, ``pec on``.
Then the bus commands, one per driver method: ``goto``, ``goto_reverse``, ``goto_panier``,
``stop``, ``set_vitesse_traj``, ``set_vitesse_rot``, ``set_filtre`` (STD, SOUPLE, RAIDE or a
number), ``set_filtre_raw``, ``set_new_pos``, ``declare_pose``, ``check_busy``, ``position``,
``info_choc``, ``version``, ``last_reject``, ``debug``; and ``wait [TIMEOUT_S]``,
``sleep SECONDS``.

The whole file is checked before anything runs: a malformed line is reported with its file
and line number, and nothing is played.
"""

from __future__ import annotations

import dataclasses
import math
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from . import codec
from . import field as fieldmod
from ._protocol import Filtre, Status
from .driver import AsservError, Board, GotoOption
from .sim import Frame, Simulator

SCENARIO_DIR = Path(__file__).resolve().parents[2] / "scenarios"


class ScenarioError(ValueError):
    """A scenario that cannot be played; the message starts with ``file:line:``."""


def _int(word: str) -> int:
    return int(word, 0)


def _num(word: str) -> float:
    x = float(word)
    if not math.isfinite(x):
        raise ValueError(word)
    return x


def _options(word: str) -> int:
    try:
        return int(word, 0)
    except ValueError:
        pass
    value = 0
    for part in word.replace("|", "+").split("+"):
        name = {"ligne": "RECALAGE_LIGNE", "bord": "RECALAGE_BORD"}.get(part.lower(), part.upper())
        try:
            value |= GotoOption[name]
        except KeyError:
            raise ValueError(word) from None
    return value


def _filtre(word: str) -> int:
    try:
        return int(word, 0)
    except ValueError:
        pass
    name = word.upper()
    name = name if name.startswith("FILTRE_") else "FILTRE_" + name
    try:
        return int(Filtre[name])
    except KeyError:
        raise ValueError(word) from None


# command: (driver method, required arg parsers, optional arg parsers, usage)
Parser = Callable[[str], Any]
BUS_COMMANDS: dict[str, tuple[str, list[Parser], list[Parser], str]] = {
    "goto": ("goto", [_int, _int], [_options], "goto X_MM Y_MM [OPTIONS]"),
    "goto_reverse": ("goto_reverse", [_int], [], "goto_reverse DISTANCE_MM"),
    "goto_panier": ("goto_panier", [_num], [], "goto_panier ANGLE_DEG"),
    "stop": ("stop", [], [], "stop"),
    "set_vitesse_traj": ("set_vitesse_traj", [_int], [_int], "set_vitesse_traj CM_S [CM_S2]"),
    "set_vitesse_rot": ("set_vitesse_rot", [_int], [_int], "set_vitesse_rot CM_S [CM_S2]"),
    "set_filtre": ("set_filtre", [_filtre], [], "set_filtre STD|SOUPLE|RAIDE"),
    "set_filtre_raw": ("set_filtre_raw", [_int, _int, _int], [], "set_filtre_raw P I D"),
    "set_new_pos": ("set_new_pos", [_int, _int, _int], [], "set_new_pos EX_MM EY_MM EA_DEG"),
    "declare_pose": ("declare_pose", [_int, _int, _int], [], "declare_pose X_MM Y_MM ANGLE_DEG"),
    "check_busy": ("check_busy", [], [], "check_busy"),
    "position": ("position", [], [], "position"),
    "info_choc": ("info_choc", [], [], "info_choc"),
    "version": ("version", [], [], "version"),
    "last_reject": ("last_reject", [], [], "last_reject"),
    "debug": ("debug", [], [], "debug"),
    "wait": ("", [], [_num], "wait [TIMEOUT_S]"),
    "sleep": ("", [_num], [], "sleep SECONDS"),
}
SETUP = (
    "field",
    "seed",
    "randomize",
    "start",
    "board_start",
    "start_uncertainty",
    "config",
    "board",
    "bus_hz",
    "pec",
)


@dataclass
class Step:
    line: int
    command: str
    args: list[Any]
    text: str


@dataclass
class Scenario:
    source: str
    field: fieldmod.Field
    seed: int = 0
    randomize: bool = False
    start: tuple[float, float, float] | None = None
    board_start: tuple[float, float, float] | None = None
    start_uncertainty: tuple[float, float] = (0.0, 0.0)
    config: dict[str, Any] = dataclasses.field(default_factory=dict)
    board: dict[str, Any] = dataclasses.field(default_factory=dict)
    bus_hz: int = 100_000
    pec: bool = False
    steps: list[Step] = dataclasses.field(default_factory=list)

    def simulator(self) -> Simulator:
        config = dict(self.config)
        if self.start is not None:
            config["start"] = self.start
        return Simulator(
            config,
            self.seed,
            field=self.field,
            randomize=self.randomize,
            bus_hz=self.bus_hz,
            board_start=self.board_start,
            start_uncertainty=self.start_uncertainty,
            board_config=self.board,
        )


def _inside(fl: fieldmod.Field, x: float, y: float) -> str | None:
    """What the point (x, y) is inside of that the robot cannot be: off the table, in a basket or
    an obstacle; None if nothing."""
    if fl.borders and not (abs(x) <= fl.length_mm / 2 and abs(y) <= fl.width_mm / 2):
        return (
            f"off the table (x within {-fl.length_mm / 2:g}..{fl.length_mm / 2:g},"
            f" y within {-fl.width_mm / 2:g}..{fl.width_mm / 2:g} mm)"
        )
    for b in fl.baskets:
        if math.hypot(x - b.x_mm, y - b.y_mm) < b.radius_mm:
            return f"inside the basket at ({b.x_mm:g}, {b.y_mm:g})"
    for o in fl.obstacles:
        if o.shape == "circle":
            hit = math.hypot(x - o.x_mm, y - o.y_mm) < o.radius_mm
        else:
            hit = abs(x - o.x_mm) < o.half_x_mm and abs(y - o.y_mm) < o.half_y_mm
        if hit:
            return f"inside the {o.shape} obstacle at ({o.x_mm:g}, {o.y_mm:g})"
    return None


def check_pose(fl: fieldmod.Field, cfg: Any, x: float, y: float, heading_deg: float) -> str | None:
    """Whether the robot's outline (``cfg``: a ``struct sim_config``) fits at the pose (the
    drive axis midpoint) without leaving the table or overlapping a basket or an obstacle:
    None, or what is wrong."""
    hl, hw = cfg.outline_length_mm / 2, cfg.outline_width_mm / 2
    ox, oy = cfg.outline_offset_x_mm, cfg.outline_offset_y_mm
    c, s = math.cos(math.radians(heading_deg)), math.sin(math.radians(heading_deg))
    n = 16
    for i in range(4 * n + 1):  # the perimeter, every 1/16 of a side, and the centre
        k, t = divmod(i, n)
        u = (t / n) * 2 - 1
        px, py = [(u * hl, -hw), (hl, u * hw), (-u * hl, hw), (-hl, -u * hw), (0.0, 0.0)][k]
        px, py = px + ox, py + oy
        problem = _inside(fl, x + px * c - py * s, y + px * s + py * c)
        if problem:
            return f"the robot at ({x:g}, {y:g}, {heading_deg:g} deg) would be {problem}"
    return None


class _DryBus:
    """Takes every write and answers zeros: lets the driver check arguments without a board."""

    def i2c_rdwr(self, *msgs: Any) -> None:
        pass


def _field_path(word: str, base: Path) -> Path:
    if "/" not in word and not word.endswith(".toml"):
        return fieldmod.FIELD_DIR / f"{word}.toml"
    p = Path(word)
    return p if p.is_absolute() else base / p


def parse(text: str, source: str = "<scenario>", base: Path | None = None) -> Scenario:
    """Check a whole scenario; ScenarioError names the first bad line."""
    base = base or Path.cwd()
    scn = Scenario(source, fieldmod.load())
    dry = Board(_DryBus(), check=False)
    for n, raw in enumerate(text.splitlines(), 1):
        words = raw.split("#", 1)[0].split()
        if not words:
            continue
        where = f"{source}:{n}"
        cmd, rest = words[0].lower(), words[1:]

        def fail(what: str, where: str = where, raw: str = raw) -> ScenarioError:
            return ScenarioError(f"{where}: {what} (line: {raw.strip()!r})")

        if cmd in SETUP:
            if scn.steps:
                raise fail(f"'{cmd}' is a setup line: put it before the first bus command")
            try:
                if cmd == "field":
                    if len(rest) != 1:
                        raise fail("field takes one name or path: field NAME|PATH")
                    scn.field = fieldmod.load(_field_path(rest[0], base))
                elif cmd == "seed":
                    if len(rest) != 1 or not 0 <= _int(rest[0]) < 2**64:
                        raise fail("seed takes one integer 0..2^64-1: seed N")
                    scn.seed = _int(rest[0])
                elif cmd == "randomize":
                    if rest:
                        raise fail("randomize takes no argument (the robot comes from the seed)")
                    scn.randomize = True
                elif cmd in ("start", "board_start"):
                    if len(rest) != 3:
                        raise fail(f"{cmd} takes three numbers: {cmd} X_MM Y_MM HEADING_DEG")
                    x, y, h = (_num(w) for w in rest)
                    setattr(scn, cmd, (x, y, h))
                elif cmd == "start_uncertainty":
                    if len(rest) != 2:
                        raise fail(
                            "start_uncertainty takes two numbers: "
                            "start_uncertainty RADIUS_MM HEADING_DEG"
                        )
                    r, h = (_num(w) for w in rest)
                    Simulator(start_uncertainty=(r, h), record=False)  # checks the ranges
                    scn.start_uncertainty = (r, h)
                elif cmd == "config":
                    if len(rest) < 2:
                        raise fail("config takes a setting and its value(s): config KEY VALUE...")
                    values = [_num(w) for w in rest[1:]]
                    value: Any = values[0] if len(values) == 1 else values
                    Simulator({rest[0]: value}, record=False)  # checks the name and the value
                    scn.config[rest[0]] = value
                elif cmd == "board":
                    if len(rest) != 2:
                        raise fail("board takes a setting and its value: board KEY VALUE")
                    # checks the name and the value
                    Simulator(board_config={rest[0]: _int(rest[1])}, record=False)
                    scn.board[rest[0]] = _int(rest[1])
                elif cmd == "bus_hz":
                    if len(rest) != 1 or not 1000 <= _int(rest[0]) <= 1_000_000:
                        raise fail("bus_hz takes one integer 1000..1000000")
                    scn.bus_hz = _int(rest[0])
                elif cmd == "pec":
                    if rest not in (["on"], ["off"]):
                        raise fail("pec takes on or off")
                    scn.pec = rest == ["on"]
            except fieldmod.FieldError as e:
                raise fail(f"bad field file: {e}") from None
            except ValueError as e:
                if isinstance(e, ScenarioError):
                    raise
                raise fail(f"bad {cmd} line: {e}") from None
            continue
        if cmd not in BUS_COMMANDS:
            known = ", ".join([*SETUP, *BUS_COMMANDS])
            raise fail(f"unknown command {words[0]!r} (known: {known})")
        method, required, optional, usage = BUS_COMMANDS[cmd]
        if not len(required) <= len(rest) <= len(required) + len(optional):
            raise fail(f"{cmd} takes {usage}, got {len(rest)} argument(s)")
        args = []
        for i, (w, conv) in enumerate(zip(rest, [*required, *optional], strict=False), 1):
            try:
                args.append(conv(w))
            except ValueError:
                raise fail(f"argument {i} of {cmd} ({w!r}) is not valid: {usage}") from None
        if cmd in ("wait", "sleep") and args and not args[0] > 0:
            raise fail(f"{cmd} takes a positive number of seconds, not {args[0]}")
        if method and args:
            try:
                getattr(dry, method)(*args)
            except (ValueError, TypeError) as e:
                raise fail(f"{cmd}: {e}") from None
        scn.steps.append(Step(n, cmd, args, raw.strip()))
    if not scn.steps:
        raise ScenarioError(f"{source}: no bus command: nothing to play")
    return scn


def load(path: str | Path) -> Scenario:
    p = Path(path)
    try:
        text = p.read_text()
    except OSError as e:
        raise ScenarioError(f"{p}: cannot read the scenario: {e.strerror}") from None
    except UnicodeDecodeError:
        raise ScenarioError(f"{p}: not a text file") from None
    return parse(text, str(p), p.parent)


def _hex(data: bytes) -> str:
    return " ".join(f"{b:02x}" for b in data)


def _flags(status: int) -> str:
    names = [s.name for s in Status if s.name and status & s]
    return "|".join(n for n in names if n) or "idle"


class FramePrinter:
    """Prints every I2C transaction with its meaning; runs of identical polls are folded into
    one line that says how many there were and until when."""

    def __init__(self, out: Callable[[str], None]) -> None:
        self.out = out
        self._pending: Frame | None = None
        self._last: tuple[bytes, bytes] | None = None
        self._repeats = 0
        self._last_t = 0.0

    def header(self) -> None:
        self.out(f"{'t [s]':>8}  {'I2C (hex: W write, R read)':<34}  meaning")

    def __call__(self, frame: Frame) -> None:
        if frame.kind == "W" and not frame.stop:
            self._pending = frame
            return
        if frame.kind == "W":
            self._emit(
                frame.t_s, frame.data, b"", f"W {_hex(frame.data)}", self._meaning(frame.data)
            )
            return
        w = self._pending
        self._pending = None
        wire = (f"W {_hex(w.data)} | " if w else "") + f"R {_hex(frame.data)}"
        self._emit(frame.t_s, w.data if w else b"", frame.data, wire, self._reply(w, frame.data))

    def _meaning(self, data: bytes) -> str:
        try:
            return codec.decode_write(data).describe()
        except codec.FrameError as e:
            return f"malformed ({e})"

    def _reply(self, w: Frame | None, data: bytes) -> str:
        if w is None or not data:
            return f"status: {_flags(data[0])}" if data else "empty read"
        try:
            msg = codec.message(w.data[0])
        except (KeyError, ValueError):
            return f"reply to an unknown designation: {_hex(data)}"
        if msg.kind != "ETAT":  # an order or setting, then the status in the same transaction
            return f"{self._meaning(w.data)} -> status: {_flags(data[0])}"
        try:
            reply = codec.decode_reply(msg.name, data[: codec.reply_length(msg.name)])
        except ValueError as e:
            return f"{msg.name}: {e}"
        if isinstance(reply, Status):
            return f"{msg.name} -> {_flags(int(reply))}"
        return f"{msg.name} -> {reply}"

    def _emit(self, t: float, w: bytes, r: bytes, wire: str, meaning: str) -> None:
        key = (w, r)
        if key == self._last:
            self._repeats += 1
            self._last_t = t
            return
        self.flush()
        self._last = key
        self.out(f"{t:8.3f}  {wire:<34}  {meaning}")

    def end_run(self) -> None:
        """Print the folded repeats, and fold nothing into what was printed before."""
        self.flush()
        self._last = None

    def flush(self) -> None:
        if self._repeats:
            self.out(
                f"{'':8}  {'':34}  (the same {self._repeats} more times,"
                f" until {self._last_t:.3f} s)"
            )
        self._repeats = 0


@dataclass
class Result:
    sim: Simulator
    board: Board
    final_status: int
    wall_s: float
    targets: list[tuple[float, float]]
    ok: bool


def play(scn: Scenario, out: Callable[[str], None] = print) -> Result:
    """Play a checked scenario on a new simulated board, printing every frame."""
    sim = scn.simulator()
    board = Board(sim.bus, pec=scn.pec)
    printer = FramePrinter(out)
    sim.on_frame.append(printer)
    out(f"robot: {sim.describe_robot()}")
    out("")
    printer.header()
    targets: list[tuple[float, float]] = []
    ok = True
    status = 0
    t0 = time.perf_counter()
    for step in scn.steps:
        try:
            if step.command == "wait":
                timeout = step.args[0] if step.args else 30.0
                status = int(board.wait_idle(timeout))
                printer.end_run()
                out(f"{sim.time_s:8.3f}  {'':34}  order ended: {_flags(status)}")
            elif step.command == "sleep":
                sim.advance(step.args[0])
            else:
                method = BUS_COMMANDS[step.command][0]
                value = getattr(board, method)(*step.args)
                if step.command == "goto":
                    targets.append((float(step.args[0]), float(step.args[1])))
                if value is not None:
                    printer.end_run()
        except AsservError as e:
            printer.flush()
            out(f"{scn.source}:{step.line}: {e}")
            ok = False
            break
    printer.flush()
    sim.on_frame.remove(printer)
    return Result(sim, board, status, time.perf_counter() - t0, targets, ok)


def summary(res: Result, out: Callable[[str], None] = print) -> float:
    """Prints where the board thinks the robot is, where it is, and the error; returns the
    error of the estimate in mm."""
    sim, tr = res.sim, res.sim.trace
    truth = sim.true_pose()
    pose = res.board.position()
    last = tr[-1]
    err = math.hypot(last["est_x_mm"] - last["x_mm"], last["est_y_mm"] - last["y_mm"])
    out("")
    out("status over time (from the board's own status byte, every tick):")
    prev = -1
    for row in tr:
        s = int(row["status"])
        if s != prev:
            out(f"{row['t_s']:8.3f} s  {_flags(s)}")
            prev = s
    out("")
    out(
        f"estimate, POSITION : x {pose.x_mm} mm, y {pose.y_mm} mm, angle {pose.angle_deg} deg, "
        f"error radius {pose.radius_mm} mm"
    )
    out(
        f"estimate, internal : x {last['est_x_mm']:.2f} mm, y {last['est_y_mm']:.2f} mm, "
        f"heading {last['est_heading_deg']:.2f} deg"
    )
    out(
        f"truth (simulator)  : x {truth.x_mm:.2f} mm, y {truth.y_mm:.2f} mm, "
        f"heading {truth.heading_deg:.2f} deg"
    )
    within = "within" if err <= pose.radius_mm else "OUTSIDE"
    out(f"estimate - truth   : {err:.2f} mm ({within} the {pose.radius_mm} mm error radius)")
    out(
        f"simulated {sim.time_s:.2f} s ({sim.ticks} control ticks) in {res.wall_s:.2f} s of wall "
        "time"
    )
    return err
