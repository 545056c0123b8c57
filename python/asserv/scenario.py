"""Scenario files: orders and waits played by the master driver on the simulated board.

A scenario is a text file, one command a line, ``#`` starts a comment::

    # the specification's annex session
    field annex              # field/annex.toml (or a path to a field file)
    set_vitesse_traj 100     # cm/s (an optional second number: cm/s^2)
    set_vitesse_rot 50
    goto 200 100             # x_mm y_mm [options: ligne, bord, append, through, a+b, a number]
    wait                     # poll CHECK_BUSY until the order ends [timeout_s, default 30]
    goto_panier 44           # degrees, sent in 2-degree steps

Setup lines come first: ``field NAME|PATH``, ``robot NAME|PATH`` (robot/NAME.toml, a robot
description), ``seed N``, ``randomize`` (a robot drawn from the seed: wheel mismatch, track
error, noise, start error), ``start X_MM Y_MM HEADING_DEG`` (the true start pose, which the
board also believes), ``config KEY VALUE...`` (a member of ``struct sim_config``, e.g.
``config enc_radius_error 0.003 -0.003``), ``bus_hz N``, ``pec on``.
Then the bus commands, one per driver method: ``goto``, ``goto_reverse``, ``goto_panier``,
``stop``, ``set_vitesse_traj``, ``set_vitesse_rot``, ``set_filtre`` (STD, SOUPLE, RAIDE or a
number), ``set_filtre_raw``, ``set_new_pos``, ``declare_pose``, ``check_busy``, ``position``,
``info_choc``, ``version``, ``last_reject``, ``debug``, ``pause``, ``resume``,
``set_speed_scale``, ``set_corner``, ``motion`` (issue 31's match play); and
``wait [TIMEOUT_S]``, ``sleep SECONDS``.

Opponents and timed events (docs/simulator.md, "Scenario files")::

    opponent -400 500 150 300 -400 -300     # X Y RADIUS_MM SPEED_MM_S, then its path [loop]
    crossing_opponent 150 random 0 -850 600 -600 900 300   # a random path across that route
    at 2.5 press 1                          # at T (simulated s): press MASK, release,
                                            # cut_encoder L|R, restore_encoder L|R,
                                            # stick_motor L|R, free_motor L|R, battery VOLTS,
                                            # move_obstacle I X Y, opponent_path I SPEED X Y...

Assertions, after a ``wait``: ``expect OUTCOME`` (done, border, basket, shock, motor, grave,
stopped) and ``expect pose X_MM Y_MM WITHIN_MM`` (the true position). A scenario passes when
every expectation holds and no order ends in a fault (motor, grave) that an ``expect`` does not
name; ``asserv sim run`` exits 1 otherwise, and warns when the scenario ends with the robot
still busy.

The whole file is checked before anything runs: a malformed line, a start pose where the
robot does not fit on the table, or a target off the table or inside an obstacle is reported
with its file and line number (exit 2), and nothing is played.
"""

from __future__ import annotations

import dataclasses
import math
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

from . import codec
from . import field as fieldmod
from ._protocol import Capability, EndReason, Filtre, ResetCause, Status
from .codec import Pose
from .driver import AsservError, Board, GotoOption, Outcome, outcome_of
from .fixes import FixSource

if TYPE_CHECKING:  # the simulator (asserv[sim]) is imported where a scenario is checked or
    # played, so that asserv[view] without it imports this module (asserv --bus 1 view)
    from .sim import Frame, Simulator

