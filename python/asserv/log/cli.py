"""``asserv log`` and the board options it shares with ``view`` and ``tune``."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from ..field import Field
from .format import LogError, Outline
from .poll import bus_truth, poll_board
from .write import LogWriter, save

if TYPE_CHECKING:
    from ..driver import Board

# ---- the command line -------------------------------------------------------------------------


def check_output(path: str | Path, what: str) -> str | None:
    """Why ``path`` cannot be written as the ``what`` file ("MCAP", "CSV", "PNG": its name must
    end so) (None: it can), checked before a run by creating it (and removing it again), so
    that a bad path changes nothing and a long run does not end on it."""
    from ..cli_args import UsageError, check_output_file

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
    from ..backends import open_bus
    from ..cli_args import UsageError
    from ..cli_bus import open_error, parse_address, parse_bus
    from ..driver import Board
    from ..server import parse_address as parse_sim_address

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
        bus = open_bus("sim", (host, port)) if remote is not None else open_bus("smbus2", number)
    except OSError as e:
        why = e.strerror or str(e) if remote is not None else open_error(number, e)
        print(f"{prog}: {why}", file=sys.stderr)
        return 1
    return Board(bus, address, pec=bool(getattr(args, "bus_pec", False))), bus


def _log_command(args: argparse.Namespace) -> int:
    from ..driver import AsservError

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
    from .. import field as fieldmod

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
    p.set_defaults(func=_log_command)
