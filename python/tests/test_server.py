"""The simulator server: its bus over TCP is the simulator's bus, its clock the simulated time,
and `asserv sim serve` / `asserv --sim HOST:PORT` work from other processes."""

from __future__ import annotations

import errno
import os
import subprocess
import sys
import time
from collections.abc import Iterator
from pathlib import Path

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from smbus2 import i2c_msg

from asserv import Board, Status
from asserv.driver import Outcome
from asserv.server import RemoteBus, SimServer, decode_rdwr, encode_rdwr, parse_address
from asserv.sim import Simulator

SLOW = settings(max_examples=25, deadline=None, suppress_health_check=[HealthCheck.too_slow])


@pytest.fixture
def lockstep() -> Iterator[tuple[Simulator, RemoteBus]]:
    sim = Simulator(record=False)
    with SimServer(sim, "127.0.0.1", 0, speed=0) as server:
        bus = RemoteBus(*server.address)
        yield sim, bus
        bus.close()


def test_a_board_on_the_server(lockstep: tuple[Simulator, RemoteBus]) -> None:
    sim, bus = lockstep
    board = Board(bus, pec=True)
    assert board.now() == pytest.approx(sim.time_s, abs=1e-9)
    assert board.complete(board.goto, -400, -600, timeout_s=30) is Outcome.DONE
    pose = board.position()
    assert (pose.x_mm, pose.y_mm) == (-400, -600)
    assert sim.true_pose().x_mm == pytest.approx(-400, abs=5)
    t = board.now()
    board.sleep(0.5)
    assert board.now() - t == pytest.approx(0.5, abs=1e-6)


def test_truth_and_obstacles_for_a_live_view(lockstep: tuple[Simulator, RemoteBus]) -> None:
    sim, bus = lockstep
    sim.add_opponent(500, 500, 100, path=[(600, 500)], speed_mm_s=100)
    bus.clock.sleep(0.5)
    t, x, y, h = bus.truth()
    assert t == pytest.approx(sim.time_s, abs=1e-9)
    assert (x, y, h) == pytest.approx(tuple(sim.true_pose()), abs=1e-3)
    assert bus.obstacles()[-1] == pytest.approx((550, 500), abs=0.01)
    assert len(bus.obstacles()) == 3  # two baskets and the opponent


def test_nack_and_errors_cross_the_socket(lockstep: tuple[Simulator, RemoteBus]) -> None:
    _, bus = lockstep
    with pytest.raises(OSError) as e:
        bus.i2c_rdwr(i2c_msg.write(0x33, b"\x03"))
    assert e.value.errno == errno.ENXIO
    for bad in ("", "nonsense", "rdwr", "rdwr x02:00", "rdwr w02:0g", "sleep -1", "sleep x"):
        with pytest.raises(OSError) as e:
            bus.request(bad)
        assert e.value.errno == errno.EINVAL
    bus.close()
    with pytest.raises(OSError) as e:
        bus.i2c_rdwr(i2c_msg.read(2, 1))
    assert e.value.errno == errno.EBADF


def test_the_server_runs_in_real_time_by_itself() -> None:
    sim = Simulator(record=False)
    with SimServer(sim, "127.0.0.1", 0, speed=20) as server, RemoteBus(*server.address) as bus:
        board = Board(bus)
        t0 = board.now()
        deadline = time.monotonic() + 10
        while board.now() - t0 < 0.2 and time.monotonic() < deadline:
            time.sleep(0.01)  # nobody sleeps on the simulated clock: it moves by itself
        assert board.now() - t0 >= 0.2
        board.goto(-100, -850)
        assert board.wait_idle(30) == Status(0)


def test_connection_refused_is_an_oserror() -> None:
    import socket

    s = socket.socket()
    s.bind(("127.0.0.1", 0))
    port = s.getsockname()[1]
    s.close()
    with pytest.raises(OSError, match="asserv sim serve"):
        RemoteBus("127.0.0.1", port, timeout_s=2)


@given(st.text(max_size=60))
def test_any_request_line_gets_one_reply_line(line: str) -> None:
    server = _SERVER
    reply = server.handle_line(line.replace("\n", " ").replace("sleep", "slp"))
    assert reply.startswith(("ok", "err")) and "\n" not in reply


_SERVER = SimServer(Simulator(record=False), "127.0.0.1", 0, speed=0)  # never started


@given(
    st.lists(
        st.tuples(
            st.sampled_from([2, 2, 2, 0x10]),
            st.one_of(st.binary(min_size=0, max_size=9), st.none()),
            st.integers(0, 24),
        ),
        min_size=1,
        max_size=4,
    )
)
def test_rdwr_lines_round_trip(ops: list[tuple[int, bytes | None, int]]) -> None:
    norm = [(a, d, 0 if d is not None else n) for a, d, n in ops]
    assert decode_rdwr(encode_rdwr(norm).split()[1:]) == norm


Step = tuple[str, int, bytes, int]
STEPS = st.lists(
    st.one_of(
        st.tuples(st.just("w"), st.sampled_from([2, 2, 5]), st.binary(max_size=8), st.just(0)),
        st.tuples(st.just("wr"), st.just(2), st.binary(min_size=1, max_size=4), st.integers(1, 24)),
        st.tuples(st.just("r"), st.just(2), st.just(b""), st.integers(0, 4)),
        st.tuples(st.just("sleep"), st.just(0), st.just(b""), st.integers(0, 40)),
    ),
    min_size=1,
    max_size=25,
)


