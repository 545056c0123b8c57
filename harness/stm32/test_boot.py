"""The bootloader's binary (firmware/boot/stm32) with the application's, linked for its two slots
(docs/update.md): updates over the emulated I2C bus driven by asserv.update, into slot B then
back into slot A, power cuts at every step of them (the chunks held in RAM while the download's
slot erases too), the fall-back to the other slot, refusals, and the promises as properties
(hypothesis): a power cut at any instant leaves a valid application that starts, and keeps the
calibration; chunks lost, resent or refused on a flaky bus never corrupt the image."""

from __future__ import annotations

import ctypes
import zlib
from pathlib import Path
from random import Random
from typing import Any

import pytest
from board import Reference, robot
from boot import (
    SLOT_A,
    SLOT_B,
    BootBoard,
    WholeFlash,
    elf_of_slot_b,
    factory_flash,
    put_slot,
    sector_of,
    with_version,
)
from conftest import ROOT
from elftools.elf.elffile import ELFFile
from emu import FLASH_BASE, SRAM_BASE
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from smbus2 import i2c_msg
from test_nvm import CAL, encode
from test_sessions import assert_same_runs, play

from asserv import Board, OrderRejected, Reject, Status
from asserv._protocol import EndReason, ResetCause
from asserv.codec import crc8, message
from asserv.scenario import load
from asserv.update import (
    BUFFER,
    CHUNK,
    IMAGE_MAX,
    Image,
    Result,
    State,
    UpdateError,
    Updater,
    WrongSlotError,
    header,
    load_image,
)

NVM = encode(CAL)  # a calibration record in sector 1 from the factory
NVM_B = encode((-2000, 27990, 400), 255)  # and an older one in sector 7 (generation 255 < 0)
BYTE_NS = {100_000: 90_000, 400_000: 22_500}  # 9 bits a byte at the bus's rate [Hz]
STAGE = SLOT_B - FLASH_BASE + 0x200  # the first download's first byte in the flash image


def image_for(elf: Path, slot: int, version: int) -> Image:
    """The application of ``version`` linked for ``slot`` (0 A: ``elf``; 1 B: beside it)."""
    return with_version(load_image(elf_of_slot_b(elf) if slot else elf), version)


def new_board(
    elf: Path, boot_elf: Path, image: bytes | None = None, rate: int = 100_000
) -> BootBoard:
    bc, sc, f = robot()
    if image is None:
        image = factory_flash(boot_elf, load_image(elf), NVM, NVM_B)
    return BootBoard(elf, boot_elf, sc, f, bc, flash_image=image, byte_ns=BYTE_NS[rate])


def nvm_of(b: BootBoard) -> bytes:
    return bytes(b.wflash.image[0x4000:0x8000])


def kept(b: BootBoard) -> bool:
    """Both calibration logs as the factory wrote them: no update touches them."""
    return nvm_of(b)[: len(NVM)] == NVM and bytes(b.wflash.data_b[: len(NVM_B)]) == NVM_B


def app_runs(b: BootBoard, version: int) -> None:
    """The application of this version runs and answers; the calibration is the factory's.
    After a power-on its status reads 0; after any other reset (the system reset of BOOTLOADER
    or START, a watchdog's) it reads the reset, PB_MOTEUR with the end reason RESET, until the
    next order (docs/failure-model.md): the master sends its settings again."""
    assert not b.in_boot() and b.running_version() == version
    master = Board(b.bus)
    info = master.reset_info()
    if info.cause == ResetCause.POWER_ON:  # test_resets checks that each flag names its cause
        assert master.check_busy() == 0
    else:
        assert master.check_busy() == Status.PB_MOTEUR
        assert master.debug().end_reason == EndReason.RESET
    assert kept(b) and nvm_of(b)[len(NVM) :] == b"\xff" * (0x4000 - len(NVM))
    assert bytes(b.wflash.data_b[len(NVM_B) :]) == b"\xff" * (0x2_0000 - len(NVM_B))


def test_the_bootloader_runs_from_ram_and_fits_sector_0(boot_elf: Path) -> None:
    with boot_elf.open("rb") as f:
        elf = ELFFile(f)
        funcs = {
            s.name: s["st_value"]
            for s in elf.get_section_by_name(".symtab").iter_symbols()  # type: ignore[union-attr]
            if s["st_info"]["type"] == "STT_FUNC"
        }
        flash_end = max(
            seg["p_paddr"] + seg["p_filesz"] for seg in elf.iter_segments() if seg["p_filesz"]
        )
    in_flash = sorted(n for n, a in funcs.items() if a < SRAM_BASE)
    assert in_flash == ["Reset_Handler"]
    assert "I2C1_EV_IRQHandler" in funcs and funcs["I2C1_EV_IRQHandler"] >= SRAM_BASE
    assert FLASH_BASE < flash_end <= FLASH_BASE + 0x4000  # sector 0 alone


