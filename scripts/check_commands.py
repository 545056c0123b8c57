"""Every command of an installed `asserv`, as one install profile should answer it.

Run by scripts/check_install.sh with the Python of each virtual environment it makes:

    python scripts/check_commands.py PROFILE SCENARIO

PROFILE is what the environment holds: ``driver`` (asserv alone), ``view`` (asserv[view]),
``sim`` (asserv[sim]) or ``both``. SCENARIO is a scenario file (scenarios/annex.txt).

1. ``--help`` of every subcommand (the parser's own list, so a new one is checked too) gives
   help (exit 0, ``usage:``), or, for a command this install cannot run, one line naming the
   extra to install (exit 1, ``pip install "asserv[...]"``).
2. The commands of the table below give the answer this profile should give: a run, a
   failure that is not about the install (no I2C bus here: exit 1, "cannot open"), a bad input
   (exit 2) or the hint naming the extra.

Never a traceback, never "unrecognized arguments". Exit 1 with the failures listed, else 0.
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import tempfile
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

PROFILES = ("driver", "view", "sim", "both")


def hint(*extras: str) -> tuple[int, str]:
    """Exit 1 and the line naming the extras to install."""
    return 1, f'pip install "asserv[{",".join(sorted(extras))}]"'


NO_BUS = (1, "cannot open /dev/i2c-1")  # this machine has no I2C bus: past the install's checks
REFUSED = (1, "refused")  # nothing listens there: past the install's checks


def expectations(profile: str, scenario: str) -> list[tuple[list[str], tuple[int, str]]]:
    """(argv, (exit code, a text of stderr or stdout)) for this profile."""
    view = profile in ("view", "both")
    sim = profile in ("sim", "both")
    nobody = "127.0.0.1:1"
    lacks = [e for e, has in (("sim", sim), ("view", view)) if not has]
    out: list[tuple[list[str], tuple[int, str]]] = [
        (["encode", "goto", "200", "100", "0"], (0, "00 00 c8 00 64 00")),
        (["--bus", "1", "status"], NO_BUS),
        (["goto", "200", "100"], (2, "--sim HOST:PORT")),
        (["--sim", nobody, "position"], REFUSED),
        # the view on a board: numpy and websockets (asserv[view]), no simulator
        (["--bus", "1", "view"], NO_BUS if view else hint("view")),
        (["--sim", nobody, "view", "--port", "0"], REFUSED if view else hint("view")),
        (["view", "--replay", "missing.mcap"], (2, "missing.mcap") if view else hint("view")),
        # the view of a simulated run needs both extras, said before the file is read
        (["view", "missing.txt"], (2, "missing.txt") if view and sim else hint(*lacks)),
        (["log", "--mcap", "x.mcap", "--bus", "1"], NO_BUS if view else hint("view")),
        (["--bus", "1", "log", "--csv", "x.csv"], NO_BUS if view or sim else hint("view")),
        (["log", "--help"], (0, "usage: asserv log") if view or sim else hint("view")),
        (["tune", "--bus", "1"], NO_BUS if view or sim else hint("view")),
        (["tune", "--axis", "distance", "--window", "0.5"], (0, "best:") if sim else hint("sim")),
        (["demo", "--no-png"], (0, "CHOC_PANIER") if sim else hint("sim")),
        (["sim", "run", scenario], (0, "estimate - truth") if sim else hint("sim")),
        (
            ["sim", "run", scenario, "--mcap", "run.mcap"],
            (0, "mcap: run.mcap") if view and sim else hint(*lacks),
        ),
        (["calibrate", "--bus", "1", "--dry-run"], NO_BUS),
        (["completion", "bash"], (0, "_shtab_asserv")),  # shtab: a dependency of every install
        (
            ["calibrate", "--turns", "1", "--round-trips", "2"],
            (0, "measured") if sim else hint("sim"),
        ),
    ]
    return out


def subcommands() -> list[list[str]]:
    """Every subcommand's words, from the installed parser (asserv.cli.parser)."""
    from asserv import cli

    words: list[list[str]] = []

    def walk(p: argparse.ArgumentParser, prefix: list[str]) -> None:
        for action in p._actions:
            if isinstance(action, argparse._SubParsersAction):
                for name, child in action.choices.items():
                    words.append([*prefix, name])
                    walk(child, [*prefix, name])

    walk(cli.parser(), [])
    return words


def run(argv: list[str], cwd: str) -> tuple[int, str, str]:
    exe = Path(sys.executable).with_name("asserv")
    p = subprocess.run(
        [str(exe), *argv],
        capture_output=True,
        text=True,
        cwd=cwd,
        timeout=300,
        env={**os.environ, "MPLBACKEND": "Agg"},
        stdin=subprocess.DEVNULL,
    )
    return p.returncode, p.stdout, p.stderr


def problems(argv: list[str], got: tuple[int, str, str], want: tuple[int, str]) -> list[str]:
    code, out, err = got
    bad: list[str] = []
    if "Traceback" in err or "unrecognized arguments" in err:
        bad.append("a traceback or an argument refused")
    if code != want[0] or want[1] not in out + err:
        bad.append(f"wanted exit {want[0]} and {want[1]!r}")
    if code in (1, 2) and (len(err.strip().splitlines()) != 1 and "pip install" in err):
        bad.append("the hint is not one line")
    if not bad:
        return []
    shown = (err.strip() or out.strip()).splitlines()[-3:]
    return [f"asserv {' '.join(argv)}: exit {code}: {'; '.join(bad)}: {' | '.join(shown)}"]


def main() -> int:
    profile, scenario = sys.argv[1], str(Path(sys.argv[2]).resolve())
    if profile not in PROFILES:
        print(f"check_commands: profile {profile!r} is not one of {PROFILES}", file=sys.stderr)
        return 2
    cases: list[tuple[list[str], tuple[int, str]]] = []
    for words in subcommands():
        if profile == "driver" and words[0] in ("log", "tune", "view"):
            cases.append(([*words, "--help"], hint("view")))  # numpy: from asserv[view]
        else:
            cases.append(([*words, "--help"], (0, "usage: asserv")))
    cases += expectations(profile, scenario)
    with tempfile.TemporaryDirectory() as cwd, ThreadPoolExecutor(2) as pool:
        results = list(pool.map(lambda c: run(c[0], cwd), cases))
    failed = [
        line
        for (argv, want), got in zip(cases, results, strict=True)
        for line in problems(argv, got, want)
    ]
    for line in failed:
        print(f"check_commands ({profile}): {line}", file=sys.stderr)
    print(
        f"check_commands ({profile}): {len(cases) - len(failed)}/{len(cases)} commands as expected"
    )
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
