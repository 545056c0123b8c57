"""The master driver of the asserv board: one method per I2C message, over an smbus2-like bus.

    from smbus2 import SMBus
    from asserv import Board

    with SMBus(1) as bus:                      # /dev/i2c-1 on a Raspberry Pi
        board = Board(bus)                     # address 2; Board(bus, pec=True) adds PECs
        board.goto(200, 100)                   # raises OrderRejected if the board refuses it
        end = board.wait_idle(timeout_s=10)    # the 2002 annex's while (BUSY_TRAJET);
        print(board.position())

Frames are built by ``codec.encode`` and replies decoded by ``codec.decode_reply``: this module
adds the bus transactions, the acceptance check and the errors. Every transfer is a single
``i2c_rdwr`` call; an ETAT reply is read after a repeated start (``S 0x04 [d] Sr 0x05 <reply> P``),
and with ``check=True`` an order or setting is followed, in the same transaction, by a read of the
status byte (``S 0x04 [frame] Sr 0x05 <status> P``), which says whether the board accepted it.
docs/driver.md is the user's guide; docs/protocol.md the protocol.
"""

from __future__ import annotations

import enum
import errno
import math
import operator
import os
import threading
import weakref
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from typing import Any, Protocol, SupportsIndex, TypeVar

from smbus2 import i2c_msg

from . import codec
from ._protocol import ADDRESS, Capability, EndReason, Filtre, Reject, Status
from .bus import Clock, clock_of
from .codec import Debug, FixInfo, LastReject, Motion, Pose, ResetInfo, Version

__all__ = [
    "AsservError",
    "Board",
    "BoardTimeout",
    "BusError",
    "GotoOption",
    "MatchOver",
    "NoAcknowledge",
    "OrderRejected",
    "Outcome",
    "PecMismatch",
    "Unsupported",
    "bus_lock",
]


class SMBusLike(Protocol):
    """What the driver needs of a bus: ``smbus2.SMBus`` and ``asserv.bus.VirtualBus`` have it.

    A bus that also has a ``clock`` (VirtualBus, RemoteBus), or ``monotonic()`` and
    ``sleep(s)``, gives the board its clock (``Board.now()``, ``Board.sleep()``), so that polling
    a simulated board advances simulated time; any other bus gets the wall clock
    (``asserv.bus.clock_of``)."""

    def i2c_rdwr(self, *i2c_msgs: i2c_msg) -> None: ...


class GotoOption(enum.IntFlag):
    """GOTO's option bits (docs/protocol.md, section 4.1)."""

    RECALAGE_LIGNE = 1  # recalibration on floor lines
    RECALAGE_BORD = 2  # recalibration by contact with the field border
    APPEND = 4  # queue behind the running order instead of replacing it (capability QUEUE)
    PASS_THROUGH = 8  # do not stop at the point when another order waits (capability CORNERS)

    @classmethod
    def parse(cls, text: str) -> int:
        """GOTO's options as the CLI and the scenario files write them: a number (``3``,
        ``0x2``), or names joined by ``+`` or ``|``: ``ligne``, ``bord``, ``ligne+bord``,
        ``RECALAGE_BORD``, ``append``, ``through`` (PASS_THROUGH), in any case. ValueError names
        what is not an option."""
        try:
            return int(text, 0)
        except ValueError:
            pass
        value = 0
        for part in text.replace("|", "+").split("+"):
            name = part.strip().upper()
            aliases = {
                "LIGNE": "RECALAGE_LIGNE",
                "BORD": "RECALAGE_BORD",
                "THROUGH": "PASS_THROUGH",
            }
            name = aliases.get(name, name)
            try:
                value |= cls[name]
            except KeyError:
                raise ValueError(
                    f"{text!r} is not GOTO options (a number, or ligne, bord, append, through,"
                    " joined by +)"
                ) from None
        return value


class Outcome(enum.Enum):
    """How an order ended, as ``Board.complete`` tells it (docs/strategy.md)."""

    DONE = "done"  # the robot settled at the target (end_reason DONE)
    BORDER_RECALIBRATED = "border recalibrated"  # CHOC_BORD with end_reason BORDER
    BASKET_REACHED = "basket reached"  # CHOC_PANIER with end_reason BASKET
    SHOCK = "shock"  # CHOC_BORD or CHOC_PANIER from a shock sensor (end_reason SHOCK)
    MOTOR_PROBLEM = "motor problem"  # PB_MOTEUR
    GRAVE_FAULT = "grave fault"  # PB_GRAVE: the board refuses orders until reset
    TIMEOUT = "timeout"  # still busy after timeout_s: the driver sent STOP
    STOPPED = "stopped"  # ended by a STOP (another thread, the match timer) or SET_TIMEOUT


