"""VirtualBus: i2c_msg transactions, SMBus calls and NACKs, against recording devices and against
the board's C protocol layer (ProtocolDevice). Helpers here are also used by the driver's and the
CLI's tests."""

from __future__ import annotations

import errno

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from smbus2 import i2c_msg

from asserv import Status, codec
from asserv.bus import Clock, I2CDevice, ProtocolDevice, SystemClock, VirtualBus
from asserv.sim.cboard import ProtocolLayer

Event = tuple[str, bytes | int, bool | None]


class Recorder:
    """An I2C device that records what it sees and passes it on to ``inner`` (or answers with
    ``fill``)."""

    def __init__(self, inner: I2CDevice | None = None, fill: bytes = b"") -> None:
        self.inner = inner
        self.fill = fill
        self.events: list[Event] = []

    def i2c_write(self, data: bytes, stop: bool) -> None:
        self.events.append(("w", bytes(data), stop))
        if self.inner is not None:
            self.inner.i2c_write(data, stop)

    def i2c_read(self, n: int) -> bytes:
        self.events.append(("r", n, None))
        if self.inner is not None:
            return self.inner.i2c_read(n)
        return (self.fill * n)[:n] if self.fill else bytes(range(n))


class FakeClock:
    """A clock that only moves when slept on; ``on_sleep`` runs after each sleep."""

    def __init__(self, on_sleep: object = None) -> None:
        self.now = 100.0
        self.sleeps: list[float] = []
        self.on_sleep = on_sleep

    def monotonic(self) -> float:
        return self.now

    def sleep(self, seconds: float) -> None:
        self.sleeps.append(seconds)
        self.now += seconds
        if callable(self.on_sleep):
            self.on_sleep()


def board_bus() -> tuple[ProtocolDevice, Recorder, VirtualBus]:
    """The C protocol layer at address 2, seen through a Recorder."""
    dev = ProtocolDevice()
    rec = Recorder(dev)
    return dev, rec, VirtualBus({2: rec})


def test_devices_and_clocks_match_their_protocols() -> None:
    assert isinstance(ProtocolDevice(), I2CDevice)
    assert isinstance(Recorder(), I2CDevice)
    clock: Clock = FakeClock()  # checked by mypy-compatible typing, and used below
    assert VirtualBus({}, clock).monotonic() == clock.monotonic()
    assert isinstance(VirtualBus({}).clock, SystemClock)


def test_write_then_read_is_one_transaction_with_a_repeated_start() -> None:
    rec = Recorder(fill=b"\xab\xcd")
    bus = VirtualBus({0x10: rec})
    w = i2c_msg.write(0x10, [1, 2, 3])
    r = i2c_msg.read(0x10, 3)
    bus.i2c_rdwr(w, r)
    # No STOP after the write: the read follows by a repeated start.
    assert rec.events == [("w", b"\x01\x02\x03", False), ("r", 3, None)]
    # The read message's buffer is filled in place, as smbus2 does.
    assert list(r) == [0xAB, 0xCD, 0xAB]
    assert bytes(r) == b"\xab\xcd\xab"
    assert list(w) == [1, 2, 3]


def test_a_lone_write_ends_with_a_stop_and_consecutive_writes_do_not() -> None:
    rec = Recorder()
    bus = VirtualBus({0x10: rec})
    bus.i2c_rdwr(i2c_msg.write(0x10, [7]))
    bus.i2c_rdwr(i2c_msg.write(0x10, [8]), i2c_msg.write(0x10, [9]))
    assert rec.events == [("w", b"\x07", True), ("w", b"\x08", False), ("w", b"\x09", True)]


def test_moving_to_another_address_ends_the_first_devices_transaction() -> None:
    a, b = Recorder(), Recorder(fill=b"\x55")
    bus = VirtualBus({0x10: a, 0x11: b})
    r = i2c_msg.read(0x11, 2)
    bus.i2c_rdwr(i2c_msg.write(0x10, [1]), r)
    assert a.events == [("w", b"\x01", True)]
    assert b.events == [("r", 2, None)]
    assert bytes(r) == b"\x55\x55"


