"""The bootloader (firmware/boot/stm32) and the application together on the emulated chip.

``WholeFlash`` is periph.Flash over the whole 512 KiB: every sector programs and erases as
sector 1 does (RM0390 3.5), with the data sheet's typical erase time of its size; sector 0, the
bootloader's, is never written (a program or an erase there is a fault: the harness fails the
run). The end of an operation raises the flash interface's interrupt when EOPIE is set.
``BootBoard`` is Stm32Board started from the bootloader: the system reset the bootloader and
the application request (SCB AIRCR), the bootloader's 1 ms SysTick, its flash operations ended
at their instant (the CPU runs from RAM meanwhile: no stall), and the application once it runs,
from either slot (A/B: the same code linked twice, whose symbols both ELFs give).
"""

from __future__ import annotations

import hashlib
from pathlib import Path
from random import Random
from typing import Any

from board import TICK_NS, Stm32Board
from elftools.elf.elffile import ELFFile
from emu import (
    FLASH_BASE,
    FLASH_SIZE,
    IRQ0,
    NVM_AREAS,
    NVM_B_BASE,
    NVM_BASE,
    NVM_SIZE,
    SRAM_BASE,
    EmuError,
)
from periph import SECTOR_ERASE_NS, Flash, Rcc
from unicorn import UC_HOOK_CODE, UC_HOOK_MEM_WRITE_PROT

from asserv.sim._core import lib
from asserv.update import SLOT_BASES, Image, load_image, slot_bytes

IRQ_FLASH = 4  # RM0390 Table 38
# (offset, size) of each sector: RM0390 3.3, Table 4.
SECTORS = [
    (0x0_0000, 0x4000),
    (0x0_4000, 0x4000),
    (0x0_8000, 0x4000),
    (0x0_C000, 0x4000),
    (0x1_0000, 0x1_0000),
    (0x2_0000, 0x2_0000),
    (0x4_0000, 0x2_0000),
    (0x6_0000, 0x2_0000),
]
ERASE_NS = SECTOR_ERASE_NS  # by sector size: periph.py
SLOT_A, SLOT_B = SLOT_BASES  # boot_layout.h: sectors 2-4, sector 5
REQUEST_ADDR = 0x2001_FFF8  # boot_layout.h: BOOT_REQUEST_ADDR, BOOT_REQUEST_MAGIC
REQUEST_MAGIC = 0xB007_1E57
SYSTEM_RESET = Rcc.SFTRSTF | Rcc.PINRSTF  # RCC_CSR's flags after SYSRESETREQ (RM0390 6.3.21)


def sector_of(offset: int) -> int:
    for i, (start, size) in enumerate(SECTORS):
        if start <= offset < start + size:
            return i
    raise ValueError(f"offset 0x{offset:x} is outside the flash")


