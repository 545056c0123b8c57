"""The master's codec of the board's I2C protocol: encode every write, decode every reply.

Everything is driven by the generated message table (``_protocol.py``, from
``protocol/messages.toml``), and validation follows the board's rules exactly, so that a frame
this module refuses is a frame the board would reject, with the same reason.
"""

from __future__ import annotations

import difflib
import math
from dataclasses import dataclass, fields
from typing import Final, NamedTuple

from ._protocol import (
    ADDRESS,
    MAX_WRITE,
    MESSAGES,
    Capability,
    EndReason,
    Field,
    FixResult,
    Message,
    OrderState,
    Reject,
    ResetCause,
    Status,
)

_SIZE: Final = {"u8": 1, "s8": 1, "u16": 2, "s16": 2}

BY_NAME: Final[dict[str, Message]] = {m.name: m for m in MESSAGES}
BY_DESIGNATION: Final[dict[int, Message]] = {
    d: m for m in MESSAGES for d in (m.designation, *m.aliases)
}


class FrameError(ValueError):
    """A frame the board rejects, with the board's reason code and where it went wrong."""

    def __init__(self, reason: Reject, detail: str) -> None:
        super().__init__(f"{reason.name}: {detail}")
        self.reason = reason
        self.detail = detail


def crc8(data: bytes | bytearray | list[int], crc: int = 0) -> int:
    """SMBus PEC: CRC-8, polynomial x^8 + x^2 + x + 1 (0x07), no reflection, from ``crc``."""
    for byte in data:
        crc ^= byte
        for _ in range(8):
            crc = ((crc << 1) ^ 0x07) & 0xFF if crc & 0x80 else (crc << 1) & 0xFF
    return crc


def write_address(address: int = ADDRESS) -> int:
    """The address byte of a write transaction."""
    return (address << 1) & 0xFE


def read_address(address: int = ADDRESS) -> int:
    """The address byte of a read transaction."""
    return ((address << 1) | 1) & 0xFF


def message(name_or_designation: str | int) -> Message:
    """The table entry of a message, by name or designation byte (aliases too).

    Names are taken in any case, with ``-`` for ``_``: ``"GOTO_PANIER"``, ``"goto_panier"`` and
    ``"goto-panier"`` are the same message."""
    if isinstance(name_or_designation, str):
        key = name_or_designation.strip().upper().replace("-", "_")
        if key in BY_NAME:
            return BY_NAME[key]
        close = difflib.get_close_matches(key, BY_NAME, n=3)
        hint = f" (did you mean {', '.join(close)}?)" if close else ""
        raise FrameError(Reject.UNKNOWN_DESIGNATION, f"no message {name_or_designation!r}{hint}")
    try:
        return BY_DESIGNATION[name_or_designation]
    except KeyError:
        raise FrameError(
            Reject.UNKNOWN_DESIGNATION, f"no message {name_or_designation!r}"
        ) from None


# Angles in 2-degree steps (GOTO_PANIER's param, POSITION's angle): the one unit that is not the
# user's. Everything shown or typed is in degrees; the raw steps only where asked for (``raw``).
STEP_SUFFIX: Final = "_2deg"


def is_2deg(f: Field) -> bool:
    """True for a field that travels in 2-degree steps."""
    return f.name.endswith(STEP_SUFFIX)


def deg_name(f: Field) -> str:
    """The field's name in degrees: ``angle_2deg`` -> ``angle_deg``; other names unchanged."""
    return f.name.removesuffix(STEP_SUFFIX) + "_deg" if is_2deg(f) else f.name


def steps_2deg(angle_deg: float) -> int:
    """Degrees to 2-degree steps: the nearest step, a half step going towards zero (45 -> 22, as
    the 2002 annex sends it; -45 -> -22). ``angle_deg`` must be finite."""
    steps = math.ceil(abs(angle_deg) / 2 - 0.5)
    return -steps if angle_deg < 0 else steps


