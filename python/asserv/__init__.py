"""asserv: master-side tools of the asserv motion-control board (driver, codec, simulator)."""

from ._protocol import ADDRESS, Capability, EndReason, Filtre, OrderState, Reject, Status
from .bus import Clock, I2CDevice, ProtocolDevice, VirtualBus
from .codec import (
    Debug,
    FrameError,
    LastReject,
    PecError,
    Pose,
    Version,
    crc8,
    decode_reply,
    decode_write,
    encode,
)
from .driver import (
    AsservError,
    Board,
    BoardTimeout,
    BusError,
    GotoOption,
    NoAcknowledge,
    OrderRejected,
    PecMismatch,
)

__all__ = [
    "ADDRESS",
    "AsservError",
    "Board",
    "BoardTimeout",
    "BusError",
    "Capability",
    "Clock",
    "Debug",
    "EndReason",
    "Filtre",
    "FrameError",
    "GotoOption",
    "I2CDevice",
    "LastReject",
    "NoAcknowledge",
    "OrderRejected",
    "OrderState",
    "PecError",
    "PecMismatch",
    "Pose",
    "ProtocolDevice",
    "Reject",
    "Status",
    "Version",
    "VirtualBus",
    "crc8",
    "decode_reply",
    "decode_write",
    "encode",
]
