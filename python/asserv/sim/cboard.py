"""The board's C protocol layer (firmware/core/protocol.c), driven byte by byte from Python.

This is the very code the board runs, compiled into ``asserv.sim._core``: tests and the protocol
demonstration use it to play I2C transactions against the board without hardware.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from ._core import ffi, lib


@dataclass(frozen=True)
class Taken:
    """A message the control core took from the protocol layer's queue."""

    designation: int
    args: tuple[int, ...]


class ProtocolLayer:
    """One board's protocol state (``struct proto``), with bus-level helpers."""

    def __init__(self) -> None:
        self._p = ffi.new("struct proto *")
        self._snap = ffi.new("struct proto_snapshot *")
        lib.proto_init(self._p)
        self._in_write = False

    def write(self, data: bytes | list[int], *, stop: bool = True) -> None:
        """One write transaction: START, address+W, the bytes, then STOP unless ``stop`` is
        False (the next read then follows by a repeated start)."""
        lib.proto_on_write_start(self._p)
        for b in bytes(data):
            lib.proto_on_byte(self._p, b)
        if stop:
            lib.proto_on_stop(self._p)

    def read(self, n: int) -> bytes:
        """One read of ``n`` bytes: address+R (after a STOP or as a repeated start), then STOP."""
        lib.proto_on_read_start(self._p)
        out = bytes(lib.proto_read_byte(self._p) for _ in range(n))
        lib.proto_on_stop(self._p)
        return out

    def abort(self) -> None:
        """A bus error in the middle of a transaction."""
        lib.proto_on_abort(self._p)

    def status(self) -> int:
        """The status byte a read would return now."""
        return int(lib.proto_status(self._p))

    def set_snapshot(self, **fields: Any) -> None:
        """Set fields of the state the next publish() makes visible (x_mm=..., status=...)."""
        for name, value in fields.items():
            if name == "debug":
                for k, v in value.items():
                    setattr(self._snap.debug, k, v)
            else:
                setattr(self._snap, name, value)

    def tick(self) -> list[Taken]:
        """What one control tick does with the protocol: take every queued message, then publish
        the snapshot."""
        taken = []
        msg = ffi.new("struct proto_msg *")
        while lib.proto_poll(self._p, msg):
            taken.append(Taken(msg.designation, tuple(msg.arg[i] for i in range(msg.n_args))))
        lib.proto_publish(self._p, self._snap)
        return taken
