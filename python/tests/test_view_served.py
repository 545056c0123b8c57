"""asserv view, log and tune on the simulator server (``asserv --sim HOST:PORT ...``): a team's
strategy drives the served simulator while the view watches it, truth included."""

from __future__ import annotations

import asyncio
import json
import math
import os
import subprocess
import sys
import threading
import time
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from asserv import Status, cli, log, view
from asserv.driver import Board
from asserv.server import RemoteBus, SimServer
from asserv.sim import Simulator

ROOT = Path(__file__).resolve().parents[2]


def _strategy(port: int, done: threading.Event, errors: list[BaseException]) -> None:
    """A team's strategy in its own connection: two GOTOs, each waited for."""
    try:
        with RemoteBus("127.0.0.1", port) as bus:
            board = Board(bus)
            board.set_vitesse_traj(60, 100)
            for x, y in ((300, -600), (300, -300)):
                board.goto(x, y)
                board.wait_idle(30)
    except BaseException as e:  # reported by the test
        errors.append(e)
    finally:
        done.set()


async def _watch(url: str, until: threading.Event) -> tuple[dict[str, Any], list[list[Any]]]:
    from websockets.asyncio.client import connect

    rows: list[list[Any]] = []
    page, _, query = url.partition("?")  # the page's address, its token
    async with connect(f"{page.replace('http', 'ws', 1)}ws?{query}") as ws:
        hello = json.loads(await ws.recv())
        while not until.is_set():
            msg = json.loads(await asyncio.wait_for(ws.recv(), 5))
            rows.extend(msg["rows"])
        # The polls after the strategy ended, until one shows the robot at rest at its last
        # point (a loaded machine polls late: wait for the row, not for a count of messages).
        for _ in range(200):
            rows.extend(json.loads(await asyncio.wait_for(ws.recv(), 5))["rows"])
            if rows and _at_rest_at_end(dict(zip(hello["info"]["fields"], rows[-1], strict=True))):
                break
    return hello, rows


def _at_rest_at_end(row: dict[str, Any]) -> bool:
    return (
        math.hypot(row["est_x_mm"] - 300, row["est_y_mm"] + 300) < 5
        and abs(row["v_mm_s"]) < 1
        and not int(row["status"]) & Status.BUSY_TRAJET
    )


def _check_watched(hello: dict[str, Any], rows: list[list[Any]], sim: Simulator) -> None:
    info = hello["info"]
    assert info["kind"] == "board" and info["truth"] is True
    named = [dict(zip(info["fields"], r, strict=True)) for r in rows]
    # It watched the moves (how many polls that takes depends on the machine's load: on a
    # loaded one a rehearsal of CI saw 7 rows, so no count is asserted).
    assert any(int(r["status"]) & Status.BUSY_TRAJET for r in named)
    # The strategy's moves, seen by the view: the estimate and the truth, both near the end.
    last = named[-1]
    assert math.hypot(last["est_x_mm"] - 300, last["est_y_mm"] + 300) < 5
    assert math.hypot(last["x_mm"] - 300, last["y_mm"] + 300) < 15
    true_now = sim.true_pose()
    assert math.hypot(last["x_mm"] - true_now.x_mm, last["y_mm"] - true_now.y_mm) < 2
    assert max(r["v_mm_s"] for r in named) > 200  # it watched the robot drive
    assert any(int(r["status"]) & 2 for r in named)


def test_the_view_watches_a_strategy_on_the_server() -> None:
    """In this process: the server, the view's BoardSource on a RemoteBus, the strategy in a
    thread with its own connection."""
    sim = Simulator(record=False)
    with SimServer(sim, "127.0.0.1", 0, speed=4) as server:
        host, port = server.address
        src = view.BoardSource(Board(RemoteBus(host, port)), hz=50)
        srv = view.ViewServer(src, "127.0.0.1", 0)
        srv.start_thread()
        done = threading.Event()
        errors: list[BaseException] = []
        try:
            th = threading.Thread(target=_strategy, args=(port, done, errors))
            th.start()
            hello, rows = asyncio.run(_watch(srv.url, done))
            th.join(10)
        finally:
            srv.stop()
            src.board.bus.close()
        assert not errors, errors
        _check_watched(hello, rows, sim)


