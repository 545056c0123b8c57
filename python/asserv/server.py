"""``asserv sim serve``: the simulated board behind a TCP socket, in real time or faster.

Other processes reach the simulated bus through it: a strategy (``Board(RemoteBus(host,
port))``), the CLI (``asserv --sim HOST:PORT status``), a live view. The protocol, one ASCII
line per request and one per reply (docs/simulator.md, "The simulator server"):

    hello                          ok asserv-sim 1 SPEED ADDRESS
    time                           ok T                     (simulated seconds)
    sleep S                        ok T                     (after S simulated seconds)
    truth                          ok T X Y HEADING         (the true pose, for a live view)
    obstacles                      ok X,Y X,Y ...           (baskets, obstacles, opponents)
    lidar                          ok T N B,R B,R ...       (the last lidar scan: asserv.lidar)
    rdwr w02:0400c80064 r02:1      ok 05                    (one I2C_RDWR transaction)
    (anything wrong)               err ERRNO TEXT

A connection starts with ``hello``. Its first line that is not a request of this protocol (an
HTTP request line, an unknown word, an empty, overlong or non-ASCII line) gets ``err 71 ...``
(EPROTO) and ends the connection, with a line on stderr: a web page that POSTs to this port
(its body lines ``hello``, ``rdwr ...``) runs nothing. A request with wrong arguments (``sleep
x``) is ``err 22`` and the connection goes on.

``rdwr`` carries the messages of one combined transaction, ``w<addr>:<hex bytes>`` for a write
and ``r<addr>:<count>`` for a read; the reply gives the bytes of each read, in hex, ``-`` for an
empty one. A NACK or a closed bus is ``err`` with the errno the local VirtualBus raises (6,
ENXIO), so ``RemoteBus`` raises the same OSError. Bytes on the bus take their simulated time, as
on ``Simulator.bus``; the transaction is whole (the bus lock of ``asserv.driver.bus_lock``).

Time: with ``speed`` > 0 a pacing thread runs the simulation at ``speed`` times the wall clock;
``sleep`` waits until the simulated time has moved on by S. With ``speed`` 0 (lockstep) the
simulated time moves only when a client sleeps (and by the bytes on the bus): the server then
behaves exactly as ``Simulator.bus`` in the client's process, as fast as the machine goes.
"""

from __future__ import annotations

import argparse
import errno
import ipaddress
import math
import os
import socket
import socketserver
import sys
import threading
import time
from collections.abc import Callable, Sequence
from pathlib import Path
from types import TracebackType
from typing import TYPE_CHECKING, Any

from smbus2 import i2c_msg

from .bus import I2C_M_RD, I2C_RDWR_MAX_MSGS
from .driver import bus_lock

if TYPE_CHECKING:
    from .lidar import LidarScan
    from .sim import Simulator

__all__ = [
    "PROTOCOL_VERSION",
    "RemoteBus",
    "RemoteClock",
    "SimServer",
    "is_loopback",
    "parse_address",
]

PROTOCOL_VERSION = 1
DEFAULT_PORT = 5021
_SLICE_S = 0.002  # simulated seconds run under the lock at a time
_MAX_LINE = 8192
_MAX_SLEEP_S = 3600.0


class ProtocolError(ValueError):
    """A malformed request or reply line."""


# Transactions as text -----------------------------------------------------------------------


def encode_rdwr(ops: Sequence[tuple[int, bytes | None, int]]) -> str:
    """``rdwr`` request line (without the newline) for ops (address, bytes or None, count)."""
    parts = ["rdwr"]
    for address, data, n in ops:
        if data is None:
            parts.append(f"r{address:02x}:{n}")
        else:
            parts.append(f"w{address:02x}:{data.hex()}")
    return " ".join(parts)


