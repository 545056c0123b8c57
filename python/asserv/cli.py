"""The ``asserv`` command line: the annex demonstration, simulated scenarios, protocol tools.

The conventions (exit codes, checks before anything runs, names and units) and how to add a
subcommand are in ``cli_args``; the commands that drive a board over I2C are in ``cli_bus``.
"""

from __future__ import annotations

import argparse
import contextlib
import importlib
import importlib.util
import os
import re
import signal
import sys
import time
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any, NoReturn

from . import __version__, cli_args, cli_bus, codec
from .cli_args import Subparsers, UsageError, at_least, finite_float, natural, positive_float
from .driver import GotoOption
from .goals import add_strict_flag

#: The extra that installs each optional module (numpy is in both: see ``_extra_of``).
EXTRA_OF = {
    "asserv_sim": "sim",
    "cffi": "sim",
    "matplotlib": "sim",
    "numpy": "sim",
    "websockets": "view",
    "mcap": "view",
}


class _Parser(argparse.ArgumentParser):
    """argparse, with a usage error on one line: ``asserv demo: argument --png: ...``."""

    def error(self, message: str) -> NoReturn:
        self.exit(2, cli_args.one_line(f"{self.prog}: {message} (see {self.prog} --help)") + "\n")


# encode / decode -----------------------------------------------------------------------------


def _parse_bytes(words: list[str]) -> bytes:
    out = bytearray()
    for i, w in enumerate(words, 1):
        try:
            value = int(w, 16)
        except ValueError:
            raise UsageError(f"byte {i} ({w!r}) is not hexadecimal") from None
        if not 0 <= value <= 255:
            raise UsageError(f"byte {i} ({w!r}) is not a byte (00..ff)")
        out.append(value)
    return bytes(out)


def _encode(args: argparse.Namespace) -> int:
    msg = cli_args.message_name(args.message)
    values: list[float] = []
    for i, w in enumerate(args.params, 1):
        f = msg.params[i - 1] if i <= len(msg.params) else None
        if f is not None and codec.is_2deg(f) and not args.raw:
            try:
                values.append(finite_float(w))
            except argparse.ArgumentTypeError:
                raise UsageError(f"param {i} ({w!r}) is not a number of degrees") from None
            continue
        if f is not None and msg.name == "GOTO" and f.name == "options":
            try:  # ligne, bord, ligne+bord, as in scenario files and --options
                values.append(GotoOption.parse(w))
            except ValueError as e:
                raise UsageError(f"param {i}: {e}") from None
            continue
        try:
            values.append(int(w, 0))
        except ValueError:
            raise UsageError(f"param {i} ({w!r}) is not an integer") from None
    if args.raw:
        frame = codec.encode(msg.name, *(int(v) for v in values), pec=args.pec)
    else:
        frame = codec.encode_deg(msg.name, *values, pec=args.pec)
    print(" ".join(f"{b:02x}" for b in frame))
    return 0


def _decode(args: argparse.Namespace) -> int:
    print(codec.decode_write(_parse_bytes(args.bytes)).describe(raw=args.raw))
    return 0


def _add_codec(sub: Subparsers) -> None:
    enc = sub.add_parser(
        "encode",
        help="print the bytes of a write, e.g. encode GOTO 200 100 0",
        description="The bytes of a write: the message name in any case (goto-panier,"
        " GOTO_PANIER), its params in the table's order; angles in degrees.",
    )
    enc.add_argument("message", help="message name, in any case: GOTO, goto-panier, stop...")
    enc.add_argument("params", nargs="*", help="params; an angle in degrees (-180..180)")
    enc.add_argument("--pec", action="store_true", help="append the SMBus PEC")
    enc.add_argument("--raw", action="store_true", help="an angle in raw 2-degree steps")
    enc.set_defaults(func=_encode)
    dec = sub.add_parser(
        "decode", help="explain the bytes of a write, e.g. decode 00 00 c8 00 64 00"
    )
    dec.add_argument("bytes", nargs="+", help="the bytes, in hexadecimal")
    dec.add_argument("--raw", action="store_true", help="show an angle in raw 2-degree steps")
    dec.set_defaults(func=_decode)


# demo / sim run ------------------------------------------------------------------------------


DEMO_PNG = "asserv-demo.png"


