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
    for bad in ("rdwr", "rdwr x02:00", "rdwr w02:0g", "sleep -1", "sleep x", "SLEEP 1e999"):
        with pytest.raises(OSError) as e:
            bus.request(bad)
        assert e.value.errno == errno.EINVAL  # a request of the protocol: the connection goes on
    assert bus.request("time")
    with pytest.raises(OSError) as e:
        bus.request("nonsense")
    assert e.value.errno == errno.EPROTO and "not a request of asserv-sim" in str(e.value)
    with pytest.raises(OSError, match="closed the connection"):
        bus.request("time")  # dropped at its first line that is not of the protocol
    bus.close()
    with pytest.raises(OSError) as e:
        bus.i2c_rdwr(i2c_msg.read(2, 1))
    assert e.value.errno == errno.EBADF


class _Recorder:
    """A bus that records each transaction as the server's ``rdwr`` line, then passes it on."""

    def __init__(self, bus: object) -> None:
        self.bus, self.lines = bus, []  # type: ignore[var-annotated]

    def i2c_rdwr(self, *msgs: i2c_msg) -> None:
        ops = [
            (m.addr, None, m.len) if m.flags & 1 else (m.addr, bytes(m), 0)  # type: ignore[attr-defined]
            for m in msgs
        ]
        self.lines.append(encode_rdwr(ops))
        self.bus.i2c_rdwr(*msgs)  # type: ignore[attr-defined]


def _goto_lines() -> list[str]:
    """The rdwr lines of a GOTO (400, -600), as Board sends them."""
    local = Simulator(record=False)
    rec = _Recorder(local.bus)
    Board(rec).goto(400, -600)
    assert rec.lines
    return list(rec.lines)


def _talk(address: tuple[str, int], data: bytes) -> list[str]:
    """Send ``data`` on a fresh connection; the reply lines until the server closes it."""
    import socket

    with socket.create_connection(address, timeout=10) as s:
        s.sendall(data)
        got = b""
        while chunk := s.recv(65536):
            got += chunk
    return got.decode("ascii").splitlines()


def test_a_post_to_the_server_runs_nothing() -> None:
    """A web page's form POSTed to the server: its body lines (hello, a GOTO) are never run,
    and the connection ends at the request line, with a line in the server's log."""
    sim = Simulator(record=False)
    logged: list[str] = []
    lines = ["hello", *_goto_lines(), "sleep 1"]
    body = "".join(line + "\n" for line in lines)
    post = (
        "POST / HTTP/1.1\r\nHost: 127.0.0.1\r\nContent-Type: text/plain\r\n"
        f"Content-Length: {len(body)}\r\n\r\n{body}"
    )
    with SimServer(sim, "127.0.0.1", 0, speed=0, log=logged.append) as server:
        replies = _talk(server.address, post.encode())
        assert replies == [
            "err 71 'POST' is not a request of asserv-sim"
            " (hello, time, sleep, truth, obstacles, lidar, rdwr)"
        ]
        # In lockstep the bytes of a transaction move the simulated time: none ran.
        assert sim.time_s == 0
        # The same lines on a connection of the protocol do run: the robot drives.
        replies = _talk(server.address, body.encode() + b"quit\n")
        assert len(replies) == len(lines) + 1 and replies[-1].startswith("err 71 'quit'")
        assert all(r.startswith("ok") for r in replies[:-1]), replies
        assert sim.true_pose().x_mm > 0.5
    assert len(logged) == 2
    assert logged[0].startswith("closed the connection of 127.0.0.1:") and "'POST'" in logged[0]


