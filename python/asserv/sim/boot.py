"""The simulated board's bootloader: the update protocol of firmware/boot/stm32 at the simulated
board's address, so that ``asserv flash`` runs against ``Simulator`` and ``asserv sim serve`` as
against the STM32 board, to rehearse the pit procedure (docs/update.md, "Rehearse in the pits").

What it keeps is the flash the real board keeps: its two slots, A and B (the images the
application was built from: their record of board, version and link, their CRC, the header's
sequence), in memory, on the ``Simulator`` (``sim.firmware`` is the one that runs, ``SimFlash``).
What it models of the real one:

- BOOTLOADER, accepted by the board's own C protocol layer (refused with REFUSED_BUSY while an
  order runs), makes the board leave its application at the next control tick: the motors off
  (a power-on of the simulated board, which then runs no order), and the bootloader answers at
  the address after its start-up (the run slot's CRC: ``START_S``; a NACK before);
- the writes and replies of boot.c and boot_i2c.c, byte for byte: the PEC mandatory, the same
  checks (board id, length, offsets, chunks sent again, CRC, the image's own record, version
  and link), the same states and results, a write while busy refused with BUSY; DATA taken
  while the download slot erases, held in RAM (BUFFER bytes; refused with BUSY when full) and
  programmed after, while more arrives;
- the download written into the slot that does not run (INFO says which), and the start-up
  starting the newest valid slot (START: a reset, nothing copied);
- the flash's data-sheet times (docs/update.md, the harness's flash model): slot B erased in
  1 s, slot A's sectors in 0.25 + 0.25 + 0.55 s, a word in 16 us; busy states last that long in
  simulated time, and the held words are programmed at a word each 16 us from the erase's end;
- the application started by a power-on of the simulated board, whose storage (the
  calibration) is kept, as the real board's sectors 1 and 7 are;
- ``protocol`` 1 or 2: the bootloaders before A/B, which write slot B as their download slot
  and copy it into slot A, their run slot, at the start-up after START (COPYING).

Not modelled: power cuts in the middle (harness/stm32/test_boot.py cuts the real bootloader at
every step), the watchdog, a board with the bootloader alone. The protocol's numbers and wire
formats are asserv.update's, which the harness checks against the real bootloader's binary.
"""

from __future__ import annotations

import errno
import os
import struct
import zlib
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

from ..codec import BY_NAME, crc8
from ..update import (
    APP_INFO_MAGIC,
    APP_INFO_OFFSET,
    BEGIN_FORMAT,
    BUFFER,
    CMD_BEGIN,
    CMD_DATA,
    CMD_END,
    CMD_INFO,
    CMD_START,
    CMD_STATUS,
    DATA_FORMAT,
    FRAME_MAX,
    HEADER_SIZE,
    IMAGE_MAX,
    INFO_FORMAT,
    INFO_FORMAT_2,
    PROTO_VERSION,
    RUN_BASE,
    SLOT_BASES,
    STATUS_FORMAT,
    Image,
    Result,
    State,
    read_record,
)

if TYPE_CHECKING:
    from . import Simulator

__all__ = ["SimBootloader", "SimFlash", "stand_in_image"]

#: The simulated board's id: it takes the STM32F446 board's images (BOOT_BOARD_ID_F446).
BOARD_ID = 0xF446
#: BOOTLOADER's designation (protocol/messages.toml).
BOOTLOADER = BY_NAME["BOOTLOADER"].designation

# The flash's data-sheet typical times (RM0390, STM32F446 data sheet at x32; the harness's flash
# model, harness/stm32/emu.py) and the bootloader's own.
WORD_S = 16e-6  # a 32-bit word programmed
STAGE_ERASE_S = 1.0  # sector 5 (128 KiB): slot B, at BEGIN
# Slot A's sectors 2, 3, 4: their first address, their erase time [s].
RUN_SECTORS = ((0x0800_8000, 0.25), (0x0800_C000, 0.25), (0x0801_0000, 0.55))
CRC_S_PER_BYTE = 0.038 / 55920  # the image's CRC-32 at 16 MHz: 38 ms for 55920 bytes
START_S = 0.040  # a reset to the bootloader answering (its run slot's CRC), or the application
HEADER_WORDS = 8


def stand_in_image(version: int = 1, board_id: int = BOARD_ID, slot: int = 0) -> Image:
    """What the simulated board runs until it is sent an update: an image that is its record
    alone (a vector table's room, then app_info.c's record), of ``version``, linked for ``slot``
    (0 A, 1 B)."""
    link = SLOT_BASES[slot] + HEADER_SIZE
    data = bytes(APP_INFO_OFFSET) + struct.pack("<4I", APP_INFO_MAGIC, board_id, version, link)
    return Image(data, board_id, version)