def _demo(args: argparse.Namespace) -> int:
    png = None if args.no_png else args.png or cli_args.check_output_file(DEMO_PNG, (".png",))
    from .sim import demo

    return demo.run(png=png)


def _add_demo(sub: Subparsers) -> None:
    p = sub.add_parser(
        "demo", help="the specification's annex session on the simulated board (frames, poses, PNG)"
    )
    p.add_argument(
        "--png",
        type=cli_args.output_file(".png"),
        help=f"plot file (default {DEMO_PNG})",
    )
    p.add_argument("--no-png", action="store_true", help="do not write the plot")
    p.set_defaults(func=_demo)


def scenario_path(text: str) -> Path:
    """A scenario file: a path, or else the name of one installed with the simulator (``annex``,
    ``recal_border``)."""
    path = Path(text)
    if path.exists():
        return path
    if text and "/" not in text:
        from .field import data_dir

        for cand in (data_dir("scenarios") / text, data_dir("scenarios") / f"{text}.txt"):
            if cand.is_file():
                return cand
    return path  # scenario.load says what is wrong with it


def _sim_run(args: argparse.Namespace) -> int:
    zoom = args.zoom
    if zoom is not None and not (zoom[0] < zoom[1] and zoom[2] < zoom[3]):
        raise UsageError(
            "--zoom XMIN XMAX YMIN YMAX needs XMIN < XMAX and YMIN < YMAX, "
            f"not {' '.join(f'{v:g}' for v in zoom)}"
        )
    if zoom is not None and not args.png:
        raise UsageError("--zoom applies to the plot: give --png too")
    path = scenario_path(args.scenario)
    from . import log, scenario
    from .sim import plots

    for kind, out_path in (("MCAP", args.mcap), ("CSV", args.csv)):
        if out_path is not None and (why := log.check_output(out_path, kind)):
            raise UsageError(why)

    try:
        scn = scenario.load(path)
    except scenario.ScenarioError as e:
        raise UsageError(str(e)) from None
    start_ns = time.time_ns()  # the logs' times: the wall clock at the start, plus the run's
    res = scenario.play(scn)
    scenario.summary(res)
    if args.png:
        box = None if zoom is None else (zoom[0], zoom[1], zoom[2], zoom[3])
        out = plots.plot_run(
            res.sim.trace,
            scn.field,
            args.png,
            title=args.scenario,
            targets=res.targets,
            zoom=box,
            outline=log.Outline.of(res.sim),
        )
        print(f"plot: {Path(out).resolve()}")
    if args.mcap or args.csv:
        rows, outline = log.from_sim(res.sim), log.Outline.of(res.sim)
        wrote = log.write_outputs(
            "asserv sim run", rows, args.mcap, args.csv, scn.field, outline, start_ns
        )
        if wrote:
            return 2
    return 0 if res.ok else 1


def _add_sim(sub: Subparsers) -> None:
    sim = sub.add_parser("sim", help="the simulated board")
    simsub = sim.add_subparsers(dest="sim_command", required=True, metavar="SUBCOMMAND")
    p = simsub.add_parser("run", help="play a scenario file (orders, waits) on the simulator")
    p.add_argument(
        "scenario",
        help="scenario file, e.g. scenarios/annex.txt, or the name of an installed one: annex",
    )
    p.add_argument(
        "--png", type=cli_args.output_file(".png"), help="also write a plot of the run to this file"
    )
    p.add_argument(
        "--zoom",
        nargs=4,
        type=finite_float,
        metavar=("XMIN", "XMAX", "YMIN", "YMAX"),
        help="field view of the plot [mm]",
    )
    p.add_argument("--mcap", metavar="FILE", help="also record the run as MCAP (docs/view.md)")
    p.add_argument("--csv", metavar="FILE", help="also record the run as CSV")
    p.set_defaults(func=_sim_run)
    from . import server

    server.register(simsub)  # asserv sim serve (python/asserv/server.py)


# calibrate -----------------------------------------------------------------------------------