def outcome_of(status: Status, end_reason: EndReason) -> Outcome:
    """The outcome of an order from the final status byte (not busy) and DEBUG's end_reason:
    CHOC_BORD is a border recalibration when end_reason is BORDER and a collision otherwise;
    CHOC_PANIER is the basket when end_reason is BASKET and a shock otherwise."""
    if status & Status.PB_GRAVE:
        return Outcome.GRAVE_FAULT
    if status & Status.PB_MOTEUR:
        return Outcome.MOTOR_PROBLEM
    if status & Status.CHOC_BORD:
        return Outcome.BORDER_RECALIBRATED if end_reason == EndReason.BORDER else Outcome.SHOCK
    if status & Status.CHOC_PANIER:
        return Outcome.BASKET_REACHED if end_reason == EndReason.BASKET else Outcome.SHOCK
    if end_reason in (EndReason.STOPPED, EndReason.TIMEOUT):
        return Outcome.STOPPED
    return Outcome.DONE


# Errors ------------------------------------------------------------------------------------------


class AsservError(Exception):
    """Base of the driver's errors: something went wrong on the bus or on the board."""


class BusError(AsservError):
    """The bus reported an error (an OSError from the adapter); ``errno`` says which."""

    def __init__(self, message: str, errno_: int | None = None) -> None:
        super().__init__(message)
        self.errno = errno_


class NoAcknowledge(BusError):  # noqa: N818 (names of the driver's API)
    """No device acknowledged the board's address: the board is off, not wired, or elsewhere."""

    def __init__(self, message: str, address: int, errno_: int | None) -> None:
        super().__init__(message, errno_)
        self.address = address


class PecMismatch(AsservError):  # noqa: N818 (names of the driver's API)
    """A reply's PEC did not match: bytes were corrupted on the bus (or, for an ETAT reply, the
    designation write was corrupted and the board sent the status byte instead)."""


class OrderRejected(AsservError):  # noqa: N818 (names of the driver's API)
    """The board rejected a write: ``reason`` and ``designation`` come from LAST_REJECT."""

    def __init__(
        self, message: str, name: str, reason: Reject, designation: int, count: int
    ) -> None:
        super().__init__(message)
        self.name = name
        self.reason = reason
        self.designation = designation
        self.count = count


class Unsupported(AsservError):  # noqa: N818 (names of the driver's API)
    """The board does not have this extension: its VERSION lacks the capability bit (a build
    that compiles the feature out, or an older firmware), or it rejected the message as
    UNSUPPORTED. Nothing was sent in the first case."""

    def __init__(self, message: str, capability: str = "") -> None:
        super().__init__(message)
        self.capability = capability


class BoardTimeout(AsservError):  # noqa: N818 (names of the driver's API)
    """``wait_idle`` gave up: the board was still busy. ``status`` is the last status read."""

    def __init__(self, message: str, status: Status) -> None:
        super().__init__(message)
        self.status = status


class MatchOver(Exception):  # noqa: N818 (names of the driver's API)
    """The match time is over (``asserv.match.MatchTimer``): the robot was sent STOP, and the
    board refuses every other transaction from this driver."""


# errno values with which Linux adapters report a NACK of the address: ENXIO is the kernel's
# documented code; i2c-bcm2835 (Raspberry Pi) gives EREMOTEIO; some give EIO (on i2c-bcm2835, EIO
# is a clock-stretching timeout instead).
_NACK_ERRNOS = frozenset({errno.ENXIO, errno.EREMOTEIO, errno.EIO})

_BUS_HINTS = {
    errno.ETIMEDOUT: "the bus is stuck or a slave stretches the clock; check the wiring",
    errno.EAGAIN: "arbitration lost: another master on the bus?",
    errno.EBUSY: "the bus is busy",
    errno.ENOENT: "no such I2C bus; is I2C enabled (raspi-config, dtparam=i2c_arm=on)?",
    errno.EACCES: "permission denied; add your user to the i2c group",
    errno.EBADF: "the bus is closed",
}

_REJECT_HINTS = {
    Reject.REFUSED_PB_GRAVE: "the board has an unrecoverable fault (PB_GRAVE); reset it",
    Reject.QUEUE_FULL: "more than 8 writes within one control tick; send them more slowly",
    Reject.BAD_PEC: "the frame was corrupted on the bus; it can be sent again",
    Reject.ABORTED: "a bus error cut the write; it can be sent again",
    Reject.BAD_LENGTH: "the board does not know this message's length: firmware version?",
    Reject.UNKNOWN_DESIGNATION: "the board does not know this message: firmware version?",
    Reject.OUT_OF_RANGE: "the board's ranges differ from the driver's: firmware version?",
    Reject.RESERVED_BIT: "the board's option bits differ from the driver's: firmware version?",
}


def _errno_name(e: int | None) -> str:
    return errno.errorcode.get(e, str(e)) if e is not None else "no errno"


# The driver --------------------------------------------------------------------------------------

T = TypeVar("T")

_SLICE_S = 0.01  # how long a simulation runs under the bus lock in Board.sleep()