def encode_deg(name: str, *values: float, pec: bool = False, address: int = ADDRESS) -> bytes:
    """``encode`` with the user's units: an angle in 2-degree steps is given in degrees
    (-180..180, rounded as ``steps_2deg``); the other params as in the table. Raises FrameError
    (OUT_OF_RANGE names the angle in degrees)."""
    msg = message(name)
    args: list[int] = []
    for f, v in zip(msg.params, values, strict=False):
        if is_2deg(f):
            lo, hi = 2 * f.min, 2 * f.max
            if not (math.isfinite(v) and lo <= v <= hi):
                raise FrameError(
                    Reject.OUT_OF_RANGE, f"{msg.name}.{deg_name(f)}={v:g} is outside {lo}..{hi}"
                )
            args.append(steps_2deg(v))
        elif isinstance(v, int):
            args.append(v)
        else:
            raise FrameError(Reject.OUT_OF_RANGE, f"{msg.name}.{f.name}={v!r} is not an integer")
    args.extend(int(v) for v in values[len(msg.params) :])  # too many: encode says BAD_LENGTH
    return encode(msg.name, *args, pec=pec, address=address)


def _check(msg: Message, f: Field, value: int) -> None:
    if f.mask is not None:
        if not 0 <= value <= 0xFF:
            raise FrameError(Reject.OUT_OF_RANGE, f"{msg.name}.{f.name}={value} is not a byte")
        if value & ~f.mask:
            raise FrameError(
                Reject.RESERVED_BIT,
                f"{msg.name}.{f.name}=0x{value:02x} sets reserved bits (allowed 0x{f.mask:02x})",
            )
    elif not f.min <= value <= f.max:
        raise FrameError(
            Reject.OUT_OF_RANGE, f"{msg.name}.{f.name}={value} is outside {f.min}..{f.max}"
        )


def _pack(f: Field, value: int) -> bytes:
    signed = f.type.startswith("s")
    return int(value).to_bytes(_SIZE[f.type], "big", signed=signed)


def _unpack(f: Field, data: bytes) -> int:
    return int.from_bytes(data, "big", signed=f.type.startswith("s"))


def encode(name: str, *args: int, pec: bool = False, address: int = ADDRESS) -> bytes:
    """The bytes of a write: designation, then params big-endian, then the PEC if asked.

    ``args`` are the params in table order; messages with a short form (SET_VITESSE_TRAJ,
    SET_VITESSE_ROT) take fewer. A PEC is only possible on the full form (docs/protocol.md).
    Raises FrameError with the reason the board would give.
    """
    msg = message(name)
    n = len(args)
    if not msg.min_params <= n <= len(msg.params):
        want = (
            f"{len(msg.params)}"
            if msg.min_params == len(msg.params)
            else f"{msg.min_params}..{len(msg.params)}"
        )
        raise FrameError(Reject.BAD_LENGTH, f"{msg.name} takes {want} params, got {n}")
    if pec and n != len(msg.params):
        raise FrameError(
            Reject.BAD_LENGTH, f"{msg.name}: a PEC needs the full form ({len(msg.params)} params)"
        )
    out = bytearray([msg.designation])
    for f, value in zip(msg.params, args, strict=False):
        _check(msg, f, value)
        out += _pack(f, value)
    _check_options(msg, list(args))
    if pec:
        out.append(crc8(bytes([write_address(address)]) + out))
    return bytes(out)


@dataclass(frozen=True)
class Write:
    """A write as the board understands it."""

    message: Message
    args: tuple[int, ...]
    pec: bool

    def describe(self, raw: bool = False) -> str:
        """``GOTO_PANIER angle_deg=44``: angles in degrees; ``raw``: as sent (``angle_2deg=22``)."""
        params = " ".join(
            f"{f.name}={v}" if raw or not is_2deg(f) else f"{deg_name(f)}={2 * v}"
            for f, v in zip(self.message.params, self.args, strict=False)
        )
        pec = " +PEC" if self.pec else ""
        return f"{self.message.name} {params}".rstrip() + pec


