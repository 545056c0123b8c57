"""A Cortex-M4 on unicorn: the ELF loaded into flash and SRAM, the peripherals as MMIO models
(periph.py), and the exception model of the ARMv7-M architecture done here, in Python (PM0214
2.3.7 exception entry and return), because unicorn 2.1.4 mishandles the exception return: a
``bx lr`` to an EXC_RETURN value stops the emulation with UC_ERR_EXCEPTION at 0xFFFFFFF8 instead
of unstacking. The harness enters exceptions itself (stack the 8-word frame, LR = EXC_RETURN,
PC = the vector) and catches the stop at the EXC_RETURN address to unstack the frame.

The CPU runs until it reaches the main loop's sleep (the ``wfi`` of ``stm32_idle``) with no
exception pending: the lockstep (board.py) then moves the world on and raises the next
interrupt, which ends the wfi: the main loop runs after the handler, and sleeps again.

A firmware that never gets there (a hang) is stopped by a watchdog thread after ``HANG_S``
seconds of one run, not by an instruction budget: unicorn counts a budget with a callback at
every instruction, which costs a quarter of the emulation's time.
"""

from __future__ import annotations

import ctypes
import struct
import threading
import time
import weakref
from collections.abc import Callable
from pathlib import Path
from typing import Any

from elftools.common.exceptions import ELFError
from elftools.elf.elffile import ELFFile
from unicorn import (
    UC_ARCH_ARM,
    UC_ERR_EXCEPTION,
    UC_HOOK_BLOCK,
    UC_HOOK_CODE,
    UC_MODE_MCLASS,
    UC_MODE_THUMB,
    UC_PROT_ALL,
    UC_PROT_EXEC,
    UC_PROT_READ,
)
from unicorn.arm_const import (
    UC_ARM_REG_LR,
    UC_ARM_REG_PC,
    UC_ARM_REG_PRIMASK,
    UC_ARM_REG_R0,
    UC_ARM_REG_R1,
    UC_ARM_REG_R2,
    UC_ARM_REG_R3,
    UC_ARM_REG_R12,
    UC_ARM_REG_SP,
    UC_ARM_REG_XPSR,
    UC_CPU_ARM_CORTEX_M4,
)
from unicorn.unicorn_py3.unicorn import Uc, UcError, uclib

FLASH_BASE = 0x0800_0000
FLASH_SIZE = 512 * 1024
NVM_BASE = 0x0800_4000  # flash sector 1, the calibration's first log: the flash model maps it
NVM_SIZE = 0x4000
NVM_B_BASE = 0x0806_0000  # flash sector 7, its second log (periph.NVM_SECTORS)
NVM_B_SIZE = 0x2_0000
NVM_AREAS = ((NVM_BASE, NVM_SIZE), (NVM_B_BASE, NVM_B_SIZE))
SRAM_BASE = 0x2000_0000
SRAM_SIZE = 128 * 1024
EXC_RETURN_THREAD_MSP = 0xFFFF_FFF9  # PM0214 Table 17: return to thread mode, main stack
EXC_RETURN_HANDLER = 0xFFFF_FFF1  # return to handler mode (a nested exception)
SYSTICK = 15  # exception numbers: PM0214 2.3.2
IRQ0 = 16
XPSR_STACK_ALIGN = 1 << 9  # PM0214 2.3.7: the frame was realigned to 8 bytes
THREAD_PRIORITY = 256  # lower than any configurable priority
HANG_S = 60.0  # [s] of wall-clock time one run of the CPU may take: past it, a hang (_Watchdog)
# The exception frame (PM0214 2.3.7), then what entry reads besides: the registers in the order
# they are stacked.
FRAME_REGS = (
    UC_ARM_REG_R0,
    UC_ARM_REG_R1,
    UC_ARM_REG_R2,
    UC_ARM_REG_R3,
    UC_ARM_REG_R12,
    UC_ARM_REG_LR,
    UC_ARM_REG_PC,
    UC_ARM_REG_XPSR,
)


class EmuError(RuntimeError):
    """The firmware did something the harness does not expect (a hang, a fault)."""


