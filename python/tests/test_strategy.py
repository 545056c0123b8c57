"""The strategy of docs/strategy.md runs unchanged against `asserv sim serve` (by its --sim
argument) and on an in-process simulated bus (the same play(), another bus), and it avoids random
crossing opponents: it never touches one, and it scores."""

from __future__ import annotations

import math
import os
import re
import subprocess
import sys
from pathlib import Path

from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from asserv import Board
from asserv.sim import Simulator

DOC = Path(__file__).resolve().parents[2] / "docs" / "strategy.md"


def strategy_source() -> str:
    return re.findall(r"```python\n(.*?)```", DOC.read_text(), re.S)[0]


def test_the_strategy_is_about_150_lines_and_uses_no_wall_clock() -> None:
    code = strategy_source()
    assert len(code.splitlines()) <= 160
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
    assert "basket: reached" in run.stdout
    assert "end of the match" in run.stdout


def test_the_strategy_on_an_in_process_bus() -> None:
    env: dict[str, object] = {"__name__": "strategy"}
    exec(compile(strategy_source(), str(DOC), "exec"), env)
    lines: list[str] = []
    sim = Simulator(record=False)
    score = env["play"](Board(sim.bus, pec=True), sim.lidar, log=lines.append)  # type: ignore[operator]
    assert score == {"points": 10, "given_up": 0}
    assert sim.time_s < 100
    assert not any("pause" in line for line in lines)  # no opponent: nothing to avoid


def _gap(sim: Simulator, i: int) -> float:
    """The gap between opponent i's disc and the robot's outline, from the truth."""
    ox, oy = sim.obstacles()[i]
    x, y, h = sim.drive_pose()
    c, s = math.cos(math.radians(h)), math.sin(math.radians(h))
    lx, ly = (ox - x) * c + (oy - y) * s, -(ox - x) * s + (oy - y) * c
    cfg = sim.config
    dx = max(abs(lx - cfg.outline_offset_x_mm) - cfg.outline_length_mm / 2, 0.0)
    dy = max(abs(ly - cfg.outline_offset_y_mm) - cfg.outline_width_mm / 2, 0.0)
    return math.hypot(dx, dy) - sim.opponent_radius(i)


@settings(max_examples=20, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(seed=st.integers(0, 2**32), randomize=st.booleans())
def test_the_avoiding_strategy_property(seed: int, randomize: bool) -> None:
    """Against 20 random opponents whose paths cross the tour (add_crossing_opponent), on
    randomized robots or not: the robot's outline never comes within 10 mm of the opponent
    (checked every 10 ms, when neither moves 10 mm), and it scores."""
    env: dict[str, object] = {"__name__": "strategy"}
    exec(compile(strategy_source(), str(DOC), "exec"), env)
    tour, (basket, _) = env["TOUR"], env["BASKET"]  # type: ignore[misc]
    sim = Simulator(seed=seed, randomize=randomize, record=False)
    start = sim.true_pose()
    route = [(start.x_mm, start.y_mm), *tour, basket]  # type: ignore[misc]
    i = sim.add_crossing_opponent(route, keep_clear=[(start.x_mm, start.y_mm, 450)])
    gaps: list[float] = []

    def watch(s: Simulator) -> None:
        gaps.append(_gap(s, i))
        s.at(s.time_s + 0.01, watch)

    sim.at(0.0, watch)
    lines: list[str] = []
    score = env["play"](Board(sim.bus, pec=True), sim.lidar, log=lines.append)  # type: ignore[operator]
    assert min(gaps) > 10, lines
    assert score["points"] > 0, lines  # type: ignore[index]
