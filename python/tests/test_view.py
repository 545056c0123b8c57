"""asserv view without a browser: the sources, the server's page and stream, the CLI."""

from __future__ import annotations

import asyncio
import itertools
import json
import math
import time
import urllib.error
import urllib.request
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from asserv import cli, log, scenario, view
from asserv._protocol import Status
from asserv.driver import Board
from asserv.sim import Simulator

ROOT = Path(__file__).resolve().parents[2]
BUSY = int(Status.BUSY_TRAJET)


@given(st.lists(st.sampled_from([0, BUSY, BUSY | 4, 8, 16, 32]), max_size=50))
def test_outcome_follows_the_status(status: list[int]) -> None:
    o = view.Outcome()
    for s in status:
        o.update(s)
    rises = sum(1 for a, b in zip([0, *status], status, strict=False) if b & 6 and not a & 6)
    assert o.orders == rises
    falls = [b for a, b in itertools.pairwise(status) if a & 6 and not b & 6]
    if falls:
        bits = [str(x.name) for x in view._END_BITS if falls[-1] & x]
        assert o.last == ("|".join(bits) if bits else "done")
    else:
        assert o.last == ""


def test_outcome_names_a_timeout_or_a_reset() -> None:
    o = view.Outcome()
    for status, why, last in [
        (BUSY, 0, ""),
        (32, 12, "PB_MOTEUR (RESET)"),
        (BUSY, 12, "PB_MOTEUR (RESET)"),
        (32, 8, "PB_MOTEUR (TIMEOUT)"),
        (BUSY, 8, "PB_MOTEUR (TIMEOUT)"),
        (32, 3, "PB_MOTEUR"),  # a motor problem: the bits say it
        (BUSY, math.nan, "PB_MOTEUR"),
        (32, math.nan, "PB_MOTEUR"),  # rows without DEBUG (the simulator's trace)
    ]:
        o.update(status, why)
        assert o.last == last


def advance_until(src: view.Source, done: Any, seconds: float) -> None:
    for _ in range(round(seconds * 30)):
        src.advance(1 / 30)
        if done():
            return
    raise AssertionError("the view never showed it")


@pytest.mark.parametrize("keep_ram", [True, False])
def test_the_sim_source_shows_a_reset(keep_ram: bool) -> None:
    """A brown-out mid-GOTO: the page's state carries RESET_INFO (the cause, the count, the
    pose kept or lost), and the order's outcome reads abandoned."""
    src = view.SimSource()
    advance_until(src, lambda: src.reset is not None, 1)
    assert src.state()["reset"] == {
        "cause": "POWER_ON",
        "count": 0,
        "pose_lost": False,
        "widened_mm": 0,
    }
    src.goto(-300, -600)
    advance_until(src, lambda: src.outcome.orders == 1, 1)
    src.sim.reset("BROWN_OUT", keep_ram=keep_ram, down_ms=50)
    advance_until(src, lambda: src.outcome.last != "", 1)
    assert src.outcome.last == "PB_MOTEUR"
    state = json.loads(json.dumps(src.state()))  # what the page gets
    assert state["reset"]["cause"] == "BROWN_OUT" and state["reset"]["count"] == 1
    assert state["reset"]["pose_lost"] == (not keep_ram)


def test_the_board_source_shows_a_reset_and_names_the_ending() -> None:
    """A watchdog reset mid-GOTO on a polled board: RESET_INFO in the state, and the ending
    with DEBUG's end reason, which the polled rows have."""
    sim = Simulator()
    srcs: list[view.BoardSource] = []  # the source, once made (its thread calls reset())
    taken: list[float] = []

    def reset(s: Simulator) -> None:
        # 0.6 s into the GOTO, between two of the polling thread's transactions. The thread
        # moves the simulated time from its start: on a loaded machine it went past 0.6 s
        # before the GOTO was queued, which then ran after the reset and ended done.
        if srcs and srcs[0].target is not None and not taken:
            taken.append(s.time_s)
        if not taken or s.time_s < taken[0] + 0.6 or s.bus_busy:
            s.at(s.time_s + 0.0005, reset)
        else:
            s.reset("WATCHDOG", keep_ram=True, down_ms=20)

    sim.at(0.01, reset)
    src = view.BoardSource(Board(sim.bus), hz=50)
    srcs.append(src)
    try:
        src.goto(-300, -600)
        for _ in range(2000):
            src.advance(0.02)
            if src.outcome.last and src.reset is not None and src.reset["count"]:
                break
            time.sleep(0.005)
        assert src.outcome.last == "PB_MOTEUR (RESET)"
        assert src.reset is not None
        assert (src.reset["cause"], src.reset["count"], src.reset["pose_lost"]) == (
            "WATCHDOG",
            1,
            False,
        )
    finally:
        src.close()