class WholeFlash(Flash):
    """The flash interface and all 8 sectors (``image``, 512 KiB). ``data`` and ``data_b`` stay
    sector 1's and sector 7's bytes (views of ``image``), as periph.Flash's users expect. ``log``
    records every operation started: (kind, offset, size, value)."""

    def __init__(self, base: int, image: bytes) -> None:
        super().__init__(base)
        if len(image) != FLASH_SIZE:
            raise ValueError(f"a flash image is {FLASH_SIZE} bytes")
        self.image = bytearray(image)
        self.data = memoryview(self.image)[NVM_BASE - FLASH_BASE : NVM_BASE - FLASH_BASE + NVM_SIZE]  # type: ignore[assignment]
        self.data_b = memoryview(self.image)[NVM_B_BASE - FLASH_BASE :]  # type: ignore[assignment]
        self.uc: Any = None
        self.log: list[tuple[str, int, int, int]] = []

    def attach_sector(self, uc: Any) -> None:
        """Sectors 1 and 7 as periph.Flash maps them; the others are the CPU's memory (code runs
        from them), which a store cannot write: a write-protection hook takes the store."""
        self.uc = uc
        super().attach_sector(uc)
        uc.hook_add(
            UC_HOOK_MEM_WRITE_PROT, self._store, begin=FLASH_BASE, end=FLASH_BASE + FLASH_SIZE - 1
        )
        self._mirror(0, FLASH_SIZE)

    def _mirror(self, off: int, size: int) -> None:
        """The CPU's view of [off, off + size) follows ``image`` (sectors 1 and 7 are read
        through the model already)."""
        a = off
        for base, n in NVM_AREAS:
            b = min(off + size, base - FLASH_BASE)
            if a < b:
                self.uc.mem_write(FLASH_BASE + a, bytes(self.image[a:b]))
            a = max(a, base - FLASH_BASE + n)
        if a < off + size:
            self.uc.mem_write(FLASH_BASE + a, bytes(self.image[a : off + size]))

    def _store(self, uc: Any, access: int, addr: int, size: int, value: int, user: Any) -> bool:
        self.program(addr - FLASH_BASE, size, value)
        return True  # the store is taken: the memory changes at the operation's end

    def _array_rd(self, uc: object, offset: int, size: int, user: int) -> int:
        self.stall()
        off = user + offset
        return int.from_bytes(self.image[off : off + size], "little")

    def _array_wr(self, uc: object, offset: int, size: int, value: int, user: int) -> None:
        self.program(user + offset, size, value)

    def program(self, offset: int, size: int, value: int) -> None:
        if sector_of(offset) == 0:
            self.faults.append(f"a store into sector 0 at 0x{FLASH_BASE + offset:08x}")
            return
        super().program(offset, size, value)
        if self.op is not None and self.op[0] == "program":
            self.log.append(self.op)

    def _cr(self, value: int) -> None:
        cr = self.mem[self.CR]
        if cr & self.LOCK:
            return
        self.mem[self.CR] = (value & self.CR_RW) | (self.LOCK if value & self.LOCK else 0)
        if value & self.STRT and not value & self.LOCK:
            if value & self.MER:
                self.faults.append("a mass erase: it would erase the bootloader")
            elif value & self.SER:
                snb = (value >> self.SNB_POS) & 0xF
                if snb == 0 or snb >= len(SECTORS):
                    self.faults.append(f"an erase of sector {snb}")
                    return
                if self.psize() == 3:
                    self.faults.append("an erase at x64: it needs an external VPP (3.6.2)")
                    return
                start, size = SECTORS[snb]
                self.mem[self.CR] |= self.STRT
                self.op = ("erase", start, size, 0)
                self.busy_ns = ERASE_NS[size][self.psize()]
                self.erases += 1
                self.erased.append(snb)
                self.log.append(self.op)

    def finish(self) -> None:
        if self.op is None:
            return
        kind, off, size, value = self.op
        if kind == "program":
            for i in range(size):
                self.image[off + i] &= (value >> (8 * i)) & 0xFF
        else:
            self.image[off : off + size] = b"\xff" * size
        self._mirror(off, size)
        self.op = None
        self.busy_ns = 0
        self.mem[self.CR] &= ~self.STRT
        if self.mem[self.CR] & self.EOPIE:
            self.sr |= self.EOP

    def cut(self, rng: Random) -> None:
        if self.op is None:
            return
        kind, off, size, value = self.op
        if kind == "program":
            for i in range(size):
                done = rng.getrandbits(8)
                self.image[off + i] &= ((value >> (8 * i)) & 0xFF) | ~done & 0xFF
        else:
            for i in range(off, off + size, 4):
                done = rng.getrandbits(32)
                word = int.from_bytes(self.image[i : i + 4], "little") | done
                self.image[i : i + 4] = word.to_bytes(4, "little")
        self._mirror(off, size)
        self.op = None
        self.busy_ns = 0


def elf_bytes_at(path: str | Path, base: int, size: int) -> bytes:
    """The loadable bytes of an ELF between base and base + size, 0xFF elsewhere."""
    out = bytearray(b"\xff" * size)
    with Path(path).open("rb") as f:
        for seg in ELFFile(f).iter_segments():
            if seg["p_type"] != "PT_LOAD" or not seg["p_filesz"]:
                continue
            a = seg["p_paddr"] - base
            if not 0 <= a < size:
                raise EmuError(f"{path}: a segment at 0x{seg['p_paddr']:08x}, outside its place")
            data = seg.data()
            out[a : a + len(data)] = data
    return bytes(out)


def with_version(image: Image, version: int) -> Image:
    """The same application with another version in its record (its CRC changes with it)."""
    data = bytearray(image.data)
    data[0x208:0x20C] = version.to_bytes(4, "little")
    return Image(bytes(data), image.board_id, version)


def factory_flash(
    boot_elf: str | Path,
    app: Image | None,
    nvm: bytes = b"",
    nvm_b: bytes = b"",
    sequence: int = 1,
) -> bytes:
    """The flash as an ST-LINK leaves it (flash.sh): the bootloader in sector 0, the
    calibration's sectors 1 and 7 (``nvm``, ``nvm_b``), ``app`` with its header (``sequence``)
    in the slot it is linked for (or none), the rest erased."""
    image = bytearray(b"\xff" * FLASH_SIZE)
    image[: SECTORS[0][1]] = elf_bytes_at(boot_elf, FLASH_BASE, SECTORS[0][1])
    image[0x4000 : 0x4000 + len(nvm)] = nvm
    image[NVM_B_BASE - FLASH_BASE : NVM_B_BASE - FLASH_BASE + len(nvm_b)] = nvm_b
    if app is not None:
        put_slot(image, app, sequence)
    return bytes(image)