def _calibrate(args: argparse.Namespace) -> int:
    from . import calibration
    from .driver import AsservError, Board

    prog = "asserv calibrate"
    real = getattr(args, "bus", None) is not None
    address = cli_bus.parse_address(args.address)
    number = cli_bus.parse_bus(args.bus) if real else 0
    current = calibration.OdometrySetting(
        args.ratio_ppm, round(args.track_mm * 100), args.scale_ppm
    )
    codec.encode("SET_ODOMETRIE", current.ratio_ppm, current.track_10um, current.scale_ppm)
    plan = calibration.Plan(turns=args.turns, round_trips=args.round_trips)
    geometry = calibration.Geometry(
        table_length_mm=args.table_length,
        robot_length_mm=args.robot_length,
        turn_radius_mm=args.turn_radius,
    )
    if not real:
        from .sim import Simulator, accuracy

        sim = Simulator(
            {"start": accuracy.CALIBRATION_START}, seed=args.seed, randomize=True, record=False
        )
        print(f"{prog}: simulated robot {args.seed}: {sim.describe_robot()}")
        geometry = calibration.Geometry(
            table_length_mm=sim.field.length_mm,
            robot_length_mm=float(sim.config.outline_length_mm),
            turn_radius_mm=args.turn_radius,
        )
        before = sim.odometry_errors()
        bus: Any = sim.bus
    else:
        from .backends import open_bus

        try:
            bus = open_bus("smbus2", number)
        except OSError as e:
            print(f"{prog}: {cli_bus.open_error(number, e)}", file=sys.stderr)
            return 1
    try:
        board = Board(bus, address, pec=args.pec)
        res = calibration.calibrate(board, geometry, plan, current, write=not args.dry_run)
    except (calibration.CalibrationError, AsservError) as e:
        print(f"{prog}: {e}", file=sys.stderr)
        return 1
    finally:
        if real:
            bus.close()
    print("measured:")
    for line in res.lines():
        print(line)
    if not real:
        sim.advance(0.002)
        after = sim.odometry_errors()
        print("the simulated robot's true errors (configured odometry vs true wheels):")
        for name, errs in (("before", before), ("after", after)):
            print(
                f"  {name}: wheel ratio {errs.ratio * 100:+.4f} %, track {errs.track_mm:+.3f} mm,"
                f" scale {errs.scale * 100:+.4f} %"
            )
        print(f"simulated time {sim.time_s:.1f} s")
    return 0


def _add_calibrate(sub: Subparsers) -> None:
    cal = sub.add_parser(
        "calibrate",
        help="odometry calibration against the borders (simulated robot, or --bus N)",
        description="Measure the wheel ratio, the encoder track and the wheel scale by N turns"
        " and wall-to-wall round trips, and write them with SET_ODOMETRIE (docs/calibration.md)."
        " The robot starts with its rear flat against a border, facing the opposite one.",
    )
    cal.add_argument(
        "--bus",
        metavar="N",
        default=argparse.SUPPRESS,
        help="a real board on /dev/i2c-N (default: a simulated robot)",
    )
    cal.add_argument("--address", default="2", help="7-bit address of the board (default 2)")
    cal.add_argument("--pec", action="store_true", help="PEC on every write and reply")
    cal.add_argument("--seed", type=natural, default=0, help="the simulated robot (default 0)")
    cal.add_argument("--turns", type=at_least(1), default=10, help="full turns in place (10)")
    cal.add_argument(
        "--round-trips", type=at_least(2), default=3, help="wall-to-wall round trips (default 3)"
    )
    cal.add_argument(
        "--table-length",
        type=positive_float,
        default=3000.0,
        help="between the two borders driven between, mm (default 3000)",
    )
    cal.add_argument(
        "--robot-length",
        type=positive_float,
        default=250.0,
        help="rear bumper to front bumper, mm (default 250)",
    )
    cal.add_argument(
        "--turn-radius",
        type=positive_float,
        default=200.0,
        help="encoder midpoint to the outline's farthest point, mm (default 200)",
    )
    cal.add_argument(
        "--ratio-ppm",
        type=at_least(-30000, 30000),
        default=0,
        help="the board's current SET_ODOMETRIE ratio (default 0, as after reset)",
    )
    cal.add_argument(
        "--track-mm",
        type=positive_float,
        default=280.0,
        help="the board's current encoder track, mm (default 280: the build's)",
    )
    cal.add_argument(
        "--scale-ppm",
        type=at_least(-30000, 30000),
        default=0,
        help="the board's current SET_ODOMETRIE scale (default 0)",
    )
    cal.add_argument(
        "--dry-run", action="store_true", help="measure, but leave the board's setting as it was"
    )
    cal.set_defaults(func=_calibrate)


