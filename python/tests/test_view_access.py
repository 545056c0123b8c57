"""Who may drive the robot through asserv view (issue 33; docs/view.md, "What is protected"):
only the page of this run (its Origin), only with this run's token, a board only with
--control; every bad message is logged and changes nothing."""

from __future__ import annotations

import asyncio
import json
import math
import os
import subprocess
import sys
import time
from collections.abc import Callable, Iterator
from typing import Any

import numpy as np
import pytest
from hypothesis import example, given, settings
from hypothesis import strategies as st
from websockets.asyncio.client import connect
from websockets.exceptions import ConnectionClosed, InvalidStatus

from asserv import cli, view
from asserv.driver import Board
from asserv.server import SimServer
from asserv.sim import Simulator


class Served:
    """A view on a source, in a thread, with its log lines kept."""

    def __init__(self, source: view.Source, host: str = "127.0.0.1") -> None:
        self.log: list[str] = []
        self.srv = view.ViewServer(source, host, 0, log=self.log.append)
        self.srv.start_thread()
        self.source = source

    def ws(self, token: str | None = "") -> str:
        """The stream's address: with this run's token (""), none (None), or another."""
        base = f"ws://127.0.0.1:{self.srv.port}/ws"
        token = self.srv.token if token == "" else token
        return base if token is None else f"{base}?token={token}"


@pytest.fixture
def served() -> Iterator[Callable[..., Served]]:
    made: list[Served] = []

    def make(source: view.Source | None = None, host: str = "127.0.0.1") -> Served:
        s = Served(source if source is not None else view.SimSource(), host)
        made.append(s)
        return s

    yield make
    for s in made:
        s.srv.stop()


async def _session(
    url: str, sends: list[Any], origin: str | None = None, frames: int = 15
) -> tuple[dict[str, Any], list[str], list[dict[str, Any]]]:
    """Connect, send each message, then read ``frames`` frames: (hello, refusals, row frames)."""
    headers = {"Origin": origin} if origin else None
    refused: list[str] = []
    rows: list[dict[str, Any]] = []
    async with connect(url, additional_headers=headers) as ws:
        hello = json.loads(await ws.recv())
        for m in sends:
            await ws.send(m if isinstance(m, str | bytes) else json.dumps(m))
        while len(rows) < frames:
            msg = json.loads(await asyncio.wait_for(ws.recv(), 5))
            if msg["type"] == "refused":
                refused.append(msg["why"])
            else:
                rows.append(msg)
    return hello, refused, rows


GOTO = {"type": "goto", "x": 500, "y": 300}


def _untouched(src: view.Source) -> None:
    """Nothing that a command changes has changed."""
    assert src.target is None and src.outcome.orders == 0
    assert src.speed == 1 and not src.paused


def test_the_reproduction_a_foreign_origin_is_refused(served: Callable[..., Served]) -> None:
    """The issue's reproduction: a client with Origin http://evil.example sends a GOTO. It is
    refused at the handshake, token or not, with a line in the log; the view took nothing."""
    s = served()
    for token in (None, "", "wrong"):
        with pytest.raises(InvalidStatus) as e:
            asyncio.run(_session(s.ws(token), [GOTO], origin="http://evil.example"))
        assert e.value.response.status_code == 403
    time.sleep(0.2)
    _untouched(s.source)
    assert len(s.log) == 3, s.log
    for line in s.log:
        assert "refused a connection from 127.0.0.1:" in line
        assert "with Origin http://evil.example: only the page that this view serves" in line
    # Another port of this machine is another origin too.
    with pytest.raises(InvalidStatus):
        asyncio.run(_session(s.ws(), [], origin=f"http://127.0.0.1:{s.srv.port + 1}"))


@pytest.mark.parametrize("name", ["127.0.0.1", "localhost", "[::1]"])
def test_the_pages_own_origin_drives(served: Callable[..., Served], name: str) -> None:
    s = served()
    origin = f"http://{name}:{s.srv.port}"
    hello, refused, _ = asyncio.run(_session(s.ws(), [GOTO], origin=origin))
    assert hello["access"]["drive"] and not refused
    assert s.source.target == (500.0, 300.0)