def thumb_insn_count(code: bytes) -> int:
    """Instructions in a block of Thumb-2 code: a halfword whose top five bits are 0b11101,
    0b11110 or 0b11111 starts a 32-bit instruction (ARMv7-M ARM A5.1)."""
    n = i = 0
    while i + 1 < len(code):
        hw = code[i] | code[i + 1] << 8
        i += 4 if (hw >> 11) in (0b11101, 0b11110, 0b11111) else 2
        n += 1
    return n


class RegFile:
    """unicorn's register calls, made on the engine's handle directly: the binding's
    ``reg_read``/``reg_write`` choose a ctypes type per call in Python (1.4 us; 0.5 us here),
    and the lockstep reads and writes some 30 registers per bus event; an exception's entry
    and return read or write theirs in one batch call (14 us through the binding's
    ``reg_read_batch``; 1.6 us here). Values are the 32-bit registers of the M profile."""

    def __init__(self, uc: Uc) -> None:
        self._h = uc._uch
        self._val = ctypes.c_uint64()
        self._ref = ctypes.byref(self._val)

    def read(self, reg: int) -> int:
        err = uclib.uc_reg_read(self._h, reg, self._ref)
        if err:
            raise UcError(err, reg)
        return int(self._val.value)

    def write(self, reg: int, value: int) -> None:
        self._val.value = value & 0xFFFF_FFFF
        err = uclib.uc_reg_write(self._h, reg, self._ref)
        if err:
            raise UcError(err, reg)

    def batch(self, regs: tuple[int, ...]) -> RegBatch:
        return RegBatch(self._h, regs)


class RegBatch:
    """A fixed list of registers read or written in one call, in its order."""

    def __init__(self, handle: Any, regs: tuple[int, ...]) -> None:
        n = len(regs)
        self._h = handle
        self._n = n
        self._ids = (ctypes.c_int * n)(*regs)
        self._vals = (ctypes.c_uint64 * n)()
        base = ctypes.addressof(self._vals)
        self._ptrs = (ctypes.c_void_p * n)(*(base + 8 * i for i in range(n)))

    def read(self) -> list[int]:
        err = uclib.uc_reg_read_batch(self._h, self._ids, self._ptrs, self._n)
        if err:
            raise UcError(err)
        return list(self._vals)

    def write(self, values: list[int]) -> None:
        for i, v in enumerate(values):
            self._vals[i] = v & 0xFFFF_FFFF
        err = uclib.uc_reg_write_batch(self._h, self._ids, self._ptrs, self._n)
        if err:
            raise UcError(err)


_MMIO_READ = ctypes.CFUNCTYPE(
    ctypes.c_uint64, ctypes.c_void_p, ctypes.c_uint64, ctypes.c_uint, ctypes.c_void_p
)
_MMIO_WRITE = ctypes.CFUNCTYPE(
    None, ctypes.c_void_p, ctypes.c_uint64, ctypes.c_uint, ctypes.c_uint64, ctypes.c_void_p
)


def mmio_map(
    uc: Uc,
    address: int,
    size: int,
    read: Callable[[Any, int, int, Any], int],
    read_user: Any,
    write: Callable[[Any, int, int, int, Any], None],
    write_user: Any,
) -> None:
    """``uc.mmio_map``, the callbacks called from unicorn's C directly: the binding wraps each in
    two more Python calls (its exception guard, then its adapter), a third of an access's cost,
    and a start-up reads the calibration's logs through 32 K of them. As in the binding, an
    exception in a model stops the run, and ``emu_start`` raises it."""

    def stopped(e: BaseException) -> None:
        if uc._hook_exception is None:
            uc._hook_exception = e  # type: ignore[assignment]  # (the binding's guard does so)
        uc.emu_stop()

    def rd(handle: int, offset: int, n: int, key: int) -> int:
        try:
            return read(uc, offset, n, read_user)
        except BaseException as e:
            stopped(e)
            return 0

    def wr(handle: int, offset: int, n: int, value: int, key: int) -> None:
        try:
            write(uc, offset, n, value, write_user)
        except BaseException as e:
            stopped(e)

    rd_c, wr_c = _MMIO_READ(rd), _MMIO_WRITE(wr)
    err = uclib.uc_mmio_map(uc._uch, address, size, rd_c, None, wr_c, None)
    if err:
        raise UcError(err)
    uc._mmio_callbacks[(address, address + size)] = (rd_c, wr_c)  # kept alive, as the binding


