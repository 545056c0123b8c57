"""The simulated board: the firmware core on the physics simulator, behind an smbus2-like bus.

    sim = Simulator(seed=0)
    board = Board(sim.bus)          # the same driver as for a real board
    board.goto(200, 100)
    board.wait_idle(10)             # polls CHECK_BUSY; simulated time advances while it waits
    print(sim.true_pose(), board.position())

``Simulator`` runs the C sources of the board (``firmware/core``, compiled into
``asserv.sim._core``) through the host port (``firmware/ports/host``) on the physics of
``sim/``, in deterministic lockstep: control ticks at 1 kHz, physics substeps of 100 us (one of
1 ms for a whole tick away from contacts and from the tyres' grip, ``COARSE_SUBSTEP_NS``), and
the I2C bytes arriving between ticks at the bus bit rate. The traces of every tick (truth, estimate,
set-points, duties, currents, status) are kept as a numpy structured array.

This package holds every module that needs the compiled simulator (the ``sim`` extra): its
modules (``demo``, ``accuracy``, ``soak``, ``fusion``, ``arena``, ``plots``, ``boot``, ``cboard``)
import it freely; a module of asserv outside it imports it only inside the function that runs
the simulator, so that the driver-only install never loads it (python/tests/test_import_graph.py).
"""

from __future__ import annotations

import heapq
import itertools
import math
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any, NamedTuple

import numpy as np

from .. import field as fieldmod
from .._columns import TRACE_FIELDS
from .._protocol import ResetCause
from ..bus import VirtualBus
from ..lidar import LIDAR, LidarScan, Target, Yielding, crossing_path, scan_targets
from ._core import ffi, lib

if TYPE_CHECKING:
    from ..fixes import FixFeed, FixSource
    from ..update import Image
    from .boot import SimBootloader

#: The columns of ``Simulator.trace``, in the order of ``struct host_sample`` (host.h).
TRACE_DTYPE = np.dtype([(name, "<f8") for name in TRACE_FIELDS])


def _check_trace_layout() -> None:
    # The Python view of struct host_sample must be the C one, field for field.
    if ffi.sizeof("struct host_sample") != TRACE_DTYPE.itemsize:
        raise ImportError(
            "asserv.sim._core is stale: struct host_sample changed (pip install -e .)"
        )
    for i, name in enumerate(TRACE_FIELDS):
        if ffi.offsetof("struct host_sample", name) != 8 * i:
            raise ImportError(f"asserv.sim._core: struct host_sample.{name} is not at {8 * i}")


_check_trace_layout()


def _spec_start() -> tuple[float, float, float]:
    bc = ffi.new("struct board_config *")
    lib.board_default_config(bc)
    s = bc.start
    heading = (s.heading_turn32 - (2**32 if s.heading_turn32 >= 2**31 else 0)) * 360.0 / 2**32
    return (s.x_um / 1000.0, s.y_um / 1000.0, heading)


#: The board's power-on pose (board_default_config()): the specification's "0, bout du
#: terrain", angle 0, as docs/control.md places it on the field.
SPEC_START = _spec_start()

_CHUNK = 4096  # trace rows per call into C

#: The simulator's default long substep [ns]: a whole 1 kHz control tick in one step of the
#: physics where no contact can happen within it and the tyres are well within their grip, and
#: for 0.5 s after a contact; the 100 us substep elsewhere (sim/robot.c, docs/simulator.md).
COARSE_SUBSTEP_NS = 1_000_000


class TruePose(NamedTuple):
    """Ground truth of the encoder axis midpoint (the specification's reference point)."""

    x_mm: float
    y_mm: float
    heading_deg: float


class Substeps(NamedTuple):
    """Physics steps run (``Simulator.substeps``)."""

    short: int  # of substep_ns (100 us)
    long: int  # of coarse_substep_ns (1 ms: a whole control tick)


class OdometryErrors(NamedTuple):
    """The board's odometry configuration against the robot's true encoder wheels (hidden from
    the board): what a calibration should bring to zero."""

    ratio: float  # configured right/left factor ratio over the true one, minus 1
    scale: float  # mean of the configured factors over the true ones, minus 1
    track_mm: float  # configured track minus the true track in the odometry's length unit


class Calibration(NamedTuple):
    """An odometry calibration as the board holds it (SET_ODOMETRIE's values)."""

    ratio_ppm: int
    track_10um: int
    scale_ppm: int


#: The AVR board's rates (firmware/ports/avr/robot.c, docs/avr.md): the planner every 8th tick
#: (125 Hz at 1 kHz), its results taken 3 ticks after its snapshot, where the AVR's main loop
#: runs it preempted by the servo. ``Simulator(board_config=AVR_RATES)`` runs a board as the AVR
#: does (and a GOTO aims a planner step after it is taken, orders.aim_delay_steps, and its PIDs
#: read the raw derivative, control.d_filter_ms 0: no "quiet servo", docs/control.md "PID"); the
#: default is one rate, the planner in the tick.
AVR_RATES: Mapping[str, int] = {
    "slow_shift": 3,
    "planner_ticks": 3,
    "orders.aim_delay_steps": 1,
    "control.d_filter_ms": 0,
}