SCENARIO_DIR = fieldmod.data_dir("scenarios")


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
    return GotoOption.parse(word)  # the same names as the CLI's --options


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
    "set_timeout": ("set_timeout", [_int], [], "set_timeout MS"),
    "heartbeat": ("heartbeat", [], [], "heartbeat"),
    "fix_info": ("fix_info", [], [], "fix_info"),
    "reset_info": ("reset_info", [], [], "reset_info"),
    "pause": ("pause", [], [], "pause"),
    "resume": ("resume", [], [], "resume"),
    "set_speed_scale": ("set_speed_scale", [_int], [], "set_speed_scale PERCENT"),
    "set_corner": ("set_corner", [_int], [], "set_corner TOLERANCE_MM"),
    "motion": ("motion", [], [], "motion"),
    "wait": ("", [], [_num], "wait [TIMEOUT_S]"),
    "sleep": ("", [_num], [], "sleep SECONDS"),
}
#: The names of ``expect OUTCOME``.
OUTCOMES: dict[str, Outcome] = {
    "done": Outcome.DONE,
    "border": Outcome.BORDER_RECALIBRATED,
    "basket": Outcome.BASKET_REACHED,
    "shock": Outcome.SHOCK,
    "motor": Outcome.MOTOR_PROBLEM,
    "grave": Outcome.GRAVE_FAULT,
    "stopped": Outcome.STOPPED,
}
_FAULTS = (Outcome.MOTOR_PROBLEM, Outcome.GRAVE_FAULT)
# at T EVENT ...: the number of arguments, and their usage
EVENTS: dict[str, str] = {
    "press": "press MASK (bit n: CAPTEUR_n)",
    "release": "release",
    "cut_encoder": "cut_encoder left|right",
    "restore_encoder": "restore_encoder left|right",
    "stick_motor": "stick_motor left|right",
    "free_motor": "free_motor left|right",
    "battery": "battery VOLTS",
    "move_obstacle": "move_obstacle INDEX X_MM Y_MM",
    "opponent_path": "opponent_path INDEX SPEED_MM_S X_MM Y_MM ... [loop]",
    "reset": "reset BROWN_OUT|WATCHDOG|PIN|SOFTWARE [kept|lost] [DOWN_MS]",
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
    "opponent",
    "crossing_opponent",
    "robot",
    "fixes",
)


def _wheel(word: str) -> int:
    w = word.lower()
    if w in ("left", "l", "0"):
        return 0
    if w in ("right", "r", "1"):
        return 1
    raise ValueError(word)


def _path(words: list[str]) -> tuple[list[tuple[float, float]], bool]:
    loop = bool(words) and words[-1].lower() == "loop"
    nums = [_num(w) for w in (words[:-1] if loop else words)]
    if len(nums) % 2:
        raise ValueError("a path is pairs of numbers X_MM Y_MM")
    return [(nums[i], nums[i + 1]) for i in range(0, len(nums), 2)], loop


@dataclass
class Opponent:
    line: int
    x_mm: float
    y_mm: float
    radius_mm: float
    speed_mm_s: float
    path: list[tuple[float, float]]
    loop: bool
    #: For a crossing_opponent: the route its random path crosses (x, y, path and loop unused).
    route: list[tuple[float, float]] | None = None


@dataclass
class Event:
    line: int
    t_s: float
    kind: str
    args: list[Any]
    text: str


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
    start_line: int = 0
    robot: Path | None = None
    opponents: list[Opponent] = dataclasses.field(default_factory=list)
    events: list[Event] = dataclasses.field(default_factory=list)
    fixes: FixSource | None = None  # a simulated localisation feeding SET_FIX (asserv.fixes)

    def simulator(self, record: bool = True) -> Simulator:
        from .sim import Simulator

        config = dict(self.config)
        if self.start is not None:
            config["start"] = self.start
        return Simulator(
            config,
            self.seed,
            field=self.field,
            robot=self.robot,
            record=record,
            randomize=self.randomize,
            bus_hz=self.bus_hz,
            board_start=self.board_start,
            start_uncertainty=self.start_uncertainty,
            board_config=self.board,
        )

    def prepare(self, sim: Simulator, out: Callable[[str], None] = print) -> None:
        """Put the opponents on ``sim``'s field, start the fix source and schedule the timed
        events."""
        if self.fixes is not None:  # drawn from the scenario's seed, wherever its line is
            sim.add_fix_source(dataclasses.replace(self.fixes, seed=self.seed))
        for o in self.opponents:
            if o.route is not None:
                speed = o.speed_mm_s if o.speed_mm_s > 0 else None
                sim.add_crossing_opponent(o.route, radius_mm=o.radius_mm, speed_mm_s=speed)
            else:
                sim.add_opponent(o.x_mm, o.y_mm, o.radius_mm, o.path, o.speed_mm_s, o.loop)
        for ev in self.events:
            sim.at(ev.t_s, _event_action(ev, out))