def decode_rdwr(words: Sequence[str]) -> list[tuple[int, bytes | None, int]]:
    """The ops of an ``rdwr`` request's words (after ``rdwr``); ProtocolError if malformed."""
    if not 1 <= len(words) <= I2C_RDWR_MAX_MSGS:
        raise ProtocolError(f"rdwr takes 1..{I2C_RDWR_MAX_MSGS} messages, got {len(words)}")
    ops: list[tuple[int, bytes | None, int]] = []
    for w in words:
        kind, sep, rest = w[:1], w[3:4], w[4:]
        try:
            address = int(w[1:3], 16)
        except ValueError:
            raise ProtocolError(f"{w!r}: expected w<addr>:<hex> or r<addr>:<count>") from None
        if kind not in ("w", "r") or sep != ":" or not 0 <= address <= 0x7F:
            raise ProtocolError(f"{w!r}: expected w<addr>:<hex> or r<addr>:<count>")
        try:
            if kind == "w":
                ops.append((address, bytes.fromhex(rest), 0))
            else:
                n = int(rest, 10)
                if not 0 <= n <= 8192:
                    raise ValueError
                ops.append((address, None, n))
        except ValueError:
            raise ProtocolError(f"{w!r}: bad bytes or count") from None
    return ops


def _log_stderr(line: str) -> None:
    print(f"asserv sim serve: {line}", file=sys.stderr, flush=True)


# The server ---------------------------------------------------------------------------------


REQUESTS = ("hello", "time", "sleep", "truth", "obstacles", "lidar", "rdwr")


def _not_a_request(raw: bytes, greeted: bool) -> str:
    """Why the raw line ``raw`` (its newline included) ends the connection, or "" if it is a
    request of the protocol (whose arguments may still be wrong: that is an ``err`` reply)."""
    if len(raw) > _MAX_LINE:
        return f"a line longer than {_MAX_LINE} bytes is not a request of asserv-sim"
    try:
        words = raw.decode("ascii").split()
    except UnicodeDecodeError:
        return "a line that is not ASCII is not a request of asserv-sim"
    if not words:
        return "an empty line is not a request of asserv-sim"
    if words[0].lower() not in REQUESTS:
        shown = words[0] if len(words[0]) <= 20 else words[0][:20] + "..."
        return f"{shown!r} is not a request of asserv-sim ({', '.join(REQUESTS)})"
    if not greeted and words[0].lower() != "hello":
        return "the first request must be hello"
    return ""


