"""Firmware update over the master's I2C bus, through the STM32 board's bootloader
(firmware/boot/stm32, docs/update.md): the image of an ELF or a .bin and the slot it is linked
for (A or B: the build links the same code for both), its slot header, and the calls of the
update protocol, with resumption after a bus error.

The protocol's numbers are firmware/boot/stm32/boot_proto.h's and boot_layout.h's; the
harness (harness/stm32/test_boot.py) runs this module against the bootloader's binary."""

from __future__ import annotations

import struct
import zlib
from collections.abc import Callable
from dataclasses import dataclass
from enum import IntEnum
from pathlib import Path
from typing import Any, NamedTuple

from smbus2 import i2c_msg

from .bus import clock_of
from .codec import crc8
from .driver import AsservError

__all__ = [
    "BOARD_IDS",
    "BootInfo",
    "BootStatus",
    "Image",
    "Result",
    "State",
    "UpdateError",
    "Updater",
    "WrongSlotError",
    "header",
    "load_image",
    "load_images",
    "slot_bytes",
]

ADDRESS = 2
# The two slots (boot_layout.h): A, sectors 2-4, and B, sector 5, each run in place by an image
# linked at its base + HEADER_SIZE. Slot A is where bootloaders of protocol 1 and 2 keep their run
# slot, into which they copy the download: they take slot A's image.
SLOT_BASES = (0x0800_8000, 0x0802_0000)
SLOT_NAMES = ("A", "B")
SLOT_SIZE = 0x18000
RUN_BASE = SLOT_BASES[0]  # protocol 1 and 2's run slot
HEADER_SIZE = 0x200
IMAGE_BASE = RUN_BASE + HEADER_SIZE  # where slot A's image is linked
IMAGE_MAX = SLOT_SIZE - HEADER_SIZE  # what a slot takes
# The files a build makes for the two slots (firmware/ports/stm32/CMakeLists.txt).
SLOT_FILES = ("asserv_stm32.elf", "asserv_stm32_b.elf")
APP_INFO_OFFSET = 0x200
APP_INFO_MAGIC = 0x4950_5041  # "APPI"
HEADER_MAGIC = 0x544F_4F42  # "BOOT"
CHUNK = 64  # the largest DATA chunk (BOOT_CHUNK_MAX)
WINDOW = 16  # chunks sent between two STATUS reads (1 KiB)
PROTO_VERSION = 3  # BOOT_PROTO_VERSION: 3 is A/B; 2 takes DATA while the download slot erases
BUFFER = 0x6000  # BOOT_BUFFER_SIZE: bytes of the download the bootloader holds in RAM
FRAME_MAX = 1 + 4 + CHUNK + 1  # BOOT_FRAME_MAX: designation, offset, chunk, PEC
# The frames and replies on the bus (boot_proto.h), big-endian, PEC excluded; the simulated
# bootloader (asserv.sim.boot) packs what Updater unpacks with the same formats.
BEGIN_FORMAT = ">BIIIH"  # BEGIN, length, CRC-32, version, board id
DATA_FORMAT = ">BI"  # DATA, offset; the chunk follows
STATUS_FORMAT = ">BBI"  # state, result, next offset
INFO_FORMAT = ">2sBHBIIIIBB"  # "BL", protocol, board, run valid, version, length, CRC, max,
# state, the download's slot (protocol 3; before, INFO_FORMAT_2: without it)
INFO_FORMAT_2 = INFO_FORMAT[:-1]
BOARD_IDS = {
    0xF446: "STM32F446 (Nucleo-F446RE)",
    0xF401: "STM32F401 (Nucleo-F401RE)",
    0x1284: "ATmega1284P",
}

CMD_INFO, CMD_BEGIN, CMD_DATA, CMD_END, CMD_START, CMD_STATUS = range(0xB0, 0xB6)


