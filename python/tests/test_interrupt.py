"""Ctrl-C: every command ends with exit 130 and one line on stderr that says what it left
(cli.INTERRUPTED; docs/driver.md, "The conventions of every asserv command").

Each command runs as its own process and gets a real SIGINT once it has said it is running;
the waits are on its output, with a long limit, so that a slow machine only makes them slower.
"""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import threading
import time
from collections.abc import Iterator
from pathlib import Path

import pytest

from asserv import cli
from asserv.log import read_csv

pytest.importorskip("websockets")

ASSERV = [sys.executable, "-m", "asserv"]
LIMIT_S = 120.0


class Running:
    """A command in its own process, its output read line by line as it comes."""

    def __init__(self, argv: list[str], cwd: Path) -> None:
        env = {**os.environ, "PYTHONUNBUFFERED": "1", "MPLBACKEND": "Agg"}
        self.p = subprocess.Popen(
            [*ASSERV, *argv],
            cwd=cwd,
            stdin=subprocess.DEVNULL,
            stdout=subprocess.PIPE,
            stderr=subprocess.PIPE,
            text=True,
            env=env,
        )
        self.out: list[str] = []
        self._seen = threading.Condition()
        self._reader = threading.Thread(target=self._read, daemon=True)
        self._reader.start()

    def _read(self) -> None:
        assert self.p.stdout is not None
        for line in self.p.stdout:
            with self._seen:
                self.out.append(line)
                self._seen.notify_all()
        with self._seen:
            self._seen.notify_all()

    def wait_for(self, text: str) -> str:
        with self._seen:
            ok = self._seen.wait_for(
                lambda: any(text in x for x in self.out) or self.p.poll() is not None, LIMIT_S
            )
        line = next((x for x in self.out if text in x), None)
        assert ok and line is not None, (text, self.out, self.p.poll())
        return line

    def interrupt(self) -> tuple[int, str]:
        self.p.send_signal(signal.SIGINT)
        code = self.p.wait(LIMIT_S)
        self._reader.join(LIMIT_S)
        assert self.p.stderr is not None
        return code, self.p.stderr.read()

    def kill(self) -> None:
        if self.p.poll() is None:
            self.p.kill()
            self.p.wait()


@pytest.fixture
def started(tmp_path: Path) -> Iterator[list[Running]]:
    procs: list[Running] = []
    yield procs
    for r in procs:
        r.kill()


def start(procs: list[Running], argv: list[str], cwd: Path) -> Running:
    r = Running(argv, cwd)
    procs.append(r)
    return r


def serve(procs: list[Running], cwd: Path) -> str:
    """A simulator server in lockstep on a free port; its HOST:PORT."""
    s = start(procs, ["sim", "serve", "--port", "0", "--speed", "0"], cwd)
    line = s.wait_for("listening on")
    return line.split("listening on ")[1].split()[0]


def test_a_server_says_it_stopped_serving(started: list[Running], tmp_path: Path) -> None:
    s = start(started, ["sim", "serve", "--port", "0"], tmp_path)
    s.wait_for("listening on")
    code, err = s.interrupt()
    assert code == 130
    assert err.splitlines() == [f"asserv sim serve: {cli.INTERRUPTED['asserv sim serve']}"]


def test_the_view_says_it_stopped_serving_the_page(started: list[Running], tmp_path: Path) -> None:
    v = start(started, ["view", "--port", "0"], tmp_path)
    v.wait_for("open http://")
    code, err = v.interrupt()
    assert code == 130
    assert err.splitlines() == [f"asserv view: {cli.INTERRUPTED['asserv view']}"]


def test_a_log_ended_by_ctrl_c_keeps_its_rows(started: list[Running], tmp_path: Path) -> None:
    where = serve(started, tmp_path)
    lg = start(started, ["--sim", where, "log", "--csv", "run.csv", "--hz", "20"], tmp_path)
    # rows come: the CSV grows past its header (flushed every 50 rows)
    deadline = time.monotonic() + LIMIT_S
    while _rows(tmp_path / "run.csv") < 50 and lg.p.poll() is None:
        assert time.monotonic() < deadline, "no rows logged"
        time.sleep(0.1)
    code, err = lg.interrupt()
    assert code == 130
    lines = err.splitlines()
    assert lines[-1] == f"asserv log: {cli.INTERRUPTED['asserv log']}"
    assert all(not x.startswith("Traceback") for x in lines)
    assert len(read_csv(tmp_path / "run.csv")) >= 50


def _rows(path: Path) -> int:
    try:
        return len(path.read_text().splitlines()) - 1
    except OSError:
        return 0


def test_a_reader_that_goes_away_is_no_traceback(tmp_path: Path) -> None:
    """asserv demo | head -1: the demo's output meets a closed pipe; it ends quietly (141, as
    a shell reports a process ended by SIGPIPE), not with a BrokenPipeError traceback."""
    p = subprocess.Popen(
        [*ASSERV, "demo", "--no-png"],
        cwd=tmp_path,
        stdin=subprocess.DEVNULL,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    assert p.stdout is not None and p.stderr is not None
    p.stdout.close()  # before it prints anything: whatever it prints meets a closed pipe
    code = p.wait(LIMIT_S)
    err = p.stderr.read()
    assert code == 141 and "Traceback" not in err, (code, err)