def test_no_device_is_a_nack_with_enxio_after_the_earlier_messages() -> None:
    a = Recorder()
    bus = VirtualBus({0x10: a})
    with pytest.raises(OSError) as e:
        bus.i2c_rdwr(i2c_msg.write(0x10, [1]), i2c_msg.read(0x22, 1))
    assert e.value.errno == errno.ENXIO
    assert "0x22" in str(e.value)
    assert a.events == [("w", b"\x01", True)]  # it went out before the NACK, as on a real bus
    for call in (
        lambda: bus.read_byte(0x22),
        lambda: bus.write_byte(0x22, 1),
        lambda: bus.write_quick(0x22),
        lambda: bus.read_i2c_block_data(0x22, 4, 6),
    ):
        with pytest.raises(OSError) as e:
            call()
        assert e.value.errno == errno.ENXIO


def test_smbus_calls_are_the_kernels_i2c_transactions() -> None:
    rec = Recorder(fill=b"\x42")
    bus = VirtualBus({2: rec})
    assert bus.read_byte(2) == 0x42
    bus.write_byte(2, 12)
    assert bus.read_byte_data(2, 3) == 0x42
    bus.write_byte_data(2, 1, 200)
    assert bus.read_i2c_block_data(2, 4, 6) == [0x42] * 6
    bus.write_i2c_block_data(2, 6, [100, 40])
    bus.write_quick(2)
    assert rec.events == [
        ("r", 1, None),
        ("w", b"\x0c", True),
        ("w", b"\x03", False),
        ("r", 1, None),
        ("w", b"\x01\xc8", True),
        ("w", b"\x04", False),
        ("r", 6, None),
        ("w", b"\x06\x64\x28", True),
        ("w", b"", True),
    ]


def test_limits_as_smbus2_and_i2c_dev() -> None:
    bus = VirtualBus({2: Recorder()})
    with pytest.raises(ValueError):
        bus.read_i2c_block_data(2, 0, 33)
    with pytest.raises(ValueError):
        bus.write_i2c_block_data(2, 0, list(range(33)))
    with pytest.raises(ValueError):
        bus.write_byte(2, 256)
    with pytest.raises(ValueError):
        bus.read_byte(0x80)
    with pytest.raises(OSError) as e:
        bus.i2c_rdwr()
    assert e.value.errno == errno.EINVAL
    with pytest.raises(OSError) as e:
        bus.i2c_rdwr(*[i2c_msg.write(2, [3])] * 43)
    assert e.value.errno == errno.EINVAL
    ten_bit = i2c_msg.write(2, [3])
    ten_bit.flags = 0x0010  # I2C_M_TEN
    with pytest.raises(OSError) as e:
        bus.i2c_rdwr(ten_bit)
    assert e.value.errno == errno.EOPNOTSUPP
    with pytest.raises(ValueError):
        VirtualBus({0x80: Recorder()})


def test_a_device_that_returns_the_wrong_length_is_a_bug_not_data() -> None:
    class Short:
        def i2c_write(self, data: bytes, stop: bool) -> None:
            pass

        def i2c_read(self, n: int) -> bytes:
            return b"\x00"

    with pytest.raises(RuntimeError, match="returned 1 bytes for a read of 2"):
        VirtualBus({2: Short()}).read_i2c_block_data(2, 4, 2)


def test_close_and_context_manager() -> None:
    rec = Recorder()
    with VirtualBus({2: rec}) as bus:
        bus.write_byte(2, 12)
    assert bus.closed
    with pytest.raises(OSError) as e:
        bus.write_byte(2, 12)
    assert e.value.errno == errno.EBADF
    assert rec.events == [("w", b"\x0c", True)]
    bus.close()  # twice is fine


def test_time_comes_from_the_clock() -> None:
    clock = FakeClock()
    bus = VirtualBus({}, clock)
    t0 = bus.monotonic()
    bus.sleep(0.25)
    assert bus.monotonic() == pytest.approx(t0 + 0.25)
    assert clock.sleeps == [0.25]