class _Watchdog:
    """One daemon thread per process over the CPUs that run: a run (one ``emu_start``, whose
    count the CPU keeps odd while it lasts) that lasts more than ``HANG_S`` is stopped with
    ``uc_emu_stop``, which unicorn lets another thread call (its own timeout does), and marked
    ``hung`` for ``Cpu.step`` to report. A run takes milliseconds."""

    def __init__(self) -> None:
        self._cpus: weakref.WeakSet[Cpu] = weakref.WeakSet()
        self._lock = threading.Lock()
        self._thread: threading.Thread | None = None

    def watch(self, cpu: Cpu) -> None:
        with self._lock:
            self._cpus.add(cpu)
            if self._thread is None:
                self._thread = threading.Thread(target=self._loop, name="emu-watchdog", daemon=True)
                self._thread.start()

    def _loop(self) -> None:
        since: dict[int, tuple[int, float]] = {}  # id(cpu) -> (its run, when first seen)
        while True:
            time.sleep(min(1.0, HANG_S / 4))
            now = time.monotonic()
            with self._lock:
                cpus = list(self._cpus)
            for cpu in cpus:
                run = cpu.runs
                if not run & 1:
                    since.pop(id(cpu), None)
                    continue
                seen, t0 = since.setdefault(id(cpu), (run, now))
                if seen != run:
                    since[id(cpu)] = (run, now)
                elif now - t0 > HANG_S:
                    cpu.hung = True
                    cpu.uc.emu_stop()


_watchdog = _Watchdog()