def test_the_first_request_must_be_hello() -> None:
    sim = Simulator(record=False)
    logged: list[str] = []
    with SimServer(sim, "127.0.0.1", 0, speed=0, log=logged.append) as server:
        replies = _talk(server.address, ("".join(f"{x}\n" for x in _goto_lines())).encode())
        assert replies == ["err 71 the first request must be hello"]
        assert _talk(server.address, b"sleep 1\nhello\n") == [
            "err 71 the first request must be hello"
        ]
        assert _talk(server.address, b"\n") == [
            "err 71 an empty line is not a request of asserv-sim"
        ]
        assert _talk(server.address, b"hello\n\xff\n")[1].startswith("err 71 a line that is not")
        long = _talk(server.address, b"hello\nrdwr " + b"w02:00 " * 2000 + b"\n")
        assert long[1].startswith("err 71 a line longer than 8192 bytes")
    assert sim.time_s == 0
    assert len(logged) == 5 and all("closed the connection" in x for x in logged)


#: Lines of each kind: requests of the protocol (with the simulated seconds each one moves in
#: lockstep), requests whose arguments are wrong, lines from other protocols.
_GOOD = st.sampled_from(
    [("time", 0.0), ("truth", 0.0), ("obstacles", 0.0), ("hello", 0.0), ("sleep 0.002", 0.002)]
)
_BAD_ARGS = st.sampled_from(["sleep", "sleep x", "sleep -1", "rdwr", "rdwr zz", "TIME 3"])
_WORDS = ("hello", "time", "sleep", "truth", "obstacles", "rdwr")
_FOREIGN = st.one_of(
    st.sampled_from(["GET / HTTP/1.1", "POST /x HTTP/1.0", "Host: 127.0.0.1", "", "  ", "\t"]),
    st.text(st.characters(codec="ascii", exclude_characters="\r\n"), max_size=30).filter(
        lambda t: not t.split() or t.split()[0].lower() not in _WORDS
    ),
)
_LINE = st.one_of(
    _GOOD.map(lambda g: ("good", *g)),
    _BAD_ARGS.map(lambda b: ("bad", b, 0.0)),
    _FOREIGN.map(lambda f: ("foreign", f, 0.0)),
)


@given(st.lists(_LINE, max_size=12))
@settings(max_examples=80, deadline=None)
def test_property_nothing_runs_after_a_line_of_another_protocol(
    lines: list[tuple[str, str, float]],
) -> None:
    """Any sequence of lines: one reply per line up to the first line that is not a request
    (or the first request before hello), then the connection ends; only the requests before it
    ran (the simulated time moved by their sleeps only)."""
    import io

    sim = Simulator(record=False)
    server = SimServer(sim, "127.0.0.1", 0, speed=0, log=lambda _: None)  # never started
    try:
        data = "".join(text + "\n" for _, text, _ in lines).encode()
        out = io.BytesIO()
        server._serve_client(io.BytesIO(data), out)
    finally:
        server._tcp.server_close()
    replies = out.getvalue().decode().splitlines()
    expected_time, greeted, n = 0.0, False, len(lines)
    for i, (kind, text, dt) in enumerate(lines):
        if kind == "foreign" or not (greeted or text == "hello"):
            n = i + 1
            assert replies[i].startswith("err 71 "), (replies, lines)
            break
        greeted = True
        assert replies[i].startswith("ok" if kind == "good" else "err 22 "), (replies[i], text)
        expected_time += dt
    assert len(replies) == n
    assert sim.time_s == pytest.approx(expected_time, abs=1e-9)


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


def test_serving_beyond_loopback_says_so() -> None:
    r = _asserv("sim", "serve", "--host", "0.0.0.0", "--port", "0", "--duration", "0.2")
    assert r.returncode == 0, r.stderr
    assert "0.0.0.0 is not loopback: any machine that reaches this port drives" in r.stderr
    r = _asserv("sim", "serve", "--port", "0", "--duration", "0.2")
    assert r.returncode == 0 and "loopback" not in r.stderr, r.stderr


def test_is_loopback() -> None:
    from asserv.server import is_loopback

    for host in ("127.0.0.1", "127.3.2.1", "::1", "[::1]", "localhost", "LOCALHOST"):
        assert is_loopback(host), host
    for host in ("0.0.0.0", "::", "192.168.1.5", "pi.local", "localhost.evil.example", ""):
        assert not is_loopback(host), host