def test_a_board_without_reset_info_shows_none() -> None:
    from test_driver_match import Without

    from asserv import Capability, VirtualBus

    board = Board(VirtualBus({2: Without(int(Capability.RESET_INFO))}))
    assert view.reset_state(board) is None


def test_sim_source_is_paced_by_the_speed_and_pauses() -> None:
    src = view.SimSource()
    t0 = src.sim.time_s
    rows = src.advance(0.1)
    assert src.sim.time_s == pytest.approx(t0 + 0.1, abs=1e-6)
    assert len(rows) == 100
    src.set_speed(20)
    src.advance(0.1)
    assert src.sim.time_s == pytest.approx(t0 + 2.1, abs=1e-6)
    src.set_paused(True)
    assert len(src.advance(0.5)) == 0
    assert src.sim.time_s == pytest.approx(t0 + 2.1, abs=1e-6)
    with pytest.raises(ValueError):
        src.set_speed(100)


def test_sim_source_plays_a_scenario_and_takes_a_goto(tmp_path: Path) -> None:
    path = tmp_path / "two.txt"
    path.write_text("set_vitesse_traj 50 100\ngoto 300 -850\nwait\ngoto 300 -500\nwait\n")
    src = view.SimSource(scenario.load(path))
    while src.outcome.orders < 1:
        src.advance(0.05)
    assert src.target == (300.0, -850.0)  # the scenario's first GOTO
    assert src.message == "line 3: wait"
    src.set_speed(50)
    for _ in range(100):
        src.advance(0.1)
        if src.message.endswith("(scenario over)") and not src.outcome.busy:
            break
    assert src.message == "line 5: wait (scenario over)"
    assert src.outcome.orders == 2 and src.outcome.last == "done"
    assert src.target == (300.0, -500.0)
    src.goto(-400, 200)  # a click
    assert src.target == (-400.0, 200.0)
    for _ in range(40):
        rows = src.advance(0.1)
    last = rows[-1]
    assert math.hypot(last["est_x_mm"] + 400, last["est_y_mm"] - 200) < 2
    assert src.outcome.orders == 3 and src.outcome.last == "done"


@given(st.lists(st.floats(0.001, 0.08), min_size=1, max_size=12))
@settings(max_examples=8, deadline=None)
def test_sim_source_following_errors_continue_across_frames(dts: list[float]) -> None:
    """Rows cut into frames of any length carry the same following errors as the whole run's."""
    src = view.SimSource()
    src.goto(400, -600)
    rows = np.concatenate([src.advance(dt) for dt in [*dts, 0.5, 0.3]])
    whole = log.from_trace(rows, float(src.sim.config.drive_track_mm))
    np.testing.assert_allclose(rows["dist_err_mm"], whole["dist_err_mm"], atol=1e-9)
    np.testing.assert_allclose(rows["angle_err_mm"], whole["angle_err_mm"], atol=1e-9)
    assert np.all(np.diff(rows["t_s"]) > 0)


@pytest.fixture(scope="module")
def replay_log(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, np.ndarray]:
    sim = Simulator()
    board = Board(sim.bus)
    board.goto(300, -600)
    sim.advance(1.5)
    rows = log.from_sim(sim)
    path = tmp_path_factory.mktemp("replay") / "run.mcap"
    log.save(rows, mcap=path, field=sim.field, outline=log.Outline.of(sim))
    return path, rows


