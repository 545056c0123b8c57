"""Every code example of README.md and docs/*.md runs, and prints what the page says it prints.

What counts as an example and the markers a page can use are in docs_examples.py (and in
docs/driver.md, "Examples in the docs"). A board is replaced by the simulated one.
"""

from __future__ import annotations

import contextlib
import io
import os
import runpy
import shlex
import subprocess
import sys
import time
from pathlib import Path
from typing import Any

import pytest
import smbus2
from docs_examples import ROOT, Example, collect, output_matches

from asserv import VirtualBus, cli
from asserv.sim import Simulator

EXAMPLES = collect()


def _simulated_board(ex: Example) -> Simulator:
    """The simulated board a ``board`` example talks to, and whose clock it runs on:
    ``start=X,Y,DEG`` places the robot (and the board's belief) there, ``calibration`` rear
    against the west border, randomized."""
    from asserv.sim import accuracy

    opts = dict(w.partition("=")[::2] for w in ex.marker_arg.split())
    if "calibration" in opts:
        return Simulator(
            {"start": accuracy.CALIBRATION_START}, seed=0, randomize=True, record=False
        )
    config: dict[str, Any] = {}
    if opts.get("start"):
        x, y, a = (float(v) for v in opts["start"].split(","))
        config["start"] = (x, y, a)
    return Simulator(config, record=False)


@pytest.fixture
def workdir(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Path:
    """A directory outside the checkout, with the paths the pages name (scenarios/)."""
    (tmp_path / "scenarios").symlink_to(ROOT / "scenarios")
    monkeypatch.chdir(tmp_path)
    return tmp_path


def _board(ex: Example, monkeypatch: pytest.MonkeyPatch) -> Simulator | None:
    if ex.marker != "board":
        return None
    sim = _simulated_board(ex)

    def open_bus(number: int) -> VirtualBus:
        return VirtualBus({2: sim}, clock=sim)

    monkeypatch.setattr(smbus2, "SMBus", open_bus)
    # The example's own clock is the simulation's: its time.sleep() lets simulated time run.
    monkeypatch.setattr(time, "sleep", sim.sleep)
    monkeypatch.setattr(time, "monotonic", sim.monotonic)
    return sim


def test_every_page_has_its_examples_collected() -> None:
    pages = {e.path.name for e in EXAMPLES}
    assert {"README.md", "driver.md", "protocol.md", "simulator.md"} <= pages
    assert sum(e.kind == "python" for e in EXAMPLES) >= 6
    known = ("", "board", "skip", "output")
    assert all(e.marker in known for e in EXAMPLES), [
        (e.id, e.marker) for e in EXAMPLES if e.marker not in known
    ]
    assert all(
        e.marker_arg.startswith(("asserv ", "python bench/", "./build/"))
        for e in EXAMPLES
        if e.kind == "output"
    )


#: The output of each command an ``output`` block quotes, run once for all its blocks.
_PRINTED: dict[str, list[str]] = {}


def _printed(command: str) -> list[str]:
    if command not in _PRINTED and command.startswith("python bench/"):
        argv = shlex.split(command)
        p = subprocess.run(
            [sys.executable, str(ROOT / argv[1]), *argv[2:]],
            capture_output=True,
            text=True,
            timeout=1800,
            check=False,
            env={**os.environ, "MPLBACKEND": "Agg"},
        )
        assert p.returncode == 0, (command, p.stderr[-2000:])
        _PRINTED[command] = p.stdout.splitlines()
    if command not in _PRINTED and command.startswith("./build/"):
        # A C program of the build scripts/test.sh makes before pytest (its tests print figures).
        argv = shlex.split(command)
        exe = ROOT / argv[0]
        if not exe.is_file():
            pytest.skip(f"{argv[0]} is not built (scripts/test.sh builds build/ before pytest)")
        p = subprocess.run(
            [str(exe), *argv[1:]], capture_output=True, text=True, timeout=600, check=False
        )
        assert p.returncode == 0, (command, p.stdout[-2000:], p.stderr[-2000:])
        _PRINTED[command] = p.stdout.splitlines()
    if command not in _PRINTED:
        out = io.StringIO()
        with contextlib.redirect_stdout(out), contextlib.redirect_stderr(io.StringIO()):
            code = cli.main(shlex.split(command)[1:])
        assert code == 0, (command, out.getvalue()[-2000:])
        _PRINTED[command] = out.getvalue().splitlines()
    return _PRINTED[command]


def test_output_matching() -> None:
    printed = ["a", "b 1", "c", "d", "e"]
    assert output_matches("b 1\nc", printed)
    assert output_matches("a\n...\nd\ne", printed)
    assert not output_matches("b 2\nc", printed)  # a figure that changed
    assert not output_matches("a\nc", printed)  # not next to each other
    assert not output_matches("d\n...\nb 1", printed)  # not in order


@pytest.mark.parametrize("ex", EXAMPLES, ids=[e.id for e in EXAMPLES])
def test_example_runs(ex: Example, workdir: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    if ex.marker == "skip":
        pytest.skip(ex.marker_arg or "marked skip")
    _board(ex, monkeypatch)
    if ex.kind == "output":
        printed = _printed(ex.marker_arg)
        assert output_matches(ex.code, printed), (ex.id, ex.marker_arg, printed)
        return
    if ex.kind == "python":
        script = workdir / "example.py"
        script.write_text(ex.code, encoding="utf-8")
        out = io.StringIO()
        with contextlib.redirect_stdout(out):
            runpy.run_path(str(script), run_name="__main__")
        return
    for cmd in ex.commands:
        out, err = io.StringIO(), io.StringIO()
        with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
            code = cli.main(shlex.split(cmd.argv))
        printed = (out.getvalue() + err.getvalue()).rstrip("\n").splitlines()
        where = f"{ex.path.name}:{cmd.line}: asserv {cmd.argv}"
        if cmd.expected:
            assert [p.rstrip() for p in printed] == [e.rstrip() for e in cmd.expected], where
        elif cmd.contains:
            assert cmd.contains in "\n".join(printed), (where, printed)
            assert code == 0, (where, printed)
        else:
            assert code == 0, (where, printed)


def test_the_match_loop_shows_its_first_error(
    workdir: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """driver.md's match loop on a robot whose left motor is stuck: PB_MOTEUR, then PB_GRAVE;
    the error that comes out is the loop's own, not STOP's refusal from its ``finally``."""
    (ex,) = [e for e in EXAMPLES if e.path.name == "driver.md" and "MATCH_S" in e.code]
    sim = _board(ex, monkeypatch)
    assert sim is not None
    sim.set_motor_stuck(0, True)
    script = workdir / "example.py"
    script.write_text(ex.code, encoding="utf-8")
    out = io.StringIO()
    with contextlib.redirect_stdout(out), pytest.raises(RuntimeError, match="has a fault"):
        runpy.run_path(str(script), run_name="__main__")
    assert "stop: STOP rejected by the board: REFUSED_PB_GRAVE" in out.getvalue()