def test_the_page_at_another_loopback_address_drives(served: Callable[..., Served]) -> None:
    """--host 127.0.0.2 is loopback too: the page opened at the address printed connects and
    drives (its Origin is that address), and a foreign Origin is still refused."""
    s = served(host="127.0.0.2")
    assert s.srv.loopback and s.srv.url.startswith(f"http://127.0.0.2:{s.srv.port}/?token=")
    origin = f"http://127.0.0.2:{s.srv.port}"
    hello, refused, _ = asyncio.run(_session(s.srv.ws_url, [GOTO], origin=origin))
    assert hello["access"]["drive"] and not refused, s.log
    assert s.source.target == (500.0, 300.0)
    with pytest.raises(InvalidStatus):
        asyncio.run(_session(s.srv.ws_url, [GOTO], origin="http://evil.example"))


@pytest.mark.parametrize("token", [None, "wrong", "x" * 300])
def test_a_command_without_the_token_is_refused(
    served: Callable[..., Served], token: str | None
) -> None:
    """Without this run's token a page on loopback watches (the stream flows) and every command
    is refused, logged, and changes nothing."""
    s = served()
    sends = [GOTO, {"type": "pause", "paused": True}, {"type": "speed", "speed": 5}]
    hello, refused, rows = asyncio.run(_session(s.ws(token), sends))
    assert hello["access"]["commands"] is False and hello["access"]["drive"] is False
    assert hello["access"]["mode"].startswith("watching only: ")
    assert len(refused) == 3 and all("commands need this run's token" in r for r in refused)
    assert sum(len(r["rows"]) for r in rows) > 100  # watching: the simulator runs, rows come
    _untouched(s.source)
    assert sum("refused a message" in line for line in s.log) == 3
    assert any("watches without the token" in line for line in s.log)


def test_beyond_loopback_the_token_is_needed_even_to_watch(
    served: Callable[..., Served],
) -> None:
    s = served(host="0.0.0.0")
    assert not s.srv.loopback
    for token in (None, "wrong"):
        with pytest.raises(InvalidStatus) as e:
            asyncio.run(_session(s.ws(token), []))
        assert e.value.response.status_code == 403
    assert sum("refused a connection" in line for line in s.log) == 2
    # The page as a laptop opens it (its Origin: the address it was opened at) drives with it.
    origin = f"http://127.0.0.1:{s.srv.port}"
    hello, refused, _ = asyncio.run(_session(s.ws(), [GOTO], origin=origin))
    assert hello["access"]["drive"] and not refused
    assert s.source.target == (500.0, 300.0)
    with pytest.raises(InvalidStatus):
        asyncio.run(_session(s.ws(), [GOTO], origin="http://evil.example"))
    # A handshake with two Host headers, or two Origin headers: refused, no traceback.
    two_hosts = "Origin: http://evil.example\r\nHost: evil.example"
    two_origins = f"Origin: {origin}\r\nOrigin: {origin}"
    for extra in (two_hosts, two_origins):
        reply = _raw_handshake(s.srv.port, extra, s.srv.token)
        assert reply.startswith(("HTTP/1.1 403", "HTTP/1.1 400")), reply
    assert not any("Traceback" in line for line in s.log)


def _raw_handshake(port: int, headers: str, token: str) -> str:
    """The status line of a WebSocket handshake with these extra header lines."""
    import socket

    request = (
        f"GET /ws?token={token} HTTP/1.1\r\nHost: 127.0.0.1:{port}\r\nUpgrade: websocket\r\n"
        "Connection: Upgrade\r\nSec-WebSocket-Key: dGhlIHNhbXBsZSBub25jZQ==\r\n"
        f"Sec-WebSocket-Version: 13\r\n{headers}\r\n\r\n"
    )
    with socket.create_connection(("127.0.0.1", port), timeout=5) as sock:
        sock.sendall(request.encode())
        return sock.recv(4096).decode("latin-1").split("\r\n")[0]