class SimServer:
    """Serves ``sim``'s bus and clock on ``host``:``port`` (port 0: any free port, see
    ``address``). ``speed``: simulated seconds per wall second, or 0 for lockstep. ``log``
    takes a line for each connection that the server closes (by default: stderr)."""

    def __init__(
        self,
        sim: Simulator,
        host: str = "127.0.0.1",
        port: int = 0,
        speed: float = 1.0,
        log: Callable[[str], None] | None = None,
    ) -> None:
        if not (speed == 0 or 0 < speed <= 1e6) or math.isnan(speed):
            raise ValueError(f"speed must be 0 (lockstep) or within 0..1e6, not {speed}")
        self.sim = sim
        self.speed = float(speed)
        self.log = log or _log_stderr
        self.lock = bus_lock(sim.bus)
        self._moved = threading.Condition(threading.Lock())
        self._stop = threading.Event()
        server = self

        class Handler(socketserver.StreamRequestHandler):
            def handle(self) -> None:
                host, port = self.client_address[:2]
                server._serve_client(self.rfile, self.wfile, f"{host}:{port}")

        class TCP(socketserver.ThreadingTCPServer):
            daemon_threads = True
            allow_reuse_address = True

        self._tcp = TCP((host, port), Handler)
        self._threads: list[threading.Thread] = []

    @property
    def address(self) -> tuple[str, int]:
        host, port = self._tcp.server_address[:2]
        return str(host), int(port)

    def start(self) -> SimServer:
        """Serve (and pace) in background threads."""
        t = threading.Thread(
            target=self._tcp.serve_forever, args=(0.05,), name="asserv-sim-serve", daemon=True
        )
        t.start()
        self._threads.append(t)
        if self.speed > 0:
            p = threading.Thread(target=self._pace, name="asserv-sim-pace", daemon=True)
            p.start()
            self._threads.append(p)
        return self

    def close(self) -> None:
        self._stop.set()
        self._tcp.shutdown()
        self._tcp.server_close()
        with self._moved:
            self._moved.notify_all()
        for t in self._threads:
            t.join(5)

    def __enter__(self) -> SimServer:
        return self.start()

    def __exit__(
        self,
        exc_type: type[BaseException] | None,
        exc: BaseException | None,
        tb: TracebackType | None,
    ) -> None:
        self.close()

    # Time.
    def _advance(self, seconds: float) -> None:
        """Run the simulation for ``seconds``, in slices under the bus lock."""
        target = self.sim.time_s + seconds
        while not self._stop.is_set():
            with self.lock:
                left = target - self.sim.time_s
                if left <= 1e-9:
                    break
                self.sim.advance(min(left, _SLICE_S))
            with self._moved:
                self._moved.notify_all()

    def _pace(self) -> None:
        wall0, sim0 = time.monotonic(), self.sim.time_s
        while not self._stop.is_set():
            goal = sim0 + (time.monotonic() - wall0) * self.speed
            behind = goal - self.sim.time_s
            if behind > 1e-4:
                with self.lock:
                    self.sim.advance(min(behind, _SLICE_S))
                with self._moved:
                    self._moved.notify_all()
            else:
                self._stop.wait(min(0.001, (1e-4 - behind) / self.speed + 1e-4))

    def _sleep(self, seconds: float) -> None:
        if self.speed == 0:
            self._advance(seconds)
            return
        target = self.sim.time_s + seconds
        with self._moved:
            while self.sim.time_s < target - 1e-9 and not self._stop.is_set():
                self._moved.wait(0.1)

    # Requests.
    def _serve_client(self, rfile: Any, wfile: Any, peer: str = "a client") -> None:
        """Answer one connection's requests until it closes. The first request must be
        ``hello``, and the first line that is not a request of the protocol (an HTTP verb, an
        unknown word, an empty or overlong line) ends the connection: so a browser's POST to this
        port, whose body lines would otherwise run as requests, runs nothing."""
        greeted = False
        while not self._stop.is_set():
            try:
                raw = rfile.readline(_MAX_LINE + 1)
            except OSError:
                return
            if not raw:
                return
            refused = _not_a_request(raw, greeted)
            reply = f"err {errno.EPROTO} {refused}" if refused else self.handle_line(raw.decode())
            try:
                wfile.write(reply.encode("ascii") + b"\n")
                wfile.flush()
            except OSError:
                return
            if refused:
                self.log(f"closed the connection of {peer}: {refused}")
                return
            greeted = True

    def handle_line(self, line: str) -> str:
        """The reply line to one request line (without newlines)."""
        words = line.split()
        if not words:
            return f"err {errno.EINVAL} empty request"
        cmd = words[0].lower()
        try:
            if cmd == "hello":
                return f"ok asserv-sim {PROTOCOL_VERSION} {self.speed:g} {self.sim.address}"
            if cmd == "time":
                return f"ok {self.sim.time_s:.9f}"
            if cmd == "sleep":
                if len(words) != 2:
                    raise ProtocolError("sleep takes one number of seconds")
                try:
                    s = float(words[1])
                except ValueError:
                    raise ProtocolError(f"sleep: {words[1]!r} is not a number") from None
                if not 0 <= s <= _MAX_SLEEP_S:
                    raise ProtocolError(f"sleep: {words[1]} is not within 0..{_MAX_SLEEP_S:g}")
                self._sleep(s)
                return f"ok {self.sim.time_s:.9f}"
            if cmd == "truth":
                with self.lock:
                    t, pose = self.sim.time_s, self.sim.true_pose()
                return f"ok {t:.9f} {pose.x_mm:.3f} {pose.y_mm:.3f} {pose.heading_deg:.3f}"
            if cmd == "obstacles":
                with self.lock:
                    where = self.sim.obstacles()
                return "ok" + "".join(f" {x:.3f},{y:.3f}" for x, y in where)
            if cmd == "lidar":
                with self.lock:
                    scan = self.sim.lidar()
                hits = "".join(f" {h.bearing_deg:g},{h.range_mm:.1f}" for h in scan.hits)
                return f"ok {scan.t_s:.9f} {scan.number}{hits}"
            if cmd == "rdwr":
                ops = decode_rdwr(words[1:])
                with self.lock:
                    try:
                        reads = self.sim.bus._transfer(ops)
                    except OSError as e:
                        return f"err {e.errno or errno.EIO} {e.strerror or e}"
                return "ok" + "".join(" " + (r.hex() or "-") for r in reads)
            raise ProtocolError(f"unknown request {words[0]!r} ({', '.join(REQUESTS)})")
        except ProtocolError as e:
            return f"err {errno.EINVAL} {e}"