class State(IntEnum):
    IDLE = 0
    ERASING = 1
    RECEIVING = 2
    PROGRAMMING = 3
    CHECKING = 4
    WRITING_HEADER = 5
    READY = 6
    COPYING = 7
    QUEUED = 8

    @property
    def busy(self) -> bool:
        return self in (
            State.ERASING,
            State.PROGRAMMING,
            State.CHECKING,
            State.WRITING_HEADER,
            State.COPYING,
            State.QUEUED,
        )


class Result(IntEnum):
    OK = 0
    BAD_PEC = 1
    BAD_LENGTH = 2
    UNKNOWN = 3
    BUSY = 4
    WRONG_BOARD = 5
    TOO_LARGE = 6
    NOT_BEGUN = 7
    BAD_OFFSET = 8
    MISMATCH = 9
    INCOMPLETE = 10
    BAD_CRC = 11
    BAD_VERSION = 12
    FLASH_ERROR = 13
    NO_APPLICATION = 14
    WRONG_SLOT = 15


class UpdateError(AsservError):
    """A refusal (bad image, another board's, a board that says no) or an update that failed:
    the message says what and what to do."""


class WrongSlotError(UpdateError):
    """The master was not given the image linked for the slot the board writes: nothing was
    written. A usage error that only the board reveals: `asserv flash` exits 2."""

    usage = True


@dataclass(frozen=True)
class Image:
    """An application image: the bytes from its vector table on, and its own record."""

    data: bytes
    board_id: int
    version: int

    @property
    def crc32(self) -> int:
        return zlib.crc32(self.data) & 0xFFFF_FFFF

    @property
    def link(self) -> int:
        """The address it is linked at, from its record (0 when the record has no link)."""
        if len(self.data) < APP_INFO_OFFSET + 16:
            return 0
        return int(struct.unpack_from("<I", self.data, APP_INFO_OFFSET + 12)[0])

    @property
    def slot(self) -> int | None:
        """0 (A) or 1 (B): the slot it is linked for; None for neither."""
        bases = [b + HEADER_SIZE for b in SLOT_BASES]
        return bases.index(self.link) if self.link in bases else None


class BootStatus(NamedTuple):
    state: State
    result: Result
    next: int  # bytes of the download received (held in RAM, or programmed)


@dataclass(frozen=True)
class BootInfo:
    proto_version: int
    board_id: int
    run_valid: bool
    run_version: int
    run_length: int
    run_crc: int
    image_max: int
    state: State
    dl_slot: int  # the slot BEGIN writes: its image is the one to send (A before protocol 3)


def _elf_bytes(raw: bytes, name: str) -> bytes:
    """The loadable bytes of a 32-bit little-endian ARM ELF from its slot's image base on (their
    load addresses: .data's initial values too), gaps filled with zeros as objcopy -O binary
    fills them, so that the ELF and its .bin are the same image."""
    if raw[18:20] == b"\x53\x00":  # EM_AVR
        raise UpdateError(
            f"{name}: an AVR image; the ATmega1284P board has no bootloader: flash it with an"
            " ISP programmer (docs/update.md, 'The AVR')"
        )
    if raw[4:6] != b"\x01\x01":
        raise UpdateError(f"{name}: not a 32-bit little-endian ELF")
    (machine,) = struct.unpack_from("<H", raw, 18)
    if machine != 40:
        raise UpdateError(f"{name}: not an ARM ELF (e_machine {machine})")
    (phoff,) = struct.unpack_from("<I", raw, 28)
    phentsize, phnum = struct.unpack_from("<HH", raw, 42)
    parts: list[tuple[int, bytes]] = []
    for i in range(phnum):
        p_type, p_offset, _vaddr, p_paddr, p_filesz = struct.unpack_from(
            "<5I", raw, phoff + i * phentsize
        )
        if p_type != 1 or p_filesz == 0:
            continue
        parts.append((p_paddr, raw[p_offset : p_offset + p_filesz]))
    if not parts:
        raise UpdateError(f"{name}: no loadable segment")
    first = min(a for a, _ in parts)
    base = next((b + HEADER_SIZE for b in SLOT_BASES if b <= first < b + SLOT_SIZE), None)
    for a, _ in parts:
        if base is None or not base <= a < base - HEADER_SIZE + SLOT_SIZE:
            raise UpdateError(
                f"{name}: a segment at 0x{a:08x}, outside the slots (A 0x{IMAGE_BASE:08x}.., B"
                f" 0x{SLOT_BASES[1] + HEADER_SIZE:08x}..): not an application linked for the"
                " bootloader"
            )
    assert base is not None
    parts = [(a - base, d) for a, d in parts]
    end = max(off + len(d) for off, d in parts)
    out = bytearray(end)
    for off, d in parts:
        out[off : off + len(d)] = d
    return bytes(out)