def test_power_on_without_an_application_enters_the_bootloader(elf: Path, boot_elf: Path) -> None:
    b = new_board(elf, boot_elf, factory_flash(boot_elf, None, NVM, NVM_B))
    assert b.boot_modes == ["boot"] and b.iwdg.running
    u = Updater(b.bus)
    info = u.info()
    assert info.board_id == 0xF446 and not info.run_valid and info.image_max == IMAGE_MAX
    u.start()  # nothing to start: refused with its reason
    assert u.status().result == Result.NO_APPLICATION and b.in_boot()
    assert info.dl_slot == 0  # nothing runs: slot A
    u.update(load_image(elf))
    u.start()
    b.sleep(0.1)  # nothing copied: the reset, the image's CRC
    app_runs(b, 1)
    assert b.running_slot() == 0
    assert b.boot_stalled_ns == 0  # no flash stall while the bootloader ran: the bus never held


def test_the_application_enters_the_bootloader_only_when_no_order_runs(
    elf: Path, boot_elf: Path
) -> None:
    """BOOTLOADER (protocol/messages.toml) through the driver: refused with REFUSED_BUSY while
    an order drives the robot, which goes on; with a wrong key, OUT_OF_RANGE; accepted when the
    robot is idle: the motors off, a system reset, the bootloader answering."""
    b = new_board(elf, boot_elf)
    master = Board(b.bus)
    master.goto(500, -850)
    b.sleep(0.2)
    with pytest.raises(OrderRejected) as e:
        master.bootloader()
    assert e.value.reason == Reject.REFUSED_BUSY
    b.sleep(0.05)
    assert not b.in_boot() and b.duty != (0, 0) and master.check_busy() & Status.BUSY_TRAJET
    b.bus.i2c_rdwr(i2c_msg.write(2, bytes([message("BOOTLOADER").designation, 0x12, 0x34])))
    assert master.last_reject().reason == Reject.OUT_OF_RANGE
    master.wait_idle(10.0)
    b.sleep(0.05)
    assert not b.in_boot() and b.system_resets == 0
    master.bootloader()
    b.sleep(0.01)
    assert b.in_boot() and b.system_resets == 1 and b.duty == (0, 0)
    info = Updater(b.bus).info()
    assert info.run_valid and info.run_version == 1 and info.state == State.IDLE
    Updater(b.bus).start()  # nothing new: the same application again
    b.sleep(0.05)
    app_runs(b, 1)


def updated(elf: Path, boot_elf: Path) -> tuple[BootBoard, Image]:
    """A board with version 1 running, updated to version 2 over the bus."""
    b = new_board(elf, boot_elf)
    app_runs(b, 1)
    Board(b.bus).bootloader()  # BOOTLOADER: the application leaves for the bootloader
    b.sleep(0.01)
    assert b.in_boot()
    assert Updater(b.bus).info().dl_slot == 1  # slot A runs: the download goes into B
    new = image_for(elf, 1, 2)
    old = bytes(b.wflash.image[SLOT_A - FLASH_BASE : SLOT_B - FLASH_BASE])
    seen: list[int] = []
    st = Updater(b.bus).update(new, progress=lambda done, total: seen.append(done))
    assert st.state == State.READY and st.next == len(new.data)
    assert seen[-1] == len(new.data) and seen == sorted(seen)
    # Slot B holds the header (sequence 2: one more than slot A's) and the image.
    img = b.wflash.image
    stage = SLOT_B - FLASH_BASE
    assert bytes(img[stage : stage + 32]) == header(new, 2)
    assert bytes(img[stage + 0x200 : stage + 0x200 + len(new.data)]) == new.data
    Updater(b.bus).start()
    b.sleep(0.1)  # the reset, nothing copied
    app_runs(b, 2)
    assert b.running_slot() == 1
    # Slot A is as it was: the old application, to fall back to.
    assert bytes(img[SLOT_A - FLASH_BASE : SLOT_B - FLASH_BASE]) == old
    assert b.boot_stalled_ns == 0 and b.watchdog_resets == 0
    assert b.wflash.faults == []
    return b, new


def test_an_update_over_the_bus_then_the_annex_session_is_bit_identical(
    elf: Path, boot_elf: Path
) -> None:
    b, _ = updated(elf, boot_elf)
    # Power on with the flash the update left (its calibration aside, which the host build
    # does not have) and play the annex against the native build.
    image = bytearray(b.wflash.image)
    image[0x4000:0x8000] = b"\xff" * 0x4000
    image[0x6_0000:0x8_0000] = b"\xff" * 0x2_0000
    scn = load(ROOT / "scenarios" / "annex.txt")
    from board import of_simulator

    bc, sc, f = of_simulator(scn.simulator())
    nb = BootBoard(elf, boot_elf, sc, f, bc, flash_image=bytes(image))
    assert nb.boot_modes == ["app"] and nb.running_version() == 2 and nb.running_slot() == 1
    r = Reference(bc, sc, f)
    r.padding = nb.padding
    nb.trace, r.trace = [], []
    ends_b = play(nb, scn)
    ends_r = play(r, scn)
    assert_same_runs(nb, r)
    assert nb.ticks > 3000 and ends_b == ends_r