# The client ---------------------------------------------------------------------------------


class RemoteBus:
    """An ``smbus2.SMBus`` look-alike on ``asserv sim serve`` at ``host``:``port``: what
    ``Board`` needs (``i2c_rdwr``), and the server's clock as ``clock``. Thread-safe: one
    request at a time on the connection."""

    def __init__(self, host: str = "127.0.0.1", port: int = DEFAULT_PORT, timeout_s: float = 10):
        self.host, self.port = host, port
        try:
            self._sock = socket.create_connection((host, port), timeout=timeout_s)
        except OSError as e:
            raise OSError(
                e.errno or errno.ECONNREFUSED,
                f"cannot reach the simulator server at {host}:{port}: {e.strerror or e}"
                " (is `asserv sim serve` running?)",
            ) from e
        self._sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
        self._file = self._sock.makefile("rwb")
        self._lock = threading.Lock()
        self.closed = False
        words = self.request("hello").split()
        if len(words) < 4 or words[0] != "asserv-sim" or words[1] != str(PROTOCOL_VERSION):
            self.close()
            raise OSError(errno.EPROTO, f"{host}:{port} is not an asserv simulator server")
        self.speed = float(words[2])
        self.clock = RemoteClock(self)

    def request(self, line: str) -> str:
        """Send one request line, return the reply's text after ``ok``; OSError on ``err``."""
        with self._lock:
            if self.closed:
                raise OSError(errno.EBADF, f"{os.strerror(errno.EBADF)}: the bus is closed")
            try:
                self._file.write(line.encode("ascii") + b"\n")
                self._file.flush()
                reply = self._file.readline(_MAX_LINE + 1).decode("ascii", "replace").strip()
            except OSError as e:
                raise OSError(errno.EIO, f"the simulator server connection failed: {e}") from e
        if not reply:
            raise OSError(errno.EIO, "the simulator server closed the connection")
        status, _, rest = reply.partition(" ")
        if status == "ok":
            return rest
        code, _, text = rest.partition(" ")
        try:
            number = int(code)
        except ValueError:
            number = errno.EPROTO
        raise OSError(number, text or reply)

    def i2c_rdwr(self, *msgs: i2c_msg) -> None:
        """One combined transaction on the server's bus; reads are filled in place."""
        import ctypes

        if not msgs or len(msgs) > I2C_RDWR_MAX_MSGS:
            raise OSError(errno.EINVAL, f"i2c_rdwr takes 1..{I2C_RDWR_MAX_MSGS} messages")
        ops: list[tuple[int, bytes | None, int]] = []
        for m in msgs:
            if int(m.flags) & I2C_M_RD:
                ops.append((int(m.addr), None, int(m.len)))
            else:
                ops.append((int(m.addr), ctypes.string_at(m.buf, int(m.len)), 0))
        words = self.request(encode_rdwr(ops)).split()
        reads = [m for m in msgs if int(m.flags) & I2C_M_RD]
        if len(words) != len(reads):
            raise OSError(errno.EPROTO, f"the server answered {len(words)} reads for {len(reads)}")
        for m, w in zip(reads, words, strict=True):
            data = b"" if w == "-" else bytes.fromhex(w)
            if len(data) != int(m.len):
                raise OSError(errno.EPROTO, "the server answered a read of the wrong length")
            ctypes.memmove(m.buf, data, len(data))

    def truth(self) -> tuple[float, float, float, float]:
        """(simulated s, x mm, y mm, heading deg): where the simulated robot truly is."""
        t, x, y, h = (float(w) for w in self.request("truth").split())
        return t, x, y, h

    def obstacles(self) -> list[tuple[float, float]]:
        """Where the field's baskets, obstacles and opponents are now, mm."""
        out = []
        for w in self.request("obstacles").split():
            x, _, y = w.partition(",")
            out.append((float(x), float(y)))
        return out

    def lidar(self) -> LidarScan:
        """The simulated robot's last lidar scan (``Simulator.lidar``)."""
        from .lidar import LidarHit, LidarScan

        words = self.request("lidar").split()
        hits = []
        for w in words[2:]:
            b, _, r = w.partition(",")
            hits.append(LidarHit(float(b), float(r)))
        return LidarScan(float(words[0]), int(words[1]), tuple(hits))

    def close(self) -> None:
        if self.closed:
            return
        self.closed = True
        try:
            self._file.close()
            self._sock.close()
        except OSError:
            pass

    def __enter__(self) -> RemoteBus:
        return self

    def __exit__(
        self,
        exc_type: type[BaseException] | None,
        exc: BaseException | None,
        tb: TracebackType | None,
    ) -> None:
        self.close()

    def __repr__(self) -> str:
        return f"RemoteBus({self.host}:{self.port}{', closed' if self.closed else ''})"