class Cpu:
    """The CPU, its memory and its exceptions. Peripheral models attach with ``mmio``; they
    report their interrupt lines through ``irq_line`` callbacks."""

    def __init__(self, elf_path: str | Path, boot_elf: str | Path | None = None) -> None:
        """``boot_elf``: the bootloader (firmware/boot/stm32) in flash sector 0 too, started at
        reset; without it the reset starts the application's vector table, as a debugger
        would (the application alone is linked at its slot, not at the boot address)."""
        self.uc = Uc(UC_ARCH_ARM, UC_MODE_THUMB | UC_MODE_MCLASS)
        self.uc.ctl_set_cpu_model(UC_CPU_ARM_CORTEX_M4)
        # SRAM first: mapped after the flash, unicorn 2.1.4 gives it the RAM offsets of the flash
        # block at 0x08008000, so that a store at SRAM + k counts as a write to the code at
        # 0x08008000 + k and throws its translation away (the application's struct board at
        # 0x20008000 shares them with board_tick's code: every tick translated it again).
        self.uc.mem_map(SRAM_BASE, SRAM_SIZE, UC_PROT_ALL)
        # Flash but its sectors 1 and 7, which the flash interface's model maps (periph.Flash).
        start = FLASH_BASE
        for base, size in NVM_AREAS:
            if base > start:
                self.uc.mem_map(start, base - start, UC_PROT_READ | UC_PROT_EXEC)
            start = base + size
        if start < FLASH_BASE + FLASH_SIZE:
            self.uc.mem_map(start, FLASH_BASE + FLASH_SIZE - start, UC_PROT_READ | UC_PROT_EXEC)
        self.regs = RegFile(self.uc)
        # An exception's entry reads the frame and SP; its return writes them back (PC last).
        self._entry_regs = self.regs.batch((*FRAME_REGS, UC_ARM_REG_SP))
        self._return_regs = self.regs.batch(
            (*FRAME_REGS[:6], UC_ARM_REG_SP, UC_ARM_REG_XPSR, UC_ARM_REG_PC)
        )
        self.symbols: dict[str, int] = {}
        self.sizes: dict[str, int] = {}
        self.sections: dict[str, int] = {}
        self._load(Path(elf_path))
        self.boot_symbols: dict[str, int] = {}
        if boot_elf is not None:
            self._load(Path(boot_elf), self.boot_symbols, {}, {})
        # Exceptions: priorities, pending, enabled; the stack of active ones.
        self.pending: set[int] = set()
        self.active: list[int] = []
        self.priority: Callable[[int], int] = lambda exc: 0
        self.enabled: Callable[[int], bool] = lambda exc: True
        self.irq_lines: list[Callable[[], set[int]]] = []
        self.vtor = FLASH_BASE
        for name in ("stm32_idle", "asserv_board", "board_restart", "stm32_layout"):
            if name not in self.symbols:
                raise EmuError(f"{elf_path}: not the asserv STM32 firmware (no symbol {name})")
        self.idle_pc = self.symbols["stm32_idle"] & ~1
        # Where the CPU sleeps: the application's wfi, and the bootloader's.
        self.idle_pcs = {self.idle_pc}
        if "boot_idle" in self.boot_symbols:
            self.idle_pcs.add(self.boot_symbols["boot_idle"] & ~1)
            at = self.boot_symbols["boot_idle"] & ~1
            self.uc.hook_add(UC_HOOK_CODE, lambda uc, a, s, u: uc.emu_stop(), begin=at, end=at)
        self.reset_base = (
            FLASH_BASE if boot_elf is not None else self.symbols.get("stm32_vectors", FLASH_BASE)
        )
        self.halt = False  # set by a model (a system reset): run_until_idle returns at once
        self.exception_returns = 0
        self.insns = 0
        self._counting = False
        self._block_insns: dict[tuple[int, int], int] = {}
        self.on_block: Callable[[int, int], None] | None = None
        self.runs = 0  # emu_start calls begun and ended: odd while one runs (_Watchdog)
        self.hung = False
        _watchdog.watch(self)

    # ---- loading ---------------------------------------------------------------------------
    def _load(
        self,
        path: Path,
        symbols: dict[str, int] | None = None,
        sizes: dict[str, int] | None = None,
        sections: dict[str, int] | None = None,
    ) -> None:
        symbols = self.symbols if symbols is None else symbols
        sizes = self.sizes if sizes is None else sizes
        sections = self.sections if sections is None else sections
        with path.open("rb") as f:
            try:
                elf = ELFFile(f)
            except ELFError as e:
                raise EmuError(f"{path}: not an ELF file ({e})") from e
            if elf["e_machine"] != "EM_ARM":
                raise EmuError(f"{path}: not an ARM ELF ({elf['e_machine']})")
            for seg in elf.iter_segments():
                if seg["p_type"] != "PT_LOAD" or not seg["p_filesz"]:
                    continue
                start = seg["p_paddr"]
                for base, size in NVM_AREAS:
                    if start < base + size and start + seg["p_filesz"] > base:
                        raise EmuError(f"{path}: code or data linked into a calibration log")
                # Flash holds every loadable byte at its load address (.data's initial values
                # too: the reset handler copies them).
                self.uc.mem_write(seg["p_paddr"], seg.data())
            for sec in elf.iter_sections():
                sections[sec.name] = int(sec["sh_size"])
            symtab = elf.get_section_by_name(".symtab")
            if symtab is None:
                raise EmuError(f"{path}: no symbol table")
            for sym in symtab.iter_symbols():  # type: ignore[attr-defined]
                if sym.name and sym["st_info"]["type"] in ("STT_FUNC", "STT_OBJECT"):
                    symbols[sym.name] = int(sym["st_value"])
                    sizes[sym.name] = int(sym["st_size"])

    # ---- memory helpers --------------------------------------------------------------------
    def read32(self, addr: int) -> int:
        return int(struct.unpack("<I", self.uc.mem_read(addr, 4))[0])

    def write32(self, addr: int, value: int) -> None:
        self.uc.mem_write(addr, struct.pack("<I", value & 0xFFFFFFFF))

    def reg(self, r: int) -> int:
        return self.regs.read(r)

    # ---- reset and exceptions --------------------------------------------------------------
    def reset(self) -> None:
        """PM0214 2.3.1 (reset): SP from vector 0, PC from vector 1 (the boot alias of flash)."""
        self.regs.write(UC_ARM_REG_SP, self.read32(self.reset_base))
        self.regs.write(UC_ARM_REG_PC, self.read32(self.reset_base + 4))
        self.regs.write(UC_ARM_REG_LR, 0xFFFF_FFFF)
        self.regs.write(UC_ARM_REG_PRIMASK, 0)  # PM0214 2.1.3: PRIMASK is 0 at reset
        self.halt = False

    def _current_priority(self) -> int:
        return self.priority(self.active[-1]) if self.active else THREAD_PRIORITY

    def _next_exception(self) -> int | None:
        """The pending exception to take now, if any (PM0214 2.3.4: the lowest priority value
        wins, then the lowest number)."""
        if self.regs.read(UC_ARM_REG_PRIMASK) & 1:
            return None
        candidates = set(self.pending)
        for line in self.irq_lines:
            candidates |= line()
        candidates -= set(self.active)
        best: int | None = None
        for exc in sorted(candidates):
            if exc >= IRQ0 and not self.enabled(exc):
                continue
            if self.priority(exc) >= self._current_priority():
                continue
            if best is None or self.priority(exc) < self.priority(best):
                best = exc
        return best

    def enter_exception(self, exc: int) -> None:
        """Exception entry, PM0214 2.3.7: the frame r0-r3, r12, lr, return address, xPSR
        pushed on the main stack (realigned to 8 bytes, flagged in the stacked xPSR bit 9),
        LR = EXC_RETURN, PC = the vector."""
        self._enter(exc, None)

    def _enter(self, exc: int, resume: int | None) -> None:
        """``enter_exception``, the return address ``resume`` (default: the PC)."""
        *frame, sp = self._entry_regs.read()
        xpsr = frame[7]
        if sp & 4:
            sp -= 4
            xpsr |= XPSR_STACK_ALIGN
        else:
            xpsr &= ~XPSR_STACK_ALIGN
        sp -= 32
        if resume is not None:
            frame[6] = resume
        frame[7] = xpsr | 1 << 24
        self.uc.mem_write(sp, struct.pack("<8I", *[v & 0xFFFFFFFF for v in frame]))
        regs = self.regs
        regs.write(UC_ARM_REG_SP, sp)
        regs.write(UC_ARM_REG_LR, EXC_RETURN_HANDLER if self.active else EXC_RETURN_THREAD_MSP)
        self.pending.discard(exc)
        self.active.append(exc)
        regs.write(UC_ARM_REG_PC, self.read32(self.vtor + 4 * exc))

    def exception_return(self) -> int:
        """Exception return (PM0214 2.3.7), done here: unstack the frame, restore the
        alignment, leave the active exception. Returns the PC it returns to."""
        if not self.active:
            raise EmuError("exception return with no active exception")
        sp = self.regs.read(UC_ARM_REG_SP)
        r0, r1, r2, r3, r12, lr, pc, xpsr = struct.unpack("<8I", self.uc.mem_read(sp, 32))
        sp += 32
        if xpsr & XPSR_STACK_ALIGN:
            sp += 4
        pc |= 1
        self._return_regs.write([r0, r1, r2, r3, r12, lr, sp, xpsr & ~XPSR_STACK_ALIGN, pc])
        self.active.pop()
        self.exception_returns += 1
        return int(pc)

    # ---- running ---------------------------------------------------------------------------
    def count_instructions(self, on: bool) -> None:
        """Counts executed instructions in ``insns`` (a block hook: slower)."""
        if on and not self._counting:
            self._hook = self.uc.hook_add(UC_HOOK_BLOCK, self._block)
            # unicorn calls a block hook from the code it translates once the hook is there:
            # blocks translated before (the boot's, the ticks' before counting) would run
            # uncounted for as long as their translation lasts. Translated again, all count.
            self.uc.ctl_flush_tb()
        elif not on and self._counting:
            self.uc.hook_del(self._hook)
        self._counting = on

    def _block(self, uc: Uc, address: int, size: int, user: object) -> None:
        key = (address, size)
        n = self._block_insns.get(key)
        if n is None:
            n = self._block_insns[key] = thumb_insn_count(bytes(uc.mem_read(address, size)))
        self.insns += n
        if self.on_block is not None:
            self.on_block(address, n)

    def step(self, until: int, max_insns: int = 0) -> int:
        """Runs from the current PC until ``until`` (or ``max_insns``, when given: unicorn then
        calls its counter at every instruction; otherwise HANG_S guards): EXC_RETURN stops are
        unstacked here and the run goes on. Returns the PC where it stopped."""
        pc = self.regs.read(UC_ARM_REG_PC)
        while True:
            err: UcError | None = None
            self.runs += 1
            try:
                self.uc.emu_start(pc | 1, until, count=max_insns)
            except UcError as e:
                err = e
            finally:
                self.runs += 1
            pc = self.regs.read(UC_ARM_REG_PC)
            if self.hung:
                raise EmuError(f"the firmware ran {HANG_S:g} s without stopping (PC 0x{pc:08x})")
            if err is None:
                return pc
            if err.errno == UC_ERR_EXCEPTION and pc >= 0xFFFF_FFF0:
                pc = self.exception_return()
                if pc & ~1 == until:
                    return pc
                continue
            raise EmuError(f"CPU stopped at 0x{pc:08x}: {err}") from err

    def wake(self, exc: int) -> None:
        """An exception ends the wfi the CPU sleeps in (PM0214 3.12.11): the wfi completes,
        and the exception returns to the instruction after it."""
        self._enter(exc, ((self.regs.read(UC_ARM_REG_PC) & ~1) + 2) | 1)

    def run_until_idle(self, max_insns: int = 0) -> None:
        """Runs the firmware, taking pending exceptions, until it sleeps in the main loop's
        wfi with none left to take (``max_insns``: as ``step``'s)."""
        pc = self.regs.read(UC_ARM_REG_PC) & ~1
        for _ in range(1000):
            if pc in self.idle_pcs and not self.active:
                exc = self._next_exception()
                if exc is None:
                    return
                self._enter(exc, (pc + 2) | 1)  # wake(): the wfi completes
            elif self.active:
                exc = self._next_exception()
                if exc is not None:
                    self.enter_exception(exc)
            raw = self.step(self.idle_pc, max_insns)
            if self.halt:
                return
            pc = raw & ~1
            if pc not in self.idle_pcs:
                raise EmuError(f"the firmware did not reach its idle loop (PC 0x{raw:08x})")
        raise EmuError("interrupts kept coming: an interrupt line is never cleared")


