"""The strategy of docs/strategy.md runs unchanged against `asserv sim serve` (by its --sim
argument) and on an in-process simulated bus (the same play(), another bus)."""

from __future__ import annotations

import os
import re
import subprocess
import sys
from pathlib import Path

from asserv import Board
from asserv.sim import Simulator

DOC = Path(__file__).resolve().parents[2] / "docs" / "strategy.md"


def strategy_source() -> str:
    return re.findall(r"```python\n(.*?)```", DOC.read_text(), re.S)[0]


def test_the_strategy_is_about_60_lines_and_uses_no_wall_clock() -> None:
    code = strategy_source()
    assert len(code.splitlines()) <= 75
    assert "time.sleep" not in code and "time.monotonic" not in code


def test_the_strategy_against_the_server(tmp_path: Path) -> None:
    script = tmp_path / "strategy.py"
    script.write_text(strategy_source())
    env = {**os.environ, "PYTHONUNBUFFERED": "1"}
    server = subprocess.Popen(
        [sys.executable, "-m", "asserv", "sim", "serve", "--port", "0", "--speed", "0"],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        env=env,
    )
    try:
        assert server.stdout is not None
        line = server.stdout.readline()
        where = line.split("listening on ")[1].split()[0]
        run = subprocess.run(
            [sys.executable, str(script), "--sim", where],
            capture_output=True,
            text=True,
            timeout=120,
            env=env,
        )
    finally:
        server.terminate()
        server.wait(10)
    assert run.returncode == 0, run.stdout + run.stderr
    assert "recalibration: border recalibrated" in run.stdout
    assert "basket: basket reached" in run.stdout
    assert "end of the match" in run.stdout


def test_the_strategy_on_an_in_process_bus() -> None:
    env: dict[str, object] = {"__name__": "strategy"}
    exec(compile(strategy_source(), str(DOC), "exec"), env)
    lines: list[str] = []
    sim = Simulator(record=False)
    score = env["play"](Board(sim.bus, pec=True), log=lines.append)  # type: ignore[operator]
    assert score == {"points": 10, "shocks": 0}
    assert sim.time_s < 100