def test_a_board_is_watched_unless_control(served: Callable[..., Served]) -> None:
    sim = Simulator()
    watched = view.BoardSource(Board(sim.bus), hz=50)
    s = served(watched)
    hello, refused, _ = asyncio.run(_session(s.ws(), [GOTO, {"type": "pause", "paused": True}]))
    assert hello["access"] == {
        "commands": True,
        "drive": False,
        "mode": "watching: the board is watched, not driven: asserv view --control lets clicks"
        " drive it",
    }
    assert refused == [
        "goto: the board is watched, not driven: asserv view --control lets clicks drive it"
    ]
    assert watched.paused  # pause freezes the page's view only: it stays a command
    time.sleep(0.3)
    assert watched.target is None and watched.outcome.orders == 0
    assert math.hypot(sim.true_pose().x_mm, sim.true_pose().y_mm + 850) < 1  # it never moved

    sim = Simulator()
    driven = view.BoardSource(Board(sim.bus), hz=50, control=True)
    s = served(driven)
    hello, refused, _ = asyncio.run(_session(s.ws(), [GOTO]))
    assert hello["access"]["mode"] == "driving the board: a click sends a GOTO" and not refused
    for _ in range(200):
        if driven.target is not None:
            break
        time.sleep(0.01)
    assert driven.target == (500.0, 300.0)


def _true_pose(server: SimServer) -> tuple[float, float]:
    with server.lock:
        pose = server.sim.true_pose()
    return pose.x_mm, pose.y_mm


@pytest.mark.parametrize("control", [False, True])
def test_cli_a_served_board_is_watched_unless_control(control: bool) -> None:
    """``asserv --sim HOST:PORT view`` as a team runs it (the --bus N path builds the same
    BoardSource): without --control it says on stdout and in the hello that it watches, its
    page's GOTO is refused and the served robot stays where it is; with it the GOTO drives."""
    sim = Simulator(record=False)
    with SimServer(sim, "127.0.0.1", 0, speed=4, log=lambda _: None) as server:
        _, port = server.address
        cmd = [sys.executable, "-m", "asserv", "--sim", f"127.0.0.1:{port}", "view", "--port", "0"]
        env = dict(os.environ, PYTHONUNBUFFERED="1")
        proc = subprocess.Popen(
            [*cmd, *(["--control"] if control else [])],
            stdout=subprocess.PIPE,
            stderr=subprocess.PIPE,
            text=True,
            env=env,
        )
        try:
            assert proc.stdout is not None
            url = proc.stdout.readline().split()[3]
            page, _, query = url.partition("?")
            ws = f"{page.replace('http', 'ws', 1)}ws?{query}"
            hello, refused, _ = asyncio.run(_session(ws, [GOTO], frames=15))
            moved = 0.0
            for _ in range(1 if not control else 200):  # driven: it turns, then drives
                x, y = _true_pose(server)  # watched: after 15 frames, 2 s of its time at x4
                moved = math.hypot(x, y + 850)
                if moved > 100:
                    break
                time.sleep(0.05)
        finally:
            proc.terminate()
            proc.wait(10)
            out = proc.stdout.read()  # with the line readline() buffered already
    watched = "the board is watched, not driven: asserv view --control lets clicks drive it"
    if control:
        assert hello["access"]["mode"] == "driving the board: a click sends a GOTO"
        assert not refused and f"asserv view: {watched}" not in out.splitlines()
        assert moved > 100 and math.hypot(x - 500, y - 300) < math.hypot(500, 300 + 850) - 100
    else:
        assert hello["access"]["drive"] is False
        assert hello["access"]["mode"] == f"watching: {watched}"
        assert refused == [f"goto: {watched}"]
        assert f"asserv view: {watched}" in out.splitlines()
        assert moved < 1


def test_a_replay_takes_no_goto() -> None:
    src = view.SimSource()
    src.can_goto = False
    src.kind = "replay"
    srv = view.ViewServer(src, "127.0.0.1", 0, log=lambda _: None)
    access = view._Access("peer", commands=True)
    assert srv.receive(access, json.dumps(GOTO)) == "goto: a replay takes no GOTO"
    assert srv._commands.empty()


# ---- bad messages -------------------------------------------------------------------------------

#: Commands of the page, all valid: a GOTO on the default field (3000 x 2100 mm), pause, speed.
VALID = st.one_of(
    st.builds(
        lambda x, y: {"type": "goto", "x": x, "y": y},
        st.one_of(st.integers(-1500, 1500), st.floats(-1500, 1500)),
        st.one_of(st.integers(-1050, 1050), st.floats(-1050, 1050)),
    ),
    st.builds(lambda p: {"type": "pause", "paused": p}, st.booleans()),
    st.builds(
        lambda v: {"type": "speed", "speed": v},
        st.one_of(st.integers(1, 50), st.floats(1, 50)),
    ),
)

