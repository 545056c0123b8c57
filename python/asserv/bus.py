"""A virtual I2C bus with the smbus2.SMBus interface, to run master code without hardware.

``VirtualBus`` stands where ``smbus2.SMBus(1)`` stands on a Raspberry Pi: the driver, the CLI and a
team's strategy code talk to it the same way. Behind it are I2C slave devices (``I2CDevice``): the
board's own C protocol layer (``ProtocolDevice``), or the simulator, which also provides the clock
so that ``sleep()`` advances simulated time.

What the Linux ``i2c-dev`` interface does and this bus reproduces:

- ``i2c_rdwr(*msgs)`` is one transaction: a START, the messages joined by repeated STARTs, one STOP
  at the end. A read message's buffer is filled in place, so ``bytes(msg)`` and ``list(msg)`` give
  the data, as with a real adapter.
- A message to an address where no device answers is not acknowledged: the transaction stops
  there and ``OSError`` is raised. The errno depends on the adapter driver: ``i2c-bcm2835`` (the
  Raspberry Pi) gives ``EREMOTEIO`` (121), the kernel's documented code and most other adapters
  give ``ENXIO`` (6), and a few give ``EIO`` (5). This bus raises ``ENXIO``. Messages before the
  one that was not acknowledged have gone out, as on a real bus.
- The SMBus calls the board can use (``read_byte``, ``write_byte``, ``read_byte_data``,
  ``write_byte_data``, ``read_i2c_block_data``, ``write_i2c_block_data``, ``write_quick``) are the
  same transactions as the kernel's SMBus emulation over plain I2C: the "command" byte is written
  first, and a read follows by a repeated START.

No SMBus PEC is added by this bus: the driver puts PECs in its frames itself.
"""

from __future__ import annotations

import ctypes
import errno
import os
import time
from collections.abc import Iterable, Mapping
from types import TracebackType
from typing import TYPE_CHECKING, Protocol, runtime_checkable

from smbus2 import i2c_msg

if TYPE_CHECKING:
    from .sim.cboard import ProtocolLayer

I2C_M_RD = 0x0001  # i2c_msg.flags: a read (include/uapi/linux/i2c.h)

# Limits of Linux i2c-dev and of SMBus block transfers (include/uapi/linux/i2c*.h).
I2C_RDWR_MAX_MSGS = 42
I2C_SMBUS_BLOCK_MAX = 32
_MAX_MSG_LEN = 8192


@runtime_checkable
class I2CDevice(Protocol):
    """An I2C slave as the bus sees it. Addressing and ACKs are the bus's business."""

    def i2c_write(self, data: bytes, stop: bool) -> None:
        """START (or repeated START), address+W acked, the bytes, then STOP if ``stop``.

        ``stop`` is False when the next message of the transaction goes to this same device
        (a repeated START follows). ``data`` may be empty: an address-only write."""
        ...

    def i2c_read(self, n: int) -> bytes:
        """(Repeated) START, address+R, ``n`` bytes from the device, NACK, STOP.

        Must return exactly ``n`` bytes."""
        ...


class Clock(Protocol):
    """Where time comes from: the wall clock, or a simulator's clock."""

    def monotonic(self) -> float:
        """Seconds, monotonic."""
        ...

    def sleep(self, seconds: float) -> None:
        """Let ``seconds`` pass (a simulator runs its world for that long)."""
        ...


class SystemClock:
    """The ``time`` module as a Clock: what a real bus (``smbus2.SMBus``) gets."""

    drives_simulation = False

    def monotonic(self) -> float:
        return time.monotonic()

    def sleep(self, seconds: float) -> None:
        time.sleep(seconds)


class _BusMethodsClock:
    """A bus's own ``monotonic()`` and ``sleep()`` as a Clock."""

    def __init__(self, bus: object) -> None:
        self._bus = bus
        self.drives_simulation = bool(getattr(bus, "drives_simulation", False))

    def monotonic(self) -> float:
        return float(self._bus.monotonic())  # type: ignore[attr-defined]

    def sleep(self, seconds: float) -> None:
        self._bus.sleep(seconds)  # type: ignore[attr-defined]


