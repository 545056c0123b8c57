"""A firmware update of the simulated board (asserv.sim.boot) through `asserv sim serve`, as the
pits rehearse it (docs/update.md, "Rehearse in the pits"): `asserv --sim HOST:PORT flash`, and
a soak of a faulty bus and bad images, whose promise is the real bootloader's: a refused update
leaves the old firmware, a good one ends on the new version, the calibration kept."""

from __future__ import annotations

import ctypes
import errno
import struct
import zlib
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from smbus2 import i2c_msg

from asserv import Board, Status
from asserv.cli import main
from asserv.codec import crc8
from asserv.driver import AsservError
from asserv.server import RemoteBus, SimServer
from asserv.sim import Simulator
from asserv.sim.boot import stand_in_image
from asserv.update import (
    APP_INFO_OFFSET,
    BUFFER,
    CHUNK,
    Image,
    Result,
    State,
    Updater,
    flash,
)


def image(
    version: int, size: int = 4096, board_id: int = 0xF446, seed: int = 0, slot: int = 1
) -> Image:
    """An application image of ``size`` bytes whose record says ``board_id``, ``version`` and
    the link of ``slot`` (default B: the stand-in the board runs at first is slot A's)."""
    head = stand_in_image(version, board_id, slot).data
    body = bytes((seed * 7 + i * 13) & 0xFF for i in range(size - len(head)))
    return Image(head + body, board_id, version)


@dataclass(frozen=True)
class Lying(Image):
    """An image whose BEGIN says another CRC, version or board than its bytes and record."""

    said_crc: int = -1

    @property
    def crc32(self) -> int:
        return self.said_crc if self.said_crc >= 0 else zlib.crc32(self.data) & 0xFFFF_FFFF


@pytest.fixture
def served() -> Iterator[tuple[Simulator, str]]:
    sim = Simulator(record=False)
    sim.add_bootloader()
    with SimServer(sim, "127.0.0.1", 0, speed=0) as server:
        host, port = server.address
        yield sim, f"{host}:{port}"


def test_asserv_flash_through_the_server_updates_the_board(
    served: tuple[Simulator, str], tmp_path: Path, capsys: Any
) -> None:
    sim, where = served
    with RemoteBus(where.split(":")[0], int(where.split(":")[1])) as bus:
        Board(bus, pec=True).set_odometrie(1200, 25000, -300)
        bus.clock.sleep(0.05)
    kept = sim.calibration
    assert kept is not None and sim.firmware == stand_in_image(1)
    new = image(2, 20_000)
    path = tmp_path / "asserv_stm32.bin"
    path.write_bytes(new.data)
    said: list[str] = []
    assert sim.boot is not None
    sim.boot.on_start.append(said.append)  # what `asserv sim serve` prints
    t0 = sim.time_s
    assert main(["--sim", where, "flash", str(path)]) == 0
    out = capsys.readouterr().out.splitlines()
    assert out[0].startswith(
        f"image: 20000 bytes, version 2, board 0xf446 (STM32F446 (Nucleo-F446RE)),"
        f" CRC-32 0x{new.crc32:08x}"
    )
    assert out[0].endswith(", linked for slot B")
    assert out[1] == "board 0xf446: runs version 1 (528 bytes) from slot A"
    assert out[2].startswith("verified: the board read the 20000 bytes back")
    assert out[3] == "running: application version 2 (protocol 1.0)"
    assert sim.firmware == new and sim.boot.flash.updates == 1
    assert said == [
        f"the board took an update: version 2, 20000 bytes, CRC-32 0x{new.crc32:08x};"
        " its application started again"
    ]
    # Restarted: a power-on whose storage kept the calibration; the new application answers.
    assert sim.calibration == kept
    assert not sim.boot.serving
    # The bus's time: 20000 bytes at 100 kHz are 1.9 s of bytes, the 1 s erase under them (the
    # board holds the chunks in RAM meanwhile), then START's reset: nothing copied.
    assert 1.9 < sim.time_s - t0 < 2.4
    # The bootloader's INFO says what runs, as the real board's does.
    with RemoteBus(where.split(":")[0], int(where.split(":")[1])) as bus:
        Board(bus, pec=True).bootloader()
        bus.clock.sleep(0.1)
        info = Updater(bus).info()
        assert (info.run_valid, info.run_version, info.run_length) == (True, 2, 20000)
        assert info.run_crc == new.crc32 and info.state == State.IDLE
    # The same image again: nothing written, the board started again.
    assert main(["--sim", where, "flash", str(path)]) == 0
    assert "has this image already" in capsys.readouterr().out
    assert sim.boot.flash.updates == 1 and not sim.boot.serving
    # Slot B runs: the next update goes into slot A, whose image this file is not.
    path.write_bytes(image(3, 20_000).data)
    assert main(["--sim", where, "flash", str(path)]) == 2
    err = capsys.readouterr().err
    assert "writes slot A" in err and "asserv_stm32.elf" in err and len(err.splitlines()) == 1
    bus_clock_s = sim.time_s
    assert sim.firmware == new and sim.boot.flash.updates == 1
    path_a = tmp_path / "asserv_stm32_a.bin"
    path_a.write_bytes(image(3, 20_000, slot=0).data)
    assert main(["--sim", where, "flash", str(path), str(path_a)]) == 0
    assert "linked for slot A" in capsys.readouterr().out.splitlines()[0]
    assert sim.firmware == image(3, 20_000, slot=0) and sim.boot.flash.updates == 2
    # Slot A's three sectors erase in 1.05 s, under the bus's 1.9 s.
    assert sim.time_s - bus_clock_s < 2.5