#: Bytes of the simulated board's storage (firmware/ports/host/host.h).
NVM_SIZE = int(lib.HOST_NVM_SIZE)


@dataclass(frozen=True)
class Frame:
    """One I2C transaction as the simulated board saw it (for logs and demos)."""

    t_s: float  # when its last byte ended
    kind: str  # "W" (write), "R" (read)
    data: bytes
    stop: bool  # ended by a STOP (False: a repeated start follows)


def _set_config(sc: Any, key: str, value: Any) -> None:
    """Set one struct sim_config member from Python, with a message that names it."""
    if key == "start":
        try:
            x, y, deg = (float(v) for v in value)
        except (TypeError, ValueError):
            raise ValueError(
                f"config start must be (x_mm, y_mm, heading_deg), not {value!r}"
            ) from None
        sc.start.x_mm, sc.start.y_mm, sc.start.heading_rad = x, y, math.radians(deg)
        return
    _set_member(sc, key, value, "config: unknown simulator setting", "sim/sim.h")


def _set_member(root: Any, key: str, value: Any, unknown: str, where: str) -> None:
    """Set a member of a cffi struct by its dotted name, with a message that names it."""
    path = key.split(".")
    obj = root
    try:
        for p in path[:-1]:
            obj = getattr(obj, p)
        current = getattr(obj, path[-1])
    except AttributeError:
        raise ValueError(f"{unknown} {key!r} (see {where})") from None
    try:
        if isinstance(current, int | float | bool):
            if type(current) is int and isinstance(value, float) and value.is_integer():
                value = int(value)  # a whole number read as a float (a scenario's config line)
            setattr(obj, path[-1], value)
        else:  # an array such as enc_radius_error
            values = list(value)
            if len(values) != len(current):
                raise ValueError(f"config {key} takes {len(current)} values, not {len(values)}")
            for i, v in enumerate(values):
                current[i] = v
    except (TypeError, OverflowError) as e:
        raise ValueError(f"config {key} = {value!r}: {e}") from None


def _fill_field(f: Any, fl: fieldmod.Field) -> None:
    f.length_mm, f.width_mm, f.borders = fl.length_mm, fl.width_mm, fl.borders
    obstacles: list[tuple[int, int, float, float, float, float, float]] = [
        (lib.SIM_SHAPE_CIRCLE, lib.SIM_OBSTACLE_BASKET, b.x_mm, b.y_mm, b.radius_mm, 0.0, 0.0)
        for b in fl.baskets
    ]
    for o in fl.obstacles:
        shape = lib.SIM_SHAPE_CIRCLE if o.shape == "circle" else lib.SIM_SHAPE_BOX
        obstacles.append(
            (shape, lib.SIM_OBSTACLE_OTHER, o.x_mm, o.y_mm, o.radius_mm, o.half_x_mm, o.half_y_mm)
        )
    f.obstacle_count = len(obstacles)
    for i, (shape, kind, x, y, r, hx, hy) in enumerate(obstacles):
        ob = f.obstacles[i]
        ob.shape, ob.kind, ob.x_mm, ob.y_mm = shape, kind, x, y
        ob.radius_mm, ob.half_x_mm, ob.half_y_mm = r, hx, hy
    f.line_count = len(fl.lines)
    for i, ln in enumerate(fl.lines):
        c = f.lines[i]
        c.x0_mm, c.y0_mm, c.x1_mm, c.y1_mm, c.width_mm = (
            ln.x0_mm,
            ln.y0_mm,
            ln.x1_mm,
            ln.y1_mm,
            ln.width_mm,
        )