def decode_write(frame: bytes | bytearray | list[int], address: int = ADDRESS) -> Write:
    """Judge a write as the board does: the message and its params, or FrameError."""
    frame = bytes(frame)
    n = len(frame)
    if n == 0:
        raise FrameError(Reject.BAD_LENGTH, "empty write (an address-only write is not a frame)")
    if n > MAX_WRITE:
        raise FrameError(Reject.BAD_LENGTH, f"{n} bytes, longer than any message ({MAX_WRITE})")
    msg = BY_DESIGNATION.get(frame[0])
    if msg is None:
        raise FrameError(Reject.UNKNOWN_DESIGNATION, f"designation {frame[0]} names no message")
    full = 1 + sum(_SIZE[f.type] for f in msg.params)
    short = 1 + sum(_SIZE[f.type] for f in msg.params[: msg.min_params])
    if n == full:
        params, pec = msg.params, False
    elif n == short:
        params, pec = msg.params[: msg.min_params], False
    elif n == full + 1:
        params, pec = msg.params, True
        want = crc8(bytes([write_address(address)]) + frame[:-1])
        if frame[-1] != want:
            raise FrameError(
                Reject.BAD_PEC, f"{msg.name}: PEC 0x{frame[-1]:02x}, expected 0x{want:02x}"
            )
    else:
        raise FrameError(
            Reject.BAD_LENGTH,
            f"{msg.name}: {n} bytes, expected {full}"
            + (f" or {short}" if short != full else "")
            + f" (or {full + 1} with PEC)",
        )
    args = []
    pos = 1
    for f in params:
        size = _SIZE[f.type]
        value = _unpack(f, frame[pos : pos + size])
        _check(msg, f, value)
        args.append(value)
        pos += size
    _check_options(msg, args)
    return Write(msg, tuple(args), pec)


#: GOTO's recalibration bits, which PASS_THROUGH cannot combine with (issue 31).
_RECAL_BITS = 0x03
_PASS_THROUGH = 0x08


def _check_options(msg: Message, args: list[int]) -> None:
    # The board's check after the table's (firmware/core/protocol.c, check_motion()): the
    # queue's room is the board's state, not the frame's, so MOTION_QUEUE_FULL is not judged here.
    if msg.name == "GOTO" and len(args) == 3 and args[2] & _PASS_THROUGH and args[2] & _RECAL_BITS:
        raise FrameError(
            Reject.BAD_OPTIONS, "GOTO: PASS_THROUGH cannot combine with a recalibration option"
        )


@dataclass(frozen=True, repr=False)
class Pose:
    """POSITION: the board's estimate and its error radius. The angle travels in 2-degree steps
    (``angle_2deg``, as on the wire); it is shown in degrees (``angle_deg``)."""

    x_mm: int
    y_mm: int
    angle_2deg: int
    radius_mm: int

    @property
    def angle_deg(self) -> int:
        return 2 * self.angle_2deg

    def __repr__(self) -> str:
        return (
            f"Pose(x_mm={self.x_mm}, y_mm={self.y_mm}, angle_deg={self.angle_deg},"
            f" radius_mm={self.radius_mm})"
        )


@dataclass(frozen=True)
class Version:
    """VERSION (extension)."""

    major: int
    minor: int
    capabilities: Capability


@dataclass(frozen=True)
class LastReject:
    """LAST_REJECT (extension)."""

    reason: Reject
    designation: int
    count: int


@dataclass(frozen=True)
class Debug:
    """DEBUG telemetry (units in protocol/messages.toml)."""

    tick: int
    heading_cdeg: int
    speed_mm_s: int
    turn_rate_cdeg_s: int
    dist_err_um: int
    angle_err_um: int
    duty_left_q15: int
    duty_right_q15: int
    current_left_ma: int
    current_right_ma: int
    order_state: OrderState
    end_reason: EndReason


class Motion(NamedTuple):
    """MOTION (extension, docs/protocol.md): the queue, the pause and the braking distance, in
    one reply a master can read every cycle."""

    running_seq: int  # sequence number of the running order (8 bits, wrapping)
    pending: int  # orders waiting behind it
    flags: int  # bit 0 paused, bit 1 an order runs
    last_seq: int  # sequence number of the order that ended last
    last_end: EndReason  # how it ended
    braking_mm: int  # distance to rest at the present speed and limits
    braking_ms: int  # time to rest
    scale_percent: int  # the speed scale (SET_SPEED_SCALE)

    @property
    def paused(self) -> bool:
        return bool(self.flags & 1)

    @property
    def running(self) -> bool:
        """An order runs (paused or not)."""
        return bool(self.flags & 2)


@dataclass(frozen=True)
class FixInfo:
    """FIX_INFO (extension): the fixes' counts since power-on (wrapping at 65536) and the last
    one's result."""

    fused: int
    outliers: int
    too_old: int
    last: FixResult
    last_d2: int