def test_slot_bs_image_is_slot_as_code_at_another_address(elf: Path, elf_b: Path) -> None:
    """The build links the same objects twice: the two images are as long, their sections
    the same, and every word where they differ is an address in the image, 0x18000 (slot B's
    base less slot A's) further in slot B's; RAM is laid out the same."""
    a, b = load_image(elf), load_image(elf_b)
    assert (a.slot, b.slot) == (0, 1) and len(a.data) == len(b.data)
    assert (a.board_id, a.version) == (b.board_id, b.version)
    shift = SLOT_B - SLOT_A
    differ = [o for o in range(0, len(a.data), 4) if a.data[o : o + 4] != b.data[o : o + 4]]
    assert len(differ) > 50  # the vector table, the literal pools' addresses
    for o in differ:
        wa = int.from_bytes(a.data[o : o + 4], "little")
        wb = int.from_bytes(b.data[o : o + 4], "little")
        assert wb - wa == shift and SLOT_A <= wa < SLOT_B, f"offset 0x{o:x}"
    sections = []
    for path in (elf, elf_b):
        with path.open("rb") as f:
            secs = {s.name: (s["sh_size"], s["sh_addr"]) for s in ELFFile(f).iter_sections()}
        sections.append(secs)
    for name in (".text", ".data", ".bss", ".noinit"):
        (size_a, addr_a), (size_b, addr_b) = sections[0][name], sections[1][name]
        assert size_a == size_b
        assert addr_b - addr_a == (shift if name == ".text" else 0)


class WrongCrc(Image):
    """An image announced with a CRC its bytes do not have."""

    @property
    def crc32(self) -> int:
        return super().crc32 ^ 1


def test_refusals_leave_the_old_application_running(elf: Path, boot_elf: Path) -> None:
    b = new_board(elf, boot_elf)
    b.request_bootloader()
    u = Updater(b.bus)
    good = image_for(elf, 1, 2)  # slot A runs: slot B's

    # Another board's image: refused by BEGIN, and by the driver before it.
    other = Image(good.data, 0xF401, 2)
    u.begin(other)
    assert u.status() == (State.IDLE, Result.WRONG_BOARD, 0)
    with pytest.raises(UpdateError, match="for board 0xf401"):
        u.update(other)
    # Too large.
    big = Image(good.data + bytes(IMAGE_MAX), 0xF446, 2)
    u.begin(big)
    assert u.status().result == Result.TOO_LARGE
    # An image whose own record names another board, sent as this board's: END refuses it.
    data = bytearray(good.data)
    data[0x204:0x208] = (0xF401).to_bytes(4, "little")
    with pytest.raises(UpdateError, match="WRONG_BOARD"):
        u.update(Image(bytes(data), 0xF446, 2))
    # A wrong CRC: every chunk goes in, END reads the image back and refuses it.
    with pytest.raises(UpdateError, match="BAD_CRC"):
        u.update(WrongCrc(good.data, 0xF446, 2))
    # The image linked for slot A, which runs: the driver refuses it, and so does END.
    wrong = image_for(elf, 0, 2)
    with pytest.raises(WrongSlotError, match="writes slot B, the image is linked for slot A"):
        u.update(wrong)
    u.begin(wrong)
    u.wait()
    for off in range(0, len(wrong.data), CHUNK):
        u.data(off, wrong.data[off : off + CHUNK])
    assert u.wait().next == len(wrong.data)
    u.end()
    assert u.wait() == (State.RECEIVING, Result.WRONG_SLOT, len(wrong.data))
    # A corrupted chunk (a byte flipped on the bus, its PEC the sent one's): not applied.
    u.begin(good)
    u.wait()
    frame = bytes([0xB2]) + (0).to_bytes(4, "big") + good.data[:64]
    pec = crc8(bytes([4]) + frame)
    bad = bytearray(frame)
    bad[10] ^= 0x10
    b.bus.i2c_rdwr(i2c_msg.write(2, bytes(bad) + bytes([pec])))
    assert u.status() == (State.RECEIVING, Result.BAD_PEC, 0)
    assert bytes(b.wflash.image[0x20200:0x20240]) == b"\xff" * 64
    # A chunk past the next offset, and one sent again differently.
    u.data(64, good.data[64:128])
    assert u.status() == (State.RECEIVING, Result.BAD_OFFSET, 0)
    u.data(0, good.data[:64])
    assert u.wait() == (State.RECEIVING, Result.OK, 64)
    u.data(0, good.data[:64])  # sent again (its reply lost): the same chunk
    assert u.wait() == (State.RECEIVING, Result.OK, 64)
    u.data(0, bytes(64))
    assert u.wait() == (State.RECEIVING, Result.MISMATCH, 64)
    u.end()
    assert u.wait().result == Result.INCOMPLETE
    # Whatever was refused, START runs the old application, and only it.
    u.start()
    b.sleep(0.1)
    app_runs(b, 1)
    assert b.wflash.faults == []


def in_ram(b: BootBoard) -> tuple[State, int, int]:
    """The bootloader's state, its next offset and the first byte it holds in RAM, not yet
    programmed (boot.c's boot.state, boot.next, held_from), read from its RAM."""
    sym = b.cpu.boot_symbols
    raw = bytes(b.cpu.uc.mem_read(sym["boot"], 8))
    return State(raw[0]), int.from_bytes(raw[4:8], "little"), b.cpu.read32(sym["held_from"])


def kept_ram(b: BootBoard) -> bytes:
    """The application's RAM that survives a reset (its .noinit, from 0x20008000): the
    bootloader's own, its buffer included, ends below it."""
    return bytes(b.cpu.uc.mem_read(0x2000_8000, b.cpu.sections[".noinit"]))