@given(
    st.lists(
        st.tuples(st.floats(0.0, 0.2), st.sampled_from(view.SPEEDS), st.booleans()), max_size=60
    )
)
@settings(
    max_examples=30, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture]
)
def test_a_replay_gives_every_row_once_in_order(
    replay_log: tuple[Path, np.ndarray], steps: list[tuple[float, int, bool]]
) -> None:
    path, rows = replay_log
    src = view.ReplaySource(path)
    assert src.truth and src.field.baskets and not src.can_goto
    got = []
    for dt, speed, pause in steps:
        src.set_speed(speed)
        if pause and not src.at_end:
            src.set_paused(not src.paused)
        got.append(src.advance(dt))
    if not src.at_end:
        src.set_paused(False)
    while not src.at_end:
        got.append(src.advance(0.5))
    assert src.paused
    out = np.concatenate(got)
    assert len(out) == len(rows)
    np.testing.assert_array_equal(out["t_s"], rows["t_s"])
    np.testing.assert_array_equal(out["est_x_mm"], rows["est_x_mm"])
    assert "end of the log" in src.message
    src.set_paused(False)  # from the start again
    assert src.advance(0.01)["t_s"][0] == rows["t_s"][0]


def test_board_source_polls_and_sends_gotos() -> None:
    sim = Simulator()
    src = view.BoardSource(Board(sim.bus), hz=50)
    try:
        src.goto(-300, -600)
        rows: list[np.ndarray] = []
        for _ in range(2000):
            rows.append(src.advance(0.02))
            if src.outcome.last:
                break
            time.sleep(0.005)
        assert src.outcome.last == "done"
        assert src.target == (-300.0, -600.0)
        out = np.concatenate(rows)
        assert len(out) > 50 and np.isnan(out["x_mm"]).all()
        # 50 rows a second on the board's clock (a 100 kHz bus: each row takes ~4 ms of it)
        assert np.diff(out["t_s"]).min() > 0.015
        assert float(np.median(np.diff(out["t_s"]))) == pytest.approx(0.02, abs=0.001)
        last = out[-1]
        assert math.hypot(last["est_x_mm"] + 300, last["est_y_mm"] + 600) < 5
        assert not src.truth and src.info()["kind"] == "board"
        # A GOTO the board cannot take: said on the page, the polling goes on.
        src.goto(40000, 0)
        for _ in range(500):
            time.sleep(0.005)
            if src.message:
                break
        assert src.message.startswith("GOTO (40000, 0):")
        n = len(src.advance(0.02))
        time.sleep(0.05)
        assert n + len(src.advance(0.02)) > 0
        assert src.target == (-300.0, -600.0)
    finally:
        src.close()


def _get(url: str) -> tuple[int, str, bytes]:
    try:
        with urllib.request.urlopen(url, timeout=5) as r:
            return r.status, r.headers["Content-Type"], r.read()
    except urllib.error.HTTPError as e:
        return e.code, "", b""