def _event_action(ev: Event, out: Callable[[str], None]) -> Callable[[Simulator], None]:
    def run(sim: Simulator) -> None:
        out(f"{sim.time_s:8.3f}  {'':34}  event (line {ev.line}): {ev.text}")
        a = ev.args
        if ev.kind == "press":
            sim.press(a[0])
        elif ev.kind == "release":
            sim.press(0)
        elif ev.kind in ("cut_encoder", "restore_encoder"):
            sim.set_encoder_cut(a[0], ev.kind == "cut_encoder")
        elif ev.kind in ("stick_motor", "free_motor"):
            sim.set_motor_stuck(a[0], ev.kind == "stick_motor")
        elif ev.kind == "battery":
            sim.set_battery_volts(a[0])
        elif ev.kind == "move_obstacle":
            sim.move_obstacle(a[0], a[1], a[2])
        elif ev.kind == "opponent_path":
            sim.set_opponent_path(a[0], a[2], a[1], a[3])
        elif ev.kind == "reset":
            reset(sim)

    def reset(sim: Simulator) -> None:  # between two of the master's transactions
        if sim.bus_busy:
            sim.at(sim.time_s + 0.0005, reset)
        else:
            sim.reset(ev.args[0], keep_ram=ev.args[1], down_ms=ev.args[2])

    return run


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


def parse(
    text: str, source: str = "<scenario>", base: Path | None = None, *, setup_only: bool = False
) -> Scenario:
    """Check a whole scenario; ScenarioError names the first bad line. ``setup_only``: the
    world of a scenario without bus commands (the robot, the field, opponents, events), for
    ``asserv sim serve --scenario``: a bus command is then refused."""
    from .sim import Simulator

    base = base or Path.cwd()
    scn = Scenario(source, fieldmod.load())
    dry = Board(_DryBus(), check=False)
    dry._capabilities = Capability(sum(int(c) for c in Capability))  # judge the args only
    for n, raw in enumerate(text.splitlines(), 1):
        words = raw.split("#", 1)[0].split()
        if not words:
            continue
        where = f"{source}:{n}"
        cmd, rest = words[0].lower(), words[1:]

        def fail(what: str, where: str = where, raw: str = raw) -> ScenarioError:
            return ScenarioError(f"{where}: {what} (line: {raw.strip()!r})")

        if cmd == "at":
            scn.events.append(_parse_event(rest, n, raw, fail))
            continue
        if cmd == "expect":
            scn.steps.append(_parse_expect(scn, rest, n, raw, fail))
            continue
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
                    if cmd == "start":
                        scn.start_line = n
                elif cmd == "robot":
                    from . import robot as robotmod

                    if len(rest) != 1:
                        raise fail("robot takes one name or path: robot NAME|PATH")
                    word = rest[0]
                    p = (
                        robotmod.ROBOT_DIR / f"{word}.toml"
                        if "/" not in word and not (word.endswith(".toml"))
                        else (Path(word) if Path(word).is_absolute() else base / word)
                    )
                    try:
                        robotmod.load(p)
                    except robotmod.RobotError as e:
                        raise fail(f"bad robot file: {e}") from None
                    scn.robot = p
                elif cmd == "opponent":
                    usage = "opponent X_MM Y_MM RADIUS_MM SPEED_MM_S [X_MM Y_MM]... [loop]"
                    if len(rest) < 4:
                        raise fail(f"opponent takes {usage}")
                    x, y, r, v = (_num(w) for w in rest[:4])
                    if not (r > 0 and v > 0):
                        raise fail(f"opponent: the radius and the speed must be > 0 ({usage})")
                    path, loop = _path(rest[4:])
                    if len(path) > 16:
                        raise fail("opponent: a path has at most 16 points")
                    for px, py in [(x, y), *path]:
                        where_ = _inside(scn.field, px, py) if scn.field.borders else None
                        if where_ and where_.startswith("off"):
                            raise fail(f"opponent: ({px:g}, {py:g}) is {where_}")
                    scn.opponents.append(Opponent(n, x, y, r, v, path, loop))
                elif cmd == "crossing_opponent":
                    usage = "crossing_opponent RADIUS_MM SPEED_MM_S|random X_MM Y_MM X_MM Y_MM..."
                    if len(rest) < 6:
                        raise fail(f"crossing_opponent takes {usage} (the route it crosses)")
                    r = _num(rest[0])
                    v = 0.0 if rest[1].lower() == "random" else _num(rest[1])
                    if not (0 < r < 1000 and (v > 0 or rest[1].lower() == "random")):
                        raise fail(
                            f"crossing_opponent: the radius and the speed must be > 0 ({usage})"
                        )
                    route, loop = _path(rest[2:])
                    if loop:
                        raise fail(f"crossing_opponent: its path loops already ({usage})")
                    for px, py in route:
                        where_ = _inside(scn.field, px, py) if scn.field.borders else None
                        if where_ and where_.startswith("off"):
                            raise fail(f"crossing_opponent: ({px:g}, {py:g}) is {where_}")
                    if len(route) < 2 or len(set(route)) < 2:
                        raise fail(
                            f"crossing_opponent: the route needs two distinct points ({usage})"
                        )
                    scn.opponents.append(Opponent(n, 0.0, 0.0, r, v, [], True, route))
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
                elif cmd == "fixes":
                    usage = (
                        "fixes RATE_HZ SIGMA_MM SIGMA_DEG|none LATENCY_MS [JITTER_MS"
                        " [OUTLIER_RATE]]"
                    )
                    if not 4 <= len(rest) <= 6:
                        raise fail(f"fixes takes {usage}")
                    nums = [_num(w) for w in rest[:2]]
                    deg = None if rest[2].lower() == "none" else _num(rest[2])
                    more = [_num(w) for w in rest[3:]]
                    scn.fixes = FixSource(
                        rate_hz=nums[0],
                        sigma_mm=nums[1],
                        sigma_deg=deg,
                        latency_ms=more[0],
                        latency_jitter_ms=more[1] if len(more) > 1 else 0.0,
                        outlier_rate=more[2] if len(more) > 2 else 0.0,
                        seed=scn.seed,
                    )
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
        if setup_only and cmd in (*BUS_COMMANDS, "expect"):
            raise fail(
                f"'{cmd}' is a bus command: a scenario for the server sets up the world only"
                " (the strategy sends the orders)"
            )
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
        if cmd == "goto":
            problem = _inside(scn.field, args[0], args[1])
            if problem:
                raise fail(f"goto: the target ({args[0]}, {args[1]}) is {problem}")
        scn.steps.append(Step(n, cmd, args, raw.strip()))
    if not scn.steps and not setup_only:
        raise ScenarioError(f"{source}: no bus command: nothing to play")
    _check_field(scn, text)
    return scn