def test_the_bootloaders_ram_ends_below_the_applications_kept_ram(
    elf: Path, boot_elf: Path
) -> None:
    with boot_elf.open("rb") as f:
        symtab = ELFFile(f).get_section_by_name(".symtab")
        end = {s.name: s["st_value"] for s in symtab.iter_symbols()}  # type: ignore[union-attr]
    with elf.open("rb") as f:
        noinit = ELFFile(f).get_section_by_name(".noinit")
    assert noinit is not None and noinit["sh_addr"] == 0x2000_8000
    assert end["held"] + BUFFER == end["_ebuffer"] <= noinit["sh_addr"]
    assert end["_ebss"] <= noinit["sh_addr"]


def write_bad_pec(b: BootBoard, offset: int, chunk: bytes) -> None:
    """DATA with a byte flipped on the bus after its PEC was computed."""
    frame = bytes([0xB2]) + offset.to_bytes(4, "big") + chunk
    pec = crc8(bytes([4]) + frame)
    bad = bytearray(frame)
    bad[10] ^= 0x10
    b.bus.i2c_rdwr(i2c_msg.write(2, bytes(bad) + bytes([pec])))


def test_chunks_are_held_in_ram_while_the_download_slot_erases(elf: Path, boot_elf: Path) -> None:
    """At 400 kHz the bus brings the BUFFER bytes the bootloader holds in 0.6 s, before the
    download slot's 1 s erase is over: chunks are taken and held in RAM, with every check of a
    chunk (a bad PEC, past the next offset, sent again the same or different), until RAM is
    full (BUSY); nothing is programmed before the erase's end, and BEGIN sent again does not
    erase again. After the erase the held words are programmed, the rest follows, and the
    application's kept RAM is what it was."""
    b = new_board(elf, boot_elf, rate=400_000)
    b.request_bootloader()
    noinit = kept_ram(b)
    new = image_for(elf, 1, 2)
    u = Updater(b.bus)
    n0 = len(b.wflash.log)
    u.begin(new)
    assert u.status() == (State.ERASING, Result.OK, 0)
    u.data(0, new.data[:64])
    assert u.status() == (State.ERASING, Result.OK, 64)
    write_bad_pec(b, 64, new.data[64:128])
    assert u.status() == (State.ERASING, Result.BAD_PEC, 64)
    u.data(128, new.data[128:192])
    assert u.status() == (State.ERASING, Result.BAD_OFFSET, 64)
    u.data(0, bytes(64))
    assert u.status() == (State.ERASING, Result.MISMATCH, 64)
    u.data(0, new.data[:64])
    assert u.status() == (State.ERASING, Result.OK, 64)
    u.end()
    assert u.status() == (State.ERASING, Result.BUSY, 64)
    u.begin(with_version(new, 3))  # another download: after this erase
    assert u.status() == (State.ERASING, Result.BUSY, 64)
    u.begin(new)  # this one again (its acknowledge lost): the same download, kept
    assert u.status() == (State.ERASING, Result.OK, 64)
    for off in range(64, BUFFER, CHUNK):
        u.data(off, new.data[off : off + CHUNK])
    assert u.status() == (State.ERASING, Result.OK, BUFFER)
    u.data(BUFFER, new.data[BUFFER : BUFFER + CHUNK])
    assert u.status() == (State.ERASING, Result.BUSY, BUFFER)  # RAM full: not taken
    held = bytes(b.cpu.uc.mem_read(b.cpu.boot_symbols["held"], BUFFER))
    assert held == new.data[:BUFFER]
    assert b.wflash.log[n0:] == [("erase", 0x20000, 0x20000, 0)]  # and nothing programmed
    assert u.wait() == (State.RECEIVING, Result.BUSY, BUFFER)
    b.sleep(0.15)  # 6144 words, 16 us each
    assert in_ram(b) == (State.RECEIVING, BUFFER, BUFFER)
    assert bytes(b.wflash.image[STAGE : STAGE + BUFFER]) == new.data[:BUFFER]
    for off in range(BUFFER, len(new.data), CHUNK):
        u.data(off, new.data[off : off + CHUNK])
    assert u.status() == (State.RECEIVING, Result.OK, len(new.data))
    u.end()
    assert u.wait() == (State.READY, Result.OK, len(new.data))
    assert kept_ram(b) == noinit and b.boot_stalled_ns == 0
    u.start()
    b.sleep(0.1)
    app_runs(b, 2)
    assert b.wflash.faults == []


def test_a_held_word_that_does_not_take_stops_the_download(elf: Path, boot_elf: Path) -> None:
    """A word of the download held in RAM whose flash is not blank after the erase (a worn
    word, say): read back wrong, it stops the download (IDLE, FLASH_ERROR), nothing after it
    is programmed, and START runs the old application."""
    b = new_board(elf, boot_elf, rate=400_000)
    b.request_bootloader()
    new = image_for(elf, 1, 2)
    u = Updater(b.bus)
    u.begin(new)
    for off in range(0, BUFFER, CHUNK):
        u.data(off, new.data[off : off + CHUNK])
    assert u.wait() == (State.RECEIVING, Result.OK, BUFFER)
    bad = next(o for o in range(20_000, BUFFER, 4) if new.data[o : o + 4] != bytes(4))
    assert in_ram(b)[2] < bad
    b.wflash.image[STAGE + bad : STAGE + bad + 4] = bytes(4)
    b.wflash._mirror(STAGE + bad, 4)
    b.sleep(0.15)
    assert u.status() == (State.IDLE, Result.FLASH_ERROR, BUFFER)
    assert bytes(b.wflash.image[STAGE : STAGE + bad]) == new.data[:bad]
    assert bytes(b.wflash.image[STAGE + bad + 4 : STAGE + BUFFER]) == b"\xff" * (BUFFER - bad - 4)
    u.data(BUFFER, new.data[BUFFER : BUFFER + CHUNK])
    assert u.status() == (State.IDLE, Result.NOT_BEGUN, BUFFER)
    u.start()
    b.sleep(0.1)
    app_runs(b, 1)


