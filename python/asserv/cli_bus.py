"""The ``asserv --bus N ...`` commands: drive a real board (or a virtual bus) from the shell.

``add_bus_arguments(parser, subparsers)`` adds ``--bus``, ``--address``, ``--pec`` and one
subcommand per message; ``run_bus_command(args)`` runs the parsed command and returns the exit
code: 0 done, 1 the bus or the board failed (the driver's message on stderr), 2 bad arguments
(one line on stderr, nothing sent). Every argument is checked against the message table before
the bus opens: a value out of range is reported as the board would (OUT_OF_RANGE) without a bus.
The options are accepted before or after the subcommand:
``asserv --bus 1 goto 200 100`` and ``asserv goto 200 100 --bus 1`` are the same.
"""

from __future__ import annotations

import argparse
import dataclasses
import enum
import errno
import math
import os
import sys
from collections.abc import Callable
from typing import Protocol

from . import codec
from ._protocol import ADDRESS, Filtre, Status
from .backends import open_bus
from .cli_args import UsageError as _UsageError
from .cli_args import one_line
from .driver import AsservError, Board, GotoOption, SMBusLike, _flag_names

__all__ = [
    "BUS_COMMANDS",
    "add_bus_arguments",
    "add_bus_options",
    "is_bus_command",
    "open_error",
    "parse_address",
    "parse_bus",
    "run_bus_command",
]


class ClosableBus(SMBusLike, Protocol):
    def close(self) -> None: ...


BusFactory = Callable[[int], ClosableBus]

# The subcommands and their help.
BUS_COMMANDS: dict[str, str] = {
    "status": "read the status byte (CHECK_BUSY)",
    "position": "read the estimated pose and error radius (POSITION)",
    "info-choc": "read the shock sensors (INFO_CHOC)",
    "goto": "GOTO X Y (mm): turn towards the point, then drive straight to it",
    "goto-reverse": "GOTO_REVERSE D (mm, 0..255): drive straight backwards",
    "goto-panier": "GOTO_PANIER ANGLE (degrees): turn, drive forward until the basket",
    "stop": "STOP: decelerate and hold the position reached",
    "version": "read the protocol version and capabilities (VERSION)",
    "last-reject": "why the last rejected write was rejected (LAST_REJECT)",
    "set-vitesse-traj": "SET_VITESSE_TRAJ SPEED [ACCEL]: straight-line limits, cm/s, cm/s^2",
    "set-vitesse-rot": "SET_VITESSE_ROT SPEED [ACCEL]: rotation limits, cm/s, cm/s^2",
    "set-filtre": "SET_FILTRE PRESET: 0/STD, 1/SOUPLE or 2/RAIDE",
    "set-filtre-raw": "SET_FILTRE_RAW P I D: raw PID gains, 0..65535",
    "set-new-pos": "SET_NEW_POS X Y ANGLE: error of the estimate (estimate minus truth)",
    "set-timeout": "SET_TIMEOUT MS: stop when the master is silent this long (0: never)",
    "set-odometrie": "SET_ODOMETRIE RATIO_PPM TRACK_MM SCALE_PPM: odometry calibration",
    "wait": "poll the status until the trajectory is over (the annex's while (BUSY_TRAJET))",
    "debug": "read the DEBUG telemetry frame",
    "pause": "PAUSE: brake along the path and hold; the order and the queue are kept",
    "resume": "RESUME: go on with the paused order from where the robot stands",
    "scale": "SET_SPEED_SCALE P: P percent (0..100) of the speed limits, at once",
    "motion": "read the queue, the pause, the braking distance and the scale (MOTION)",
    "flash": "FIRMWARE...: update the STM32 board's application over the bus (docs/update.md)",
}


def _bus_options(parser: argparse.ArgumentParser, *, suppress: bool) -> None:
    def default(value: object) -> object:
        return argparse.SUPPRESS if suppress else value

    parser.add_argument(
        "--bus",
        metavar="N",
        default=default(None),
        help="Linux I2C bus number (/dev/i2c-N; 1 on a Raspberry Pi)",
    )
    parser.add_argument(
        "--sim",
        dest="bus_sim",
        metavar="HOST:PORT",
        default=default(None),
        help="the simulated board of `asserv sim serve` instead of an I2C bus",
    )
    parser.add_argument(
        "--address",
        dest="bus_address",
        metavar="ADDR",
        default=default(str(ADDRESS)),
        help=f"7-bit address of the board (default {ADDRESS})",
    )
    parser.add_argument(
        "--pec",
        dest="bus_pec",
        action="store_true",
        default=default(False),
        help="add a PEC to every write and check the PEC of every reply",
    )


