"""The CPU side of the harness on the real binary: the exception model done in Python around
unicorn 2.1.4's faulty exception return, and what the firmware set up at boot (clock tree, pins,
timers, the configuration compiled in)."""

import sys
import time
from pathlib import Path
from typing import Any

import emu
import pytest
from board import Stm32Board, robot
from emu import IRQ0, SRAM_BASE, SYSTICK, Cpu, EmuError, thumb_insn_count
from unicorn import UC_ERR_EXCEPTION
from unicorn.arm_const import (
    UC_ARM_REG_LR,
    UC_ARM_REG_PC,
    UC_ARM_REG_R0,
    UC_ARM_REG_R1,
    UC_ARM_REG_R2,
    UC_ARM_REG_R3,
    UC_ARM_REG_R12,
    UC_ARM_REG_SP,
)
from unicorn.unicorn_py3.unicorn import UcError

from asserv.sim._core import ffi

REGS = (UC_ARM_REG_R0, UC_ARM_REG_R1, UC_ARM_REG_R2, UC_ARM_REG_R3, UC_ARM_REG_R12)


@pytest.fixture
def board(elf: Any) -> Stm32Board:
    bc, sc, f = robot()
    return Stm32Board(elf, sc, f, bc)


def test_a_run_that_never_stops_is_stopped_and_reported(
    board: Stm32Board, monkeypatch: pytest.MonkeyPatch
) -> None:
    """No instruction budget (unicorn would count every instruction): a run that never reaches
    where it stops, here a branch to itself in RAM, is stopped by the watchdog after HANG_S of
    wall-clock time and reported."""
    monkeypatch.setattr(emu, "HANG_S", 0.5)
    cpu = board.cpu
    loop = SRAM_BASE + 0x1_0000  # above the firmware's RAM, below its stack
    cpu.uc.mem_write(loop, bytes.fromhex("fee7"))  # b .
    cpu.uc.reg_write(UC_ARM_REG_PC, loop | 1)
    t0 = time.monotonic()
    with pytest.raises(EmuError, match=r"ran 0.5 s without stopping \(PC 0x20010000\)"):
        cpu.run_until_idle()
    assert time.monotonic() - t0 < 5
    assert not cpu.runs & 1


def test_an_exception_in_a_peripheral_model_stops_the_run_and_is_raised(
    board: Stm32Board, monkeypatch: pytest.MonkeyPatch
) -> None:
    """The models' callbacks are called from unicorn's C without the binding's guard
    (emu.mmio_map): an exception in one still stops the run, and reaches the caller."""

    def broken(off: int) -> int:
        raise RuntimeError(f"GPIOA read at 0x{off:x}")

    monkeypatch.setattr(board.gpio["A"], "read", broken)
    cpu = board.cpu
    code = SRAM_BASE + 0x1_0000  # above the firmware's RAM, below its stack
    cpu.uc.mem_write(code, bytes.fromhex("08680868fee7"))  # ldr r0, [r1] (twice); b .
    cpu.uc.reg_write(UC_ARM_REG_R1, 0x4002_0010)  # GPIOA IDR
    cpu.uc.reg_write(UC_ARM_REG_PC, code | 1)
    with pytest.raises(RuntimeError, match="GPIOA read at 0x10"):
        cpu.step(code + 4)
    assert not cpu.runs & 1


def test_unicorn_stops_at_exc_return_without_the_workaround(board: Stm32Board) -> None:
    """The bug worked around: a handler's bx lr to EXC_RETURN stops the emulation."""
    cpu = board.cpu
    cpu.enter_exception(SYSTICK)
    with pytest.raises(UcError) as e:
        cpu.uc.emu_start(cpu.reg(UC_ARM_REG_PC) | 1, cpu.idle_pc, count=1_000_000)
    assert e.value.errno == UC_ERR_EXCEPTION
    assert cpu.reg(UC_ARM_REG_PC) & ~1 == 0xFFFF_FFF8