def _play(bus: object, clock: object, steps: list[Step]) -> list[object]:
    out: list[object] = []
    for kind, addr, data, n in steps:
        try:
            if kind == "sleep":
                clock.sleep(n * 1e-3)  # type: ignore[attr-defined]
                out.append(round(clock.monotonic(), 9))  # type: ignore[attr-defined]
                continue
            msgs = []
            if kind in ("w", "wr"):
                msgs.append(i2c_msg.write(addr, data))
            if kind in ("r", "wr"):
                msgs.append(i2c_msg.read(addr, n))
            bus.i2c_rdwr(*msgs)  # type: ignore[attr-defined]
            out.append([bytes(m) for m in msgs if m.flags & 1])
        except OSError as e:
            out.append(("OSError", e.errno))
    out.append(round(clock.monotonic(), 9))  # type: ignore[attr-defined]
    return out


@SLOW
@given(STEPS)
def test_server_bus_property_equivalent_to_the_local_bus(steps: list[Step]) -> None:
    """Any sequence of transactions (any bytes, reads, NACKed addresses) and sleeps gives the
    same replies, errors and simulated times through a lockstep server as on Simulator.bus."""
    local = Simulator(record=False)
    expected = _play(local.bus, local, steps)
    remote_sim = Simulator(record=False)
    with (
        SimServer(remote_sim, "127.0.0.1", 0, speed=0) as server,
        RemoteBus(*server.address) as bus,
    ):
        got = _play(bus, bus.clock, steps)
    assert got == expected


@SLOW
@given(st.lists(st.floats(0, 0.05), min_size=1, max_size=6))
def test_remote_clock_property_sleep_moves_the_server_time(sleeps: list[float]) -> None:
    sim = Simulator(record=False)
    with SimServer(sim, "127.0.0.1", 0, speed=0) as server, RemoteBus(*server.address) as bus:
        board = Board(bus)
        for s in sleeps:
            t = board.now()
            board.sleep(s)
            assert board.now() - t == pytest.approx(s, abs=1e-6)
            assert board.now() == pytest.approx(sim.time_s, abs=1e-9)


def test_parse_address() -> None:
    assert parse_address("localhost:1234") == ("localhost", 1234)
    assert parse_address(":99") == ("127.0.0.1", 99)
    assert parse_address("host") == ("host", 5021)
    for bad in ("h:x", "h:0", "h:70000"):
        with pytest.raises(ValueError):
            parse_address(bad)


# The command line, from other processes.

ENV = {**os.environ, "PYTHONUNBUFFERED": "1"}


def _serve(*extra: str) -> tuple[subprocess.Popen[str], str]:
    proc = subprocess.Popen(
        [sys.executable, "-m", "asserv", "sim", "serve", "--port", "0", "--duration", "60", *extra],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        env=ENV,
    )
    assert proc.stdout is not None
    line = proc.stdout.readline()
    assert "listening on 127.0.0.1:" in line, line + (proc.stderr.read() if proc.stderr else "")
    return proc, line.split("listening on ")[1].split()[0]


def _asserv(*args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [sys.executable, "-m", "asserv", *args],
        capture_output=True,
        text=True,
        timeout=60,
        env=ENV,
    )


def test_cli_against_the_server() -> None:
    proc, where = _serve("--speed", "0")
    try:
        r = _asserv("--sim", where, "status")
        assert r.returncode == 0, r.stderr
        assert r.stdout.strip() == "status 0x00: (no flag: idle)"
        r = _asserv("--sim", where, "goto", "-300", "-700")
        assert r.returncode == 0, r.stderr
        r = _asserv("--sim", where, "wait", "--timeout", "30")
        assert r.returncode == 0, r.stderr
        r = _asserv("--sim", where, "position")
        assert r.stdout.startswith("x -300 mm, y -700 mm"), r.stdout + r.stderr
    finally:
        proc.terminate()
        proc.wait(10)


def test_serve_a_scenario_world_with_an_opponent(tmp_path: Path) -> None:
    world = tmp_path / "world.txt"
    world.write_text("start -1000 -300 0\nopponent -400 500 150 400 -400 -300\nat 0.5 press 0\n")
    proc, where = _serve("--speed", "0", "--scenario", str(world))
    try:
        host, port = parse_address(where)
        with RemoteBus(host, port) as bus:
            board = Board(bus)
            assert board.complete(board.goto, 200, -300, timeout_s=20) is Outcome.SHOCK
            assert bus.truth()[1] == pytest.approx(-675, abs=2)
    finally:
        proc.terminate()
        proc.wait(10)
    (tmp_path / "orders.txt").write_text("goto 0 0\n")
    r = _asserv("sim", "serve", "--scenario", str(tmp_path / "orders.txt"))
    assert r.returncode == 2 and "orders.txt:1: 'goto' is a bus command" in r.stderr


def test_cli_bad_server_arguments_exit_2() -> None:
    r = _asserv("sim", "serve", "--speed", "-3")
    assert r.returncode == 2 and "--speed" in r.stderr and "Traceback" not in r.stderr
    r = _asserv("sim", "serve", "--start", "5000", "0", "0", "--port", "0")
    assert r.returncode == 2 and "off the table" in r.stderr
    r = _asserv("--sim", "localhost:notaport", "status")
    assert r.returncode == 2 and "port" in r.stderr
    r = _asserv("--sim", "127.0.0.1:1", "status")
    assert r.returncode == 1 and "asserv sim serve" in r.stderr