def add_bus_options(parser: argparse.ArgumentParser) -> None:
    """``--bus``, ``--sim``, ``--address``, ``--pec`` on a subcommand's parser, left out of its
    namespace when absent (the main parser has them before the subcommand too)."""
    _bus_options(parser, suppress=True)


def add_bus_arguments(
    parser: argparse.ArgumentParser,
    subparsers: argparse._SubParsersAction[argparse.ArgumentParser] | None = None,
) -> None:
    """Add ``--bus N``, ``--address``, ``--pec`` to ``parser`` and the bus subcommands to
    ``subparsers`` (created on ``parser`` when not given; pass the main CLI's own when it has
    subcommands already, since a parser can have only one set)."""
    _bus_options(parser, suppress=False)
    if subparsers is None:
        subparsers = parser.add_subparsers(dest="command", required=True)
    common = argparse.ArgumentParser(add_help=False)
    _bus_options(common, suppress=True)

    def add(name: str) -> argparse.ArgumentParser:
        p = subparsers.add_parser(name, parents=[common], help=BUS_COMMANDS[name])
        p.set_defaults(bus_command=name, func=run_bus_command)
        return p

    for name in (
        "status",
        "position",
        "info-choc",
        "stop",
        "version",
        "last-reject",
        "debug",
        "pause",
        "resume",
        "motion",
    ):
        add(name)
    add("scale").add_argument("percent", metavar="P", help="percent of the limits (0..100)")
    append_help = "queue it behind the running order instead of replacing it (QUEUE)"
    p = add("goto")
    p.add_argument("x", metavar="X", help="target X, mm (-32000..32000)")
    p.add_argument("y", metavar="Y", help="target Y, mm (-32000..32000)")
    p.add_argument(
        "--options",
        default="0",
        help="recalibration: ligne (1), bord (2), ligne+bord (3), or the number",
    )
    p.add_argument("--append", action="store_true", help=append_help)
    p.add_argument(
        "--through", action="store_true", help="do not stop at the point if another order waits"
    )
    p = add("goto-reverse")
    p.add_argument("distance", metavar="D", help="distance, mm (0..255)")
    p.add_argument("--append", action="store_true", help=append_help)
    p = add("goto-panier")
    p.add_argument("angle", metavar="ANGLE", help="heading, degrees (-180..180)")
    p.add_argument("--raw", action="store_true", help="ANGLE in raw 2-degree steps (-90..90)")
    p.add_argument("--append", action="store_true", help=append_help)
    for name in ("set-vitesse-traj", "set-vitesse-rot"):
        p = add(name)
        p.add_argument("speed", metavar="SPEED", help="cm/s (1..255)")
        p.add_argument("accel", metavar="ACCEL", nargs="?", help="cm/s^2 (1..255); kept if absent")
    add("set-filtre").add_argument("preset", metavar="PRESET", help="0/STD, 1/SOUPLE, 2/RAIDE")
    p = add("set-filtre-raw")
    for g in ("p", "i", "d"):
        p.add_argument(g, metavar=g.upper(), help="0..65535")
    p = add("set-new-pos")
    p.add_argument("x", metavar="X", help="error of the estimate in X, mm")
    p.add_argument("y", metavar="Y", help="error of the estimate in Y, mm")
    p.add_argument("angle", metavar="ANGLE", help="error of the estimate in angle, degrees")
    add("set-timeout").add_argument("ms", metavar="MS", help="milliseconds (0..65535), 0: off")
    p = add("set-odometrie")
    p.add_argument("ratio", metavar="RATIO_PPM", help="right/left wheel factor correction, ppm")
    p.add_argument("track", metavar="TRACK_MM", help="encoder track, mm (to 0.01 mm)")
    p.add_argument("scale", metavar="SCALE_PPM", help="common wheel factor correction, ppm")
    add("flash").add_argument(
        "firmware",
        metavar="FIRMWARE",
        nargs="+",
        help="the build folder, or the application's ELF (or .bin) for each slot:"
        " asserv_stm32.elf (slot A) and asserv_stm32_b.elf (slot B); the board takes one",
    )
    p = add("wait")
    p.add_argument("--timeout", default="30", help="give up after S seconds (default 30)")
    p.add_argument("--poll", default="0.01", help="poll period, seconds (default 0.01)")