def _check_field(scn: Scenario, text: str) -> None:
    """The start pose against the field (with the robot's outline), and the obstacles the
    events name."""
    lines = text.splitlines()

    def fail(line: int, what: str) -> ScenarioError:
        raw = lines[line - 1].strip() if 0 < line <= len(lines) else ""
        where = f"{scn.source}:{line}" if line else scn.source
        return ScenarioError(f"{where}: {what}" + (f" (line: {raw!r})" if raw else ""))

    sim = scn.simulator()
    x, y, h = scn.start if scn.start is not None else sim.drive_pose()
    problem = check_pose(scn.field, sim.config, x, y, h)
    if problem:
        raise fail(scn.start_line, f"start: {problem}")
    n_obstacles = len(scn.field.baskets) + len(scn.field.obstacles) + len(scn.opponents)
    for ev in scn.events:
        if ev.kind in ("move_obstacle", "opponent_path") and not 0 <= ev.args[0] < n_obstacles:
            raise fail(
                ev.line,
                f"{ev.kind}: no obstacle {ev.args[0]} (the field's baskets, obstacles and"
                f" opponents are 0..{n_obstacles - 1})",
            )
        if ev.kind == "move_obstacle":
            problem = _inside(scn.field, ev.args[1], ev.args[2])
            if problem and problem.startswith("off"):
                raise fail(ev.line, f"move_obstacle: ({ev.args[1]}, {ev.args[2]}) is {problem}")


Fail = Callable[[str], ScenarioError]