def read_record(data: bytes) -> tuple[int, int] | None:
    """(board id, version) of an image's own record (app_info.c, at APP_INFO_OFFSET), or None
    when it has none: what the bootloader's END and load_image both check."""
    if len(data) < APP_INFO_OFFSET + 12:
        return None
    magic, board, version = struct.unpack_from("<3I", data, APP_INFO_OFFSET)
    if magic != APP_INFO_MAGIC:
        return None
    return board & 0xFFFF, version


def load_image(path: str | Path) -> Image:
    """The image of an application ELF (its loadable segments) or .bin (the bytes of the run
    slot from its vector table: objcopy -O binary of the ELF), and its record of board and
    version. Raises UpdateError for anything else."""
    p = Path(path)
    try:
        raw = p.read_bytes()
    except OSError as e:
        raise UpdateError(f"{p}: {e.strerror or e}") from None
    data = _elf_bytes(raw, str(p)) if raw[:4] == b"\x7fELF" else raw
    data += bytes(-len(data) % 4)
    if len(data) < APP_INFO_OFFSET + 12:
        raise UpdateError(f"{p}: {len(data)} bytes, too short to be an application image")
    record = read_record(data)
    if record is None:
        raise UpdateError(
            f"{p}: no application record at offset 0x{APP_INFO_OFFSET:x} "
            "(not an asserv application built for the bootloader)"
        )
    return Image(data, *record)


def load_images(paths: list[str]) -> list[Image]:
    """The images ``asserv flash`` is given: a build folder (its SLOT_FILES), or one or two
    files (ELF or .bin), each linked for a slot, one a slot, the same board and version. Raises
    UpdateError for anything else."""
    if len(paths) == 1 and Path(paths[0]).is_dir():
        folder = Path(paths[0])
        missing = [f for f in SLOT_FILES if not (folder / f).is_file()]
        if missing:
            raise UpdateError(f"{folder}: no {' nor '.join(missing)} (a build folder has both)")
        paths = [str(folder / f) for f in SLOT_FILES]
    if not 1 <= len(paths) <= 2:
        raise UpdateError(f"{len(paths)} files: give one or two (slot A's, slot B's) or a folder")
    images = [load_image(p) for p in paths]
    for p, im in zip(paths, images, strict=True):
        if im.slot is None:
            raise UpdateError(
                f"{p}: its record gives no slot (link 0x{im.link:08x}): an image built before"
                " the bootloader's two slots; build it again"
            )
    if len(images) == 2:
        a, b = images
        if a.slot == b.slot:
            raise UpdateError(f"both files are linked for slot {SLOT_NAMES[a.slot or 0]}")
        if (a.board_id, a.version, len(a.data)) != (b.board_id, b.version, len(b.data)):
            raise UpdateError(
                "the two files are not one build: "
                + ", ".join(f"version {i.version} board 0x{i.board_id:04x}" for i in images)
            )
    return sorted(images, key=lambda i: i.slot or 0)