def is_bus_command(args: argparse.Namespace) -> bool:
    """True if ``args`` was parsed from one of the bus subcommands."""
    return getattr(args, "bus_command", None) is not None


def _checked(name: str, *args: int) -> None:
    """Raise FrameError now if the board would refuse these params (before the bus opens)."""
    codec.encode(name, *args)


def _int(what: str, text: str) -> int:
    try:
        return int(text, 0)
    except (TypeError, ValueError):
        raise _UsageError(f"{what} ({text!r}) is not an integer") from None


def _float(what: str, text: str) -> float:
    try:
        value = float(text)
    except (TypeError, ValueError):
        raise _UsageError(f"{what} ({text!r}) is not a number") from None
    if not math.isfinite(value):
        raise _UsageError(f"{what} ({text!r}) is not a finite number")
    return value


def _preset(text: str) -> Filtre:
    try:
        return Filtre(int(text, 0))
    except ValueError:
        pass
    name = text.upper()
    for f in Filtre:
        if name in (f.name, f.name.removeprefix("FILTRE_")):
            return f
    names = ", ".join(f"{f.value}/{f.name.removeprefix('FILTRE_')}" for f in Filtre)
    raise _UsageError(f"PRESET ({text!r}) is not a filter preset ({names})")


def _flags(status: Status) -> str:
    names = _flag_names(status)
    return f"status 0x{int(status):02x}: " + (names if status else "(no flag: idle)")


Action = Callable[[Board], list[str]]