class Simulator:
    """One simulated board on one simulated robot on one field.

    ``config`` overrides members of the simulator's ``struct sim_config`` (sim/sim.h) by name,
    e.g. ``{"enc_radius_error": (0.003, -0.003), "start": (0, -850, 1.0)}``; ``start`` is the
    true start pose (x mm, y mm, heading degrees) and the board believes it starts at
    ``board_start`` (default: the true start as configured, before ``randomize``), known within
    ``start_uncertainty`` = (radius mm, heading degrees), the bounds the error radius starts from
    (default (0, 0): the start is the reference).
    ``seed`` seeds the encoder noise; ``randomize=True`` also draws a robot off the shelf from it
    (wheel mismatch, track error, noise, start pose error: ``sim_config_randomize``).
    ``field`` is a field file path or a ``field.Field`` (default: field/default.toml).
    ``robot`` is a robot description file (robot/default.toml is the default robot; ``config``
    overrides it): wheels, encoders, motor, outline (``asserv.robot``).
    ``bus_hz`` is the I2C bit rate: each byte takes 9 bit times of simulated time.
    ``board_config`` overrides members of the board's ``struct board_config`` (board.h and the
    module headers it includes) by dotted name, after ``host_board_config()`` has set it for the
    nominal robot, e.g. ``{"control.ff_speed_q15_per_m_s": 0, "orders.settle_ms": 1}``.
    ``nvm`` is the board's storage at power-on (at most ``NVM_SIZE`` bytes, the rest erased;
    default: all erased): what ``Simulator.nvm`` read from an earlier board, so that the
    calibration it kept is installed at start (docs/calibration.md).
    """

    def __init__(
        self,
        config: Mapping[str, Any] | None = None,
        seed: int = 0,
        *,
        field: str | Path | fieldmod.Field | None = None,
        robot: str | Path | None = None,
        randomize: bool = False,
        board_start: tuple[float, float, float] | None = None,
        board_config: Mapping[str, Any] | None = None,
        start_uncertainty: tuple[float, float] = (0.0, 0.0),
        address: int = 2,
        bus_hz: int = 100_000,
        record: bool = True,
        nvm: bytes | None = None,
    ) -> None:
        if nvm is not None:
            if not isinstance(nvm, bytes | bytearray | memoryview):
                raise ValueError(f"nvm must be bytes, not {type(nvm).__name__}")
            nvm = bytes(nvm)
            if len(nvm) > NVM_SIZE:
                raise ValueError(f"nvm holds at most {NVM_SIZE} bytes, not {len(nvm)}")
        if not 1_000 <= bus_hz <= 1_000_000:
            raise ValueError(f"bus_hz must be 1000..1000000, not {bus_hz}")
        if not 0 <= seed < 2**64:
            raise ValueError(f"seed must be 0..2^64-1, not {seed}")
        self.field = (
            field
            if isinstance(field, fieldmod.Field)
            else fieldmod.load(fieldmod.DEFAULT if field is None else field)
        )
        self._f = ffi.new("struct sim_field *")
        _fill_field(self._f, self.field)
        sc = ffi.new("struct sim_config *")
        lib.sim_config_defaults(sc)
        # The 1 ms substep away from contacts and from the tyres' grip (docs/simulator.md,
        # "Speed"); ``{"coarse_substep_ns": 0}`` keeps the 100 us substep everywhere.
        sc.coarse_substep_ns = COARSE_SUBSTEP_NS
        _set_config(sc, "start", SPEC_START)
        if robot is not None:
            from .. import robot as robotmod

            for key, value in robotmod.load(robot).sim_config().items():
                _set_config(sc, key, value)
        for key, value in (config or {}).items():
            _set_config(sc, key, value)
        bc = ffi.new("struct board_config *")
        # The board is configured with the nominal robot: the errors drawn below stay hidden.
        lib.host_board_config(sc, self._f, bc)
        for key, value in (board_config or {}).items():
            _set_member(bc, key, value, "board_config: unknown board setting", "firmware/core/*.h")
        if board_start is not None:
            x, y, deg = board_start
            bc.start.x_um = round(x * 1000)
            bc.start.y_um = round(y * 1000)
            bc.start.heading_turn32 = round(deg / 360.0 * 2**32) % 2**32
        radius_mm, heading_deg = start_uncertainty
        if not (0 <= radius_mm <= 255 and 0 <= heading_deg <= 90):
            raise ValueError(
                f"start_uncertainty must be (0..255 mm, 0..90 degrees), not {start_uncertainty!r}"
            )
        bc.start_radius_um = round(radius_mm * 1000)
        bc.start_heading_bound_turn32 = round(heading_deg / 360.0 * 2**32)
        if randomize:
            lib.sim_config_randomize(sc, seed)
        else:
            sc.seed = seed
        self._sc = sc
        self._h = ffi.new("struct host *")
        err = lib.host_init(self._h, bc, sc, self._f)
        if err:
            raise ValueError(
                f"the simulator refused this configuration (host_init returned {err}): "
                "a value is out of range (sim/sim.h, firmware/core/board.h)"
            )
        if nvm is not None:
            # Powered on with that storage: the same as a power cycle before the first tick.
            lib.host_nvm_set(self._h, nvm, len(nvm))
            lib.host_power_cycle(self._h)
        self.address = address
        self._byte_ns = round(9 * 1e9 / bus_hz)
        self._record = record
        self._buf = ffi.new("struct host_sample[]", _CHUNK)
        self._n = ffi.new("uint32_t *")
        self._chunks: list[np.ndarray] = []
        self.frames: list[Frame] = []
        self.on_frame: list[Callable[[Frame], None]] = []
        self._events: list[tuple[int, int, Callable[[Simulator], None]]] = []
        self._event_seq = itertools.count()
        self.bus = VirtualBus({address: self}, clock=self)
        self._proto = ffi.addressof(self._h.board, "proto")
        self._tx_open = False  # between bus_start() and bus_stop()/bus_abort()
        self.seed = seed
        #: The obstacles the lidar sees (the opponents, the other robots of an Arena).
        self.lidar_targets: set[int] = set()
        self._scan: LidarScan | None = None
        self._scan_pose = (0.0, 0.0, 0.0)
        self._crossings = 0
        #: The crossing opponents that stop for our robot, by obstacle index.
        self.yielding: dict[int, Yielding] = {}
        #: The board's bootloader (``add_bootloader``), or None: BOOTLOADER is then ignored.
        self.boot: SimBootloader | None = None

    # ---- time -------------------------------------------------------------------------------
    #: Sleeping on this clock runs the simulation (asserv.bus.clock_of, Board.sleep).
    drives_simulation = True

    @property
    def time_s(self) -> float:
        """Simulated time since power-on."""
        return int(self._h.now_ns) * 1e-9

    def monotonic(self) -> float:
        """Clock interface of the bus: the simulated time."""
        return self.time_s

    def sleep(self, seconds: float) -> None:
        """Clock interface of the bus: waiting runs the simulation."""
        self.advance(seconds)

    def advance(self, seconds: float) -> None:
        """Run the board and the physics for ``seconds`` of simulated time."""
        if not seconds >= 0:
            raise ValueError(f"advance: seconds must be >= 0, not {seconds}")
        self._advance_ns(round(seconds * 1e9))

    def _advance_ns(self, ns: int) -> None:
        # Timed events (at()) split the run: each runs at its time, between two calls into C.
        while self._events and self._events[0][0] <= int(self._h.now_ns) + ns:
            t_ns, _, fn = heapq.heappop(self._events)
            step = max(0, t_ns - int(self._h.now_ns))
            self._run_ns(step)
            ns -= step
            fn(self)
        self._run_ns(ns)

    def at(self, t_s: float, fn: Callable[[Simulator], None]) -> None:
        """Run ``fn(sim)`` when the simulated time reaches ``t_s`` (seconds since power-on; at
        once on the next advance if it has passed), e.g.
        ``sim.at(3.0, lambda s: s.set_motor_stuck(0, True))``. Events at the same time run in
        the order they were given."""
        if not math.isfinite(t_s) or t_s < 0:
            raise ValueError(f"at: t_s must be a finite time >= 0, not {t_s}")
        heapq.heappush(self._events, (round(t_s * 1e9), next(self._event_seq), fn))

    def _run_ns(self, ns: int) -> None:
        while ns > 0:
            if self._record:
                done = lib.host_advance_ns(self._h, ns, self._buf, _CHUNK, self._n)
                n = int(self._n[0])
                if n:
                    raw = ffi.buffer(self._buf, n * TRACE_DTYPE.itemsize)
                    self._chunks.append(np.frombuffer(raw, dtype=TRACE_DTYPE).copy())
            else:
                done = lib.host_advance_ns(self._h, ns, ffi.NULL, 0, ffi.NULL)
            ns -= int(done)

    # ---- power and storage ----------------------------------------------------------------------
    def power_cycle(self) -> None:
        """Switch the board off and on between two ticks: it starts again as at power-on (its
        configuration, the start pose it believes, an empty queue, the motors off), then
        installs the calibration its storage kept. The robot stays where it is and the clock
        goes on; a calibration whose record was not completely written yet (16 bytes, all at
        the first tick after SET_ODOMETRIE's slow steps on the simulator) is lost."""
        lib.host_power_cycle(self._h)

    def reset(
        self, cause: ResetCause | int | str, keep_ram: bool = True, down_ms: int = 30
    ) -> None:
        """A reset of the board between two ticks, to rehearse one mid-match: ``cause`` a
        ResetCause (or its name: "BROWN_OUT", "WATCHDOG", "PIN", "SOFTWARE"; "POWER_ON" is
        ``power_cycle()``). The motors are off for ``down_ms`` (0..1000: the start-up; the
        robot coasts, the physics runs), then the board starts again with that cause: from the
        RAM it kept (``keep_ram``: its pose and radius resume, widened), or from RAM the reset
        scrambled (the pose is lost: motion orders refused until SET_NEW_POS). The status reads
        PB_MOTEUR, DEBUG end_reason RESET, until the next order, whether one ran or not (the
        settings are the power-on ones again); ``Board.reset_info()`` says the rest."""
        names = ", ".join(ResetCause.__members__)
        try:
            c = ResetCause[cause] if isinstance(cause, str) else ResetCause(cause)
        except (KeyError, ValueError):
            raise ValueError(f"reset: no cause {cause!r} (the causes: {names})") from None
        if not 0 <= down_ms <= 1000:
            raise ValueError(f"reset: down_ms must be 0..1000, not {down_ms}")
        if lib.host_reset(self._h, int(c), 1 if keep_ram else 0, down_ms):
            raise RuntimeError("reset: the board refused its configuration")
        self._tx_open = False

    def _power_cycle_board(self) -> None:
        lib.host_power_cycle(self._h)
        self._tx_open = False

    # ---- the bootloader (asserv.sim.boot) --------------------------------------------------------
    def add_bootloader(self, image: Image | None = None) -> SimBootloader:
        """Give the board the STM32 board's bootloader: BOOTLOADER, once taken, leaves the
        application for it, and ``asserv flash`` updates the board (docs/update.md, "Rehearse
        in the pits"). ``image`` is what the board runs at first (an ``asserv.update.Image``
        for board 0xf446; default: a stand-in of version 1, its record alone)."""
        from .boot import SimBootloader, stand_in_image

        self.boot = SimBootloader(self, image or stand_in_image())
        return self.boot

    @property
    def firmware(self) -> Image | None:
        """The image in the run slot of the board's bootloader (the last update it took), or
        None without a bootloader."""
        return self.boot.flash.run if self.boot is not None else None

    @property
    def nvm(self) -> bytes:
        """The board's storage (``NVM_SIZE`` bytes, 0xFF where erased): give it to a new
        ``Simulator(nvm=...)`` to power on a board that kept its calibration."""
        return bytes(ffi.buffer(self._h.storage.mem))

    @property
    def calibration(self) -> Calibration | None:
        """The odometry calibration the board has installed, or None (uncalibrated)."""
        b = self._h.board.planner
        if not b.calibrated:
            return None
        c = b.calibration
        return Calibration(int(c.ratio_ppm), int(c.track_10um), int(c.scale_ppm))

    # ---- I2C device (asserv.bus.I2CDevice) ----------------------------------------------------
    def i2c_write(self, data: bytes, stop: bool) -> None:
        """A write transaction at the bus bit rate: each byte reaches the board's interrupt when
        its ninth clock ends, while the control ticks go on. To the bootloader while it serves."""
        data = bytes(data)
        if self.boot is not None and self.boot.serving:
            self.boot.i2c_write(data, stop)
            self._log(Frame(self.time_s, "W", data, stop))
            return
        if self._in_one_call(len(data)):
            rows = lib.asim_bus_write(
                self._h, data, len(data), stop, self._byte_ns, *self._rows_buffer()
            )
            self._keep_rows(rows)
        else:
            self.bus_start(read=False)
            for b in data:
                self.bus_write_byte(b)
            if stop:
                self.bus_stop()
        self._tx_open = not stop  # a read by repeated start follows
        self._log(Frame(self.time_s, "W", data, stop))
        if self.boot is not None:
            self.boot.watch(data)

    def i2c_read(self, n: int) -> bytes:
        """A read transaction of n bytes, ended by NACK and STOP."""
        if self.boot is not None and self.boot.serving:
            got = self.boot.i2c_read(n)
            self._log(Frame(self.time_s, "R", got, True))
            return got
        if self._in_one_call(n):
            buf = ffi.new("uint8_t[]", max(1, n))
            self._keep_rows(lib.asim_bus_read(self._h, buf, n, self._byte_ns, *self._rows_buffer()))
            out = bytes(ffi.buffer(buf, n))
        else:
            self.bus_start(read=True)
            out = bytes(self.bus_read_byte() for _ in range(n))
            self.bus_stop()
        self._tx_open = False
        frame = Frame(self.time_s, "R", out, True)
        self._log(frame)
        return frame.data

    def _in_one_call(self, n_bytes: int) -> bool:
        # The transaction runs in one call into C (asim_bus_write/read, the same steps as the
        # bus_*() methods below) unless a timed event falls within it, or its ticks' trace rows
        # might not fit in the buffer.
        span = (n_bytes + 1) * self._byte_ns
        if self._events and self._events[0][0] <= int(self._h.now_ns) + span:
            return False
        return (n_bytes + 1) * (self._byte_ns // int(self._h.tick_ns) + 2) <= _CHUNK

    def _rows_buffer(self) -> tuple[Any, int]:
        return (self._buf, _CHUNK) if self._record else (ffi.NULL, 0)

    def _keep_rows(self, n: int) -> None:
        if n:
            raw = ffi.buffer(self._buf, n * TRACE_DTYPE.itemsize)
            self._chunks.append(np.frombuffer(raw, dtype=TRACE_DTYPE).copy())

    # ---- raw bus events, as the board's I2C interrupt sees them (for tests of any sequence) --
    @property
    def bus_busy(self) -> bool:
        """A transaction is in progress byte by byte (a timed event falls within it)."""
        return self._tx_open

    def write_now(self, data: bytes) -> None:
        """A whole write at once, between two ticks and outside any transaction: a second
        master's frame (the simulated fix source's, ``add_fix_source``)."""
        if self._tx_open:
            raise RuntimeError("write_now: a transaction is in progress")
        lib.proto_on_write_start(self._proto)
        for b in bytes(data):
            lib.proto_on_byte(self._proto, b)
        lib.proto_on_stop(self._proto)
        self._log(Frame(self.time_s, "W", bytes(data), True))

    def add_fix_source(self, source: FixSource | None = None) -> FixFeed:
        """Start a simulated localisation (asserv.fixes.FixSource: rate, noise, latency,
        outliers) writing SET_FIX to the board from now on; the returned feed logs every fix
        with the truth at the time it was measured, and ``feed.stop()`` ends it."""
        from .. import fixes

        return fixes.start(self, source or fixes.FixSource())

    def fix_counts(self) -> tuple[int, int, int, int]:
        """The board's own fix counters as of its last planner period, read from its memory
        (not over the bus): fused, outliers, too old or stale, the last result (FixResult)."""
        i = self._h.board.planner.fix.info
        return int(i.fused), int(i.outliers), int(i.too_old), int(i.last)

    def bus_start(self, read: bool) -> None:
        """A START or a repeated START, then the board's address with the read or write bit:
        one byte time, then proto_on_read_start() or proto_on_write_start()."""
        self._tx_open = True
        self._advance_ns(self._byte_ns)
        if read:
            lib.proto_on_read_start(self._proto)
        else:
            lib.proto_on_write_start(self._proto)

    def bus_write_byte(self, value: int) -> None:
        """One data byte written by the master: one byte time, then proto_on_byte()."""
        self._advance_ns(self._byte_ns)
        lib.proto_on_byte(self._proto, value)

    def bus_read_byte(self) -> int:
        """One data byte read by the master: proto_read_byte(), then one byte time."""
        value = int(lib.proto_read_byte(self._proto))
        self._advance_ns(self._byte_ns)
        return value

    def bus_stop(self) -> None:
        """A STOP: proto_on_stop()."""
        self._tx_open = False
        lib.proto_on_stop(self._proto)

    def bus_restart(self) -> None:
        """A repeated START as the AVR's TWI reports it, before the next address byte:
        proto_on_restart(). Without it, the next bus_start() ends the write or the read (what
        the host port does)."""
        lib.proto_on_restart(self._proto)

    def bus_abort(self) -> None:
        """A bus error in the middle of a transaction (lost arbitration, a misplaced START or
        STOP): proto_on_abort()."""
        self._tx_open = False
        lib.proto_on_abort(self._proto)

    def _log(self, frame: Frame) -> None:
        self.frames.append(frame)
        for cb in self.on_frame:
            cb(frame)

    def describe_robot(self) -> str:
        """The hidden errors of this robot, in one line (what randomize drew, or the config)."""
        sc = self._sc
        b = self._h.board.cfg.start
        believed = (b.x_um / 1000.0, b.y_um / 1000.0)
        e, k, st = sc.enc_radius_error, sc.enc_noise_mm2_per_m, sc.start
        parts = [
            f"free wheels {e[0] * 100:+.3f} % / {e[1] * 100:+.3f} % in diameter",
            f"track {sc.enc_track_error_mm:+.2f} mm",
            f"noise {k[0]:.2f} / {k[1]:.2f} mm^2/m",
            f"start ({st.x_mm:.1f}, {st.y_mm:.1f}) mm {math.degrees(st.heading_rad):.2f} deg",
            f"believed ({believed[0]:.1f}, {believed[1]:.1f}) mm",
        ]
        return ", ".join(parts)

    # ---- truth, estimate, traces ----------------------------------------------------------------
    def true_pose(self) -> TruePose:
        """Where the robot really is (encoder axis midpoint), heading in degrees -180..180."""
        t = ffi.new("struct sim_truth *")
        lib.sim_get_truth(ffi.addressof(self._h, "sim"), t)
        return TruePose(t.odo_pose.x_mm, t.odo_pose.y_mm, math.degrees(t.odo_pose.heading_rad))

    def drive_pose(self) -> TruePose:
        """Where the drive axis midpoint truly is (the simulator's own reference point, that of
        ``place`` and of the start pose), heading in degrees."""
        t = ffi.new("struct sim_truth *")
        lib.sim_get_truth(ffi.addressof(self._h, "sim"), t)
        return TruePose(t.pose.x_mm, t.pose.y_mm, math.degrees(t.pose.heading_rad))

    @property
    def config(self) -> Any:
        """The simulated robot's ``struct sim_config`` (sim/sim.h), as drawn: read it only
        (changing it after construction has no effect on the physics)."""
        return self._sc

    @property
    def board_config(self) -> Any:
        """The board's ``struct board_config`` (firmware/core/board.h) it was started with: the
        nominal robot, with the ``board_config`` overrides: a copy, which stays valid after the
        simulator is gone."""
        cfg = ffi.new("struct board_config *")
        cfg[0] = self._h.board.cfg
        return cfg

    def odometry_errors(self) -> OdometryErrors:
        """How far the board's odometry configuration (SET_ODOMETRIE included) is from the true
        wheels. With q = configured factor / true factor per wheel, a straight line is seen
        turning by (qR - qL) s / b, and a turn as mean(q) b_true / b times itself: the track the
        heading needs is mean(q) times the true one (docs/calibration.md)."""
        sc, oc = self._sc, self._h.board.servo.counter.cfg
        q = []
        for i, k in enumerate((oc.left_um_per_count_q16, oc.right_um_per_count_q16)):
            true_um = 2 * math.pi * sc.enc_radius_mm * 1000 * (1 + sc.enc_radius_error[i])
            q.append(k / 65536 / (true_um / sc.enc_cpr))
        mean = (q[0] + q[1]) / 2
        true_track = sc.enc_track_mm + sc.enc_track_error_mm
        return OdometryErrors(q[1] / q[0] - 1, mean - 1, oc.track_um / 1000 - mean * true_track)

    @property
    def trace(self) -> np.ndarray:
        """One row per control tick (columns TRACE_FIELDS), as a numpy structured array."""
        if len(self._chunks) > 1:
            self._chunks = [np.concatenate(self._chunks)]
        return self._chunks[0] if self._chunks else np.zeros(0, dtype=TRACE_DTYPE)

    @property
    def ticks(self) -> int:
        """Control ticks run since power-on."""
        return int(self._h.ticks)

    @property
    def substeps(self) -> Substeps:
        """The physics steps run since power-on: short ones (``substep_ns``), and long ones
        (``coarse_substep_ns``: a whole control tick, away from contacts and from the grip)."""
        s = self._h.sim
        return Substeps(int(s.short_steps), int(s.coarse_steps))

    # ---- disturbances and faults (sim/sim.h) --------------------------------------------------
    def set_battery_volts(self, volts: float) -> None:
        lib.sim_set_battery_V(ffi.addressof(self._h, "sim"), volts)

    def set_friction_scale(self, wheel: int, scale: float) -> None:
        lib.sim_set_friction_scale(ffi.addressof(self._h, "sim"), wheel, scale)

    def set_motor_stuck(self, wheel: int, stuck: bool) -> None:
        lib.sim_set_motor_stuck(ffi.addressof(self._h, "sim"), wheel, stuck)

    def set_encoder_cut(self, wheel: int, cut: bool) -> None:
        lib.sim_set_encoder_cut(ffi.addressof(self._h, "sim"), wheel, cut)

    def set_motor_encoder_cut(self, wheel: int, cut: bool) -> None:
        lib.sim_set_motor_encoder_cut(ffi.addressof(self._h, "sim"), wheel, cut)

    def press(self, shock_mask: int = 0, basket: bool = False) -> None:
        """Hold shock switches closed (bit i: CAPTEUR_i), and the basket switch if ``basket``,
        whatever touches them; ``press(0)`` releases them (sim_force_sensors)."""
        if not 0 <= shock_mask <= 0xFF:
            raise ValueError(f"press: shock_mask must be 0..0xff, not {shock_mask}")
        lib.sim_force_sensors(self._sim, shock_mask, bool(basket))

    # ---- moving obstacles and opponents (sim/sim.h) --------------------------------------------
    @property
    def _sim(self) -> Any:
        return ffi.addressof(self._h, "sim")

    def add_obstacle(
        self,
        x_mm: float,
        y_mm: float,
        *,
        radius_mm: float = 0.0,
        half_x_mm: float = 0.0,
        half_y_mm: float = 0.0,
        heading_deg: float = 0.0,
        basket: bool = False,
    ) -> int:
        """Add an obstacle now: a disc of ``radius_mm``, or a box of half sizes ``half_x_mm``,
        ``half_y_mm`` turned by ``heading_deg``; returns its index (for ``move_obstacle``)."""
        box = half_x_mm > 0 or half_y_mm > 0
        if box == (radius_mm > 0):
            raise ValueError("add_obstacle: give radius_mm (a disc) or half_x_mm, half_y_mm")
        o = ffi.new("struct sim_obstacle *")
        o.shape = lib.SIM_SHAPE_BOX if box else lib.SIM_SHAPE_CIRCLE
        o.kind = lib.SIM_OBSTACLE_BASKET if basket else lib.SIM_OBSTACLE_OTHER
        o.x_mm, o.y_mm, o.radius_mm = x_mm, y_mm, radius_mm
        o.half_x_mm, o.half_y_mm, o.heading_rad = half_x_mm, half_y_mm, math.radians(heading_deg)
        i = int(lib.sim_add_obstacle(self._sim, o))
        if i < 0:
            raise ValueError(
                f"add_obstacle: the field is full ({lib.SIM_MAX_OBSTACLES} obstacles) or a value"
                " is out of range"
            )
        return i

    def move_obstacle(self, i: int, x_mm: float, y_mm: float, heading_deg: float = 0.0) -> None:
        """Put obstacle ``i`` (the field's baskets and obstacles come first) somewhere now."""
        self._obstacle_index(i)
        lib.sim_move_obstacle(self._sim, i, x_mm, y_mm, math.radians(heading_deg))

    def obstacles(self) -> list[tuple[float, float]]:
        """Where every obstacle is now (x_mm, y_mm), baskets first, as in the field file."""
        f = self._h.sim.field
        return [(f.obstacles[i].x_mm, f.obstacles[i].y_mm) for i in range(f.obstacle_count)]

    def add_opponent(
        self,
        x_mm: float,
        y_mm: float,
        radius_mm: float = 150.0,
        path: Sequence[tuple[float, float]] = (),
        speed_mm_s: float = 300.0,
        loop: bool = False,
    ) -> int:
        """An opponent robot seen as a disc, at (x, y), following ``path`` (see
        ``set_opponent_path``); returns its obstacle index. Touching it closes the shock
        switches it reaches; it is not pushed."""
        i = self.add_obstacle(x_mm, y_mm, radius_mm=radius_mm)
        self.set_opponent_path(i, path, speed_mm_s, loop)
        return i

    def add_crossing_opponent(
        self,
        route: Sequence[tuple[float, float]],
        *,
        radius_mm: float = 150.0,
        speed_mm_s: float | None = None,
        crossings: int = 4,
        keep_clear: Sequence[tuple[float, float, float]] = (),
        seed: int | None = None,
        yield_mm: float | None = 100.0,
    ) -> int:
        """An opponent on a random looping path that crosses ``route`` (our robot's, a
        polyline) ``crossings`` times, at 45 to 135 degrees (``asserv.lidar.crossing_path``),
        at ``speed_mm_s`` (default: drawn within 200..400 mm/s). It starts at its path's first
        point. The draw comes from ``seed`` (default: the simulator's seed and the number of
        crossing opponents added before): the same call on the same simulator gives the same
        opponent. ``keep_clear``: points (x, y, r) its runs stay r away from (a start area).
        ``yield_mm``: it stops while our robot is that close ahead of it, as a real opponent
        with its own lidar would (``asserv.lidar.Yielding``; None: it never stops). Returns its
        obstacle index."""
        if yield_mm is not None and not 0 <= yield_mm < 1000:
            raise ValueError(f"add_crossing_opponent: yield_mm must be 0..1000, not {yield_mm}")
        if speed_mm_s is not None and not 0 < speed_mm_s < 1e6:
            raise ValueError(f"add_crossing_opponent: speed_mm_s must be > 0, not {speed_mm_s}")
        if not 0 < radius_mm < 1000:
            raise ValueError(f"add_crossing_opponent: radius_mm must be 0..1000, not {radius_mm}")
        rng = np.random.default_rng([self.seed if seed is None else seed, 0xC2055, self._crossings])
        fl = self.field
        path = crossing_path(
            route,
            rng,
            length_mm=fl.length_mm,
            width_mm=fl.width_mm,
            radius_mm=radius_mm,
            crossings=crossings,
            keep_clear=keep_clear,
        )
        speed = float(rng.uniform(200, 400)) if speed_mm_s is None else speed_mm_s
        self._crossings += 1
        loop = path[1:] + path[:1]
        i = self.add_opponent(*path[0], radius_mm, loop, speed, loop=True)
        if yield_mm is not None:
            y = Yielding(i, loop, speed, yield_mm)
            self.yielding[i] = y
            self.at(self.time_s, y.step)
        return i

    def opponent_radius(self, i: int) -> float:
        """The radius of obstacle ``i`` (a disc), mm."""
        self._obstacle_index(i)
        return float(self._h.sim.field.obstacles[i].radius_mm)

    # ---- the lidar (asserv.lidar) ---------------------------------------------------------------
    def lidar(self) -> LidarScan:
        """What the robot's lidar (``asserv.lidar.LIDAR``) saw of the opponents in its last full
        scan. The first call switches it on: a scan is taken then, and every 1 / scan_hz s of
        simulated time after (timed events, as ``at``). Between two scans the same scan is
        returned; its ``t_s`` says when it was taken."""
        if self._scan is None:
            self._take_scan(0, self.time_s)
        assert self._scan is not None
        return self._scan

    def lidar_view(self) -> list[Target]:
        """What the lidar can see now, where it truly is (for tests and views)."""
        f = self._h.sim.field
        out = []
        for i in sorted(self.lidar_targets):
            o = f.obstacles[i]
            out.append(
                Target(
                    o.x_mm,
                    o.y_mm,
                    o.radius_mm if o.shape == lib.SIM_SHAPE_CIRCLE else 0.0,
                    o.half_x_mm if o.shape == lib.SIM_SHAPE_BOX else 0.0,
                    o.half_y_mm if o.shape == lib.SIM_SHAPE_BOX else 0.0,
                    math.degrees(o.heading_rad),
                )
            )
        return out

    def lidar_points(self) -> list[tuple[float, float]]:
        """The last scan's hits on the field, from the true pose the robot had at the scan
        (for a view); empty while the lidar is off."""
        if self._scan is None:
            return []
        return self._scan.points(*self._scan_pose)

    def _take_scan(self, index: int, t0_s: float) -> None:
        x, y, h = self.true_pose()
        self._scan_pose = (x, y, h)
        rng = np.random.default_rng([self.seed, 0x11DA2, index])
        self._scan = LidarScan(self.time_s, index, scan_targets(x, y, h, self.lidar_view(), rng))
        nxt = t0_s + (index + 1) / LIDAR.scan_hz
        self.at(nxt, lambda s: s._take_scan(index + 1, t0_s))

    def set_opponent_path(
        self,
        i: int,
        path: Sequence[tuple[float, float]],
        speed_mm_s: float = 300.0,
        loop: bool = False,
    ) -> None:
        """Make obstacle ``i`` go through the points of ``path`` at ``speed_mm_s`` from now on
        (an empty path: stand still); with ``loop`` it goes round again. A script drives it by
        calling this again, e.g. from ``at()``."""
        self._obstacle_index(i)
        points = [(float(x), float(y)) for x, y in path]
        if len(points) > lib.SIM_MAX_PATH:
            raise ValueError(f"an opponent's path has at most {lib.SIM_MAX_PATH} points")
        flat = ffi.new("double[]", [v for p in points for v in p] or [0.0])
        if lib.sim_set_opponent_path(self._sim, i, flat, len(points), speed_mm_s, loop) != 0:
            raise ValueError(
                f"set_opponent_path: speed {speed_mm_s} must be > 0 and the points finite"
                f" (and at most {lib.SIM_MAX_OPPONENTS} opponents)"
            )
        self.lidar_targets.add(i)

    def _obstacle_index(self, i: int) -> None:
        n = int(self._h.sim.field.obstacle_count)
        if not isinstance(i, int) or not 0 <= i < n:
            raise ValueError(f"no obstacle {i!r}: there are {n} (0..{n - 1})")

    def place(self, x_mm: float, y_mm: float, heading_deg: float) -> None:
        """Put the robot somewhere by hand (at rest); the board is not told."""
        pose = ffi.new("struct sim_pose *", (x_mm, y_mm, math.radians(heading_deg)))
        lib.sim_set_pose(ffi.addressof(self._h, "sim"), pose)