def header(image: Image, sequence: int = 1) -> bytes:
    """A slot's header (boot_layout.h's struct boot_header), as the bootloader writes it: the
    link from the image's record, and ``sequence`` (one more than the slot that ran)."""
    body = struct.pack(
        "<7I",
        HEADER_MAGIC,
        len(image.data),
        image.crc32,
        image.version,
        image.board_id,
        image.link,
        sequence & 0xFFFF_FFFF,
    )
    return body + struct.pack("<I", zlib.crc32(body) & 0xFFFF_FFFF)


def slot_bytes(image: Image, sequence: int = 1) -> bytes:
    """The image's slot as the bootloader leaves it (header, then the image): what a factory
    flashes with an ST-LINK at the slot's base (slot A: 0x08008000, flash.sh), beside the
    bootloader at 0x08000000."""
    return header(image, sequence) + b"\xff" * (HEADER_SIZE - 32) + image.data


class Updater:
    """The update protocol's calls on a bus (smbus2.SMBus, asserv.VirtualBus): each write
    carries its PEC, each read is checked against its PEC. ``update`` is the whole procedure."""

    def __init__(self, bus: Any, address: int = ADDRESS, poll_s: float = 0.0002) -> None:
        self.bus = bus
        self.address = address
        self.clock = clock_of(bus)
        self.poll_s = poll_s
        self._info_selected = True  # unknown at first: select STATUS before reading it
        self.retries = 0  # bus errors recovered from

    # ---- frames ----------------------------------------------------------------------------
    def _write(self, frame: bytes) -> None:
        pec = crc8(bytes([self.address << 1]) + frame)
        self.bus.i2c_rdwr(i2c_msg.write(self.address, frame + bytes([pec])))

    def _read(self, n: int) -> bytes:
        msg = i2c_msg.read(self.address, n + 1)
        self.bus.i2c_rdwr(msg)
        got = bytes(msg)
        if crc8(bytes([self.address << 1 | 1]) + got) != 0:
            raise OSError(f"a reply from the bootloader failed its PEC: {got.hex()}")
        return got[:n]

    # ---- calls -----------------------------------------------------------------------------
    def status(self) -> BootStatus:
        if self._info_selected:
            self._write(bytes([CMD_STATUS]))
            self._info_selected = False
        raw = self._read(struct.calcsize(STATUS_FORMAT))
        state, result, nxt = struct.unpack(STATUS_FORMAT, raw)
        return BootStatus(State(state), Result(result), nxt)

    def info(self) -> BootInfo:
        """The bootloader's identity and what its run slot holds. Raises UpdateError when what
        answers at the address is not the bootloader (the application, say)."""
        self._write(bytes([CMD_INFO]))
        self._info_selected = True
        # As long as protocol 3's reply; a bootloader of protocol 1 or 2 gives one byte less,
        # then its PEC, then 0xFF.
        n = struct.calcsize(INFO_FORMAT)
        msg = i2c_msg.read(self.address, n + 1)
        self.bus.i2c_rdwr(msg)
        got = bytes(msg)
        if got[:2] != b"BL":
            raise UpdateError(
                f"the board at 0x{self.address:02x} is not in its bootloader (it answered "
                f"{got[:4].hex()}); enter it first (`asserv flash` does)"
            )
        if got[2] < 3:
            n = struct.calcsize(INFO_FORMAT_2)
        if crc8(bytes([self.address << 1 | 1]) + got[: n + 1]) != 0:
            raise OSError(f"a reply from the bootloader failed its PEC: {got.hex()}")
        if got[2] < 3:
            fields = (*struct.unpack(INFO_FORMAT_2, got[:n]), 0)
        else:
            fields = struct.unpack(INFO_FORMAT, got[:n])
        _, ver, board, valid, rver, rlen, rcrc, imax, state, dl = fields
        return BootInfo(ver, board, bool(valid), rver, rlen, rcrc, imax, State(state), dl)

    def begin(self, image: Image) -> None:
        self._write(
            struct.pack(
                BEGIN_FORMAT, CMD_BEGIN, len(image.data), image.crc32, image.version, image.board_id
            )
        )

    def data(self, offset: int, chunk: bytes) -> None:
        self._write(struct.pack(DATA_FORMAT, CMD_DATA, offset) + chunk)

    def end(self) -> None:
        self._write(bytes([CMD_END]))

    def start(self) -> None:
        self._write(bytes([CMD_START]))

    def wait(self, timeout_s: float = 10.0) -> BootStatus:
        """Polls STATUS until the board is no longer busy."""
        t_end = self.clock.monotonic() + timeout_s
        while True:
            st: BootStatus = self._retry(self.status)
            if not st.state.busy:
                return st
            if self.clock.monotonic() > t_end:
                raise UpdateError(f"the bootloader stayed {st.state.name} for {timeout_s} s")
            self.clock.sleep(self.poll_s)

    def _retry(self, call: Callable[[], Any], tries: int = 20) -> Any:
        """A call again after a bus error (a NACK, a PEC that fails), a little later."""
        for k in range(tries):
            try:
                return call()
            except OSError:
                if k + 1 == tries:
                    raise
                self.retries += 1
                self.clock.sleep(0.002 * (k + 1))
        raise AssertionError("unreachable")

    # ---- the procedure ---------------------------------------------------------------------
    def update(
        self, image: Image, progress: Callable[[int, int], None] | None = None
    ) -> BootStatus:
        """Begin, the chunks, end: the download whole, read back, its header written. Any
        bus error is retried; a chunk whose reply was lost is sent again, which the board
        takes as the same chunk. Returns the READY status; raises UpdateError on a refusal."""
        info: BootInfo = self._retry(self.info)
        if info.board_id != image.board_id:
            raise UpdateError(
                f"the image is for board 0x{image.board_id:04x} "
                f"({BOARD_IDS.get(image.board_id, 'unknown')}), this board is "
                f"0x{info.board_id:04x} ({BOARD_IDS.get(info.board_id, 'unknown')})"
            )
        if len(image.data) > info.image_max:
            raise UpdateError(
                f"the image is {len(image.data)} bytes; the board's slot takes {info.image_max}"
            )
        if image.slot != info.dl_slot:
            raise WrongSlotError(
                f"the board writes slot {SLOT_NAMES[info.dl_slot]}, the image is linked for "
                + (f"slot {SLOT_NAMES[image.slot]}" if image.slot is not None else "no slot")
            )
        self._begin(image)
        total = len(image.data)
        offset = 0
        stalled = 0
        while offset < total:
            # A window of chunks back to back, then one STATUS. The board holds them in RAM
            # while its download slot erases (BEGIN), and programs them after, each in less
            # time than the next one takes on the bus: while it takes them, nothing waits. A
            # chunk it refused (BUSY: RAM full; BAD_PEC), and those after it (BAD_OFFSET), are
            # sent again from the next offset STATUS gives.
            sent = offset
            try:
                while sent < total and sent - offset < WINDOW * CHUNK:
                    chunk = image.data[sent : sent + CHUNK]
                    self.data(sent, chunk)
                    sent += len(chunk)
                st = self.status()
            except OSError:
                self.retries += 1
                self.clock.sleep(0.002)
                st = self._retry(self.status)  # resume from what the board has
            # Busy, it takes nothing: a write not yet handled (QUEUED), a chunk programming (a
            # bootloader of protocol 1), or the erase with RAM full (or a bootloader of protocol
            # 1, which takes nothing while it erases). Wait until it takes chunks again.
            while st.state.busy and not (st.state == State.ERASING and st.next > offset):
                self.clock.sleep(self.poll_s)
                st = self._retry(self.status)
            if st.state not in (State.RECEIVING, State.ERASING):
                raise UpdateError(f"the download stopped at {st.next} bytes: {st.result.name}")
            if st.result not in (Result.OK, Result.BUSY, Result.BAD_PEC, Result.BAD_OFFSET):
                raise UpdateError(f"chunk at {offset} refused: {st.result.name}")
            stalled = stalled + 1 if st.next <= offset else 0
            if stalled > 20:
                raise UpdateError(f"the download made no progress past {st.next} bytes")
            offset = st.next
            if progress is not None:
                progress(offset, total)
        self.wait()  # a small image may be whole before the erase is over
        self._retry(self.end)
        st = self.wait()
        if st.state != State.READY:
            raise UpdateError(f"END refused: {st.result.name} (the application that ran stays)")
        return st

    def _begin(self, image: Image) -> None:
        """BEGIN, until the board takes it: ERASING (or RECEIVING, once the erase is over),
        OK. Sent again while the board's erase runs (its acknowledge lost), it is the same
        download (OK); refused BUSY (an earlier BEGIN's erase, or a bootloader of protocol 1,
        for which BEGIN sent again is another one), it is sent again after that erase; a frame
        that failed its PEC on the way, sent again. Raises UpdateError on a refusal."""
        for _ in range(5):
            self._retry(lambda: self.begin(image))
            st: BootStatus = self._retry(self.status)
            while st.state == State.QUEUED:
                self.clock.sleep(self.poll_s)
                st = self._retry(self.status)
            if st.result == Result.OK and st.state in (State.ERASING, State.RECEIVING):
                return
            if st.result == Result.BUSY and st.state.busy:
                self.wait()
            elif st.result != Result.BAD_PEC:
                break
        raise UpdateError(f"BEGIN refused: {st.result.name}")