def _parse_event(rest: list[str], n: int, raw: str, fail: Fail) -> Event:
    if len(rest) < 2:
        raise fail(f"at takes a time and an event: at T_S EVENT ... ({', '.join(EVENTS)})")
    try:
        t = _num(rest[0])
    except ValueError:
        raise fail(f"at: the time {rest[0]!r} is not a number of seconds") from None
    if t < 0:
        raise fail(f"at: the time {t:g} is before the start (0 s)")
    kind, words = rest[1].lower(), rest[2:]
    if kind not in EVENTS:
        raise fail(f"at: unknown event {rest[1]!r} (known: {', '.join(EVENTS)})")
    usage = EVENTS[kind]
    try:
        args: list[Any]
        if kind == "press":
            if len(words) != 1 or not 0 <= _int(words[0]) <= 0xFF:
                raise ValueError
            args = [_int(words[0])]
        elif kind == "release":
            if words:
                raise ValueError
            args = []
        elif kind == "battery":
            if len(words) != 1 or not 0 <= _num(words[0]) <= 60:
                raise ValueError
            args = [_num(words[0])]
        elif kind == "move_obstacle":
            if len(words) != 3:
                raise ValueError
            args = [_int(words[0]), _num(words[1]), _num(words[2])]
        elif kind == "opponent_path":
            if len(words) < 2:
                raise ValueError
            path, loop = _path(words[2:])
            speed = _num(words[1])
            if not speed > 0 or len(path) > 16:
                raise ValueError
            args = [_int(words[0]), speed, path, loop]
        elif kind == "reset":
            args = _reset_args(words)
        else:
            if len(words) != 1:
                raise ValueError
            args = [_wheel(words[0])]
    except ValueError:
        raise fail(f"at {rest[0]} {kind} takes {usage}") from None
    return Event(n, t, kind, args, " ".join([kind, *words]))


def _reset_args(words: list[str]) -> list[Any]:
    """``reset CAUSE [kept|lost] [DOWN_MS]``: the cause's name, whether the RAM is kept (the
    default), the time down (0..1000 ms, default 30, as ``Simulator.reset``)."""
    if not 1 <= len(words) <= 3:
        raise ValueError
    cause = ResetCause[words[0].upper()] if words[0].upper() in ResetCause.__members__ else None
    if cause in (None, ResetCause.POWER_ON):
        raise ValueError
    keep, down = True, 30
    rest = words[1:]
    if rest and rest[0].lower() in ("kept", "lost"):
        keep = rest.pop(0).lower() == "kept"
    if rest:
        down = _int(rest.pop(0))
        if not 0 <= down <= 1000:
            raise ValueError
    if rest:
        raise ValueError
    return [cause, keep, down]


def _parse_expect(scn: Scenario, rest: list[str], n: int, raw: str, fail: Fail) -> Step:
    usage = f"expect {'|'.join(OUTCOMES)}, or expect pose X_MM Y_MM WITHIN_MM"
    if not scn.steps or scn.steps[-1].command not in ("wait", "expect"):
        raise fail(f"expect follows a wait (it checks how the order waited for ended): {usage}")
    if len(rest) == 1 and rest[0].lower() in OUTCOMES:
        return Step(n, "expect", [OUTCOMES[rest[0].lower()]], raw.strip())
    if len(rest) == 4 and rest[0].lower() == "pose":
        try:
            x, y, tol = (_num(w) for w in rest[1:])
        except ValueError:
            raise fail(f"expect pose takes three numbers: {usage}") from None
        if not tol > 0:
            raise fail("expect pose: WITHIN_MM must be > 0")
        return Step(n, "expect_pose", [x, y, tol], raw.strip())
    raise fail(f"expect takes {usage}")


def load(path: str | Path, *, setup_only: bool = False) -> Scenario:
    p = Path(path)
    try:
        text = p.read_text()
    except OSError as e:
        raise ScenarioError(f"{p}: cannot read the scenario: {e.strerror}") from None
    except UnicodeDecodeError:
        raise ScenarioError(f"{p}: not a text file") from None
    return parse(text, str(p), p.parent, setup_only=setup_only)


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
    position: Pose | None = None  # the reply of the scenario's last ``position`` line