class RemoteClock:
    """The server's simulated clock: ``Board.now()`` and ``Board.sleep()`` on a RemoteBus."""

    drives_simulation = False  # the server runs the simulation, not this process

    def __init__(self, bus: RemoteBus) -> None:
        self.bus = bus

    def monotonic(self) -> float:
        return float(self.bus.request("time"))

    def sleep(self, seconds: float) -> None:
        """In requests of at most 10 ms, so that other threads' transactions go in between."""
        if not seconds >= 0 or seconds == math.inf:
            raise ValueError(f"sleep: seconds must be finite and >= 0, not {seconds}")
        now = self.monotonic()
        target = now + seconds
        while (left := target - now) > 1e-9:
            now = float(self.bus.request(f"sleep {min(left, 0.01):.9f}"))


def is_loopback(host: str) -> bool:
    """Whether ``host`` (an address or ``localhost``) is only reachable from this machine."""
    if host.lower() == "localhost":
        return True
    try:
        return ipaddress.ip_address(host.strip("[]")).is_loopback
    except ValueError:
        return False  # another name: it may resolve to any address


def parse_address(text: str, default_port: int = DEFAULT_PORT) -> tuple[str, int]:
    """``HOST:PORT``, ``HOST`` or ``:PORT`` as (host, port); ValueError says what is wrong."""
    host, sep, port_text = text.rpartition(":")
    if not sep:
        host, port_text = text, str(default_port)
    host = host or "127.0.0.1"
    try:
        port = int(port_text, 10)
    except ValueError:
        raise ValueError(f"{text!r}: the port {port_text!r} is not a number (HOST:PORT)") from None
    if not 0 < port < 65536:
        raise ValueError(f"{text!r}: the port must be 1..65535")
    return host, port


# asserv sim serve ---------------------------------------------------------------------------


def register(simsub: Any) -> None:
    """Add ``serve`` to the ``asserv sim`` subcommands."""
    p = simsub.add_parser(
        "serve",
        help="serve the simulated board over TCP (strategy, CLI --sim, live view)",
        description="Run the simulated board in real time (or --speed times faster, or in"
        " lockstep with --speed 0) and let other processes reach its I2C bus over TCP"
        " (docs/simulator.md, 'The simulator server').",
    )
    p.add_argument("--host", default="127.0.0.1", help="address to bind (default 127.0.0.1)")
    p.add_argument("--port", default=str(DEFAULT_PORT), help=f"TCP port (default {DEFAULT_PORT})")
    p.add_argument("--speed", default="1", help="simulated s per wall s; 0: lockstep (default 1)")
    p.add_argument("--seed", default="0", help="the simulated robot's seed (default 0)")
    p.add_argument("--randomize", action="store_true", help="a robot off the shelf from the seed")
    p.add_argument("--field", default=None, help="field name or file (default field/default)")
    p.add_argument(
        "--start", nargs=3, metavar=("X_MM", "Y_MM", "DEG"), help="start pose of the robot"
    )
    p.add_argument(
        "--scenario",
        default=None,
        help="a scenario file without bus commands: robot, field, start, opponents, 'at' events",
    )
    p.add_argument("--duration", default=None, help="stop after this many wall seconds")
    p.add_argument(
        "--firmware",
        default=None,
        metavar="FIRMWARE",
        help="the STM32 application (ELF or .bin) the board runs at first, for `asserv flash`"
        " (default: a stand-in of version 1)",
    )
    p.set_defaults(func=serve_main)