class Progress:
    """One line on a terminal, rewritten: bytes done, percent, time left (from the rate so far).
    Quiet when the stream is not a terminal (a log, a pipe)."""

    def __init__(self, stream: Any, clock: Any) -> None:
        self.stream = stream
        self.on = bool(getattr(stream, "isatty", lambda: False)())
        self.clock = clock
        self.t0 = clock.monotonic()

    def __call__(self, done: int, total: int) -> None:
        if not self.on:
            return
        spent = self.clock.monotonic() - self.t0
        left = spent * (total - done) / done if done else 0.0
        self.stream.write(
            f"\r{done / 1024:6.1f}/{total / 1024:.1f} KiB {100 * done // total:3d} %"
            f"  {left:4.0f} s left "
        )
        if done == total:
            self.stream.write("\n")
        self.stream.flush()


AFTER_A_CUT = (
    "if the power is cut during an update, the board starts the application it had (or the new "
    "one, if its download was whole): run the same command again"
)


def _in_bootloader(board: Any) -> bool | None:
    """Which firmware answers, from a plain read, which changes nothing in either: the
    application gives its status, its PEC, then 0xFF; the bootloader its STATUS (an offset never
    0xFFFFFFFF) or its INFO ("BL"). Two reads: the application's first may still give a reply
    the master selected and never read; its second is the status. None when a read fails."""
    msg = i2c_msg.read(board.address, 7)
    try:
        for _ in range(2):
            board.bus.i2c_rdwr(msg)
    except OSError:
        return None
    return bytes(msg)[2:6] != b"\xff" * 4