def clock_of(bus: object) -> Clock:
    """The clock of a bus: its ``clock`` attribute (VirtualBus: the simulator's time on a
    simulated bus; RemoteBus: the server's), else its own ``monotonic()`` and ``sleep()``, else
    the wall clock (``smbus2.SMBus``). A clock with ``drives_simulation`` true runs a simulation
    in this process when slept on (``Simulator``)."""
    clock = getattr(bus, "clock", None)
    if callable(getattr(clock, "monotonic", None)) and callable(getattr(clock, "sleep", None)):
        return clock  # type: ignore[return-value]
    if callable(getattr(bus, "monotonic", None)) and callable(getattr(bus, "sleep", None)):
        return _BusMethodsClock(bus)
    return SystemClock()


def _nack(address: int) -> OSError:
    return OSError(
        errno.ENXIO, f"{os.strerror(errno.ENXIO)}: no device acknowledged address 0x{address:02x}"
    )


class VirtualBus:
    """An ``smbus2.SMBus`` look-alike whose slaves are Python objects.

    ``devices`` maps 7-bit addresses to devices; the dict is kept (not copied), so devices can be
    added or removed while the bus is open. ``clock`` defaults to the system clock.
    """

    def __init__(self, devices: Mapping[int, I2CDevice], clock: Clock | None = None) -> None:
        for address in devices:
            _check_address(address)
        self.devices: dict[int, I2CDevice] = devices if isinstance(devices, dict) else dict(devices)
        self.clock: Clock = clock if clock is not None else SystemClock()
        self.closed = False

    # Time, for code that polls (the driver's wait_idle): simulated time with a simulator.
    def monotonic(self) -> float:
        return self.clock.monotonic()

    def sleep(self, seconds: float) -> None:
        self.clock.sleep(seconds)

    # smbus2.SMBus housekeeping.
    def close(self) -> None:
        """Close the bus; later transfers raise OSError(EBADF) like a closed file descriptor."""
        self.closed = True

    def __enter__(self) -> VirtualBus:
        return self

    def __exit__(
        self,
        exc_type: type[BaseException] | None,
        exc: BaseException | None,
        tb: TracebackType | None,
    ) -> None:
        self.close()

    def __repr__(self) -> str:
        addrs = ", ".join(f"0x{a:02x}" for a in sorted(self.devices))
        return f"VirtualBus(devices at [{addrs}]{', closed' if self.closed else ''})"

    # The transaction engine.
    def _transfer(self, ops: list[tuple[int, bytes | None, int]]) -> list[bytes]:
        """Run one transaction. Each op is (address, bytes to write, or None for a read of n).

        Returns the data of each read op, in order."""
        if self.closed:
            raise OSError(errno.EBADF, f"{os.strerror(errno.EBADF)}: the bus is closed")
        out: list[bytes] = []
        for i, (address, data, n) in enumerate(ops):
            device = self.devices.get(address)
            if device is None:
                raise _nack(address)
            if data is not None:
                # The device sees its transaction end (a STOP for it) at the end of the whole
                # transaction, or when the bus moves on to another address.
                last_here = i + 1 == len(ops) or ops[i + 1][0] != address
                device.i2c_write(bytes(data), last_here)
            else:
                got = bytes(device.i2c_read(n))
                if len(got) != n:
                    raise RuntimeError(
                        f"device at 0x{address:02x} returned {len(got)} bytes for a read of {n}"
                    )
                out.append(got)
        return out

    def i2c_rdwr(self, *msgs: i2c_msg) -> None:
        """One combined transaction (the I2C_RDWR ioctl): read messages are filled in place."""
        if not msgs or len(msgs) > I2C_RDWR_MAX_MSGS:
            raise OSError(
                errno.EINVAL,
                f"{os.strerror(errno.EINVAL)}: i2c_rdwr takes 1..{I2C_RDWR_MAX_MSGS} messages,"
                f" got {len(msgs)}",
            )
        ops: list[tuple[int, bytes | None, int]] = []
        for m in msgs:
            address, flags, length = int(m.addr), int(m.flags), int(m.len)
            if flags & ~I2C_M_RD:
                raise OSError(
                    errno.EOPNOTSUPP,
                    f"{os.strerror(errno.EOPNOTSUPP)}: message flags 0x{flags:04x}"
                    " (only plain 7-bit reads and writes are emulated)",
                )
            if not 0 <= address <= 0x7F or length > _MAX_MSG_LEN:
                raise OSError(
                    errno.EINVAL,
                    f"{os.strerror(errno.EINVAL)}: address 0x{address:x}, length {length}",
                )
            if flags & I2C_M_RD:
                ops.append((address, None, length))
            else:
                ops.append((address, ctypes.string_at(m.buf, length), 0))
        reads = iter(self._transfer(ops))
        for m in msgs:
            if int(m.flags) & I2C_M_RD:
                data = next(reads)
                ctypes.memmove(m.buf, data, len(data))

    # SMBus calls, as the kernel emulates them over plain I2C. ``force`` is accepted for
    # compatibility with smbus2 and has no effect (there is no kernel driver to override).
    def write_quick(self, i2c_addr: int, force: bool | None = None) -> None:
        """S addr+W P: an address-only write (what i2cdetect sends)."""
        self._transfer([(_check_address(i2c_addr), b"", 0)])

    def read_byte(self, i2c_addr: int, force: bool | None = None) -> int:
        """S addr+R <byte> P."""
        return self._transfer([(_check_address(i2c_addr), None, 1)])[0][0]

    def write_byte(self, i2c_addr: int, value: int, force: bool | None = None) -> None:
        """S addr+W [value] P."""
        self._transfer([(_check_address(i2c_addr), _bytes([value]), 0)])

    def read_byte_data(self, i2c_addr: int, register: int, force: bool | None = None) -> int:
        """S addr+W [register] Sr addr+R <byte> P."""
        a = _check_address(i2c_addr)
        return self._transfer([(a, _bytes([register]), 0), (a, None, 1)])[0][0]

    def write_byte_data(
        self, i2c_addr: int, register: int, value: int, force: bool | None = None
    ) -> None:
        """S addr+W [register value] P."""
        self._transfer([(_check_address(i2c_addr), _bytes([register, value]), 0)])

    def read_i2c_block_data(
        self, i2c_addr: int, register: int, length: int, force: bool | None = None
    ) -> list[int]:
        """S addr+W [register] Sr addr+R <length bytes> P; length at most 32, as in smbus2."""
        if not 0 <= length <= I2C_SMBUS_BLOCK_MAX:
            raise ValueError(f"Desired block length over {I2C_SMBUS_BLOCK_MAX} bytes")
        a = _check_address(i2c_addr)
        return list(self._transfer([(a, _bytes([register]), 0), (a, None, length)])[0])

    def write_i2c_block_data(
        self, i2c_addr: int, register: int, data: Iterable[int], force: bool | None = None
    ) -> None:
        """S addr+W [register data...] P; data at most 32 bytes, as in smbus2."""
        payload = list(data)
        if len(payload) > I2C_SMBUS_BLOCK_MAX:
            raise ValueError(f"Data length cannot exceed {I2C_SMBUS_BLOCK_MAX} bytes")
        self._transfer([(_check_address(i2c_addr), _bytes([register, *payload]), 0)])


def _check_address(address: int) -> int:
    if not isinstance(address, int) or not 0 <= address <= 0x7F:
        raise ValueError(f"I2C address {address!r} is not a 7-bit address (0..0x7f)")
    return address


def _bytes(values: Iterable[int]) -> bytes:
    try:
        return bytes(values)
    except ValueError:
        raise ValueError(f"{list(values)} are not all bytes (0..255)") from None


class ProtocolDevice:
    """The board's real C protocol layer (firmware/core/protocol.c) as an I2C device, with no
    motion behind it: the control tick is ``self.layer.tick()``, the published state is set with
    ``self.layer.set_snapshot(...)``. Useful for tests of master code."""

    def __init__(self, layer: ProtocolLayer | None = None) -> None:
        if layer is None:
            from .sim.cboard import ProtocolLayer  # the cffi extension, only when it is needed

            layer = ProtocolLayer()
        self.layer = layer

    def i2c_write(self, data: bytes, stop: bool) -> None:
        self.layer.write(data, stop=stop)

    def i2c_read(self, n: int) -> bytes:
        return self.layer.read(n)