def test_asserv_flash_refused_while_an_order_runs(
    served: tuple[Simulator, str], tmp_path: Path, capsys: Any
) -> None:
    sim, where = served
    path = tmp_path / "fw.bin"
    path.write_bytes(image(2).data)
    assert main(["--sim", where, "goto", "600", "-850"]) == 0
    capsys.readouterr()
    assert main(["--sim", where, "flash", str(path)]) == 1
    err = capsys.readouterr().err
    assert "REFUSED_BUSY" in err and "stop the robot" in err and len(err.splitlines()) == 1
    assert sim.boot is not None and not sim.boot.serving and sim.firmware == stand_in_image(1)
    with RemoteBus(where.split(":")[0], int(where.split(":")[1])) as bus:
        assert Status.BUSY_TRAJET in Board(bus, pec=True).check_busy()  # the order runs on


def test_bad_files_exit_2_in_one_line_and_send_nothing(
    served: tuple[Simulator, str], tmp_path: Path, capsys: Any
) -> None:
    sim, where = served
    avr = tmp_path / "asserv_avr.elf"
    avr.write_bytes(b"\x7fELF\x01\x01\x01" + bytes(11) + b"\x53\x00" + bytes(40))
    junk = tmp_path / "junk.bin"
    junk.write_bytes(bytes(600))
    short = tmp_path / "short.bin"
    short.write_bytes(b"\x00" * 12)
    x86 = tmp_path / "x86.elf"
    x86.write_bytes(b"\x7fELF\x01\x01\x01" + bytes(11) + b"\x03\x00" + bytes(40))
    frames = len(sim.frames)
    for args, words in (
        ([str(tmp_path / "none.bin")], "No such file"),
        ([str(tmp_path)], "a build folder has both"),
        ([str(junk)] * 3, "give one or two"),
        ([str(avr)], "ISP"),
        ([str(x86)], "not an ARM ELF"),
        ([str(junk)], "no application record"),
        ([str(short)], "too short"),
        ([], "the following arguments are required"),
    ):
        assert main(["--sim", where, "flash", *args]) == 2, args
        err = capsys.readouterr().err
        assert words in err and len(err.splitlines()) == 1 and "Traceback" not in err, err
    assert len(sim.frames) == frames and sim.firmware == stand_in_image(1)


def test_serve_refuses_a_bad_firmware_in_one_line(tmp_path: Path, capsys: Any) -> None:
    junk = tmp_path / "junk.bin"
    junk.write_bytes(bytes(600))
    other = tmp_path / "f401.bin"
    other.write_bytes(image(1, board_id=0xF401).data)
    for path, words in ((junk, "no application record"), (other, "0xf401 cannot run")):
        assert main(["sim", "serve", "--port", "0", "--firmware", str(path)]) == 2
        err = capsys.readouterr().err
        assert words in err and len(err.splitlines()) == 1 and "Traceback" not in err, err


class FaultyBus:
    """The served bus with the faults drawn for one update: a write lost before the board, a
    write taken but its acknowledge lost, a write delivered twice, a reply garbled."""

    def __init__(self, bus: RemoteBus, faults: list[int]) -> None:
        self.bus = bus
        self.clock = bus.clock
        self.faults = faults
        self.n = 0

    def i2c_rdwr(self, *msgs: i2c_msg) -> None:
        fault = self.faults[self.n % len(self.faults)]
        self.n += 1
        write = not int(msgs[0].flags) & 1
        if fault == 1 and write:
            raise OSError(errno.EREMOTEIO, "lost on the way")
        self.bus.i2c_rdwr(*msgs)
        if fault == 2 and write:
            raise OSError(errno.EREMOTEIO, "its acknowledge lost")
        if fault == 3 and write:
            self.bus.i2c_rdwr(*msgs)
        if fault == 4 and not write and int(msgs[0].len) >= 2:
            got = bytearray(bytes(msgs[0]))
            got[1] ^= 0x5A
            ctypes.memmove(msgs[0].buf, bytes(got), len(got))