@pytest.mark.parametrize("misalign", [0, 4])
def test_exception_entry_and_return_restore_the_interrupted_context(
    board: Stm32Board, misalign: int
) -> None:
    cpu = board.cpu
    lr = cpu.reg(UC_ARM_REG_LR)
    sp = cpu.reg(UC_ARM_REG_SP) - misalign
    cpu.uc.reg_write(UC_ARM_REG_SP, sp)
    values = [0x1111_0000 + i for i in range(len(REGS))]
    for r, v in zip(REGS, values, strict=True):
        cpu.uc.reg_write(r, v)
    cpu.uc.reg_write(UC_ARM_REG_LR, 0x0800_1235)
    returns = cpu.exception_returns
    cpu.wake(SYSTICK)  # ends the main loop's wfi
    cpu.step(cpu.idle_pc + 2, 1_000_000)  # the handler, up to its return after the wfi
    assert cpu.exception_returns == returns + 1
    assert cpu.reg(UC_ARM_REG_SP) == sp
    assert [cpu.reg(r) for r in REGS] == values
    assert cpu.reg(UC_ARM_REG_LR) == 0x0800_1235
    assert cpu.reg(UC_ARM_REG_PC) & ~1 == cpu.idle_pc + 2
    assert board.ticks == 0 and not cpu.active
    cpu.uc.reg_write(UC_ARM_REG_SP, sp + misalign)
    cpu.uc.reg_write(UC_ARM_REG_LR, lr)  # main()'s: the main loop goes on, and sleeps again
    cpu.run_until_idle()
    assert cpu.reg(UC_ARM_REG_PC) & ~1 == cpu.idle_pc


def test_nested_exception_returns_to_the_handler_it_preempted(board: Stm32Board) -> None:
    cpu = board.cpu
    sp = cpu.reg(UC_ARM_REG_SP)
    cpu.enter_exception(SYSTICK)
    assert cpu.reg(UC_ARM_REG_LR) == 0xFFFF_FFF9  # to thread mode
    systick_entry = cpu.reg(UC_ARM_REG_PC)
    ev = IRQ0 + 31  # I2C1 event: preempts the tick (priority 0x40 < 0xF0)
    assert cpu.priority(ev) < cpu.priority(SYSTICK)
    cpu.enter_exception(ev)
    assert cpu.reg(UC_ARM_REG_LR) == 0xFFFF_FFF1  # to handler mode
    cpu.step(systick_entry & ~1, 100_000)
    assert cpu.active == [SYSTICK]
    assert cpu.reg(UC_ARM_REG_PC) & ~1 == systick_entry & ~1
    cpu.run_until_idle()
    assert not cpu.active and cpu.reg(UC_ARM_REG_SP) == sp


def test_a_masked_or_lower_priority_exception_waits(board: Stm32Board) -> None:
    cpu = board.cpu
    cpu.enter_exception(IRQ0 + 31)
    cpu.pending.add(SYSTICK)
    assert cpu._next_exception() is None  # SysTick (0xF0) cannot preempt the I2C (0x40)
    cpu.run_until_idle()  # taken after the I2C handler returns
    assert SYSTICK not in cpu.pending and board.cpu.exception_returns >= 2


def test_thumb_instruction_widths() -> None:
    # movs r0, #5 (16) ; ldr.w r1, [r2] (32) ; bx lr (16)
    assert thumb_insn_count(bytes([0x05, 0x20, 0xD2, 0xF8, 0x00, 0x10, 0x70, 0x47])) == 3


def test_boot_sets_the_clock_tree_and_the_pins(board: Stm32Board) -> None:
    assert board.rcc.sysclk_hz() == 180_000_000
    assert board.rcc.apb_div(1) == 4 and board.rcc.apb_div(2) == 2
    assert board.pwr.overdrive() and board.flash.latency() == 5
    assert board.cpu.vtor == board.cpu.symbols["stm32_vectors"]  # the run slot's image
    gb = board.gpio["B"]
    assert gb.mode(8) == gb.mode(9) == 2  # I2C1 on AF
    assert gb.read(gb.OTYPER) >> 8 & 3 == 3  # open-drain
    assert gb.read(0x24) & 0xFF == 0x44  # AF4
    for t in (2, 3, 4, 5):
        assert board.tim[t].encoder_mode() == 3
    assert board.tim[1].arr_active == 8999
    assert board.i2c.read(board.i2c.OAR1) >> 1 & 0x7F == 2


def test_the_configuration_compiled_in_is_the_default_robots(elf: Any) -> None:
    bc, sc, f = robot()
    b = Stm32Board(elf, sc, f)  # no configuration given: robot.c's
    off = 0  # cfg is struct board's first member
    size = ffi.sizeof("struct board_config")
    assert b.board_bytes()[off : off + size] == bytes(ffi.buffer(bc))


def test_a_file_that_is_not_the_firmware_is_refused(tmp_path: Path, elf: Any) -> None:
    text = tmp_path / "notes.txt"
    text.write_text("not an ELF\n")
    with pytest.raises(EmuError, match="not an ELF"):
        Cpu(text)
    host_elf = Path(sys.executable).resolve()  # an ELF, but an x86-64 one
    with pytest.raises(EmuError, match="not an ARM ELF"):
        Cpu(host_elf)