def test_devices_can_be_added_to_an_open_bus() -> None:
    bus = VirtualBus({})
    with pytest.raises(OSError):
        bus.read_byte(2)
    bus.devices[2] = Recorder(fill=b"\x07")
    assert bus.read_byte(2) == 7


# Against the board's C protocol layer: the vectors of docs/protocol.md, byte for byte.


def test_position_with_a_repeated_start_and_its_pec() -> None:
    dev, _, bus = board_bus()
    dev.layer.set_snapshot(x_mm=200, y_mm=100, angle_2deg=13, radius_mm=4)
    dev.layer.tick()
    r = i2c_msg.read(2, 7)
    bus.i2c_rdwr(i2c_msg.write(2, [0x04]), r)
    assert bytes(r).hex(" ") == "00 c8 00 64 0d 04 d8"  # docs/protocol.md, section 8
    # Separate transactions: the PEC covers only the read.
    bus.write_byte(2, 0x04)
    r = i2c_msg.read(2, 7)
    bus.i2c_rdwr(r)
    assert bytes(r).hex(" ") == "00 c8 00 64 0d 04 77"
    # The SMBus block call is the repeated-start form.
    assert bus.read_i2c_block_data(2, 4, 6) == [0x00, 0xC8, 0x00, 0x64, 0x0D, 0x04]


def test_status_poll_order_and_status_in_one_transaction_quick_command() -> None:
    dev, _, bus = board_bus()
    assert bus.read_byte(2) == 0
    r = i2c_msg.read(2, 2)
    bus.i2c_rdwr(i2c_msg.write(2, codec.encode("GOTO", 200, 100, 0)), r)
    assert bytes(r).hex(" ") == "02 74"  # section 8: an order and its status, with PEC
    assert dev.layer.tick()[0].args == (200, 100, 0)
    # An address-only write (i2cdetect's probe) does not drop a selection.
    dev.layer.set_snapshot(sensors=0x81, status=int(Status.BUSY_TRAJET))
    dev.layer.tick()
    bus.write_byte(2, 0x05)
    bus.write_quick(2)
    assert bus.read_byte(2) == 0x81
    assert bus.read_byte(2) == int(Status.BUSY_TRAJET)  # the selection served one read


@settings(max_examples=150)
@given(st.binary(min_size=0, max_size=10), st.integers(1, 4), st.booleans())
def test_the_bus_gives_the_c_layer_what_a_direct_call_gives(
    frame: bytes, n: int, repeated_start: bool
) -> None:
    """Differential: a transaction through VirtualBus and the same bus events played directly on
    a twin ProtocolLayer leave both in the same state and read the same bytes."""
    dev = ProtocolDevice()
    twin = ProtocolLayer()
    bus = VirtualBus({2: dev})
    r = i2c_msg.read(2, n)
    if repeated_start:
        bus.i2c_rdwr(i2c_msg.write(2, frame), r)
        twin.write(frame, stop=False)
    else:
        bus.i2c_rdwr(i2c_msg.write(2, frame))
        bus.i2c_rdwr(r)
        twin.write(frame)
    assert bytes(r) == twin.read(n)
    assert dev.layer.tick() == twin.tick()
    assert bus.read_byte(2) == twin.read(1)[0]


def test_the_bus_registry_opens_by_kind(monkeypatch: pytest.MonkeyPatch) -> None:
    """One registry (asserv.backends.BACKENDS) opens every bus a command names: --bus N, --sim."""
    from asserv import backends as bus_mod

    assert set(bus_mod.BACKENDS) == {"smbus2", "sim"}
    opened: list[object] = []
    monkeypatch.setitem(bus_mod.BACKENDS, "smbus2", lambda n: opened.append(n) or "bus")
    assert bus_mod.open_bus("smbus2", 3) == "bus" and opened == [3]
    with pytest.raises(ValueError, match="no bus of kind 'can'"):
        bus_mod.open_bus("can", 0)
    # A served simulator that is not there: the OSError a command reports as a bus error.
    with pytest.raises(OSError):
        bus_mod.open_bus("sim", ("127.0.0.1", 9))