BAD_KINDS = ("crc", "board", "begin_board", "version", "short_crc", "slot")


@settings(max_examples=30, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(
    kind=st.sampled_from(("good", *BAD_KINDS)),
    faults=st.lists(st.sampled_from((0, 0, 0, 0, 0, 0, 1, 2, 3, 4)), min_size=1, max_size=40),
    size=st.one_of(st.integers(APP_INFO_OFFSET // 4 + 4, 1500), st.integers(6200, 7500)).map(
        lambda w: 4 * w
    ),
    seed=st.integers(0, 255),
    bus_hz=st.sampled_from((100_000, 400_000)),
    protocol=st.sampled_from((3, 3, 2, 1)),
)
def test_soak_a_faulty_bus_and_bad_images(
    kind: str, faults: list[int], size: int, seed: int, bus_hz: int, protocol: int
) -> None:
    """Whatever the bus loses, repeats or garbles, a good image ends on the board with its
    version (or the command fails and the board keeps the old one); a bad one is refused and
    the old firmware starts again; the calibration is kept either way. Images up to 30000
    bytes: at 400 kHz, more than the board holds in RAM during the erase; and a bootloader of
    protocol 2 or 1 (a board flashed before its two slots, or before it took DATA during the
    erase), with the same master: it writes slot B, then copies it into slot A, so takes slot
    A's image. An image linked for the other slot is refused before anything is written."""
    sim = Simulator(record=False, bus_hz=bus_hz)
    sim.add_bootloader()
    assert sim.boot is not None
    sim.boot.protocol = protocol
    good = image(2, size, seed=seed, slot=1 if protocol == 3 else 0)
    record = struct.pack("<3I", 0x49505041, 0xF401, 2)
    other_record = good.data[:APP_INFO_OFFSET] + record + good.data[APP_INFO_OFFSET + 12 :]
    sent = {
        "good": good,
        "crc": Lying(good.data, 0xF446, 2, said_crc=good.crc32 ^ 1),
        "board": image(2, size, board_id=0xF401, seed=seed),
        "begin_board": Lying(other_record, 0xF446, 2),  # its own record says 0xf401: END
        "version": Lying(good.data, 0xF446, 3),
        "short_crc": Lying(good.data, 0xF446, 2, said_crc=zlib.crc32(good.data[:-4])),
        "slot": image(2, size, seed=seed, slot=0 if protocol == 3 else 1),
    }[kind]
    with SimServer(sim, "127.0.0.1", 0, speed=0) as server:
        bus = RemoteBus(*server.address)
        board = Board(bus, pec=True)
        board.set_odometrie(-800, 24000, 150)
        bus.clock.sleep(0.05)
        kept = sim.calibration
        assert kept is not None
        try:
            flash(Board(FaultyBus(bus, faults), pec=True), sent)
            done = True
        except AsservError:  # a refusal (UpdateError), or the bus failed past the retries
            done = False
        assert sim.boot is not None
        if kind == "good" and not done:
            # The bus failed past the retries: the same command again, on a bus that works.
            flash(board, good)
            done = True
        if kind == "good":
            assert sim.firmware == good and not sim.boot.serving
        else:
            assert kind == "good" or not done
            # What the bootloader holds is never the bad image: started, the old one runs.
            if sim.boot.serving:
                u = Updater(bus)
                st_ = u.wait()
                assert st_.state != State.READY or kind == "good"
                u._retry(u.start)
                bus.clock.sleep(0.5)
            assert not sim.boot.serving
            assert sim.firmware in (stand_in_image(1), good)
            if kind != "good":
                assert sim.firmware == stand_in_image(1) and sim.boot.flash.updates == 0
        assert sim.calibration == kept
        assert board.version().major == 1  # the application answers
        bus.close()


def test_each_refusal_names_its_reason(served: tuple[Simulator, str]) -> None:
    """The bootloader's checks, one by one, over the server: what the real one answers."""
    sim, where = served
    host, port = where.split(":")
    good = image(2, 1024)
    with RemoteBus(host, int(port)) as bus:
        Board(bus, pec=True).bootloader()
        bus.clock.sleep(0.1)
        u = Updater(bus)
        u._write(struct.pack(">BIIIH", 0xB1, 1024, good.crc32, 2, 0xF401))
        assert u.wait().result == Result.WRONG_BOARD
        u._write(struct.pack(">BIIIH", 0xB1, 200_000, good.crc32, 2, 0xF446))
        assert u.wait().result == Result.TOO_LARGE
        u.data(0, good.data[:64])
        assert u.wait() == (State.IDLE, Result.NOT_BEGUN, 0)
        altered = good.data[:60] + bytes([good.data[60] ^ 1]) + good.data[61:64]
        u.begin(good)
        assert u.status() == (State.ERASING, Result.OK, 0)
        # While the download slot erases: DATA held in RAM, checked as after the erase.
        u.data(0, good.data[:64])
        assert u.status() == (State.ERASING, Result.OK, 64)
        u.data(128, good.data[128:192])
        assert u.status() == (State.ERASING, Result.BAD_OFFSET, 64)
        u.data(0, altered)
        assert u.status() == (State.ERASING, Result.MISMATCH, 64)
        u.end()  # anything else waits for the erase
        assert u.status() == (State.ERASING, Result.BUSY, 64)
        u.begin(image(3, 1024))  # another download's BEGIN: after this erase
        assert u.status() == (State.ERASING, Result.BUSY, 64)
        u.begin(good)  # this one sent again: the same download, still held
        assert u.status() == (State.ERASING, Result.OK, 64)
        assert u.wait() == (State.RECEIVING, Result.OK, 64)
        u.data(128, good.data[128:192])
        assert u.wait().result == Result.BAD_OFFSET
        u.data(0, good.data[:64])
        assert u.wait() == (State.RECEIVING, Result.OK, 64)
        u.data(0, altered)
        assert u.wait() == (State.RECEIVING, Result.MISMATCH, 64)
        u.end()
        assert u.wait().result == Result.INCOMPLETE
        pec = crc8(b"\x04\xb3")
        bus.i2c_rdwr(i2c_msg.write(2, bytes([0xB3, pec ^ 1])))  # END with a wrong PEC
        assert u.status().result == Result.BAD_PEC
        u.start()
        bus.clock.sleep(0.1)
        assert sim.boot is not None and not sim.boot.serving
        assert sim.firmware == stand_in_image(1)


def test_the_board_holds_chunks_while_it_erases_until_its_ram_is_full() -> None:
    """At 400 kHz the bus brings BUFFER bytes in 0.6 s, before the download slot's 1 s erase is
    over: chunks are taken (ERASING, OK) until RAM is full, then refused with BUSY and taken
    again once the erase is over; the master's update waits there and nowhere else."""
    sim = Simulator(record=False, bus_hz=400_000)
    sim.add_bootloader()
    assert sim.boot is not None
    Board(sim.bus, pec=True).bootloader()
    sim.bus.clock.sleep(0.1)
    new = image(2, 30_000)
    u = Updater(sim.bus)
    u.begin(new)
    t0 = sim.time_s
    for off in range(0, BUFFER, CHUNK):
        u.data(off, new.data[off : off + CHUNK])
    assert u.status() == (State.ERASING, Result.OK, BUFFER)
    assert 0.5 < sim.time_s - t0 < 0.7
    u.data(BUFFER, new.data[BUFFER : BUFFER + CHUNK])
    assert u.status() == (State.ERASING, Result.BUSY, BUFFER)  # full: not taken
    assert u.wait() == (State.RECEIVING, Result.BUSY, BUFFER)
    assert 1.0 <= sim.time_s - t0 < 1.01
    u.data(BUFFER, new.data[BUFFER : BUFFER + CHUNK])
    assert u.status() == (State.RECEIVING, Result.OK, BUFFER + CHUNK)
    # The whole update from BEGIN: the bus's bytes, and the erase's end past RAM's 0.6 s.
    t0 = sim.time_s
    assert u.update(new) == (State.READY, Result.OK, len(new.data))
    assert sim.time_s - t0 < 30_000 * 9 * 1.2 / 400_000 + 0.45


def test_serve_says_what_the_board_runs(tmp_path: Path, capsys: Any) -> None:
    fw = tmp_path / "fw.bin"
    fw.write_bytes(image(7, 2048).data)
    args = ["sim", "serve", "--port", "0", "--speed", "0", "--duration", "0.2"]
    assert main([*args, "--firmware", str(fw)]) == 0
    out = capsys.readouterr().out.splitlines()
    assert "the board runs version 7 (2048 bytes, CRC-32 0x" in out[1]
    assert "flash FIRMWARE` updates it" in out[1]
    assert main(args) == 0
    assert "the board runs version 1 (528 bytes" in capsys.readouterr().out