_JSON = st.recursive(
    st.none() | st.booleans() | st.integers() | st.floats(allow_nan=False) | st.text(max_size=8),
    lambda inner: st.lists(inner, max_size=3) | st.dictionaries(st.text(max_size=6), inner),
    max_leaves=6,
)
_NOT_A_NUMBER = st.one_of(
    st.none(), st.booleans(), st.text(max_size=5), st.lists(st.integers(), max_size=2)
)
_OFF = st.one_of(
    st.integers(min_value=1051, max_value=10**300),
    st.integers(max_value=-1051, min_value=-(10**300)),
)


def _with(msg: dict[str, Any], **changes: Any) -> dict[str, Any]:
    return {**msg, **changes}


#: Bad messages that random text seldom draws: each also sent as such (@example).
HARD = [
    '{"type": "speed", "speed": NaN}',
    '{"type": "speed", "speed": Infinity}',
    '{"type": "speed", "speed": true}',  # a bool is an int in Python, not a number here
    '{"type": "goto", "x": 1e999, "y": 0}',
    '{"type": "goto", "x": -Infinity, "y": 0}',
    "[" * 2000 + "]" * 2000,  # nested deeper than Python's default recursion limit
    # ... and deeper than hypothesis's (the stack's depth + 2000, for every thread): as deep
    # as a message may go (RecursionError in Python 3.11)
    "[" * view.MAX_MESSAGE_BYTES,
    '{"type": "goto", "x": ' + "9" * 4000 + ', "y": 0}',  # a number of 4000 digits
    '{"type": "goto", "x": 1, "y": 2',  # cut short
    '{"type": "goto", "x": 1, "y": 2, "type": "pause"}',  # a key twice: its last value
    "x" * 5000,  # longer than a message may be
]

#: Messages that are never a command, each built to break one rule.
INVALID = st.one_of(
    st.binary(max_size=20),  # a binary frame
    st.text(max_size=30).filter(lambda t: not t.lstrip().startswith("{")),  # not an object
    _JSON.filter(lambda v: not isinstance(v, dict)).map(json.dumps),
    st.dictionaries(st.text(max_size=6), _JSON, max_size=3)
    .filter(lambda d: d.get("type") not in ("goto", "pause", "speed"))
    .map(json.dumps),  # an unknown kind
    st.builds(lambda v: {"type": "goto", "x": v, "y": 0}, _NOT_A_NUMBER).map(json.dumps),
    st.builds(lambda v: {"type": "goto", "x": 0, "y": v}, _OFF).map(json.dumps),  # huge
    st.builds(lambda v: {"type": "speed", "speed": v}, _NOT_A_NUMBER).map(json.dumps),
    st.builds(
        lambda v: {"type": "speed", "speed": v},
        st.one_of(st.floats(max_value=0.999), st.floats(min_value=50.001), st.integers(51)),
    ).map(json.dumps),
    st.builds(
        lambda v: {"type": "pause", "paused": v}, st.one_of(st.integers(), st.text(max_size=3))
    ).map(json.dumps),
    VALID.map(lambda m: json.dumps(_with(m, extra=1))),  # a key too many
    VALID.map(lambda m: json.dumps({k: v for k, v in m.items() if k == "type"})),  # too few
    st.sampled_from(HARD),
)


_FIELD = view.SimSource().field
_OUTLINE = view.log.Outline()


class _Stub(view.Source):
    """A source that only keeps the state commands change (a GOTO sets the target)."""

    def goto(self, x_mm: float, y_mm: float) -> None:
        self.target = (x_mm, y_mm)


def _state(src: view.Source) -> tuple[Any, ...]:
    return (src.target, src.paused, src.speed)


