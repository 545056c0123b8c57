"""A part that is not installed: one line naming the extra that brings it, exit 1 (issue 30).

scripts/check_install.sh checks the same on real installs (scripts/check_commands.py); here any
set of optional modules is taken away, and every command must name exactly the extras that
bring what it lacks, or else get past the check (to its run, its bus or its input's check).
"""

from __future__ import annotations

import importlib
from collections.abc import Iterator
from pathlib import Path
from types import ModuleType

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from test_cli_convention import RunReachedError, no_runs, run

from asserv import cli

__all__ = ["no_runs"]  # the fixture, used here

OPTIONAL = ("asserv_sim", "numpy", "matplotlib", "websockets", "mcap")

# argv: what it needs (module: the extra to name). Written out here, not taken from cli.needs.
COMMANDS: list[tuple[list[str], dict[str, str]]] = [
    (["--bus", "1", "view"], {"numpy": "view", "websockets": "view"}),
    (["--sim", ":5021", "view"], {"numpy": "view", "websockets": "view"}),
    (["view", "--replay", "r.mcap"], {"numpy": "view", "websockets": "view", "mcap": "view"}),
    (["view", "s.txt"], {"numpy": "view", "websockets": "view", "asserv_sim": "sim"}),
    (["--bus", "1", "log", "--mcap", "x.mcap"], {"numpy": "view", "mcap": "view"}),
    (["log", "--csv", "x.csv", "--bus", "1"], {"numpy": "view"}),
    (["tune", "--bus", "1"], {"numpy": "view"}),
    (["tune"], {"numpy": "sim", "asserv_sim": "sim"}),
    (["tune", "--png", "t.png"], {"numpy": "sim", "asserv_sim": "sim", "matplotlib": "sim"}),
    (["demo", "--no-png"], {"asserv_sim": "sim", "numpy": "sim"}),
    (
        ["sim", "run", "annex", "--mcap", "x.mcap"],
        {"asserv_sim": "sim", "numpy": "sim", "mcap": "view"},
    ),
    (["calibrate", "--bus", "1"], {}),
    (["--bus", "1", "status"], {}),
]


@pytest.fixture
def absent(monkeypatch: pytest.MonkeyPatch) -> Iterator[set[str]]:
    """The modules in the set are not installed, as far as the CLI can tell."""
    gone: set[str] = set()
    monkeypatch.setattr(cli, "_installed", lambda m: m not in gone)
    yield gone


def outcome(argv: list[str]) -> tuple[int, str]:
    try:
        code, _, err = run(argv)
    except RunReachedError:
        return 0, "reached the run"
    return code, err


@settings(
    max_examples=60, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture]
)
@given(
    k=st.integers(0, len(COMMANDS) - 1),
    gone=st.sets(st.sampled_from(OPTIONAL)),
)
def test_the_hint_names_exactly_the_extras_missing(
    no_runs: list[int], absent: set[str], k: int, gone: set[str]
) -> None:
    argv, wants = COMMANDS[k]
    absent.clear()
    absent.update(gone)
    no_runs.clear()
    code, err = outcome(argv)
    lacking = {m: e for m, e in wants.items() if m in gone}
    if lacking:
        extras = ",".join(sorted(set(lacking.values())))
        assert code == 1, err
        assert f'pip install "asserv[{extras}]"' in err, (argv, gone, err)
        assert len(err.strip().splitlines()) == 1 and err.startswith("asserv ")
        assert no_runs == []  # nothing ran, no bus opened
    else:
        assert "pip install" not in err, (argv, gone, err)


@pytest.fixture
def without(monkeypatch: pytest.MonkeyPatch) -> Iterator[set[str]]:
    """cli's modules named in the set fail to import (numpy absent): the stand-in parsers."""
    names: set[str] = set()
    real = importlib.import_module

    def fake(name: str, package: str | None = None) -> ModuleType:
        if name.lstrip(".") in names:
            raise ModuleNotFoundError("No module named 'numpy'", name="numpy")
        return real(name, package)

    monkeypatch.setattr(cli.importlib, "import_module", fake)
    yield names


@pytest.mark.parametrize(
    ("argv", "extra"),
    [
        (["log", "--help"], "view"),
        (["log", "--mcap", "x.mcap", "--bus", "1"], "view"),
        (["--bus", "1", "log", "--csv", "x.csv", "--hz", "10"], "view"),
        (["view", "--replay", "missing.mcap"], "view"),
        (["view", "--help"], "view"),
        (["--bus", "1", "view"], "view"),
        (["view", "scenarios/annex.txt"], "sim,view"),
        (["tune", "--help"], "view"),
        (["tune", "--bus", "1", "--p", "100,200"], "view"),
        (["tune"], "sim"),
    ],
)
def test_a_command_whose_module_needs_numpy_says_so(
    no_runs: list[int], absent: set[str], without: set[str], argv: list[str], extra: str
) -> None:
    """The driver-only install: log, tune and view take any words, --help too, and name the
    extra (issue 30: 'unrecognized arguments: --help', and tune's hint with exit 2)."""
    without.update({"log", "tune", "view"})
    absent.update({"numpy", "asserv_sim", "matplotlib", "websockets", "mcap"})
    code, out, err = run(argv)
    assert code == 1 and out == ""
    assert f'pip install "asserv[{extra}]"' in err, err
    assert len(err.strip().splitlines()) == 1


def test_other_words_are_still_refused(no_runs: list[int]) -> None:
    code, _, err = run(["status", "--bus", "1", "--bogus"])
    assert code == 2 and "unrecognized arguments: --bogus" in err
    code, _, err = run(["demo", "extra"])
    assert code == 2 and "unrecognized arguments: extra" in err
    assert list(Path().iterdir()) == []