def play(scn: Scenario, out: Callable[[str], None] = print) -> Result:
    """Play a checked scenario on a new simulated board, printing every frame. The result is
    not ``ok`` when a bus call fails, an expectation does not hold, or an order ends in a fault
    that no ``expect`` names."""
    sim = scn.simulator()
    board = Board(sim.bus, pec=scn.pec)
    printer = FramePrinter(out)
    scn.prepare(sim, out)
    sim.on_frame.append(printer)
    out(f"robot: {sim.describe_robot()}")
    out("")
    printer.header()
    targets: list[tuple[float, float]] = []
    ok = True
    status = 0
    outcome: Outcome | None = None
    position: Pose | None = None
    t0 = time.perf_counter()
    steps = scn.steps
    for k, step in enumerate(steps):
        nxt = steps[k + 1] if k + 1 < len(steps) else None
        try:
            if step.command == "wait":
                timeout = step.args[0] if step.args else 30.0
                st = board.wait_idle(timeout)
                status = int(st)
                ends = Status.CHOC_BORD | Status.CHOC_PANIER
                expects = nxt is not None and nxt.command == "expect"
                reason = board.debug().end_reason if st & ends or expects else None
                ended = outcome_of(st, EndReason.DONE if reason is None else reason)
                outcome = ended
                printer.end_run()
                out(f"{sim.time_s:8.3f}  {'':34}  order ended: {_flags(status)} ({ended.value})")
                if ended in _FAULTS and not _expected_later(steps, k, ended):
                    out(
                        f"{scn.source}:{step.line}: the order ended in a fault the scenario"
                        f" does not expect: {ended.value} ({_flags(status)}); add"
                        f" 'expect {_outcome_name(ended)}' after this wait if it is meant"
                    )
                    ok = False
                    break
            elif step.command == "expect":
                want: Outcome = step.args[0]
                if outcome is not want:
                    got = outcome.value if outcome else "no order waited for"
                    out(
                        f"{scn.source}:{step.line}: expectation failed: expected"
                        f" {want.value}, the order ended: {got}"
                    )
                    ok = False
                else:
                    out(f"{'':8}  {'':34}  expect {want.value}: ok")
            elif step.command == "expect_pose":
                x, y, tol = step.args
                truth = sim.true_pose()
                d = math.hypot(truth.x_mm - x, truth.y_mm - y)
                if d > tol:
                    out(
                        f"{scn.source}:{step.line}: expectation failed: the robot is at"
                        f" ({truth.x_mm:.1f}, {truth.y_mm:.1f}), {d:.1f} mm from ({x:g}, {y:g}),"
                        f" not within {tol:g} mm"
                    )
                    ok = False
                else:
                    out(f"{'':8}  {'':34}  expect pose within {tol:g} mm: ok ({d:.1f} mm)")
            elif step.command == "sleep":
                sim.advance(step.args[0])
            else:
                method = BUS_COMMANDS[step.command][0]
                value = getattr(board, method)(*step.args)
                if step.command == "goto":
                    targets.append((float(step.args[0]), float(step.args[1])))
                if step.command == "position":
                    position = value
                if value is not None:
                    printer.end_run()
        except AsservError as e:
            printer.flush()
            out(f"{scn.source}:{step.line}: {e}")
            ok = False
            break
    printer.flush()
    sim.on_frame.remove(printer)
    try:
        busy = board.check_busy() & (Status.BUSY_TRAJET | Status.BUSY_GOTO_PANIER)
    except AsservError:
        busy = Status(0)
    if busy:
        out(
            f"warning: {scn.source}: the scenario ended with the robot still busy"
            f" ({_flags(int(busy))}): end it with a 'wait' to see how the order ends"
        )
    return Result(sim, board, status, time.perf_counter() - t0, targets, ok, position)


def _outcome_name(outcome: Outcome) -> str:
    return next(k for k, v in OUTCOMES.items() if v is outcome)


def _expected_later(steps: list[Step], k: int, outcome: Outcome) -> bool:
    """Whether the expect lines right after step k name ``outcome``."""
    for s in steps[k + 1 :]:
        if s.command == "expect_pose":
            continue
        if s.command != "expect":
            return False
        if s.args[0] is outcome:
            return True
    return False


def summary(res: Result, out: Callable[[str], None] = print) -> float:
    """Prints where the board thinks the robot is, where it is, and the error; returns the
    error of the estimate in mm."""
    sim, tr = res.sim, res.sim.trace
    truth = sim.true_pose()
    # the scenario's own POSITION, the one its log shows; a new read would be a later one
    pose = res.position or res.board.position()
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
