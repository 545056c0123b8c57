"""The ``asserv`` command line's conventions, as helpers every subcommand uses.

- **Exit codes.** 0 done; 1 the bus or the board failed, or an extra is not installed (one
  line naming it: ``cli.needs``); 2 bad usage or input: one line on stderr, ``asserv COMMAND:
  what is wrong``, nothing done; 130 Ctrl-C, one line on stderr (``cli.INTERRUPTED``).
- **Checked first.** Every argument and output path is checked before the bus opens or a long
  run starts: raise ``UsageError`` (or use the ``type=`` checkers below with argparse).
- **Names and units.** Message names in any case (``message_name``); angles in degrees, raw
  2-degree steps only behind an explicit ``--raw``.

Adding a subcommand (``asserv view`` in ``view.py``, say) takes a few lines::

    def register(sub: cli_args.Subparsers) -> None:
        p = sub.add_parser("view", help="...")
        p.add_argument("--out", type=cli_args.output_file(".html"), help="...")
        p.add_argument("--seed", type=cli_args.natural)
        p.set_defaults(func=run)          # run(args) -> exit code; may raise UsageError

and one line in ``cli.py``'s ``REGISTER`` list. ``cli.main`` turns ``UsageError`` into exit 2
and a missing simulator (ImportError) into exit 1, each with one line on stderr.
"""

from __future__ import annotations

import argparse
import math
import os
import sys
import tempfile
from collections.abc import Callable
from pathlib import Path
from typing import Any, TypeAlias

from . import codec
from ._protocol import Message

__all__ = [
    "Subparsers",
    "UsageError",
    "at_least",
    "finite_float",
    "message_name",
    "natural",
    "one_line",
    "output_dir",
    "output_file",
    "positive_float",
]

Subparsers: TypeAlias = "argparse._SubParsersAction[argparse.ArgumentParser]"

SEED_MAX = 2**64 - 1


class UsageError(Exception):
    """Bad usage or input: ``cli.main`` prints ``asserv COMMAND: <message>`` and exits 2."""


def message_name(text: str) -> Message:
    """The message named ``text``: any case, ``-`` or ``_`` (``goto-panier``, ``GOTO_PANIER``)."""
    try:
        return codec.message(text)
    except codec.FrameError as e:
        raise UsageError(e.detail) from None


def _type(check: Callable[[str], object], name: str) -> Callable[[str], object]:
    """An argparse ``type=`` from a checker that raises ValueError with a message."""

    def convert(text: str) -> object:
        try:
            return check(text)
        except ValueError as e:
            raise argparse.ArgumentTypeError(str(e)) from None

    convert.__name__ = name  # argparse names the type in its message when the text is empty
    return convert


def _int(text: str) -> int:
    try:
        return int(text, 0)
    except ValueError:
        raise ValueError(f"{text!r} is not an integer") from None


def at_least(low: int, high: int | None = None) -> Callable[[str], object]:
    """argparse ``type=``: an integer >= ``low`` (and <= ``high``)."""

    def check(text: str) -> int:
        value = _int(text)
        if value < low or (high is not None and value > high):
            top = "2^64-1" if high == SEED_MAX else str(high)
            span = f"at least {low}" if high is None else f"within {low}..{top}"
            raise ValueError(f"{text!r} must be {span}")
        return value

    return _type(check, f"integer >= {low}")


#: argparse ``type=``: a seed, 0..2^64-1.
natural = at_least(0, SEED_MAX)


def finite_float(text: str) -> float:
    """argparse ``type=``: a finite number."""
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a number") from None
    if not math.isfinite(value):
        raise argparse.ArgumentTypeError(f"{text!r} is not a finite number")
    return value


def positive_float(text: str) -> float:
    """argparse ``type=``: a finite number > 0."""
    value = finite_float(text)
    if value <= 0:
        raise argparse.ArgumentTypeError(f"{text!r} must be > 0")
    return value


def one_line(text: str) -> str:
    """``text`` with its unprintable characters escaped, so that a message stays on one line
    whatever a path or an argument contains (``\\n``, ``\\x1d``...)."""
    return "".join(c if c.isprintable() else repr(c)[1:-1] for c in text)


def _reason(e: OSError) -> str:
    return e.strerror or str(e)


def check_output_file(text: str, suffixes: tuple[str, ...]) -> Path:
    """The path of a file to write, checked now: its suffix is one of ``suffixes``, its directory
    exists and a file can be created there. Nothing is left behind. Raises UsageError."""
    path = Path(text)
    if not text or path.suffix.lower() not in suffixes:
        raise UsageError(f"{text!r}: the file name must end in {' or '.join(suffixes)}")
    if path.is_dir():
        raise UsageError(f"{text}: is a directory")
    existed = path.exists()
    try:
        with path.open("ab"):
            pass
    except OSError as e:
        raise UsageError(f"{text}: cannot write the file: {_reason(e)}") from None
    if not existed:
        path.unlink()
    return path


def output_file(*suffixes: str) -> Callable[[str], object]:
    """argparse ``type=``: ``check_output_file`` with these suffixes (``".png"``)."""
    wanted = tuple(s.lower() for s in suffixes)

    def check(text: str) -> Path:
        try:
            return check_output_file(text, wanted)
        except UsageError as e:
            raise ValueError(str(e)) from None

    return _type(check, "output file")


def check_output_dir(text: str) -> Path:
    """A directory to write files into, checked now: created if missing, and writable."""
    path = Path(text)
    if not text:
        raise UsageError("the output directory is empty")
    try:
        path.mkdir(parents=True, exist_ok=True)
        with tempfile.TemporaryFile(dir=path):
            pass
    except OSError as e:
        raise UsageError(f"{text}: cannot write into the directory: {_reason(e)}") from None
    return path


def _output_dir(text: str) -> Path:
    try:
        return check_output_dir(text)
    except UsageError as e:
        raise ValueError(str(e)) from None


#: argparse ``type=``: ``check_output_dir``.
output_dir = _type(_output_dir, "output directory")


def progress_bar(total: int, unit: str) -> Any:
    """A progress bar on stderr (tqdm) for a long command, quiet when stderr is not a terminal
    (a log, a pipe, CI): ``with progress_bar(200, "robots") as bar: bar.update(1)``."""
    from tqdm import tqdm

    return tqdm(total=total, unit=f" {unit}", file=sys.stderr, disable=not sys.stderr.isatty())


def readable_file(text: str) -> Path:
    """An input file that exists and can be read (raises UsageError)."""
    path = Path(text)
    if not path.is_file() or not os.access(path, os.R_OK):
        why = "no such file" if not path.exists() else "not a readable file"
        raise UsageError(f"{text}: {why}")
    return path