@dataclass
class SimFlash:
    """The flash the simulated bootloader writes, kept across its resets and the board's power
    cycles: each slot's image once its header is written (None: erased, or being written) and
    its header's sequence, the download's bytes, and the updates the board took."""

    slots: list[Image | None]
    sequences: list[int] = field(default_factory=lambda: [1, 0])
    stage: bytearray = field(default_factory=lambda: bytearray(b"\xff" * IMAGE_MAX))
    updates: int = 0

    def newest(self) -> int:
        """The slot the start-up starts (boot.c slot_to_start): the newest valid one."""
        valid = [k for k in (0, 1) if self.slots[k] is not None]
        return max(valid, key=lambda k: self.sequences[k]) if valid else 0

    @property
    def run(self) -> Image:
        """The image the board runs (the newest slot's)."""
        image = self.slots[self.newest()]
        assert image is not None  # the simulated board always has an application
        return image

    def stage_newer(self) -> bool:
        """Protocol 1 and 2: a valid download in slot B that differs from slot A, their run
        slot (boot.c's same_header then), which the start-up copies."""
        a, b = self.slots
        return b is not None and (
            a is None
            or (len(a.data), a.crc32, a.version)
            != (
                len(b.data),
                b.crc32,
                b.version,
            )
        )


def _nack(address: int) -> OSError:
    return OSError(
        errno.ENXIO, f"{os.strerror(errno.ENXIO)}: no device acknowledged address 0x{address:02x}"
    )