class CutError(Exception):
    """The power cut, raised at the master between two transactions."""


class CutWhen:
    """The board's bus until ``when(state, next, held_from)`` of the bootloader's RAM holds
    before a transaction: then CutError."""

    def __init__(self, b: BootBoard, when: Any) -> None:
        self.b = b
        self.clock = b.bus.clock
        self.when = when

    def i2c_rdwr(self, *msgs: Any) -> None:
        if self.b.in_boot() and self.when(*in_ram(self.b)):
            raise CutError
        self.b.bus.i2c_rdwr(*msgs)


HELD_CUTS = {
    # the erase runs, RAM holds chunks
    "erasing": lambda state, nxt, held: state == State.ERASING and nxt >= 4096,
    # the erase runs, RAM full: the master waits
    "full": lambda state, nxt, held: state == State.ERASING and nxt == BUFFER,
    # after the erase: the held words being programmed while more chunks arrive
    "programming": lambda state, nxt, held: state == State.RECEIVING and 8192 <= held < nxt - 4096,
}


@pytest.mark.parametrize("moment", sorted(HELD_CUTS))
def test_a_power_cut_while_chunks_are_held_in_ram(elf: Path, boot_elf: Path, moment: str) -> None:
    """A power cut at 400 kHz while the bootloader holds chunks in RAM (lost with it): in the
    download slot's erase, with RAM holding chunks or full, and while the held words are
    programmed (a word cut part way, if one was). The old application starts, calibrated; the
    update again ends on the new one."""
    b = new_board(elf, boot_elf, rate=400_000)
    b.request_bootloader()
    new = image_for(elf, 1, 2)
    with pytest.raises(CutError):
        Updater(CutWhen(b, HELD_CUTS[moment])).update(new)
    b.power_cycle(Random(sorted(HELD_CUTS).index(moment)))
    assert not b.in_boot() and b.running_version() == 1
    assert kept(b) and b.wflash.faults == []
    b.request_bootloader()
    Updater(b.bus).update(new)
    Updater(b.bus).start()
    b.sleep(0.1)
    app_runs(b, 2)


def test_a_start_up_switch_of_logs_outlasts_the_bootloaders_watchdog(
    elf: Path, boot_elf: Path
) -> None:
    """The bootloader starts the watchdog (1 s) and then the application, whose start-up finds
    sector 1 nearly full and switches to sector 7: its 1 s erase stalls the start-up, under the
    watchdog the application widened to 5 s first (firmware/ports/stm32/main.c). The
    application runs, calibrated, its record in sector 7, no reset."""
    log = b"".join(encode((i, 28000, -i)) for i in range(1024 - 63))
    b = new_board(elf, boot_elf, factory_flash(boot_elf, load_image(elf), log))
    assert b.wflash.erased == [7] and b.watchdog_resets == 0 and b.wflash.faults == []
    assert not b.in_boot() and Board(b.bus).check_busy() == 0
    assert bytes(b.wflash.data_b[:16]) == encode((960, 28000, -960), 1)
    assert bytes(b.wflash.data[: len(log)]) == log


def test_the_watchdog_runs_in_the_bootloader(elf: Path, boot_elf: Path) -> None:
    b = new_board(elf, boot_elf)
    b.request_bootloader()
    b.sleep(1.5)
    assert b.in_boot() and b.watchdog_resets == 0  # fed by its main loop
    b.ticks_on = False  # its main loop no longer wakes (a hung interrupt, say)
    t0 = b.now_ns
    while b.watchdog_resets == 0 and b.now_ns - t0 < 1_200_000_000:
        b.sleep(0.005)
    assert b.watchdog_resets == 1
    assert 0.99e9 <= b.now_ns - t0 <= 1.01e9  # 1 s: (999 + 1) * 32 / 32 kHz
    b.ticks_on = True
    b.sleep(0.05)
    app_runs(b, 1)  # the reset's start-up: the request is gone, the valid application runs


class NoCpu:
    """No CPU sees a replayed flash."""

    def mem_write(self, address: int, data: bytes) -> None:
        pass


def update_to(b: BootBoard, elf: Path, version: int, bus: Any = None) -> None:
    """From the bootloader: ``version`` linked for the slot it writes, downloaded, started."""
    u = Updater(bus or b.bus)
    u.update(image_for(elf, u.info().dl_slot, version))
    u.start()
    b.sleep(0.1)