def struct_padding(elf_path: str | Path, name: str) -> list[int]:
    """Offsets of the padding bytes of ``struct name`` (and of every struct inside it), from the
    ELF's DWARF: bytes no member covers. A struct copied from the stack carries whatever was
    there in its padding, so comparisons of RAM skip them."""
    with Path(elf_path).open("rb") as f:
        elf = ELFFile(f)
        dwarf = elf.get_dwarf_info()
        top = None
        for cu in dwarf.iter_CUs():
            for die in cu.iter_DIEs():
                if (
                    die.tag == "DW_TAG_structure_type"
                    and "DW_AT_name" in die.attributes
                    and die.attributes["DW_AT_name"].value == name.encode()
                    and "DW_AT_byte_size" in die.attributes
                ):
                    top = die
                    break
            if top is not None:
                break
        if top is None:
            raise EmuError(f"no struct {name} in the DWARF of {elf_path}")
        size = int(top.attributes["DW_AT_byte_size"].value)
        used = bytearray(size)

        def resolve(die: Any) -> Any:
            while die.tag in ("DW_TAG_typedef", "DW_TAG_volatile_type", "DW_TAG_const_type"):
                die = die.get_DIE_from_attribute("DW_AT_type")
            return die

        def mark(die: Any, base: int) -> None:
            die = resolve(die)
            if die.tag == "DW_TAG_structure_type":
                for m in die.iter_children():
                    if m.tag == "DW_TAG_member":
                        loc = int(m.attributes["DW_AT_data_member_location"].value)
                        mark(m.get_DIE_from_attribute("DW_AT_type"), base + loc)
            elif die.tag == "DW_TAG_array_type":
                elem = die.get_DIE_from_attribute("DW_AT_type")
                esize = int(resolve(elem).attributes["DW_AT_byte_size"].value)
                dims = []
                for sub in die.iter_children():
                    if "DW_AT_count" in sub.attributes:
                        dims.append(int(sub.attributes["DW_AT_count"].value))
                    elif "DW_AT_upper_bound" in sub.attributes:
                        dims.append(int(sub.attributes["DW_AT_upper_bound"].value) + 1)
                n = 1
                for d in dims:
                    n *= d
                for i in range(n):
                    mark(elem, base + i * esize)
            else:
                for i in range(int(die.attributes["DW_AT_byte_size"].value)):
                    used[base + i] = 1

        mark(top, 0)
        return [i for i in range(size) if not used[i]]
