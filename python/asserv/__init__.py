"""asserv: master-side tools of the asserv motion-control board (driver, codec, simulator)."""

from ._protocol import ADDRESS, Capability, EndReason, Filtre, OrderState, Reject, Status
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

__all__ = [
    "ADDRESS",
    "Capability",
    "Debug",
    "EndReason",
    "Filtre",
    "FrameError",
    "LastReject",
    "OrderState",
    "PecError",
    "Pose",
    "Reject",
    "Status",
    "Version",
    "crc8",
    "decode_reply",
    "decode_write",
    "encode",
]