# bench ---------------------------------------------------------------------------------------


def _bench_accuracy(args: argparse.Namespace) -> int:
    if args.first_seed + args.robots - 1 > cli_args.SEED_MAX:
        raise UsageError("--first-seed + --robots goes past the last seed (2^64-1)")
    if not args.no_png:
        cli_args.check_output_dir(args.out)
    from .calibration import Plan
    from .goals import Goals
    from .sim import accuracy

    plan = Plan(turns=args.turns, round_trips=args.round_trips)
    with cli_args.progress_bar(args.robots, "robots") as bar:
        res = accuracy.bench(
            args.robots,
            args.first_seed,
            plan=plan,
            jobs=args.jobs,
            examples=not args.no_png,
            progress=lambda done, total: bar.update(done - bar.n),
        )
    goals = Goals("asserv bench accuracy")
    lines = accuracy.report(res, goals)
    for line in lines[:-1]:
        print(line)
    if not args.no_png:
        from .sim import plots

        for path in plots.plot_accuracy(res, Path(args.out)):
            print(f"plot: {Path(path).resolve()}")
    print(lines[-1])  # the summary line, last
    return goals.exit_code(args.strict)


def _add_bench(sub: Subparsers) -> None:
    bench = sub.add_parser("bench", help="benchmarks that print figures")
    bsub = bench.add_subparsers(dest="bench_command", required=True, metavar="SUBCOMMAND")
    acc = bsub.add_parser(
        "accuracy",
        help="the specification's Performances experiment on randomized robots",
        description="A 1.8 m straight at 0.2, 0.5 and 1 m/s on randomized simulated robots:"
        " legacy P-only baseline, this board, this board calibrated (bench/README.md).",
    )
    acc.add_argument("--robots", type=at_least(1), default=200, help="how many (default 200)")
    acc.add_argument("--first-seed", type=natural, default=0, help="seed of the first robot")
    acc.add_argument(
        "--jobs",
        type=at_least(1, 256),
        default=min(os.cpu_count() or 1, 256),
        help="processes (default: all cores)",
    )
    acc.add_argument("--turns", type=at_least(1), default=10, help="calibration: full turns")
    acc.add_argument("--round-trips", type=at_least(2), default=3, help="calibration: round trips")
    acc.add_argument(
        "--out", default="bench-out", help="directory of the PNGs (default %(default)s)"
    )
    acc.add_argument("--no-png", action="store_true", help="do not write the plots")
    add_strict_flag(acc)
    acc.set_defaults(func=_bench_accuracy)


# main ----------------------------------------------------------------------------------------


def _completion_command(args: argparse.Namespace) -> int:
    import shtab

    print(shtab.complete(parser(), args.shell), end="")
    return 0


def _add_completion(sub: Subparsers) -> None:
    """``asserv completion bash|zsh``: the shell's completion script (shtab), installed as
    docs/driver.md says."""
    p = sub.add_parser(
        "completion",
        help="print the bash or zsh completion script (docs/driver.md)",
        description="Print the completion script of the shell: asserv completion bash >"
        " ~/.local/share/bash-completion/completions/asserv (docs/driver.md).",
    )
    p.add_argument("shell", choices=("bash", "zsh"), help="the shell")
    p.set_defaults(func=_completion_command)


def _add_optional(
    module: str, command: str, what: str, options: tuple[str, ...] = ()
) -> Callable[[Subparsers], None]:
    """A subcommand whose module needs an extra (numpy, mcap, websockets): its own register()
    when the module imports, otherwise a stand-in that takes any words (``--help`` too) and
    names the module that is missing; ``main`` then prints the extra to install (exit 1)."""

    def add(sub: Subparsers) -> None:
        try:
            mod = importlib.import_module(f".{module}", __package__)
        except ImportError as e:
            p = sub.add_parser(
                command, help=f"{what} (needs an extra: {command} --help)", add_help=False
            )
            p.add_argument("-h", "--help", action="store_true", default=argparse.SUPPRESS)
            for option in options:  # what the hint depends on (--replay: no simulator needed)
                p.add_argument(option, default=argparse.SUPPRESS)
            cli_bus.add_bus_options(p)
            p.set_defaults(unavailable=(e.name or "numpy").split(".")[0])
            return
        mod.register(sub)

    return add