def put_slot(image: bytearray, app: Image, sequence: int) -> None:
    """``app`` and its header (``sequence``) into the slot of ``image`` it is linked for."""
    if app.slot is None:
        raise ValueError("the image is linked for no slot")
    off = SLOT_BASES[app.slot] - FLASH_BASE
    slot = slot_bytes(app, sequence)
    image[off : off + len(slot)] = slot


def elf_of_slot_b(elf: str | Path) -> Path:
    """Slot B's ELF beside slot A's (the build makes both)."""
    return Path(elf).parent / "asserv_stm32_b.elf"


def elf_symbols(path: str | Path, names: tuple[str, ...]) -> dict[str, int]:
    with Path(path).open("rb") as f:
        symtab = ELFFile(f).get_section_by_name(".symtab")
        return {
            s.name: int(s["st_value"])
            for s in symtab.iter_symbols()  # type: ignore[union-attr]
            if s.name in names
        }


def symbol_words(path: str | Path, name: str, n: int) -> tuple[int, ...]:
    """``n`` words of a constant in an ELF's flash image, by its symbol."""
    image = load_image(path)
    off = elf_symbols(path, (name,))[name] - image.link
    return tuple(
        int.from_bytes(image.data[off + 4 * i : off + 4 * i + 4], "little") for i in range(n)
    )


