"""asserv: master-side tools of the asserv motion-control board (driver, codec, simulator).

``pip install asserv``: the driver, the codec and the CLI (needs smbus2 only). The simulator
(the subpackage ``asserv.sim``: ``Simulator``, the demo, the benches' runs, the plots) is the
``sim`` extra: ``pip install "asserv[sim]"``.
"""

from importlib.metadata import PackageNotFoundError
from importlib.metadata import version as _version

from ._protocol import (
    ADDRESS,
    Capability,
    EndReason,
    Filtre,
    FixResult,
    OrderState,
    Reject,
    ResetCause,
    Status,
)
from .bus import Clock, I2CDevice, ProtocolDevice, VirtualBus
from .codec import (
    Debug,
    FixInfo,
    FrameError,
    LastReject,
    Motion,
    PecError,
    Pose,
    ResetInfo,
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
    Unsupported,
)

try:
    __version__ = _version("asserv")
except PackageNotFoundError:  # run from a checkout that is not installed
    __version__ = "0+unknown"

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
    "FixInfo",
    "FixResult",
    "FrameError",
    "GotoOption",
    "I2CDevice",
    "LastReject",
    "Motion",
    "NoAcknowledge",
    "OrderRejected",
    "OrderState",
    "PecError",
    "PecMismatch",
    "Pose",
    "ProtocolDevice",
    "Reject",
    "ResetCause",
    "ResetInfo",
    "Status",
    "Unsupported",
    "Version",
    "VirtualBus",
    "__version__",
    "crc8",
    "decode_reply",
    "decode_write",
    "encode",
]