#: The subcommands: each adds its parser and sets ``func``, the one dispatch key (see cli_args
#: for the convention), those of log, tune, view and sim serve from their own module.
REGISTER: list[Callable[[Subparsers], None]] = [
    _add_demo,
    _add_sim,
    _add_codec,
    _add_calibrate,
    _add_bench,
    _add_optional("log", "log", "record a board to MCAP and/or CSV"),
    _add_optional("tune", "tune", "step responses and a P/I/D sweep"),
    _add_optional("view", "view", "the robot on its field in the browser", ("--replay",)),
    _add_completion,
]


def parser() -> argparse.ArgumentParser:
    """The whole command line's parser."""
    ap: argparse.ArgumentParser = _Parser(
        prog="asserv",
        description="The asserv command line: the annex demonstration, simulated scenarios,"
        " protocol tools, and the commands that drive a board (--bus N or --sim HOST:PORT).",
    )
    ap.add_argument("--version", action="version", version=f"asserv {__version__}")
    sub = ap.add_subparsers(dest="command", required=True, metavar="COMMAND")
    for register in REGISTER:
        register(sub)
    cli_bus.add_bus_arguments(ap, sub)
    _plain_text(ap)
    return ap


_MARKUP = re.compile(r"``?([^`]+?)``?")


def _plain_text(ap: argparse.ArgumentParser) -> None:
    """The help as plain text: ``x`` and `x` (docstring and Markdown markup) become 'x', in
    every parser's description and every argument's help, whoever registered them."""
    seen: set[int] = set()

    def walk(p: argparse.ArgumentParser) -> None:
        if id(p) in seen:
            return
        seen.add(id(p))
        if p.description:
            p.description = _MARKUP.sub(r"'\1'", p.description)
        for action in p._actions:
            if isinstance(action.help, str):
                action.help = _MARKUP.sub(r"'\1'", action.help)
            if isinstance(action, argparse._SubParsersAction):
                for choice in action._choices_actions:
                    if isinstance(choice.help, str):
                        choice.help = _MARKUP.sub(r"'\1'", choice.help)
                for child in action.choices.values():
                    walk(child)

    walk(ap)


def _prog(args: argparse.Namespace) -> str:
    words = [getattr(args, k, None) for k in ("command", "sim_command", "bench_command")]
    return " ".join(["asserv", *(w for w in words if w)])


def _names_board(args: argparse.Namespace) -> bool:
    return getattr(args, "bus", None) is not None or getattr(args, "bus_sim", None) is not None


def _extra_of(module: str, args: argparse.Namespace) -> str:
    """The extra that brings ``module`` for this command: numpy comes with asserv[view] (a
    board: log, view, tune --bus; the lighter one for --help) and with asserv[sim]."""
    light = args.command in ("log", "view") or _names_board(args) or getattr(args, "help", False)
    if module == "numpy" and light:
        return "view"
    return EXTRA_OF.get(module, "sim")


def _installed(module: str) -> bool:
    try:
        return importlib.util.find_spec(module) is not None
    except (ImportError, ValueError):
        return False


def needs(args: argparse.Namespace) -> dict[str, str]:
    """The optional modules this command line needs (module: the extra that brings it)."""
    cmd, board = args.command, _names_board(args)
    want: list[str] = []
    if getattr(args, "unavailable", None):
        want.append(args.unavailable)
        if getattr(args, "help", False):  # the help of a command this install lacks
            return {m: _extra_of(m, args) for m in want}
    replay = getattr(args, "replay", None) is not None
    if cmd == "view":
        want += ["numpy", "websockets"] + (["mcap"] if replay else [])
        if not (board or replay):
            want.append("asserv_sim")
    elif cmd == "log":
        want += ["numpy"] + (["mcap"] if getattr(args, "mcap", None) else [])
    elif cmd == "tune":
        want += ["numpy"] + ([] if board else ["asserv_sim"])
        want += ["matplotlib"] if getattr(args, "png", None) else []
    elif cmd in ("demo", "sim", "bench") or (cmd == "calibrate" and not board):
        want += ["asserv_sim", "numpy"]
        if getattr(args, "mcap", None):
            want.append("mcap")
    return {m: _extra_of(m, args) for m in want if not _installed(m)}