def flash(
    board: Any,
    images: Image | list[Image],
    progress: Callable[[int, int], None] | None = None,
) -> list[str]:
    """As _flash, a bus that fails past the retries reported as an UpdateError."""
    try:
        return _flash(board, [images] if isinstance(images, Image) else images, progress)
    except OSError as e:
        raise UpdateError(f"the bus failed ({e}); " + AFTER_A_CUT) from None


def _flash(
    board: Any, images: list[Image], progress: Callable[[int, int], None] | None = None
) -> list[str]:
    """``asserv flash``: the board (an asserv.Board on its bus) into its bootloader, the image
    linked for the slot it writes picked from ``images`` (one a slot, one build) and checked
    against it, downloaded, read back by the board, started; the lines to print. Raises
    WrongSlotError (not given that image: nothing written, the board started again), UpdateError
    (the board refused, or has no bootloader) and OSError (the bus)."""
    from .driver import Board, OrderRejected

    image = images[0]
    lines: list[str] = []
    clock = clock_of(board.bus)
    u = Updater(board.bus, board.address)
    if _in_bootloader(board):
        lines.append("the board is in its bootloader already")
    else:
        try:
            board.bootloader()
        except OrderRejected as e:
            raise UpdateError(
                f"the board refused to leave its application ({e.reason.name}): an order runs;"
                " stop the robot (asserv stop), wait, and flash again"
            ) from None
        for _ in range(10):
            clock.sleep(0.02)
            if _in_bootloader(board):
                break
        else:
            raise UpdateError(
                "the board took BOOTLOADER but no bootloader answers: a board without one (the"
                " AVR board has none: docs/update.md gives its ISP route), or its bootloader is"
                " not flashed"
            )
    info: BootInfo = u._retry(u.info, tries=5)
    if info.board_id != image.board_id:
        raise UpdateError(
            f"this board is 0x{info.board_id:04x} ({BOARD_IDS.get(info.board_id, 'unknown')}),"
            f" the image is for 0x{image.board_id:04x}: nothing written; the board stays in its"
            " bootloader until it is reset or sent `asserv flash` with its own image"
        )
    by_slot = {im.slot: im for im in images}
    run_slot = info.dl_slot ^ 1 if info.proto_version >= 3 else info.dl_slot
    where = f" from slot {SLOT_NAMES[run_slot]}" if info.proto_version >= 3 else ""
    lines.append(
        f"board 0x{info.board_id:04x}: runs "
        + (
            f"version {info.run_version} ({info.run_length} bytes){where}"
            if info.run_valid
            else "nothing"
        )
    )
    same = by_slot.get(run_slot)
    if (
        info.run_valid
        and same is not None
        and (info.run_crc, info.run_version) == (same.crc32, same.version)
    ):
        image = same
        lines.append("the board has this image already: started again, nothing written")
    elif info.dl_slot not in by_slot:
        u._retry(u.start)  # back to the application it runs (or to the bootloader, if none)
        for _ in range(20):  # its start-up: the image's CRC, 40 ms
            clock.sleep(0.02)
            if _in_bootloader(board) is False:
                break
        name = SLOT_NAMES[info.dl_slot]
        raise WrongSlotError(
            f"the board writes slot {name}, and no image linked for slot {name} was given"
            f" ({SLOT_FILES[info.dl_slot]}): give both files or the build folder; nothing"
            " written, the board runs what it ran"
        )
    else:
        image = by_slot[info.dl_slot]
        st = u.update(image, progress)
        lines.append(
            f"verified: the board read the {st.next} bytes back, CRC-32 0x{image.crc32:08x},"
            " and wrote their header"
        )
    lines.insert(
        0,
        f"image: {len(image.data)} bytes, version {image.version}, board 0x{image.board_id:04x}"
        f" ({BOARD_IDS.get(image.board_id, 'unknown')}), CRC-32 0x{image.crc32:08x}"
        + (f", linked for slot {SLOT_NAMES[image.slot]}" if image.slot is not None else ""),
    )
    u._retry(u.start)
    # The bootloader starts the newest slot (a bootloader of protocol 1 or 2 copies the download
    # into its run slot first, up to 3 s).
    t_end = clock.monotonic() + 8.0
    while True:
        clock.sleep(0.1)
        try:
            if _in_bootloader(board) is False:
                version = Board(board.bus, board.address, pec=True).version()
                break
        except (AsservError, OSError):
            pass
        if clock.monotonic() > t_end:
            raise UpdateError(
                "the new application did not answer within 8 s: read `asserv version`; "
                + AFTER_A_CUT
            )
    lines.append(
        f"running: application version {image.version} (protocol {version.major}.{version.minor})"
    )
    lines.append(AFTER_A_CUT)
    return lines