# One lock per bus object, for every Board on it (weakly held: the bus may go away).
_BUS_LOCKS: weakref.WeakKeyDictionary[Any, threading.RLock] = weakref.WeakKeyDictionary()
_BUS_LOCKS_LOCK = threading.Lock()


def bus_lock(bus: object) -> threading.RLock:
    """The lock that makes each transaction on ``bus`` atomic: the same for every Board on the
    same bus object (a bus that cannot be weakly referenced gets one per call)."""
    with _BUS_LOCKS_LOCK:
        try:
            lock = _BUS_LOCKS.get(bus)
            if lock is None:
                lock = _BUS_LOCKS[bus] = threading.RLock()
        except TypeError:
            lock = threading.RLock()
        return lock


class Board:
    """The asserv board at ``address`` on ``bus`` (an ``smbus2.SMBus`` or a ``VirtualBus``).

    ``pec``: append a PEC to every write and check the PEC of every reply (the board always sends
    one after its reply; the driver then reads one byte more).
    ``check``: after every order or setting, read the status byte in the same transaction, and
    if COMMANDE_REJETEE is set, read LAST_REJECT and raise ``OrderRejected``.

    Arguments outside the protocol's ranges raise ``ValueError`` (``codec.FrameError``) before
    anything is sent; non-integers raise ``TypeError``. Bus problems raise ``NoAcknowledge`` or
    ``BusError``, corrupted replies ``PecMismatch``.

    Time: ``now()`` and ``sleep(s)`` are the bus's clock, the simulated time on a simulated bus
    (``Simulator.bus``, ``asserv.server.RemoteBus``) and the wall clock on a real one: a strategy
    that waits with them runs unchanged on both.

    Threads: every transaction holds a lock shared by all the Boards on the same bus object, so
    threads can share a Board (or a bus); ``with board.exclusive():`` holds it over several
    calls. ``complete()`` reads the final status and DEBUG under it.
    """

    def __init__(
        self, bus: SMBusLike, address: int = ADDRESS, *, pec: bool = False, check: bool = True
    ) -> None:
        if not isinstance(address, int) or not 0 <= address <= 0x7F:
            raise ValueError(f"I2C address {address!r} is not a 7-bit address (0..0x7f)")
        self.bus = bus
        self.address = address
        self.pec = pec
        self.check = check
        self.clock: Clock = clock_of(bus)
        # A clock whose sleep runs a simulation in this process must not run while another
        # thread's transaction is half-way through the simulated board: it is slept in slices
        # under the bus lock.
        self._drives = bool(getattr(self.clock, "drives_simulation", False))
        self._lock = bus_lock(bus)
        #: The end of the match on ``clock`` (``asserv.match.MatchTimer``), or None. Once
        #: passed, the next transaction or sleep sends STOP and raises MatchOver.
        self.deadline: float | None = None
        self._match_stopped = False
        self._capabilities: Capability | None = None

    def __repr__(self) -> str:
        return (
            f"Board(address=0x{self.address:02x}, pec={self.pec}, check={self.check},"
            f" bus={self.bus!r})"
        )

    # Time and sharing ---------------------------------------------------------------------

    def now(self) -> float:
        """Seconds on the bus's clock: simulated time on a simulated bus, the wall clock
        (``time.monotonic``) on a real one."""
        return self.clock.monotonic()

    def sleep(self, seconds: float) -> None:
        """Let ``seconds`` pass on the bus's clock (on a simulated bus, the simulation runs).

        After the match deadline (``asserv.match.MatchTimer``) the sleep is cut there, STOP is
        sent and MatchOver raised."""
        if not seconds >= 0 or seconds == math.inf:
            raise ValueError(f"sleep: seconds must be finite and >= 0, not {seconds}")
        self._check_deadline("sleep")
        now = self.now()
        target = now + seconds
        if self.deadline is not None and target > self.deadline:
            seconds, target = max(0.0, self.deadline - now), self.deadline
        if not self._drives:
            self.clock.sleep(seconds)
        else:
            while (left := target - self.now()) > 1e-9:
                with self._lock:  # slices, so that other threads' transactions go in between
                    self.clock.sleep(min(left, _SLICE_S))
        if self.deadline is not None and target >= self.deadline:
            self._check_deadline("sleep")

    @contextmanager
    def exclusive(self) -> Iterator[Board]:
        """Hold the bus lock over several calls (no other thread's transaction in between)."""
        with self._lock:
            yield self

    def _check_deadline(self, name: str) -> None:
        if self.deadline is None or self.now() < self.deadline - 1e-6:
            return
        with self._lock:
            if not self._match_stopped:
                self._match_stopped = True
                frame = codec.encode("STOP", pec=self.pec, address=self.address)
                self._rdwr("STOP", i2c_msg.write(self.address, frame), at_deadline=True)
        raise MatchOver(f"{name}: the match is over (the robot was sent STOP)")

    # ORDRE ---------------------------------------------------------------------------------

    def goto(
        self,
        x_mm: int,
        y_mm: int,
        options: GotoOption | int = 0,
        *,
        append: bool = False,
        through: bool = False,
    ) -> None:
        """GOTO: turn towards (x, y), then drive straight to it, forwards.

        x_mm, y_mm: -32000..32000 mm (0, 0 is the centre of the field); options: GotoOption bits.
        ``append``: queue it behind the running order (GotoOption.APPEND, capability QUEUE)
        instead of replacing everything; ``through``: do not stop at the point when another
        order waits, turn through the corner (GotoOption.PASS_THROUGH, capability CORNERS).
        A board without the capability raises ``Unsupported`` and nothing is sent."""
        opts = _integer("options", options)
        opts |= (GotoOption.APPEND if _flag("append", append) else 0) | (
            GotoOption.PASS_THROUGH if _flag("through", through) else 0
        )
        self._command(
            "GOTO",
            _integer("x_mm", x_mm),
            _integer("y_mm", y_mm),
            opts,
            needs=_needs(opts),
        )

    def goto_reverse(self, distance_mm: int, *, append: bool = False) -> None:
        """GOTO_REVERSE: drive straight backwards over 0..255 mm; ``append``: queue it
        (capability QUEUE)."""
        d = _integer("distance_mm", distance_mm)
        more = self._options_byte("GOTO_REVERSE", append)
        self._command("GOTO_REVERSE", d, *more, needs=_needs_append(append))

    def goto_panier(self, angle_deg: float, *, append: bool = False) -> None:
        """GOTO_PANIER: turn to an absolute heading, drive forwards until the basket is touched.

        angle_deg: -180..180 degrees, sent in 2-degree steps: rounded to the nearest step, a
        half step going towards zero (45 degrees is sent as 22, that is 44, as in the 2002
        annex). The expected ending is CHOC_PANIER in the final status. ``append``: queue it
        (capability QUEUE)."""
        if isinstance(angle_deg, bool) or not isinstance(angle_deg, int | float):
            raise TypeError(f"angle_deg must be a number of degrees, got {angle_deg!r}")
        if not -180 <= angle_deg <= 180:
            raise codec.FrameError(
                Reject.OUT_OF_RANGE, f"GOTO_PANIER.angle_deg={angle_deg} is outside -180..180"
            )
        steps = math.ceil(abs(angle_deg) / 2 - 0.5)  # nearest, a half step towards zero
        self._command(
            "GOTO_PANIER",
            -steps if angle_deg < 0 else steps,
            *self._options_byte("GOTO_PANIER", append),
            needs=_needs_append(append),
        )

    def _options_byte(self, name: str, append: bool) -> tuple[int, ...]:
        # The trailing options byte of GOTO_REVERSE and GOTO_PANIER: absent unless needed, so
        # that a plain order is the 2002 frame; a PEC needs the full form (docs/protocol.md).
        if _flag("append", append):
            return (int(GotoOption.APPEND),)
        return (0,) if self.pec and len(codec.message(name).params) > 1 else ()

    def pause(self) -> None:
        """PAUSE (capability PAUSE): brake along the path, within the grip, and hold; the running
        order and the queue are kept (CHECK_BUSY still reads busy, MOTION says paused)."""
        self._command("PAUSE", needs=("PAUSE",))

    def resume(self) -> None:
        """RESUME (capability PAUSE): go on with the same order, to the same target, from where
        the robot stands."""
        self._command("RESUME", needs=("PAUSE",))

    def stop(self) -> None:
        """STOP (extension): decelerate at the current limits and hold the position reached."""
        self._command("STOP")

    # SET -----------------------------------------------------------------------------------

    def set_vitesse_traj(self, speed_cm_s: int, accel_cm_s2: int | None = None) -> None:
        """SET_VITESSE_TRAJ: straight-line limits, 1..255 cm/s and 1..255 cm/s^2.

        Without ``accel_cm_s2`` the short form is sent and the acceleration is unchanged; with
        ``pec=True`` the board needs the full form, so the acceleration must be given."""
        self._set_vitesse("SET_VITESSE_TRAJ", speed_cm_s, accel_cm_s2)

    def set_vitesse_rot(self, speed_cm_s: int, accel_cm_s2: int | None = None) -> None:
        """SET_VITESSE_ROT: wheel limits during a rotation in place (as set_vitesse_traj)."""
        self._set_vitesse("SET_VITESSE_ROT", speed_cm_s, accel_cm_s2)

    def set_speed_scale(self, percent: int) -> None:
        """SET_SPEED_SCALE (capability SPEED_SCALE): 0..100 % of the speed limits, at once for the
        running order and those that follow; the robot slows or speeds up within its
        acceleration limit and the grip."""
        self._command("SET_SPEED_SCALE", _integer("percent", percent), needs=("SPEED_SCALE",))

    def set_corner(self, tolerance_mm: int) -> None:
        """SET_CORNER (capability CORNERS): how far, 1..255 mm, a pass-through corner's curve may
        stay from its point."""
        self._command("SET_CORNER", _integer("tolerance_mm", tolerance_mm), needs=("CORNERS",))

    def set_filtre(self, preset: Filtre | int) -> None:
        """SET_FILTRE: a preset of PID gains (Filtre.FILTRE_STD, FILTRE_SOUPLE, FILTRE_RAIDE)."""
        self._command("SET_FILTRE", _integer("preset", preset))

    def set_filtre_raw(self, p: int, i: int, d: int) -> None:
        """SET_FILTRE_RAW: raw PID gains, 0..65535 each (scales in docs/protocol.md, 5.4)."""
        self._command("SET_FILTRE_RAW", _integer("p", p), _integer("i", i), _integer("d", d))

    def set_timeout(self, timeout_ms: int) -> None:
        """SET_TIMEOUT (extension): stop the running order when the master has written nothing
        accepted for ``timeout_ms`` (1..65535 ms); 0, the power-on value, turns it off. Only
        writes feed it (orders, settings, ``heartbeat()``): a polling thread that lives on while
        the strategy has hung does not, so such a master is stopped; the order then ends
        PB_MOTEUR with DEBUG end_reason TIMEOUT (docs/failure-model.md, section 5)."""
        self._command("SET_TIMEOUT", _integer("timeout_ms", timeout_ms))

    def heartbeat(self) -> None:
        """HEARTBEAT (extension): the strategy is alive; feeds SET_TIMEOUT, changes nothing
        else. Call it from the thread that decides, not from a polling thread."""
        self._command("HEARTBEAT")

    def fix(
        self,
        x_mm: float,
        y_mm: float,
        heading_deg: float | None,
        sigma_mm: float,
        sigma_deg: float | None,
        age_ms: float,
    ) -> None:
        """SET_FIX (extension): a position fix from a lidar or a camera, with its noise and how
        long before this call it was measured. The board compares it with its estimate of that
        moment, fuses it weighted by both uncertainties (a precise fix pulls hard, a noisy one a
        little), carries the correction to now and shrinks the error radius; a fix too far from
        the estimate is rejected as an outlier and changes nothing (``fix_info()`` counts them).

        ``heading_deg`` None (or ``sigma_deg`` None or 0): the fix has no heading. Ranges:
        x, y -32000..32000 mm, heading -180..180 degrees (0.01), sigma_mm 1..255 (rounded up),
        sigma_deg 0.1..25.5 (rounded up: the noise is never understated), age_ms 0..500.
        Raises Unsupported on a board built without fixes (VERSION's FIX bit 0: the AVR)."""
        for name, v in (("x_mm", x_mm), ("y_mm", y_mm), ("sigma_mm", sigma_mm), ("age_ms", age_ms)):
            if not math.isfinite(v):
                raise ValueError(f"fix: {name}={v} must be finite")
        no_heading = heading_deg is None or sigma_deg is None or sigma_deg == 0
        if not no_heading:
            assert heading_deg is not None and sigma_deg is not None
            if not (math.isfinite(heading_deg) and math.isfinite(sigma_deg)):
                raise ValueError("fix: heading_deg and sigma_deg must be finite")
            if not -180 <= heading_deg <= 180 or not 0 < sigma_deg <= 25.5:
                raise ValueError(
                    f"fix: heading_deg={heading_deg} must be -180..180 and sigma_deg={sigma_deg}"
                    " 0..25.5"
                )
        if not 0 < sigma_mm <= 255 or not 0 <= age_ms <= 500:
            raise ValueError(f"fix: sigma_mm={sigma_mm} must be 0..255, age_ms={age_ms} 0..500")
        self._require(("FIX",), "SET_FIX")
        self._command(
            "SET_FIX",
            round(x_mm),
            round(y_mm),
            0 if no_heading else round(heading_deg * 100),  # type: ignore[operator]
            math.ceil(sigma_mm),
            0 if no_heading else math.ceil(sigma_deg * 10 - 1e-9),  # type: ignore[operator]
            round(age_ms),
        )

    def fix_info(self) -> FixInfo:
        """FIX_INFO (extension): fixes fused, rejected as outliers, rejected as too old or
        stale, since power-on (each wrapping at 65536), and the last one's result."""
        self._require(("FIX",), "FIX_INFO")
        return self._query("FIX_INFO", FixInfo)

    def reset_info(self) -> ResetInfo:
        """RESET_INFO (extension): the last reset's cause, the resets since power-on, whether
        the pose survived it (``pose_lost``: motion orders are refused, REFUSED_NO_POSE, until
        ``set_new_pos()`` or ``declare_pose()``) and the radius's widening for the time the
        board was down. Read it when the status shows PB_MOTEUR with DEBUG end_reason RESET."""
        self._require(("RESET_INFO",), "RESET_INFO")
        return self._query("RESET_INFO", ResetInfo)

    def set_new_pos(self, err_x_mm: int, err_y_mm: int, err_angle_deg: int) -> None:
        """SET_NEW_POS: the error of the board's estimate (estimate minus truth), which the
        board subtracts: X, Y within -32000..32000 mm, angle within -180..180 whole degrees.
        To declare a known pose instead, use ``declare_pose``."""
        self._command(
            "SET_NEW_POS",
            _integer("err_x_mm", err_x_mm),
            _integer("err_y_mm", err_y_mm),
            _integer("err_angle_deg", err_angle_deg),
        )

    def bootloader(self) -> None:
        """BOOTLOADER (extension): leave the application for the bootloader, which takes a
        firmware update (docs/update.md, ``asserv.update``). Refused (OrderRejected,
        REFUSED_BUSY) while an order runs: stop the robot first. The board leaves at its next
        control tick; a board without a bootloader (the AVR, a Simulator without
        ``add_bootloader``) ignores it."""
        self._command("BOOTLOADER", 0xB007)

    def set_odometrie(self, ratio_ppm: int, track_10um: int, scale_ppm: int = 0) -> None:
        """SET_ODOMETRIE (extension): the odometry's calibration, absolute (docs/calibration.md).

        ratio_ppm: -30000..30000, the right wheel's factor times (1 + ratio/2) and the left's
        times (1 - ratio/2), from the build's nominal factors; track_10um: the encoder track in
        0.01 mm, 1639..65535; scale_ppm: -30000..30000, both factors times (1 + scale). The pose
        and the error radius are kept."""
        self._command(
            "SET_ODOMETRIE",
            _integer("ratio_ppm", ratio_ppm),
            _integer("track_10um", track_10um),
            _integer("scale_ppm", scale_ppm),
        )

    def declare_pose(self, x_mm: int, y_mm: int, angle_deg: int) -> None:
        """Tell the board that the robot truly is at (x_mm, y_mm, angle_deg): read POSITION and
        DEBUG's fine heading, and send their difference with the truth as SET_NEW_POS
        (docs/protocol.md, 5.5). The robot should stand still between the reads and the write."""
        x, y, a = _integer("x_mm", x_mm), _integer("y_mm", y_mm), _integer("angle_deg", angle_deg)
        with self._lock:
            pose = self.position()
            heading_deg = round(self.debug().heading_cdeg / 100)
            err_angle = (heading_deg - a + 180) % 360 - 180
            self.set_new_pos(pose.x_mm - x, pose.y_mm - y, err_angle)

    # ETAT ----------------------------------------------------------------------------------

    def check_busy(self) -> Status:
        """CHECK_BUSY: the status byte, as named flags (Status.BUSY_TRAJET, ...)."""
        return self._query("CHECK_BUSY", Status)

    def position(self) -> Pose:
        """POSITION: x_mm, y_mm, angle_2deg (``.angle_deg`` in degrees), radius_mm."""
        return self._query("POSITION", Pose)

    def info_choc(self) -> int:
        """INFO_CHOC: the shock sensors, bit n set when CAPTEUR_n is pressed."""
        return self._query("INFO_CHOC", int)

    def version(self) -> Version:
        """VERSION (extension): protocol major, minor and capability bits."""
        return self._query("VERSION", Version)

    def motion(self) -> Motion:
        """MOTION (capability PAUSE): the running order's sequence number (of the last accepted
        one when idle), the orders pending, paused or not, the last ending, the braking distance
        and time if paused now, the speed scale."""
        self._require(_MOTION_CAPS, "MOTION")
        return self._query("MOTION", Motion)

    def capabilities(self, *, refresh: bool = False) -> Capability:
        """VERSION's capability bits, read once per Board (``refresh``: read them again, after
        the board was flashed)."""
        if self._capabilities is None or refresh:
            self._capabilities = self.version().capabilities
        return self._capabilities

    def last_reject(self) -> LastReject:
        """LAST_REJECT (extension): why the last rejected write was rejected, and the count."""
        return self._query("LAST_REJECT", LastReject)

    def debug(self) -> Debug:
        """DEBUG: the telemetry frame (units in protocol/messages.toml)."""
        return self._query("DEBUG", Debug)

    def wait_idle(self, timeout_s: float, poll_s: float = 0.01) -> Status:
        """Poll CHECK_BUSY every ``poll_s`` until the board is no longer busy; return the final
        status (look at PB_MOTEUR, CHOC_BORD, CHOC_PANIER, PB_GRAVE to see how the order ended).

        An order the board has accepted but not yet started reads as busy, so calling this right
        after an order never returns early. Uses the bus's clock when it has one (a simulated
        bus), the system clock otherwise. Raises BoardTimeout after ``timeout_s`` seconds; the
        robot is then still moving: ``stop()`` it if that is what you want."""
        if not timeout_s >= 0:
            raise ValueError(f"timeout_s={timeout_s} must be >= 0")
        if not poll_s > 0:
            raise ValueError(f"poll_s={poll_s} must be > 0")
        busy = Status.BUSY_TRAJET | Status.BUSY_GOTO_PANIER
        start = self.now()
        while True:
            status = self.check_busy()
            if not status & busy:
                return status
            remaining = timeout_s - (self.now() - start)
            if remaining <= 1e-9:  # not a sleep of rounding errors more
                raise BoardTimeout(
                    f"the board at 0x{self.address:02x} is still busy after {timeout_s:g} s"
                    f" (status 0x{int(status):02x}: {_flag_names(status)})",
                    status,
                )
            self.sleep(min(poll_s, remaining))

    def complete(
        self,
        order: Callable[..., object],
        *args: Any,
        timeout_s: float = 30.0,
        poll_s: float = 0.01,
    ) -> Outcome:
        """Send an order, wait for its end and say how it ended::

            outcome = board.complete(board.goto, 600, 0, GotoOption.RECALAGE_BORD, timeout_s=10)
            if outcome is Outcome.BORDER_RECALIBRATED: ...

        ``order(*args)`` sends it (a method of this board, or any callable that sends one);
        OrderRejected and the bus errors are raised as they are. The final status and DEBUG's
        end_reason are read together under the bus lock and told apart by ``outcome_of``. After
        ``timeout_s`` on the board's clock the robot is sent STOP and the outcome is TIMEOUT."""
        if not timeout_s >= 0 or timeout_s == math.inf:
            raise ValueError(f"timeout_s={timeout_s} must be finite and >= 0")
        if not poll_s > 0:
            raise ValueError(f"poll_s={poll_s} must be > 0")
        order(*args)
        busy = Status.BUSY_TRAJET | Status.BUSY_GOTO_PANIER
        start = self.now()
        while True:
            with self._lock:
                status = self.check_busy()
                if not status & busy:
                    return outcome_of(status, self.debug().end_reason)
            remaining = timeout_s - (self.now() - start)
            if remaining <= 1e-9:
                self.stop()
                return Outcome.TIMEOUT
            self.sleep(min(poll_s, remaining))

    # Transactions --------------------------------------------------------------------------

    def _set_vitesse(self, name: str, speed: int, accel: int | None) -> None:
        if accel is None:
            if self.pec:
                raise codec.FrameError(
                    Reject.BAD_LENGTH,
                    f"{name}: with PEC the board needs the full form; give accel_cm_s2 too"
                    " (40 cm/s^2 after a reset)",
                )
            self._command(name, _integer("speed_cm_s", speed))
        else:
            self._command(name, _integer("speed_cm_s", speed), _integer("accel_cm_s2", accel))

    def _rdwr(self, name: str, *msgs: i2c_msg, at_deadline: bool = False) -> None:
        if not at_deadline and name != "STOP":  # STOP is always let through
            self._check_deadline(name)
        try:
            with self._lock:
                self.bus.i2c_rdwr(*msgs)
        except OSError as e:
            if e.errno in _NACK_ERRNOS:
                what = (
                    ", or a clock-stretching timeout on a Raspberry Pi"
                    if e.errno == errno.EIO
                    else ""
                )
                raise NoAcknowledge(
                    f"{name}: no acknowledge from address 0x{self.address:02x} on the bus"
                    f" ({_errno_name(e.errno)}{what}; is the board powered and wired?)",
                    self.address,
                    e.errno,
                ) from e
            hint = _BUS_HINTS.get(e.errno) if e.errno is not None else None
            detail = os.strerror(e.errno) if e.errno is not None else str(e)
            raise BusError(
                f"{name}: bus error talking to 0x{self.address:02x}:"
                f" {_errno_name(e.errno)} ({detail})" + (f"; {hint}" if hint else ""),
                e.errno,
            ) from e

    def _write_read(self, name: str, frame: bytes, reply: str) -> codec.Reply:
        """S addr+W [frame] Sr addr+R <reply (+ PEC)> P, decoded as ``reply``."""
        n = codec.reply_length(reply) + (1 if self.pec else 0)
        w = i2c_msg.write(self.address, frame)
        r = i2c_msg.read(self.address, n)
        self._rdwr(name, w, r)
        data = bytes(r)
        prefix = None
        if self.pec:
            prefix = bytes(
                [codec.write_address(self.address), *frame, codec.read_address(self.address)]
            )
        try:
            return codec.decode_reply(reply, data, pec_prefix=prefix)
        except codec.PecError as e:
            raise PecMismatch(
                f"{name}: corrupted reply from 0x{self.address:02x}: {e} (read {data.hex(' ')})"
            ) from e

    def _query(self, name: str, kind: type[T]) -> T:
        frame = codec.encode(name, pec=self.pec, address=self.address)
        try:
            with self._lock:
                reply = self._write_read(name, frame, name)
        except PecMismatch as e:
            raise PecMismatch(
                f"{e}; if the designation itself was corrupted, the board sent its status byte"
                " instead: read again"
            ) from e
        return _expect(name, reply, kind)

    def _command(self, name: str, *args: int, needs: tuple[str, ...] = ()) -> None:
        """An ORDRE or SET; with ``check``, confirm in the same transaction that it was taken
        (the write, the status and LAST_REJECT under the bus lock: no other thread's write
        in between). ``needs``: the capabilities it takes, all of them (``Unsupported``)."""
        frame = codec.encode(name, *args, pec=self.pec, address=self.address)
        for cap in needs:
            self._require((cap,), name)
        with self._lock:
            self._command_locked(name, frame, args)

    def _require(self, caps: tuple[str, ...], what: str) -> None:
        """Raise Unsupported unless the board has one of ``caps`` (names of the capability
        table)."""
        have = self.capabilities()
        if any(c in Capability.__members__ and Capability[c] & have for c in caps):
            return
        names = " ".join(f.name for f in Capability if f in have and f.name) or "none"
        which = caps[0] if len(caps) == 1 else "any of " + ", ".join(caps)
        raise Unsupported(
            f"{what}: this board has no {which} (its VERSION lists {names}: a build that"
            " compiles it out, or an older firmware; nothing was sent)",
            caps[0],
        )

    def _command_locked(self, name: str, frame: bytes, args: tuple[int, ...]) -> None:
        if not self.check:
            self._rdwr(name, i2c_msg.write(self.address, frame))
            return
        try:
            status = self._write_read(name, frame, "CHECK_BUSY")
        except PecMismatch:
            # The write went out but the status came back corrupted. No designation is selected
            # after an order or setting, so a plain read gives the status again; it still says
            # whether the last write (ours) was rejected.
            status = self._read_status(name)
        if _expect(name, status, Status) & Status.COMMANDE_REJETEE:
            raise self._rejected(name, frame[0], args)

    def _read_status(self, name: str) -> Status:
        r = i2c_msg.read(self.address, 2 if self.pec else 1)
        self._rdwr(name, r)
        data = bytes(r)
        prefix = bytes([codec.read_address(self.address)]) if self.pec else None
        try:
            reply = codec.decode_reply("CHECK_BUSY", data, pec_prefix=prefix)
        except codec.PecError as e:
            raise PecMismatch(
                f"{name}: the status after the write was corrupted twice ({e}): the board may or"
                " may not have taken it; read check_busy() and last_reject().count before"
                " sending it again"
            ) from e
        return _expect(name, reply, Status)

    def _rejected(self, name: str, designation: int, args: tuple[int, ...]) -> OrderRejected:
        why = self.last_reject()
        params = codec.message(name).params
        sent = " ".join(f"{f.name}={v}" for f, v in zip(params, args, strict=False))
        sent = f" (sent {name}{' ' + sent if sent else ''})"
        if why.designation != designation:
            other = codec.BY_DESIGNATION.get(why.designation)
            label = other.name if other else f"designation 0x{why.designation:02x}"
            msg = (
                f"{name} rejected by the board, but LAST_REJECT names another write, {label}:"
                f" {why.reason.name} (another master on the bus?)"
            )
        else:
            hint = _REJECT_HINTS.get(why.reason)
            msg = f"{name} rejected by the board: {why.reason.name}" + (f": {hint}" if hint else "")
        return OrderRejected(msg + sent, name, why.reason, why.designation, why.count)