def test_a_power_cut_at_every_step_of_an_update_leaves_a_valid_application(
    elf: Path, boot_elf: Path
) -> None:
    """Two updates' flash operations, recorded (version 1 in slot A to 2 in slot B, then to 3
    back in slot A, whose three sectors erase), then replayed to each step with a power cut in
    it: in every erase, in one word of every chunk of the first download and of every 16th of
    the second, in every word of both headers. Each time the chip boots a valid application:
    the one that ran until the download's header is whole, the new one after, never the
    bootloader alone; the calibration's sectors are untouched."""
    b = new_board(elf, boot_elf)
    before = bytes(b.wflash.image)
    n0 = len(b.wflash.log)
    ends = []
    for version in (2, 3):
        b.request_bootloader()
        update_to(b, elf, version)
        app_runs(b, version)
        assert b.running_slot() == version % 2 ^ 1
        ends.append(len(b.wflash.log) - n0)
    log = b.wflash.log[n0:]
    erases = [k for k, op in enumerate(log) if op[0] == "erase"]
    # Slot B's sector 5, then slot A's sectors 2, 3, 4 (the header's first): nothing else.
    assert [log[k][1] for k in erases] == [0x20000, 0x8000, 0xC000, 0x10000]
    assert all(sector_of(op[1]) in (2, 3, 4, 5) for op in log)  # never sector 0, 1 or 7
    programs = [k for k, op in enumerate(log) if op[0] == "program"]
    hdr_b = [k for k in programs if 0x20000 <= log[k][1] < 0x20200]
    hdr_a = [k for k in programs if 0x8000 <= log[k][1] < 0x8200]
    # Each header's words (0xFFFFFFFF is not programmed) after its image, last of its update.
    assert len(hdr_b) == len(hdr_a) == 8 and hdr_b[-1] == ends[0] - 1 and hdr_a[-1] == ends[1] - 1
    assert hdr_b[0] > max(k for k in programs if 0x20200 <= log[k][1] < 0x40000)
    assert hdr_a[0] > max(k for k in programs if 0x8200 <= log[k][1] < 0x20000)
    rng = Random(29)
    chunks: dict[tuple[int, int], list[int]] = {}
    for k in programs:
        off = log[k][1]
        if 0x20200 <= off < 0x40000:
            chunks.setdefault((0, (off - 0x20200) // 64), []).append(k)
        elif 0x8200 <= off < 0x20000 and (off - 0x8200) // 64 % 16 == 0:
            chunks.setdefault((1, (off - 0x8200) // 64), []).append(k)
    cuts = set(erases + hdr_b + hdr_a) | {rng.choice(ks) for ks in chunks.values()}
    size = len(load_image(elf).data)
    assert sum(1 for u, _ in chunks if u == 0) == -(-size // 64)
    f = WholeFlash(0x4002_3C00, before)  # the flash replayed, one operation at a time
    f.uc = g_uc = NoCpu()
    seen = []
    for k, op in enumerate(log):
        if k in cuts:
            g = WholeFlash(0x4002_3C00, bytes(f.image))
            g.uc, g.op = g_uc, op
            g.cut(rng)
            b.power_on(bytes(g.image))
            assert not b.in_boot(), f"cut in step {k} ({op[:2]}): no application starts"
            v = b.running_version()
            assert kept(b) and b.wflash.faults == [], f"cut in step {k}"
            # Before an update's header is whole, what ran runs; after it, the new one.
            first = k < ends[0]
            hdr = hdr_b if first else hdr_a
            old, new = (1, 2) if first else (2, 3)
            if k < hdr[0]:
                assert v == old, f"cut in step {k}"
            elif k > hdr[-1]:
                assert v == new, f"cut in step {k}"
            else:
                assert v in (old, new), f"cut in step {k}"  # a torn header: almost always old
            assert b.running_slot() == (v % 2 ^ 1)
            seen.append(v)
        f.op = op
        f.finish()
    assert set(seen) == {1, 2} and len(seen) == len(cuts)  # 3 only once its header is whole:
    b.power_on(bytes(f.image))  # the whole log, no cut
    app_runs(b, 3)
    assert b.running_slot() == 0


def test_the_newest_slot_that_fails_its_checks_falls_back_to_the_other(
    elf: Path, boot_elf: Path
) -> None:
    """Both slots valid, B the newest (sequence 2): B starts. B's image with a flipped byte, its
    header torn, or its header saying slot A's link: A starts, by itself; and the next update
    goes into B, which does not run. The sequence wraps: 0 is newer than 0xFFFFFFFF."""
    image = bytearray(factory_flash(boot_elf, load_image(elf), NVM, NVM_B))
    put_slot(image, image_for(elf, 1, 2), 2)
    b = new_board(elf, boot_elf, bytes(image))
    app_runs(b, 2)
    assert b.running_slot() == 1
    bad_image = bytearray(image)
    bad_image[STAGE + 0x1000] ^= 0x40
    torn = bytearray(image)
    # The header's CRC, part programmed: its first byte that programming clears bits of is
    # still erased (0xFF), whatever this image's CRC is.
    crc_at = SLOT_B - FLASH_BASE + 0x1C
    left = next(i for i in range(crc_at, crc_at + 4) if torn[i] != 0xFF)
    torn[left] = 0xFF
    other_link = bytearray(image)
    put_slot(other_link, image_for(elf, 1, 2), 2)
    hdr = bytearray(header(image_for(elf, 1, 2), 2))
    hdr[20:24] = (SLOT_A + 0x200).to_bytes(4, "little")  # link: slot A's
    hdr[28:32] = (zlib.crc32(bytes(hdr[:28])) & 0xFFFF_FFFF).to_bytes(4, "little")
    other_link[SLOT_B - FLASH_BASE : SLOT_B - FLASH_BASE + 32] = hdr
    for flash in (bad_image, torn, other_link):
        b.power_on(bytes(flash))
        app_runs(b, 1)
        assert b.running_slot() == 0 and b.boot_modes[-1] == "app"
        b.request_bootloader()
        assert Updater(b.bus).info().dl_slot == 1
    wrapped = bytearray(factory_flash(boot_elf, load_image(elf), NVM, NVM_B, 0xFFFF_FFFF))
    put_slot(wrapped, image_for(elf, 1, 2), 0)
    b.power_on(bytes(wrapped))
    app_runs(b, 2)
    assert b.running_slot() == 1


class FlakyBus:
    """The board's bus with faults drawn for each transaction: a write lost before the board
    sees it, a write whose acknowledge is lost after it was taken, a write delivered twice, a
    read whose reply is corrupted on the wire. Each fault raises OSError at the master, as a
    Raspberry Pi's controller reports a failed transfer."""

    def __init__(self, bus: Any, faults: list[int]) -> None:
        self.bus = bus
        self.clock = bus.clock
        self.faults = faults  # per transaction: 0 none, 1 lost, 2 ack lost, 3 twice, 4 garbled
        self.n = 0

    def i2c_rdwr(self, *msgs: Any) -> None:
        fault = self.faults[self.n % len(self.faults)]
        self.n += 1
        is_read = any(int(m.flags) & 1 for m in msgs)
        if fault == 1:
            raise OSError("lost")
        self.bus.i2c_rdwr(*msgs)
        if fault == 3 and not is_read:
            self.bus.i2c_rdwr(*msgs)
        if fault == 2 and not is_read:
            raise OSError("acknowledge lost")
        if fault == 4 and is_read:  # a bit flipped: the driver's PEC check finds it
            raw = bytearray(bytes(msgs[0]))
            raw[0] ^= 0x01
            ctypes.memmove(msgs[0].buf, bytes(raw), len(raw))


@settings(max_examples=3, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(
    faults=st.lists(st.sampled_from([0, 0, 0, 0, 0, 0, 1, 2, 3, 4]), min_size=5, max_size=40),
    rate=st.sampled_from([100_000, 400_000]),
)
def test_lost_resent_and_garbled_frames_never_corrupt_the_image(
    elf: Path, boot_elf: Path, faults: list[int], rate: int
) -> None:
    """At 400 kHz, faults also fall on chunks held in RAM during the erase, and on RAM full."""
    b = new_board(elf, boot_elf, rate=rate)
    b.request_bootloader()
    new = image_for(elf, 1, 2)
    flaky = FlakyBus(b.bus, faults)
    u = Updater(flaky)
    st_ = u.update(new)
    assert st_ == (State.READY, Result.OK, len(new.data))
    stage = SLOT_B - FLASH_BASE
    assert bytes(b.wflash.image[stage + 0x200 : stage + 0x200 + len(new.data)]) == new.data
    assert bytes(b.wflash.image[stage : stage + 32]) == header(new, 2)
    assert u.retries > 0 or set(faults) <= {0, 3}
    Updater(b.bus).start()
    b.sleep(0.1)
    app_runs(b, 2)


@settings(max_examples=3, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(
    into=st.sampled_from(["B", "A"]),
    at=st.floats(0.0, 1.0),
    seed=st.integers(0, 2**32 - 1),
    rate=st.sampled_from([100_000, 400_000]),
)
def test_a_power_cut_at_any_instant_then_the_update_again(
    elf: Path, boot_elf: Path, into: str, at: float, seed: int, rate: int
) -> None:
    """A power cut at a random instant of a live update (its download over the bus, its
    START), mid-operation included, into slot B (slot A runs version 1), or back into slot A
    (slot B runs version 2, after a first update): the board then starts a valid application
    with its calibration, and the update, done again, gets the new one. At 400 kHz the
    download's first 1 s is the erase with chunks held in RAM."""
    b = new_board(elf, boot_elf, rate=rate)
    old = 1
    if into == "A":
        b.request_bootloader()
        update_to(b, elf, 2)
        old = 2
    b.request_bootloader()
    new = image_for(elf, 0 if into == "A" else 1, old + 1)
    u = Updater(b.bus)
    # The download takes 5.7 s at 100 kHz, 1.8 s at 400 kHz; START's reset 40 ms more.
    cut_ns = b.now_ns + int(at * (5.75e9 if rate == 100_000 else 1.9e9))

    def progress(done: int, total: int) -> None:
        if b.now_ns >= cut_ns:
            raise CutError

    try:
        u.update(new, progress=progress)
        u.start()
        b.sleep(max(0.0, (cut_ns - b.now_ns) * 1e-9))
    except CutError:
        pass
    b.power_cycle(Random(seed))
    assert not b.in_boot()
    assert b.running_version() in (old, old + 1)
    assert kept(b)
    assert b.wflash.faults == []
    b.request_bootloader()
    update_to(b, elf, old + 1)
    app_runs(b, old + 1)


class Unclosed:
    """The board's bus for the CLI, which closes its bus at the end: left open here."""

    def __init__(self, bus: Any) -> None:
        self.bus = bus
        self.clock = bus.clock

    def i2c_rdwr(self, *msgs: Any) -> None:
        self.bus.i2c_rdwr(*msgs)

    def close(self) -> None:
        pass


def test_asserv_flash_updates_the_board_and_says_what_runs(
    elf: Path, boot_elf: Path, tmp_path: Path, capsys: Any
) -> None:
    from asserv.cli import parser
    from asserv.cli_bus import run_bus_command

    b = new_board(elf, boot_elf)
    new = image_for(elf, 1, 3)
    path_a, path = tmp_path / "asserv_stm32.bin", tmp_path / "asserv_stm32_b.bin"
    path_a.write_bytes(image_for(elf, 0, 3).data)
    path.write_bytes(new.data)
    # Slot A runs: the board writes slot B, whose image the master was not given.
    only_a = parser().parse_args(["--bus", "1", "flash", str(path_a)])
    assert run_bus_command(only_a, bus_factory=lambda n: Unclosed(b.bus)) == 2
    err = capsys.readouterr().err
    assert "writes slot B" in err and "asserv_stm32_b.elf" in err and len(err.splitlines()) == 1
    b.sleep(0.1)
    app_runs(b, 1)  # started again, nothing written
    args = parser().parse_args(["--bus", "1", "flash", str(path_a), str(path)])
    assert run_bus_command(args, bus_factory=lambda n: Unclosed(b.bus)) == 0
    out = capsys.readouterr()
    assert "board 0xf446: runs version 1 (60812 bytes) from slot A" in out.out.replace(
        str(len(new.data)), "60812"
    )
    assert out.out.startswith(f"image: {len(new.data)} bytes, version 3") and (
        "linked for slot B" in out.out.splitlines()[0]
    )
    assert f"verified: the board read the {len(new.data)} bytes back" in out.out
    assert "running: application version 3" in out.out and "power is cut" in out.out
    app_runs(b, 3)
    # The same image again: nothing written, started again.
    writes = len(b.wflash.log)
    assert run_bus_command(args, bus_factory=lambda n: Unclosed(b.bus)) == 0
    assert "has this image already" in capsys.readouterr().out
    assert len(b.wflash.log) == writes
    app_runs(b, 3)
    assert b.running_slot() == 1
    # An order runs: refused with its reason, the robot goes on.
    Board(b.bus).goto(500, -850)
    b.sleep(0.1)
    assert run_bus_command(args, bus_factory=lambda n: Unclosed(b.bus)) == 1
    err = capsys.readouterr().err
    assert "REFUSED_BUSY" in err and "stop the robot" in err and len(err.splitlines()) == 1
    assert not b.in_boot()


def test_asserv_flash_refuses_bad_files_in_one_line(
    tmp_path: Path, boot_elf: Path, capsys: Any
) -> None:
    from asserv.cli import main

    avr = tmp_path / "asserv_avr.elf"
    avr.write_bytes(b"\x7fELF\x01\x01\x01" + bytes(11) + b"\x53\x00" + bytes(40))
    junk = tmp_path / "junk.bin"
    junk.write_bytes(bytes(600))
    for path, words in (
        (avr, "ISP"),
        (junk, "no application record"),
        (boot_elf, "outside the slots"),
        (tmp_path / "none.elf", "No such file"),
    ):
        assert main(["--bus", "1", "flash", str(path)]) == 2
        err = capsys.readouterr().err
        assert words in err and len(err.splitlines()) == 1 and "Traceback" not in err


def test_asserv_flash_says_when_no_bootloader_answers(elf: Path) -> None:
    """A board without a bootloader (the AVR's, a simulator without ``add_bootloader``: the
    host build here) takes BOOTLOADER and carries on; `asserv flash` says so, naming the AVR's
    ISP route."""
    from asserv.sim import Simulator
    from asserv.update import flash

    sim = Simulator(seed=0)
    board = Board(sim.bus)
    with pytest.raises(UpdateError, match=r"no bootloader answers.*ISP route"):
        flash(board, load_image(elf))
    assert board.check_busy() == 0 and board.last_reject().count == 0  # the board runs on


def test_flash_sh_writes_the_run_slot_the_bootloader_writes(elf: Path, tmp_path: Path) -> None:
    """firmware/ports/stm32/flash.sh builds the run slot (header, then the image) in shell, for
    st-flash: the same bytes as asserv.update.slot_bytes, which the bootloader accepts."""
    import shutil
    import subprocess

    from asserv.update import slot_bytes

    script = (ROOT / "firmware" / "ports" / "stm32" / "flash.sh").read_text()
    part = script[script.index("crc32() {") : script.index("head -c 512 /dev/zero")]
    shutil.copy(elf.with_suffix(".bin"), tmp_path / "asserv_stm32.bin")
    subprocess.run(
        ["bash", "-c", "set -euo pipefail\n" + part],
        env={"BUILD": str(tmp_path), "PATH": "/usr/bin:/bin"},
        check=True,
    )
    assert (tmp_path / "slot.bin").read_bytes() == slot_bytes(load_image(elf))