@given(
    st.lists(
        st.one_of(VALID.map(lambda m: ("valid", m)), INVALID.map(lambda m: ("bad", m))),
        max_size=view.BURST,  # within the rate (test_a_flood_is_dropped_with_one_line)
    )
)
@example([("bad", m) for m in HARD] + [("valid", GOTO)])
@settings(max_examples=300, deadline=None)
def test_property_bad_messages_change_nothing(messages: list[tuple[str, Any]]) -> None:
    """Any mix of commands and bad messages: each bad one is refused with a log line and
    without an exception, and the view ends as the commands alone leave it."""
    src = _Stub(_FIELD, _OUTLINE)
    logged: list[str] = []
    srv = view.ViewServer(src, "127.0.0.1", 0, log=logged.append)
    access = view._Access("peer", commands=True)
    expected = _state(src)
    for kind, m in messages:
        text = m if isinstance(m, str | bytes) else json.dumps(m)
        why = srv.receive(access, text)
        if kind == "bad":
            assert why, text
        else:
            assert why == "", (why, text)
            t, p, v = expected
            if m["type"] == "goto":
                t = (float(m["x"]), float(m["y"]))
            elif m["type"] == "pause":
                p = m["paused"]
            else:
                v = float(m["speed"])
            expected = (t, p, v)
        while not srv._commands.empty():
            srv._apply(srv._commands.get())
        assert _state(src) == expected
    bad = [m for k, m in messages if k == "bad"]
    assert len(logged) == len(bad)
    assert all(line.startswith("refused a message of peer: ") for line in logged)
    assert all("\n" not in line and len(line) < 300 for line in logged)


@given(st.lists(VALID, max_size=10))
@settings(max_examples=50, deadline=None)
def test_property_commands_without_the_token_change_nothing(messages: list[Any]) -> None:
    src = _Stub(_FIELD, _OUTLINE)
    srv = view.ViewServer(src, "127.0.0.1", 0, log=lambda _: None)
    access = view._Access("peer", commands=False, why="no token")
    for m in messages:
        assert "commands need this run's token" in srv.receive(access, json.dumps(m))
    assert srv._commands.empty()


class _Still(_Stub):
    """A stub whose time stands still: nothing but the commands changes it."""

    def advance(self, dt_s: float) -> np.ndarray:
        return view.log.empty(0)


def _fits(m: Any) -> bool:
    """Under the size that closes the socket (test_a_message_too_long_closes_the_socket)."""
    data = m if isinstance(m, bytes) else (m if isinstance(m, str) else json.dumps(m)).encode()
    return len(data) <= view.MAX_MESSAGE_BYTES


_END = '{"type": "end"}'  # a bad message sent last: once it is refused, all the others were read


@given(
    st.lists(
        st.one_of(
            VALID.map(lambda m: ("valid", m)), INVALID.filter(_fits).map(lambda m: ("bad", m))
        ),
        max_size=view.BURST - 1,
    )
)
@example([("bad", m) for m in HARD if _fits(m)] + [("valid", GOTO)])
@settings(max_examples=40, deadline=None)
def test_property_bad_messages_on_the_socket(messages: list[tuple[str, Any]]) -> None:
    """The same promise through a running view's socket, as a page sends them: one refusal
    answered and one log line per bad message, no error of websockets (no traceback), the
    connection open to the end, and the view as the commands alone leave it."""
    import logging

    errors: list[logging.LogRecord] = []
    handler = logging.Handler(logging.WARNING)
    handler.emit = errors.append  # type: ignore[method-assign]
    logging.getLogger("websockets").addHandler(handler)
    src = _Still(_FIELD, _OUTLINE)
    logged: list[str] = []
    srv = view.ViewServer(src, "127.0.0.1", 0, log=logged.append)
    srv.start_thread()
    expected = _state(src)
    for kind, m in messages:
        if kind == "valid":
            t, p, v = expected
            if m["type"] == "goto":
                t = (float(m["x"]), float(m["y"]))
            elif m["type"] == "pause":
                p = m["paused"]
            else:
                v = float(m["speed"])
            expected = (t, p, v)

    async def talk() -> list[str]:
        refused: list[str] = []
        async with connect(srv.ws_url) as ws:
            await ws.recv()  # the hello
            for _, m in messages:
                await ws.send(m if isinstance(m, str | bytes) else json.dumps(m))
            await ws.send(_END)
            frames = 0
            while frames < 2:  # the second frame after the last refusal applied every command
                msg = json.loads(await asyncio.wait_for(ws.recv(), 5))
                if msg["type"] == "refused":
                    refused.append(msg["why"])
                elif refused[-1:] == ["unknown kind 'end' (goto, pause, speed)"]:
                    frames += 1
        return refused

    try:
        refused = asyncio.run(talk())
    finally:
        srv.stop()
        logging.getLogger("websockets").removeHandler(handler)
    bad = sum(k == "bad" for k, _ in messages)
    assert len(refused) == bad + 1 and all(refused), refused
    assert _state(src) == expected
    assert len(logged) == bad + 1, logged
    assert all(line.startswith("refused a message of 127.0.0.1:") for line in logged), logged
    assert errors == [], [r.getMessage() for r in errors]