def _action(args: argparse.Namespace) -> Action:
    """Parse the command's arguments (raising _UsageError) into what to do with the board."""
    cmd: str = args.bus_command

    def order(call: Callable[[Board], None], label: str) -> Action:
        def run(board: Board) -> list[str]:
            call(board)
            return [f"{label}: accepted" if board.check else f"{label}: sent"]

        return run

    if cmd == "status":
        return lambda b: [_flags(b.check_busy())]
    if cmd == "flash":
        from .bus import clock_of
        from .update import Progress, UpdateError, flash, load_images

        try:
            images = load_images(args.firmware)
        except UpdateError as e:
            raise _UsageError(str(e)) from None
        return lambda b: flash(b, images, Progress(sys.stderr, clock_of(b.bus)))
    if cmd == "position":

        def position(b: Board) -> list[str]:
            p = b.position()
            return [
                f"x {p.x_mm} mm, y {p.y_mm} mm, angle {p.angle_deg} deg,"
                f" error radius {p.radius_mm} mm"
            ]

        return position
    if cmd == "info-choc":

        def info_choc(b: Board) -> list[str]:
            s = b.info_choc()
            pressed = [f"CAPTEUR_{n}" for n in range(8) if s >> n & 1]
            return [f"sensors 0x{s:02x}: " + (" ".join(pressed) if pressed else "none pressed")]

        return info_choc
    if cmd == "goto":
        x, y = _int("X", args.x), _int("Y", args.y)
        try:
            opts = GotoOption.parse(args.options)  # the scenario files' names too
        except ValueError as e:
            raise _UsageError(f"--options {e}") from None
        app, thr = bool(args.append), bool(args.through)
        _checked("GOTO", x, y, opts | (4 if app else 0) | (8 if thr else 0))
        label = f"GOTO ({x}, {y}) options {opts}" + (" append" if app else "")
        label += " through" if thr else ""
        return order(lambda b: b.goto(x, y, opts, append=app, through=thr), label)
    if cmd == "goto-reverse":
        d = _int("D", args.distance)
        app = bool(args.append)
        _checked("GOTO_REVERSE", d, *((4,) if app else ()))
        label = f"GOTO_REVERSE {d} mm" + (" append" if app else "")
        return order(lambda b: b.goto_reverse(d, append=app), label)
    if cmd == "goto-panier":
        app = bool(args.append)
        more = (4,) if app else ()
        tail = " append" if app else ""
        if args.raw:
            steps = _int("ANGLE", args.angle)
            _checked("GOTO_PANIER", steps, *more)
            return order(
                lambda b: b.goto_panier(2 * steps, append=app), f"GOTO_PANIER {2 * steps} deg{tail}"
            )
        a = _float("ANGLE", args.angle)
        codec.encode_deg("GOTO_PANIER", a, *more)
        return order(lambda b: b.goto_panier(a, append=app), f"GOTO_PANIER {a:g} deg{tail}")
    if cmd == "pause":
        return order(lambda b: b.pause(), "PAUSE")
    if cmd == "resume":
        return order(lambda b: b.resume(), "RESUME")
    if cmd == "scale":
        pc = _int("P", args.percent)
        _checked("SET_SPEED_SCALE", pc)
        return order(lambda b: b.set_speed_scale(pc), f"SET_SPEED_SCALE {pc} %")
    if cmd == "motion":

        def motion(b: Board) -> list[str]:
            m = b.motion()
            state = "paused" if m.paused else ("running" if m.running else "idle")
            return [
                f"{state}: order {m.running_seq} runs, {m.pending} pending;"
                f" last ended {m.last_seq}: {m.last_end.name}",
                f"braking {m.braking_mm} mm in {m.braking_ms} ms; speed scale {m.scale_percent} %",
            ]

        return motion
    if cmd == "stop":
        return order(lambda b: b.stop(), "STOP")
    if cmd in ("set-vitesse-traj", "set-vitesse-rot"):
        speed = _int("SPEED", args.speed)
        accel = None if args.accel is None else _int("ACCEL", args.accel)
        name = cmd.upper().replace("-", "_")
        _checked(name, speed, *(() if accel is None else (accel,)))
        label = f"{name} {speed} cm/s" + (f", {accel} cm/s^2" if accel is not None else "")
        if cmd == "set-vitesse-traj":
            return order(lambda b: b.set_vitesse_traj(speed, accel), label)
        return order(lambda b: b.set_vitesse_rot(speed, accel), label)
    if cmd == "set-filtre":
        preset = _preset(args.preset)
        return order(lambda b: b.set_filtre(preset), f"SET_FILTRE {preset.name}")
    if cmd == "set-filtre-raw":
        p, i, d = _int("P", args.p), _int("I", args.i), _int("D", args.d)
        _checked("SET_FILTRE_RAW", p, i, d)
        return order(lambda b: b.set_filtre_raw(p, i, d), f"SET_FILTRE_RAW P={p} I={i} D={d}")
    if cmd == "set-new-pos":
        ex, ey, ea = _int("X", args.x), _int("Y", args.y), _int("ANGLE", args.angle)
        _checked("SET_NEW_POS", ex, ey, ea)
        return order(lambda b: b.set_new_pos(ex, ey, ea), f"SET_NEW_POS ({ex}, {ey}, {ea})")
    if cmd == "set-timeout":
        ms = _int("MS", args.ms)
        _checked("SET_TIMEOUT", ms)
        return order(lambda b: b.set_timeout(ms), f"SET_TIMEOUT {ms} ms")
    if cmd == "set-odometrie":
        ratio, scale = _int("RATIO_PPM", args.ratio), _int("SCALE_PPM", args.scale)
        track = round(_float("TRACK_MM", args.track) * 100)
        _checked("SET_ODOMETRIE", ratio, track, scale)
        return order(
            lambda b: b.set_odometrie(ratio, track, scale),
            f"SET_ODOMETRIE ratio {ratio} ppm, track {track / 100:.2f} mm, scale {scale} ppm",
        )
    if cmd == "version":

        def version(b: Board) -> list[str]:
            v = b.version()
            caps = " ".join(f.name for f in type(v.capabilities) if f in v.capabilities and f.name)
            return [
                f"protocol {v.major}.{v.minor}, capabilities 0x{int(v.capabilities):04x}:"
                f" {caps or 'none'}"
            ]

        return version
    if cmd == "last-reject":

        def last_reject(b: Board) -> list[str]:
            r = b.last_reject()
            if r.count == 0:
                return ["no write rejected since reset"]
            m = codec.BY_DESIGNATION.get(r.designation)
            what = m.name if m else "an unknown message"
            return [
                f"{r.reason.name} on {what} (designation 0x{r.designation:02x});"
                f" {r.count}{'+' if r.count == 255 else ''} writes rejected since reset"
            ]

        return last_reject
    if cmd == "wait":
        timeout = _float("--timeout", args.timeout)
        poll = _float("--poll", args.poll)
        if timeout < 0:
            raise _UsageError(f"--timeout ({args.timeout!r}) must be >= 0")
        if poll <= 0:
            raise _UsageError(f"--poll ({args.poll!r}) must be > 0")
        return lambda b: [_flags(b.wait_idle(timeout, poll))]
    if cmd == "debug":

        def debug(b: Board) -> list[str]:
            d = b.debug()
            values = {f.name: getattr(d, f.name) for f in dataclasses.fields(d)}
            return [f"{k} {v.name if isinstance(v, enum.Enum) else v}" for k, v in values.items()]

        return debug
    raise _UsageError(f"unknown command {cmd!r}")  # add_bus_arguments and this list disagree