def _integer(name: str, value: object) -> int:
    """The value as an int, refusing floats and other non-integers (never truncate silently)."""
    if not isinstance(value, SupportsIndex):
        raise TypeError(f"{name} must be an integer, got {value!r}")
    return operator.index(value)


_MOTION_CAPS = ("PAUSE",)  # messages.toml: PAUSE covers PAUSE, RESUME and MOTION


def _flag(name: str, value: object) -> bool:
    if not isinstance(value, bool):
        raise TypeError(f"{name} must be True or False, got {value!r}")
    return value


def _needs(options: int) -> tuple[str, ...]:
    """The capabilities GOTO's option bits take."""
    return (("QUEUE",) if options & GotoOption.APPEND else ()) + (
        ("CORNERS",) if options & GotoOption.PASS_THROUGH else ()
    )


def _needs_append(append: bool) -> tuple[str, ...]:
    return ("QUEUE",) if append else ()


def _expect(name: str, reply: codec.Reply, kind: type[T]) -> T:
    if not isinstance(reply, kind):  # the codec's table and this driver disagree
        raise TypeError(f"{name}: decoded {reply!r}, not a {kind.__name__}")
    return reply


def _flag_names(status: Status) -> str:
    """``BUSY_TRAJET BUSY_GOTO_PANIER``, or ``none``."""
    names = [f.name for f in Status if f in status and f.name]
    return " ".join(names) if names else "none"