def test_server_serves_the_page_and_the_stream() -> None:
    src = view.SimSource()
    srv = view.ViewServer(src, "127.0.0.1", 0)
    srv.start_thread()
    try:
        time.sleep(0.3)
        assert src.sim.time_s == 0  # no page yet: the simulator waits
        assert srv.url == f"{srv.base_url}?token={srv.token}"
        assert srv.base_url.startswith("http://127.0.0.1:")
        code, ctype, body = _get(srv.url)
        assert code == 200 and ctype.startswith("text/html") and b"view.js" in body
        assert _get(srv.base_url + "view.js")[0] == 200
        code, ctype, _ = _get(srv.base_url + "favicon.svg")
        assert code == 200 and ctype == "image/svg+xml"
        for bad in ("nothing.js", "..%2Fview.py", "../view.py", "view_static/view.js"):
            assert _get(srv.base_url + bad)[0] == 404, bad

        async def talk() -> tuple[dict[str, Any], dict[str, Any], list[str]]:
            from websockets.asyncio.client import connect

            refused: list[str] = []
            async with connect(srv.ws_url) as ws:
                hello = json.loads(await ws.recv())
                await ws.send("not json")
                await ws.send(json.dumps({"type": "speed", "speed": 1000}))
                await ws.send(json.dumps({"type": "goto", "x": "a"}))
                await ws.send(json.dumps({"type": "speed", "speed": 10}))
                await ws.send(json.dumps({"type": "goto", "x": 500, "y": 200}))
                msg: dict[str, Any] = {}
                for _ in range(300):
                    msg = json.loads(await ws.recv())
                    if msg["type"] == "refused":
                        refused.append(msg["why"])
                    elif msg["state"]["outcome"] == "done":
                        break
                return hello, msg, refused

        hello, msg, refused = asyncio.run(talk())
        assert refused == [
            "not JSON: 'not json': JSONDecodeError",
            "speed 1000 is not within 1..50",
            "goto takes x, y; got ['type', 'x']",
        ]
        assert hello["access"] == {
            "commands": True,
            "drive": True,
            "mode": "driving the simulator: a click sends a GOTO",
        }
        info = hello["info"]
        assert info["kind"] == "sim" and info["fields"] == list(log.LOG_FIELDS)
        assert info["field"]["length_mm"] == src.field.length_mm
        assert msg["state"]["speed"] == 10 and msg["state"]["target"] == [500.0, 200.0]
        assert msg["state"]["outcome"] == "done"
        last = dict(zip(info["fields"], msg["rows"][-1], strict=True))
        assert math.hypot(last["est_x_mm"] - 500, last["est_y_mm"] - 200) < 3
    finally:
        srv.stop()


@pytest.mark.parametrize(
    "argv",
    [
        ["view", "--replay", "missing.mcap"],
        ["view", "missing-scenario.txt"],
        ["view", "--port", "70000"],
        ["view", str(ROOT / "scenarios/annex.txt"), "--replay", "x.mcap"],
        ["--bus", "1", "view", "--hz", "0"],
    ],
)
def test_view_bad_arguments(argv: list[str], capsys: pytest.CaptureFixture[str]) -> None:
    assert cli.main(argv) == 2
    err = capsys.readouterr().err
    assert err.startswith("asserv view:") and "Traceback" not in err


def test_a_log_that_is_not_mcap_is_refused(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    bad = tmp_path / "x.mcap"
    bad.write_text("hello")
    assert cli.main(["view", "--replay", str(bad)]) == 2
    assert "not an asserv MCAP log" in capsys.readouterr().err


STRATEGY = """
from asserv import view

def strategy(board):
    board.set_vitesse_traj(60, 100)
    board.goto(400, -850)
    yield from view.wait_idle(board)
    yield 0.5
    board.goto(400, -500)
    yield from view.wait_idle(board)
"""


def test_a_python_strategy_plays_in_simulated_time(tmp_path: Path) -> None:
    path = tmp_path / "strat.py"
    path.write_text(STRATEGY)
    src = view.SimSource(strategy=view.load_strategy(path))
    src.set_speed(20)
    for _ in range(200):
        rows = src.advance(0.1)
        if src.message == "strategy over":
            break
    assert src.message == "strategy over"
    assert src.outcome.orders == 2 and src.outcome.last == "done"
    last = rows[-1]
    assert math.hypot(last["est_x_mm"] - 400, last["est_y_mm"] + 500) < 2


@pytest.mark.parametrize(
    ("text", "why"),
    [
        ("def strategy(board):\n    return 1\n", "generator function"),
        ("x = 1\n", "generator function"),
        ("def strategy(board:\n", "cannot load it"),
    ],
)
def test_bad_strategy_files(tmp_path: Path, text: str, why: str) -> None:
    path = tmp_path / "s.py"
    path.write_text(text)
    with pytest.raises(view.StrategyError, match=why):
        view.load_strategy(path)
    assert cli.main(["view", str(path)]) == 2


def test_a_strategy_that_fails_is_shown(tmp_path: Path) -> None:
    path = tmp_path / "s.py"
    path.write_text("def strategy(board):\n    yield 0.1\n    board.goto(99999, 0)\n")
    src = view.SimSource(strategy=view.load_strategy(path))
    src.advance(0.5)
    assert src.message.startswith("strategy stopped: FrameError")
    assert len(src.advance(0.1)) == 100  # the simulator goes on