def serve_main(args: argparse.Namespace) -> int:
    prog = "asserv sim serve"

    def bad(message: str) -> int:
        print(f"{prog}: {message}", file=sys.stderr)
        return 2

    try:
        speed = float(args.speed)
    except ValueError:
        return bad(f"--speed {args.speed!r} is not a number")
    if not (speed == 0 or 0 < speed <= 1e6):
        return bad(f"--speed {args.speed!r} must be 0 (lockstep) or within 0..1e6")
    try:
        port = int(args.port, 10)
    except ValueError:
        return bad(f"--port {args.port!r} is not an integer")
    try:
        seed = int(args.seed, 0)
    except ValueError:
        return bad(f"--seed {args.seed!r} is not an integer")
    if not 0 <= port < 65536:
        return bad(f"--port {port} is not a TCP port (0..65535; 0: any free port)")
    if not 0 <= seed < 2**64:
        return bad(f"--seed {seed} is not within 0..2^64-1")
    duration = None
    if args.duration is not None:
        try:
            duration = float(args.duration)
        except ValueError:
            return bad(f"--duration {args.duration!r} is not a number")
        if not 0 < duration < 1e9:
            return bad(f"--duration {args.duration!r} must be > 0")
    config: dict[str, Any] = {}
    if args.start is not None:
        try:
            x, y, h = (float(v) for v in args.start)
        except ValueError:
            return bad(f"--start {' '.join(args.start)}: three numbers X_MM Y_MM DEG")
        config["start"] = (x, y, h)
    from . import field as fieldmod
    from . import scenario
    from .sim import Simulator

    try:
        if args.scenario is not None:
            if args.field is not None or args.start is not None or args.randomize:
                return bad(
                    "--scenario sets the field, the start and the robot: not with"
                    " --field, --start or --randomize"
                )
            scn = scenario.load(args.scenario, setup_only=True)
            if args.seed != "0":
                scn.seed = seed
            sim = scn.simulator(record=False)
            scn.prepare(sim, lambda line: print(f"{prog}: {line.strip()}", flush=True))
        else:
            fl = None
            if args.field is not None:
                fl = fieldmod.load(scenario._field_path(args.field, Path.cwd()))
            sim = Simulator(config, seed, field=fl, randomize=args.randomize, record=False)
            if fl is not None or config:
                problem = scenario.check_pose(sim.field, sim.config, *sim.drive_pose())
                if problem:
                    return bad(f"--start: {problem}")
    except (fieldmod.FieldError, ValueError) as e:  # ScenarioError is a ValueError
        return bad(str(e))
    from .update import UpdateError, load_image

    try:
        image = None if args.firmware is None else load_image(args.firmware)
        boot = sim.add_bootloader(image)
    except (UpdateError, ValueError) as e:
        return bad(f"--firmware {e}")
    boot.on_start.append(lambda line: print(f"{prog}: {line}", flush=True))
    try:
        server = SimServer(sim, args.host, port, speed)
    except OSError as e:
        print(f"{prog}: cannot listen on {args.host}:{port}: {e.strerror or e}", file=sys.stderr)
        return 1
    host, bound = server.address
    mode = "lockstep" if speed == 0 else f"{speed:g}x real time"
    print(f"{prog}: listening on {host}:{bound} ({mode}); Ctrl-C stops", flush=True)
    run = boot.flash.run
    print(
        f"{prog}: the board runs version {run.version} ({len(run.data)} bytes, CRC-32"
        f" 0x{run.crc32:08x}); `asserv --sim {host}:{bound} flash FIRMWARE` updates it",
        flush=True,
    )
    if not is_loopback(args.host):
        print(
            f"{prog}: {args.host} is not loopback: any machine that reaches this port drives"
            " the simulated robot (the protocol has no password)",
            file=sys.stderr,
            flush=True,
        )
    wall0 = time.monotonic()
    server.start()
    try:
        while duration is None or time.monotonic() - wall0 < duration:
            time.sleep(0.05 if duration is None else min(0.05, duration))
    except KeyboardInterrupt:
        pass
    finally:
        server.close()
    wall = time.monotonic() - wall0
    print(f"{prog}: simulated {sim.time_s:.3f} s in {wall:.3f} s of wall time", flush=True)
    return 0