def parse_bus(text: str) -> int:
    """``--bus N``: the bus number (raises _UsageError)."""
    number = _int("--bus", text)
    if not 0 <= number <= 0xFFFF:
        raise _UsageError(f"--bus ({text!r}) is not a bus number (0..65535)")
    return number


def parse_address(text: str) -> int:
    """``--address A``: a 7-bit address (raises _UsageError)."""
    address = _int("--address", text)
    if not 0 <= address <= 0x7F:
        raise _UsageError(f"--address ({text!r}) is not a 7-bit address (0..0x7f)")
    return address


def open_error(number: int, e: OSError) -> str:
    """The message for a bus that does not open, with a hint for the usual causes."""
    hint = {
        errno.ENOENT: "; is I2C enabled? (raspi-config, or dtparam=i2c_arm=on)",
        errno.EACCES: "; add your user to the i2c group",
    }.get(e.errno or 0, "")
    reason = os.strerror(e.errno) if e.errno else str(e)
    return f"cannot open /dev/i2c-{number}: {reason}{hint}"


def _opened(bus: ClosableBus) -> BusFactory:
    return lambda _number: bus


def run_bus_command(args: argparse.Namespace, bus_factory: BusFactory | None = None) -> int:
    """Run a parsed bus command; return the exit code (0 done, 1 bus or board error, 2 bad
    arguments). ``bus_factory(N)`` opens bus N: the registry's (``asserv.backends.BACKENDS``) by
    default, or a VirtualBus in tests."""
    cmd = getattr(args, "bus_command", None) or "?"
    prog = f"asserv {cmd}"

    def fail(code: int, message: str) -> int:
        print(one_line(f"{prog}: {message}"), file=sys.stderr)
        return code

    remote = getattr(args, "bus_sim", None)
    try:
        if remote is not None:
            from .server import parse_address as parse_sim_address

            if getattr(args, "bus", None) is not None:
                raise _UsageError("give --bus N or --sim HOST:PORT, not both")
            try:
                host, port = parse_sim_address(remote)
            except ValueError as e:
                raise _UsageError(f"--sim {e}") from None
            number = -1
        elif getattr(args, "bus", None) is None:
            raise _UsageError(
                "--bus N is required (the Linux I2C bus number, 1 on a Raspberry Pi),"
                " or --sim HOST:PORT for the simulator of `asserv sim serve`"
            )
        else:
            number = parse_bus(args.bus)
        address = parse_address(args.bus_address)
        action = _action(args)
    except _UsageError as e:
        return fail(2, str(e))
    except codec.FrameError as e:  # out of range: reported as the board would, nothing opened
        return fail(2, str(e))

    if remote is not None:
        try:
            bus: ClosableBus = open_bus("sim", (host, port))
        except OSError as e:
            return fail(1, e.strerror or str(e))
        bus_factory = _opened(bus)
    try:
        bus = bus_factory(number) if bus_factory else open_bus("smbus2", number)
    except OSError as e:
        return fail(1, open_error(number, e))
    try:
        board = Board(bus, address, pec=bool(args.bus_pec))
        for line in action(board):
            print(line)
    except (codec.FrameError, TypeError) as e:  # an argument outside its range: nothing sent
        return fail(2, str(e))
    except AsservError as e:  # a usage the board revealed (asserv.update.WrongSlotError): 2
        return fail(2 if getattr(e, "usage", False) else 1, str(e))
    except KeyboardInterrupt:
        return fail(130, "interrupted (an order already sent goes on; `stop` stops the robot)")
    finally:
        bus.close()
    return 0