@dataclass(frozen=True)
class ResetInfo:
    """RESET_INFO (extension): why the board last started, the resets since power-on, whether
    the pose survived (pose_lost: motion orders refused until SET_NEW_POS) and what the radius
    was widened by for the time the board was down."""

    cause: ResetCause
    count: int
    pose_lost: bool
    widened_mm: int


Reply = Status | Pose | int | Version | LastReject | Debug | Motion | FixInfo | ResetInfo


class PecError(ValueError):
    """A reply whose PEC does not match: the bytes were corrupted on the bus."""


def reply_length(name: str) -> int:
    """Bytes of a reply, without PEC."""
    return sum(_SIZE[f.type] for f in message(name).reply)


def decode_reply(
    name: str, data: bytes | bytearray | list[int], pec_prefix: bytes | None = None
) -> Reply:
    """Decode the bytes read after an ETAT designation into a named type.

    With ``pec_prefix`` (the transaction's bytes before the reply: the read address byte, preceded
    by the write address byte and the designation when the read follows by a repeated start), the
    last byte of ``data`` is the PEC and is checked.
    """
    msg = message(name)
    data = bytes(data)
    n = reply_length(msg.name)
    if pec_prefix is not None:
        if len(data) != n + 1:
            raise ValueError(f"{msg.name}: {len(data)} bytes read, expected {n} + PEC")
        want = crc8(pec_prefix + data[:-1])
        if data[-1] != want:
            raise PecError(f"{msg.name}: PEC 0x{data[-1]:02x}, expected 0x{want:02x}")
        data = data[:-1]
    if len(data) != n:
        raise ValueError(f"{msg.name}: {len(data)} bytes read, expected {n}")
    values = []
    pos = 0
    for f in msg.reply:
        values.append(_unpack(f, data[pos : pos + _SIZE[f.type]]))
        pos += _SIZE[f.type]
    if msg.name == "CHECK_BUSY":
        return Status(values[0])
    if msg.name == "POSITION":
        return Pose(*values)
    if msg.name == "INFO_CHOC":
        return values[0]
    if msg.name == "VERSION":
        return Version(values[0], values[1], Capability(values[2]))
    if msg.name == "LAST_REJECT":
        return LastReject(Reject(values[0]), values[1], values[2])
    if msg.name == "DEBUG":
        v = dict(zip((f.name for f in msg.reply), values, strict=True))
        return Debug(
            tick=v["tick"],
            heading_cdeg=v["heading_cdeg"],
            speed_mm_s=v["speed_mm_s"],
            turn_rate_cdeg_s=v["turn_rate_cdeg_s"],
            dist_err_um=v["dist_err_um"],
            angle_err_um=v["angle_err_um"],
            duty_left_q15=v["duty_left_q15"],
            duty_right_q15=v["duty_right_q15"],
            current_left_ma=v["current_left_ma"],
            current_right_ma=v["current_right_ma"],
            order_state=OrderState(v["order_state"]),
            end_reason=EndReason(v["end_reason"]),
        )
    if msg.name == "MOTION":
        m = dict(zip((f.name for f in msg.reply), values, strict=True))
        return Motion(
            running_seq=m["running_seq"],
            pending=m["pending"],
            flags=m["flags"],
            last_seq=m["last_seq"],
            last_end=EndReason(m["last_end"]),
            braking_mm=m["braking_mm"],
            braking_ms=m["braking_ms"],
            scale_percent=m["scale_percent"],
        )
    if msg.name == "RESET_INFO":
        return ResetInfo(ResetCause(values[0]), values[1], bool(values[2]), values[3])
    if msg.name == "FIX_INFO":
        return FixInfo(values[0], values[1], values[2], FixResult(values[3]), values[4])
    raise AssertionError(f"no decoder for {msg.name}")  # the table check keeps this unreachable


def reply_fields(reply: Reply) -> dict[str, int]:
    """The reply's values by table field name, for printing and for comparing with the table."""
    if isinstance(reply, Pose | Version | LastReject | Debug | FixInfo | ResetInfo):
        return {f.name: int(getattr(reply, f.name)) for f in fields(reply)}
    if isinstance(reply, Motion):
        return {k: int(v) for k, v in reply._asdict().items()}
    return {"value": int(reply)}