def missing_hint(prog: str, missing: dict[str, str]) -> str:
    """One line: what is missing and the extra that installs it."""
    extras = ",".join(sorted(set(missing.values())))
    install = f'pip install "asserv[{extras}]"'
    if set(missing.values()) == {"sim"}:
        return f"{prog}: the simulator is not installed: {install} {SIM_NOTE}"
    names = ", ".join(sorted(missing))
    note = f" {SIM_NOTE}" if "sim" in missing.values() else ""
    verb = "is" if len(missing) == 1 else "are"
    return f"{prog}: needs asserv[{extras}] ({names} {verb} not installed): {install}{note}"


SIM_NOTE = "(it needs a C compiler and the Python headers)"


#: What Ctrl-C leaves, by command (``interrupted`` for the others); printed on stderr.
INTERRUPTED = {
    "asserv view": "stopped serving the page (Ctrl-C)",
    "asserv sim serve": "stopped serving (Ctrl-C)",
    "asserv log": "interrupted: the log is closed with the rows so far",
    "asserv calibrate": "interrupted (the robot may still be moving: `asserv --bus N stop`)",
    "asserv tune": "interrupted (the robot may still be moving: `asserv --bus N stop`)",
}


@contextlib.contextmanager
def _sigint(seen: list[bool]) -> Iterator[None]:
    """Ctrl-C raises KeyboardInterrupt as usual, and is noted in ``seen``: a command that
    catches it to close its files or its server still ends with 130."""

    def on_sigint(signum: int, frame: object) -> None:
        seen.append(True)
        raise KeyboardInterrupt

    try:
        before = signal.signal(signal.SIGINT, on_sigint)
    except ValueError:  # not the main thread: left as it is
        yield
        return
    try:
        yield
    finally:
        signal.signal(signal.SIGINT, before)


def main(argv: list[str] | None = None) -> int:
    """Run the command line; returns the exit code: 0 done, 1 the bus, the board or the run
    failed, or an extra is not installed, 2 bad usage or input (one line on stderr), 130
    interrupted by Ctrl-C (one line on stderr that says what it left: INTERRUPTED)."""
    try:
        code = _main(argv)
        sys.stdout.flush()  # here, so that a closed pipe is met while it can be handled
        return code
    except BrokenPipeError:  # asserv demo | head: the reader has gone, so has the output
        with contextlib.suppress(OSError):
            os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        return 141


def _main(argv: list[str] | None) -> int:
    ap = parser()
    try:
        args, rest = ap.parse_known_args(argv)
        if rest and not getattr(args, "unavailable", None):
            ap.error(f"unrecognized arguments: {' '.join(rest)}")
    except SystemExit as e:  # --help, --version (0) or a usage error (2), already printed
        return e.code if isinstance(e.code, int) else 2
    prog = "asserv " + args.bus_command if cli_bus.is_bus_command(args) else _prog(args)
    missing = {} if cli_bus.is_bus_command(args) else needs(args)
    if missing:
        print(cli_args.one_line(missing_hint(prog, missing)), file=sys.stderr)
        return 1
    seen: list[bool] = []
    try:
        with _sigint(seen):
            code = _run(args, prog)
    except KeyboardInterrupt:
        seen.append(True)
        code = -1
    if seen and code != 130:  # a command that says 130 has said what it left
        sys.stdout.flush()
        print(f"{prog}: {INTERRUPTED.get(prog, 'interrupted')}", file=sys.stderr)
        return 130
    return code


def _run(args: argparse.Namespace, prog: str) -> int:
    try:
        # Every subcommand sets one key, func: its handler (cli_args.py, "adding a subcommand").
        code: int = args.func(args)
    except UsageError as e:
        print(cli_args.one_line(f"{prog}: {e}"), file=sys.stderr)
        return 2
    except codec.FrameError as e:  # a value the board would refuse: nothing was sent
        print(cli_args.one_line(f"{prog}: the board would reject this: {e}"), file=sys.stderr)
        return 2
    except ImportError as e:
        module = (getattr(e, "name", None) or "").split(".")[0]
        if "asserv[sim]" in str(e):
            module = "asserv_sim"
        if module not in EXTRA_OF:
            raise
        print(missing_hint(prog, {module: _extra_of(module, args)}), file=sys.stderr)
        return 1
    return code