def test_cli_sim_view_watches_the_server() -> None:
    """``asserv --sim HOST:PORT view`` as a team runs it, in its own process."""
    sim = Simulator(record=False)
    with SimServer(sim, "127.0.0.1", 0, speed=4) as server:
        _, port = server.address
        env = dict(os.environ, PYTHONUNBUFFERED="1")
        cmd = [sys.executable, "-m", "asserv", "--sim", f"127.0.0.1:{port}", "view", "--port", "0"]
        proc = subprocess.Popen(
            cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=env
        )
        try:
            assert proc.stdout is not None
            line = proc.stdout.readline()
            assert line.startswith("asserv view: open http://127.0.0.1:"), line
            url = line.split()[3]
            done = threading.Event()
            errors: list[BaseException] = []
            th = threading.Thread(target=_strategy, args=(port, done, errors))
            th.start()
            hello, rows = asyncio.run(_watch(url, done))
            th.join(10)
        finally:
            proc.terminate()
            proc.wait(10)
        assert not errors, errors
        _check_watched(hello, rows, sim)


def test_cli_sim_log_records_the_truth(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """``asserv --sim HOST:PORT log``: the served robot with its true pose, in simulated time
    (lockstep: the log's own waits move the server's clock)."""
    sim = Simulator(record=False)
    with SimServer(sim, "127.0.0.1", 0, speed=0) as server:
        _, port = server.address
        with RemoteBus("127.0.0.1", port) as bus:
            Board(bus).goto(400, -850)
        m, c = tmp_path / "s.mcap", tmp_path / "s.csv"
        argv = ["--sim", f":{port}", "log", "--mcap", str(m), "--csv", str(c), "--duration", "2"]
        assert cli.main(argv) == 0, capsys.readouterr().err
    rows = log.read_csv(c)
    assert 95 <= len(rows) <= 101
    assert not np.isnan(rows["x_mm"]).any()
    assert np.abs(rows["x_mm"] - rows["est_x_mm"]).max() < 5
    assert rows["x_mm"][-1] > 150  # 10 cm/s for 2 s, accelerating first
    assert np.all(np.diff(rows["x_mm"]) >= -0.5)
    back = log.read_mcap(m)
    assert "/pose/true" in back.schemas
    np.testing.assert_array_equal(back.rows["x_mm"], rows["x_mm"])


def test_cli_sim_tune_on_the_server(capsys: pytest.CaptureFixture[str]) -> None:
    sim = Simulator({"start": (-300.0, 0.0, 0.0)}, record=False)
    with SimServer(sim, "127.0.0.1", 0, speed=0) as server:
        _, port = server.address
        argv = ["--sim", f":{port}", "tune", "--axis", "distance", "--window", "1.5", "--apply"]
        assert cli.main(argv) == 0, capsys.readouterr().err
    out = capsys.readouterr()
    assert "simulator server" in out.err
    assert "applied: SET_FILTRE_RAW 205 400 160" in out.out
    assert sim.true_pose().x_mm == pytest.approx(-300, abs=3)  # stepped, and came back


@pytest.mark.parametrize(
    ("argv", "message"),
    [
        (["--sim", "h:x", "view"], "--sim"),
        (["--sim", ":1", "--bus", "1", "view"], "not both"),
        (["--sim", ":1", "log", "--csv", "x.csv", "--bus", "1"], "not both"),
        (["--sim", ":0", "tune"], "--sim"),
        (["--sim", ":1", "view", "--replay", "x.mcap"], "give one of"),
    ],
)
def test_bad_sim_arguments(
    argv: list[str], message: str, capsys: pytest.CaptureFixture[str]
) -> None:
    assert cli.main(argv) == 2
    err = capsys.readouterr().err
    assert message in err and "Traceback" not in err


def test_no_server_is_a_bus_failure(capsys: pytest.CaptureFixture[str]) -> None:
    with SimServer(Simulator(record=False), "127.0.0.1", 0) as server:
        _, port = server.address  # a port that was free, and is again once closed
    for argv in (["--sim", f":{port}", "view", "--port", "0"], ["--sim", f":{port}", "tune"]):
        assert cli.main(argv) == 1
        err = capsys.readouterr().err
        assert "cannot reach the simulator server" in err and "Traceback" not in err


def test_view_of_a_served_board_does_not_move_its_time() -> None:
    """The view polls by the wall clock: in lockstep the server's time stays where the
    strategy leaves it."""
    sim = Simulator(record=False)
    with SimServer(sim, "127.0.0.1", 0, speed=0) as server:
        src = view.BoardSource(Board(RemoteBus(*server.address)), hz=50)
        try:
            time.sleep(0.5)
            rows = src.advance(0.5)
        finally:
            src.close()
            src.board.bus.close()
    assert len(rows) >= 5
    # Only the bytes of its polls (38 bytes at 100 kHz each) moved the simulated time.
    assert sim.time_s < len(rows) * 0.004 + 0.05