class SimBootloader:
    """The bootloader of one ``Simulator``: it watches for BOOTLOADER taken (``watch``), and
    while it serves, the simulator's I2C transactions reach it instead of the application
    (``serving``, ``i2c_write``, ``i2c_read``). ``on_start`` gets a line each time the board
    starts an application the bootloader copied."""

    def __init__(self, sim: Simulator, image: Image) -> None:
        if image.board_id != BOARD_ID:
            raise ValueError(
                f"the simulated board is 0x{BOARD_ID:04x}: an image for 0x{image.board_id:04x}"
                " cannot run on it"
            )
        self.sim = sim
        slot = image.slot if image.slot is not None else 0
        self.flash = SimFlash([image, None] if slot == 0 else [None, image], [1, 1])
        self.on_start: list[Callable[[str], None]] = []
        #: BOOT_PROTO_VERSION of the bootloader modelled: 1 is a board flashed before DATA was
        #: taken during the erase (refused BUSY then; busy PROGRAMMING while a chunk programs).
        self.protocol = PROTO_VERSION
        self.serving = False  # the bootloader has the bus (or is starting: NACK until _up_s)
        self._up_s = 0.0
        self._leaving = False  # an application start is scheduled
        self._ran: Image = self.flash.run  # the image the board's application was started from
        self.dl_slot = 1  # the slot BEGIN writes
        self._reset_ram()

    def _reset_ram(self) -> None:
        self.state = State.IDLE
        self.result = Result.OK
        self.next = 0
        self._busy_until = 0.0
        self._held_from = 0  # the download's bytes [_held_from, next) wait in RAM
        self._held_s = 0.0  # when the held word being programmed began (boot.c op_start)
        self._info = False
        self._pec_carry: int | None = None
        self._length = self._crc = self._version = 0

    # ---- entering and leaving -------------------------------------------------------------
    def watch(self, frame: bytes) -> None:
        """A write the application took: after BOOTLOADER, look at the board's request at
        the next control ticks (the port leaves at the tick that handles it)."""
        if frame[:1] == bytes([BOOTLOADER]) and not self.serving:
            t = self.sim.time_s
            for k in range(1, 21):  # its tick, or its planner period (AVR_RATES: 8 ticks)
                self.sim.at(t + k * 1e-3 + 1e-6, lambda s: self.poll())

    def poll(self) -> None:
        """Enter the bootloader when the application asked for it (board.h's boot_request)."""
        if not self.serving and self.sim._h.board.planner.boot_request:
            self.sim._power_cycle_board()  # the reset: the motors off, the request cleared
            self._boot_main(asked=True)

    def _boot_main(self, asked: bool) -> None:
        """boot.c's start-up after a reset: the application when nothing asks otherwise, else
        serve, copying a newer download first."""
        self._reset_ram()
        self.serving = True
        self._up_s = self.sim.time_s + START_S
        old = self.protocol < 3
        # The download goes into the slot that does not run; before protocol 3, slot B always.
        self.dl_slot = 1 if old else self.flash.newest() ^ 1
        if not asked and not (old and self.flash.stage_newer()):
            self._start_application_at(self._up_s)
            return
        if old and self.flash.stage_newer():
            length = len(self.flash.slots[1].data)  # type: ignore[union-attr]
            copy_s = (
                self._erase_s(0, length)
                + (length // 4 + HEADER_WORDS) * WORD_S
                + length * CRC_S_PER_BYTE
            )
            self.state = State.COPYING
            self._busy_until = self._up_s + copy_s
            self.sim.at(self._busy_until, lambda s: self._copied())

    @staticmethod
    def _erase_s(slot: int, length: int) -> float:
        """The erase of a slot for an image of ``length`` bytes: slot A's sectors that it
        reaches (boot.c), slot B's one sector."""
        if slot == 1:
            return STAGE_ERASE_S
        end = RUN_BASE + HEADER_SIZE + length
        return sum(s for first, s in RUN_SECTORS if first == RUN_BASE or end > first)

    def _copied(self) -> None:
        self.flash.slots[0] = self.flash.slots[1]
        self._boot_main(asked=False)  # the reset after the copy: the new application starts

    def _start_application_at(self, t_s: float) -> None:
        self._leaving = True

        def start(sim: Simulator) -> None:
            self._leaving = False
            self.serving = False
            new = self.flash.run
            if new != self._ran:
                self._ran = new
                self.flash.updates += 1
                for cb in self.on_start:
                    cb(
                        f"the board took an update: version {new.version}, {len(new.data)}"
                        f" bytes, CRC-32 0x{new.crc32:08x}; its application started again"
                    )
            sim._power_cycle_board()  # the new application's power-on, the storage kept

        self.sim.at(t_s, start)

    # ---- the bus --------------------------------------------------------------------------
    def _byte_time(self, n: int) -> None:
        self.sim._advance_ns(n * self.sim._byte_ns)

    def _answering(self) -> bool:
        return self.serving and not self._leaving and self.sim.time_s >= self._up_s

    def i2c_write(self, data: bytes, stop: bool) -> None:
        address = self.sim.address
        self._byte_time(1)
        if not self._answering():
            raise _nack(address)
        self._byte_time(len(data))
        if not self._answering():
            return  # reset in the middle: the write is lost
        pec = crc8(bytes([address << 1]) + data)
        self._settle()
        self._end_write(data, pec)
        self._pec_carry = None if stop else pec

    def i2c_read(self, n: int) -> bytes:
        address = self.sim.address
        self._byte_time(1)
        if not self._answering():
            self._pec_carry = None
            raise _nack(address)
        self._settle()
        reply = self._reply()
        pec = crc8(bytes([address << 1 | 1]) + reply, self._pec_carry or 0)
        self._pec_carry = None
        out = (reply + bytes([pec]) + b"\xff" * n)[:n]
        self._byte_time(n)
        return out

    def _reply(self) -> bytes:
        if self._info:
            r = self.flash.slots[0] if self.protocol < 3 else self.flash.run
            assert r is not None
            info = (b"BL", self.protocol, BOARD_ID, 1, r.version, len(r.data), r.crc32)
            if self.protocol < 3:
                return struct.pack(INFO_FORMAT_2, *info, IMAGE_MAX, self.state)
            return struct.pack(INFO_FORMAT, *info, IMAGE_MAX, self.state, self.dl_slot)
        return struct.pack(STATUS_FORMAT, self.state, self.result, self.next)

    def _settle(self) -> None:
        """The flash job the state started, over when its time has passed (boot.c job_done),
        and the held words programmed since (boot.c op_start), a word each WORD_S."""
        now = self.sim.time_s
        if self.state == State.ERASING and now >= self._busy_until:
            self.state = State.RECEIVING  # the result stays the last write's
            self._held_s = self._busy_until
        if self.state == State.PROGRAMMING and now >= self._busy_until:
            self.state = State.RECEIVING  # protocol 1: the chunk programmed, then the next
            self.result = Result.OK
            self._held_from, self._held_s = self.next, now
        if self.state == State.RECEIVING:
            words = min(int((now - self._held_s) / WORD_S), (self.next - self._held_from) // 4)
            self._held_from += 4 * words
            self._held_s = now if self._held_from == self.next else self._held_s + words * WORD_S
        if self.state == State.WRITING_HEADER and now >= self._busy_until:
            # The header, with a sequence one more than the slot that runs: the newest.
            dl = self.dl_slot
            self.flash.slots[dl] = Image(
                bytes(self.flash.stage[: self._length]), BOARD_ID, self._version
            )
            # Before protocol 3 the start-up runs slot A, which the download is copied into.
            self.flash.sequences[dl] = (
                self.flash.sequences[dl ^ 1] + 1
                if dl == 0 or (self.protocol >= 3)
                else self.flash.sequences[0] - 1
            )
            self.state = State.READY
            self.result = Result.OK

    def _busy(self, state: State, seconds: float) -> None:
        self.state = state
        self.result = Result.OK
        self._busy_until = self.sim.time_s + seconds

    def _end_write(self, frame: bytes, pec: int) -> None:
        """boot_i2c.c's end_write, then boot.c's run_command."""
        if not frame:
            return  # a quick write
        if len(frame) > FRAME_MAX:
            self.result = Result.BAD_LENGTH
            return
        if len(frame) < 2 or pec != 0:
            self.result = Result.BAD_PEC
            return
        f = frame[:-1]
        if len(f) == 1 and f[0] in (CMD_INFO, CMD_STATUS):
            self._info = f[0] == CMD_INFO
            return
        erasing = self.state == State.ERASING and self.protocol > 1
        if self.state.busy and not (erasing and f[0] in (CMD_DATA, CMD_BEGIN)):
            self.result = Result.BUSY
            return
        if f[0] == CMD_BEGIN:
            if len(f) != struct.calcsize(BEGIN_FORMAT):
                self.result = Result.BAD_LENGTH
            elif erasing:  # sent again (the same download), or another's: after this erase
                same = (self._length, self._crc, self._version, BOARD_ID)
                self.result = (
                    Result.OK if struct.unpack(BEGIN_FORMAT, f)[1:] == same else Result.BUSY
                )
            else:
                self._begin(*struct.unpack(BEGIN_FORMAT, f)[1:])
        elif f[0] == CMD_DATA:
            head = struct.calcsize(DATA_FORMAT)
            if len(f) < head + 4:
                self.result = Result.BAD_LENGTH
            else:
                self._data(struct.unpack_from(DATA_FORMAT, f)[1], f[head:])
        elif f[0] == CMD_END:
            self._end()
        elif f[0] == CMD_START:
            # The simulated run slot always holds an application (NO_APPLICATION is for a
            # real board with its bootloader alone): the reset, which copies a newer download.
            self._boot_main(asked=False)
        else:
            self.result = Result.UNKNOWN

    def _begin(self, length: int, crc: int, version: int, board: int) -> None:
        if board != BOARD_ID:
            self.result = Result.WRONG_BOARD
            return
        if length == 0 or length > IMAGE_MAX or length % 4:
            self.result = Result.TOO_LARGE
            return
        self._length, self._crc, self._version = length, crc, version
        self.next = self._held_from = 0
        self.flash.stage[:] = b"\xff" * IMAGE_MAX
        self.flash.slots[self.dl_slot] = None
        self._busy(State.ERASING, self._erase_s(self.dl_slot, length))

    def _data(self, off: int, chunk: bytes) -> None:
        if self.state not in (State.RECEIVING, State.ERASING):
            self.result = Result.NOT_BEGUN
            return
        n = len(chunk)
        if n % 4 or off % 4 or off > self.next or off + n > self._length:
            self.result = Result.BAD_OFFSET
            return
        if off < self.next:  # sent again (its reply was lost): it must be what was received
            have = min(self.next - off, n)
            if self.flash.stage[off : off + have] != chunk[:have]:
                self.result = Result.MISMATCH
                return
            if have == n:
                self.result = Result.OK
                return
            chunk, off = chunk[have:], off + have
        if off + len(chunk) - self._held_from > BUFFER:
            self.result = Result.BUSY  # RAM is full (the erase is not over): send it again
            return
        # Held in RAM, then programmed (_settle); kept here at once: no cut is modelled.
        self.flash.stage[off : off + len(chunk)] = chunk
        self.next = off + len(chunk)
        self.result = Result.OK
        if self.protocol == 1:
            self._busy(State.PROGRAMMING, len(chunk) // 4 * WORD_S)

    def _end(self) -> None:
        if self.state != State.RECEIVING:
            self.result = Result.OK if self.state == State.READY else Result.NOT_BEGUN
            return
        img = bytes(self.flash.stage[: self._length])
        record = read_record(img)
        if self.next != self._length:
            self.result = Result.INCOMPLETE
        elif zlib.crc32(img) & 0xFFFF_FFFF != self._crc:
            self.result = Result.BAD_CRC
        elif record is None or record[0] != BOARD_ID:
            self.result = Result.WRONG_BOARD
        elif record[1] != self._version:
            self.result = Result.BAD_VERSION
        elif self.protocol >= 3 and Image(img, BOARD_ID, self._version).link != (
            SLOT_BASES[self.dl_slot] + HEADER_SIZE
        ):
            self.result = Result.WRONG_SLOT
        else:
            # The held words programmed, the image read back at 16 MHz, then the header's
            # words: one busy span, as seen on the bus.
            held = (self.next - self._held_from) // 4 * WORD_S
            self._busy(
                State.WRITING_HEADER,
                held + self._length * CRC_S_PER_BYTE + HEADER_WORDS * WORD_S,
            )