class BootBoard(Stm32Board):
    """The chip from its reset vector: the bootloader, then the application it starts. The
    application's symbols come from ``elf`` (slot A's: an image of the same code whatever its
    version) and ``elf_b`` (slot B's, beside it by default): the same RAM, the code elsewhere."""

    def __init__(
        self,
        elf: str | Path,
        boot_elf: str | Path,
        sc: Any,
        f: Any,
        bc: Any = None,
        flash_image: bytes | None = None,
        byte_ns: int = 90_000,
        elf_b: str | Path | None = None,
    ) -> None:
        self._initial = (
            flash_image if flash_image is not None else factory_flash(boot_elf, load_image(elf))
        )
        self.elf_b = Path(elf_b) if elf_b is not None else elf_of_slot_b(elf)
        self._layout_words = symbol_words(elf, "stm32_layout", 3)
        self._ready = False
        self.reset_requested = False
        self.system_resets = 0
        self.boot_modes: list[str] = []  # what each start-up ended in: "boot" or "app"
        self.boot_stalled_ns = 0  # flash stalls while the bootloader ran (it runs from RAM)
        super().__init__(elf, sc, f, bc, byte_ns, boot_elf=boot_elf)

    def _make_flash(self) -> Flash:
        return WholeFlash(0x4002_3C00, self._initial)

    @property
    def wflash(self) -> WholeFlash:
        assert isinstance(self.flash, WholeFlash)
        return self.flash

    def _layout(self) -> tuple[int, int, int]:
        a, b, c = self._layout_words  # the same in both slots' images: read from the ELF
        return a, b, c

    def _setup(self) -> None:
        if self._ready:
            return
        self._ready = True
        # Slot B's image: where its main loop sleeps, and its board_restart() for the robot's
        # configuration (the RAM symbols are slot A's: the same addresses).
        cpu = self.cpu
        b_sym = elf_symbols(self.elf_b, ("stm32_idle", "board_restart", "asserv_board"))
        if b_sym["asserv_board"] != cpu.symbols["asserv_board"]:
            raise EmuError("slot B's image puts the board elsewhere in RAM than slot A's")
        at = b_sym["stm32_idle"] & ~1
        cpu.idle_pcs.add(at)
        cpu.uc.hook_add(UC_HOOK_CODE, lambda uc, a, s, u: uc.emu_stop(), begin=at, end=at)
        if self.config_override is not None:
            at = b_sym["board_restart"] & ~1
            cpu.uc.hook_add(UC_HOOK_CODE, self._inject_config, begin=at, end=at)
        self.scs.on_reset = self._on_reset
        # The bootloader runs from RAM; the application it starts from flash, its start-up too.
        self.flash.code_in_flash = lambda: not self.in_boot()
        self.cpu.irq_lines.append(self._flash_line)

    def _on_reset(self) -> None:
        self.reset_requested = True
        self.cpu.halt = True
        self.cpu.uc.emu_stop()

    def _flash_line(self) -> set[int]:
        fl = self.flash
        if fl.sr & fl.EOP and fl.mem.get(fl.CR, 0) & fl.EOPIE and self.scs.irq_enabled(IRQ_FLASH):
            return {IRQ0 + IRQ_FLASH}
        return set()

    def in_boot(self) -> bool:
        """The bootloader runs: its vector table is in RAM (or the reset's is current)."""
        return self.cpu.vtor >= SRAM_BASE or self.cpu.vtor == FLASH_BASE

    # ---- start-up, resets ----------------------------------------------------------------------
    def _boot(self) -> None:
        self._setup()
        self.reset_requested = False
        self.flash.stall_on_sr = False  # the reset handler reads no flash register
        self.cpu.reset()
        self.cpu.run_until_idle()
        if self.reset_requested:
            raise EmuError("a system reset during the start-up")
        self._check_flash()
        self._check_boot()

    def _check_boot(self) -> None:
        if self.in_boot():
            self.boot_modes.append("boot")
            if not self.iwdg.running:
                raise EmuError("the bootloader runs without the watchdog")
            return
        self.boot_modes.append("app")
        super()._check_boot()

    def _run(self, in_tick: bool = False) -> bool:
        if not self._wait_for_flash(in_tick):
            return False
        boot = self.in_boot()
        # A read of FLASH_SR waits for the flash only when the code runs from it.
        self.flash.stall_on_sr = not boot
        stalled = self.flash.stalled_ns
        self.cpu.run_until_idle()
        if boot:
            self.boot_stalled_ns += self.flash.stalled_ns - stalled
        if self.reset_requested:
            self.system_resets += 1
            self.flash.cut(Random(self.system_resets))
            self._restart(SYSTEM_RESET)  # RAM kept: a system reset, not a power cycle
            return True
        self._check_flash()
        self._outputs()
        return True

    def _wait_for_flash(self, in_tick: bool) -> bool:
        if self.in_boot():
            return True  # the bootloader's code and vectors are in RAM: nothing waits
        return super()._wait_for_flash(in_tick)

    def control_tick(self) -> None:
        if self.in_boot() and not self.scs.systick_on():
            self._drive_inputs()
            return
        super().control_tick()

    def advance_ns(self, duration_ns: int) -> None:
        """The lockstep's loop (board._Lockstep), with one more event: in the bootloader, the
        end of a flash operation, where its interrupt wakes the main loop (an operation that a
        tick starts ends within the same call too)."""
        end = self.now_ns + duration_ns
        while self.now_ns < end:
            if self.now_ns == self.ticks * TICK_NS:
                self.control_tick()
                self.ticks += 1
                if self.trace is not None:
                    self.trace.append(hashlib.blake2b(self.board_state(), digest_size=16).digest())
            nxt = min(self.ticks * TICK_NS, end)
            waking = self.flash.busy() and self.in_boot()
            if waking:
                nxt = min(nxt, self.now_ns + max(1, self.flash.busy_ns))
            if nxt <= self.now_ns:
                break  # a stall of the CPU on the flash moved the time past the end
            lib.sim_advance_ns(self.sim, nxt - self.now_ns)
            self.time_passes(nxt - self.now_ns)
            self.now_ns = nxt
            if waking and not self.flash.busy() and self.in_boot():
                self._run()  # the end-of-operation interrupt

    # ---- helpers for the tests ---------------------------------------------------------------
    def request_bootloader(self) -> None:
        """What the application does to enter the bootloader: the request words at the end of
        RAM, then a system reset."""
        self.cpu.write32(REQUEST_ADDR, REQUEST_MAGIC)
        self.cpu.write32(REQUEST_ADDR + 4, ~REQUEST_MAGIC & 0xFFFF_FFFF)
        self.system_resets += 1
        self._restart(SYSTEM_RESET)

    def power_on(self, image: bytes) -> None:
        """Power off, the flash replaced by ``image`` (as another chip's), power on."""
        self.wflash.op = None
        self.wflash.image[:] = image
        self.wflash._mirror(0, FLASH_SIZE)
        self.power_cycle()

    def running_slot(self) -> int | None:
        """The slot whose application runs (0 A, 1 B: its vector table is the current one), or
        None in the bootloader."""
        if self.in_boot():
            return None
        return SLOT_BASES.index(self.cpu.vtor - 0x200)

    def running_version(self) -> int | None:
        """The version of the application running (its record in its slot), or None in the
        bootloader."""
        slot = self.running_slot()
        if slot is None:
            return None
        off = SLOT_BASES[slot] - FLASH_BASE + 0x200 + 0x208
        return int.from_bytes(self.wflash.image[off : off + 4], "little")