def test_a_flood_is_dropped_with_one_line() -> None:
    src = view.SimSource()
    logged: list[str] = []
    srv = view.ViewServer(src, "127.0.0.1", 0, log=logged.append)
    access = view._Access("peer", commands=True)
    taken = sum(
        srv.receive(access, json.dumps({"type": "speed", "speed": 2})) == "" for _ in range(500)
    )
    assert view.BURST <= taken <= view.BURST + 2  # the burst, and what the rate refilled meanwhile
    assert len(logged) == 1 and logged[0].startswith(
        "dropped 1 message(s) of peer: over 10 a second"
    )
    time.sleep(0.25)  # the rate refills: a page that calms down is heard again
    assert srv.receive(access, json.dumps({"type": "speed", "speed": 3})) == ""


def test_a_message_too_long_closes_the_socket(served: Callable[..., Served]) -> None:
    s = served()

    async def send_long() -> None:
        async with connect(s.ws()) as ws:
            await ws.recv()
            await ws.send("x" * (view.MAX_MESSAGE_BYTES + 1))
            while True:
                await asyncio.wait_for(ws.recv(), 5)

    with pytest.raises(ConnectionClosed) as e:
        asyncio.run(send_long())
    assert e.value.rcvd is not None and e.value.rcvd.code == 1009
    time.sleep(0.1)
    assert any("closed the connection of 127.0.0.1:" in line for line in s.log), s.log
    _untouched(s.source)


# ---- the command line ---------------------------------------------------------------------------


@pytest.mark.parametrize(
    "argv", [["view", "--control"], ["view", "--replay", "x.mcap", "--control"]]
)
def test_control_needs_a_board(argv: list[str], capsys: pytest.CaptureFixture[str]) -> None:
    assert cli.main(argv) == 2
    err = capsys.readouterr().err
    assert (
        err.startswith("asserv view: --control lets the page drive a board")
        and "Traceback" not in err
    )


def test_another_host_than_loopback_says_control_is_exposed() -> None:
    env = dict(os.environ, PYTHONUNBUFFERED="1")
    cmd = [sys.executable, "-m", "asserv", "view", "--host", "0.0.0.0", "--port", "0"]
    proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=env)
    try:
        assert proc.stdout is not None and proc.stderr is not None
        line = proc.stdout.readline()
        assert line.startswith("asserv view: open http://0.0.0.0:") and "/?token=" in line, line
        token = line.split("?token=")[1].split()[0]
        assert len(token) >= 32
        warning = proc.stderr.readline()
        assert warning.startswith("asserv view: 0.0.0.0 is not loopback: the robot's control is")
        assert "needs the token" in warning
    finally:
        proc.terminate()
        proc.wait(10)


def test_each_run_has_its_own_token() -> None:
    tokens = {view.ViewServer(view.SimSource(), "127.0.0.1", 0).token for _ in range(5)}
    assert len(tokens) == 5 and all(len(t) >= 32 for t in tokens)


def test_at_most_max_clients_pages(served: Callable[..., Served]) -> None:
    s = served()

    async def many() -> int:
        opened = []
        try:
            for _ in range(view.MAX_CLIENTS):
                ws = await connect(s.ws())
                opened.append(ws)
                await ws.recv()  # the hello: it is one of the clients now
            with pytest.raises(InvalidStatus) as e:
                await connect(s.ws())
            return e.value.response.status_code
        finally:
            for ws in opened:
                await ws.close()

    assert asyncio.run(many()) == 503
    assert s.log[-1].endswith(f"{view.MAX_CLIENTS} pages are open already")
