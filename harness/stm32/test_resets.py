"""Resets on the STM32 binary in the emulator (issue 28, item 4): RCC_CSR's reset flags read at
boot (RM0390 6.3.21) and the record the planner keeps in the .noinit RAM (stm32f446re.ld). A
watchdog reset (the ticks hang until the watchdog fires) or a brown-out at a random moment of a
GOTO, with the RAM kept or scrambled, or while idle: the master learns of it at its next poll
(PB_MOTEUR, RESET_INFO), and the pose is within the radius or refused, never silently wrong. The
same resets during a calibration's write to flash (a record's words, the erase of the log switch):
the calibration installed is the old one or the new one, never a mix or none. The host's soak
of the same promise is python/tests/test_resets.py."""

from __future__ import annotations

import math
import re
from pathlib import Path
from random import Random

import pytest
from board import TICK_NS, Stm32Board, robot
from boot import BootBoard
from conftest import ROOT
from hypothesis import HealthCheck, Phase, event, given, settings
from hypothesis import strategies as st
from periph import Rcc
from test_nvm import (
    SLOTS,
    START_FREE,
    Cal,
    encode,
    erasing,
    fill_until_full,
    installed,
    newest,
    ram_board,
)

from asserv import Board, Capability, EndReason, OrderRejected, Reject, ResetCause, Status
from asserv.sim import Simulator
from asserv.sim._core import ffi, lib
from asserv.sim.soak import ideal_calibration

BROWN_OUT = Rcc.BORRSTF | Rcc.PINRSTF  # RM0390 6.3.21: a BOR reset, which drives NRST too
FLAGS = {
    ResetCause.BROWN_OUT: BROWN_OUT,
    ResetCause.WATCHDOG: Rcc.IWDGRSTF | Rcc.PINRSTF,
    ResetCause.PIN: Rcc.PINRSTF,
    ResetCause.SOFTWARE: Rcc.SFTRSTF | Rcc.PINRSTF,
}


def port_constant(name: str) -> int:
    """A #define of stm32_port.h (the bounds of the down time)."""
    text = (ROOT / "firmware" / "ports" / "stm32" / "stm32_port.h").read_text()
    m = re.search(rf"#define {name} (\d+)u", text)
    assert m, name
    return int(m.group(1))


START_MS = port_constant("STM32_START_MS")


def started(elf: Path, seed: int) -> tuple[Stm32Board, Board]:
    bc, sc, f = robot(seed=seed, randomize=True, start_uncertainty=(3, 0.5))
    b = Stm32Board(elf, sc, f, bc)
    board = Board(b.bus)
    board.set_vitesse_traj(100, 100)
    board.set_vitesse_rot(50, 100)
    return b, board


def error_mm(b: Stm32Board, board: Board) -> float:
    p = board.position()
    t = ffi.new("struct sim_truth *")
    lib.sim_get_truth(b.sim, t)
    return math.hypot(p.x_mm - t.odo_pose.x_mm, p.y_mm - t.odo_pose.y_mm)


def hang_until_the_watchdog(b: Stm32Board) -> None:
    """The ticks stop (a hung handler), the motors keep their duty until the watchdog fires."""
    resets = b.watchdog_resets
    b.ticks_on = False
    while b.watchdog_resets == resets:
        b.sleep(0.001)
    b.ticks_on = True


@settings(
    max_examples=12,
    phases=[Phase.explicit, Phase.generate],  # no shrinking: each example runs for seconds
    suppress_health_check=[HealthCheck.too_slow],
)
@given(
    seed=st.integers(0, 10_000),
    at_ms=st.integers(50, 2500),
    cause=st.sampled_from([ResetCause.WATCHDOG, ResetCause.BROWN_OUT]),
    keep_ram=st.booleans(),
    down_ms=st.integers(0, START_MS),
    scramble_seed=st.integers(0, 2**32 - 1),
)
def test_a_reset_mid_goto_is_reported_and_the_pose_kept_or_refused(
    elf: Path,
    seed: int,
    at_ms: int,
    cause: ResetCause,
    keep_ram: bool,
    down_ms: int,
    scramble_seed: int,
) -> None:
    b, board = started(elf, seed)
    board.goto(-200, -500)
    b.sleep(at_ms / 1000)
    scramble = None if keep_ram else Random(scramble_seed)
    if cause == ResetCause.WATCHDOG and keep_ram:
        hang_until_the_watchdog(b)  # the real thing: the robot drives on during the hang
    else:
        b.reset(FLAGS[cause], scramble, down_ms * 1_000_000)
    assert b.rcc.mem[Rcc.CSR] & Rcc.RESET_FLAGS == 0  # read, then cleared (RMVF)

    # The master's next poll.
    status = board.check_busy()
    info = board.reset_info()
    assert (info.cause, info.count, info.pose_lost) == (cause, 1, not keep_ram)
    assert status & Status.PB_MOTEUR and not status & Status.BUSY_TRAJET
    assert board.debug().end_reason == EndReason.RESET
    if keep_ram:
        assert error_mm(b, board) <= board.position().radius_mm
        b.sleep(1.0)  # the robot, motors off, coasts to rest
        assert error_mm(b, board) <= board.position().radius_mm
        board.goto(-200, -500)  # the next order runs
        assert board.wait_idle(20) == 0
        assert error_mm(b, board) <= board.position().radius_mm
    else:
        assert board.position().radius_mm == 255
        b.sleep(1.0)  # the robot, motors off, coasts to rest
        with pytest.raises(OrderRejected) as e:
            board.goto(0, 0)
        assert e.value.reason == Reject.REFUSED_NO_POSE
        board.stop()  # STOP is always taken
        t = ffi.new("struct sim_truth *")
        lib.sim_get_truth(b.sim, t)
        h = math.degrees(t.odo_pose.heading_rad)
        board.declare_pose(round(t.odo_pose.x_mm), round(t.odo_pose.y_mm), round(h))
        board.goto(-200, -500)
        assert board.wait_idle(20) == 0
        assert not board.reset_info().pose_lost
    # A second reset counts on from the first.
    b.reset(BROWN_OUT)
    assert board.reset_info().count == 2


@pytest.mark.parametrize("cause", list(FLAGS))
def test_each_flag_names_its_cause(elf: Path, cause: ResetCause) -> None:
    b, board = started(elf, 1)
    b.reset(FLAGS[cause])
    info = board.reset_info()
    assert (info.cause, info.count, info.pose_lost) == (cause, 1, False)
    # Nothing ran, the pose kept: still said, for the settings are the power-on ones again.
    assert board.check_busy() == Status.PB_MOTEUR
    assert board.debug().end_reason == EndReason.RESET
    assert board.version().capabilities & (1 << 13)  # KEEP_POSE


def test_a_power_on_is_as_before(elf: Path) -> None:
    b, board = started(elf, 2)
    board.goto(-200, -500)
    b.sleep(0.8)
    b.power_cycle()
    assert board.check_busy() == 0
    info = board.reset_info()
    assert (info.cause, info.count, info.pose_lost) == (ResetCause.POWER_ON, 0, False)


def boot_board(elf: Path, boot_elf: Path) -> BootBoard:
    bc, sc, f = robot()
    return BootBoard(elf, boot_elf, sc, f, bc)  # the factory's flash: bootloader, application


def test_the_bootloader_passes_the_flags_and_the_ram_on(elf: Path, boot_elf: Path) -> None:
    """Through the bootloader (which runs first at every reset): the flags are the reset's, the
    record in .noinit is whole, and the start-up fits STM32_START_MS: from the reset to the
    application's main loop asleep (past stm32_encoder_init(), from which the encoders count), its
    instructions at 4 cycles each (a taken branch's most, PM0214 3.3.1; loads take 2), all at
    the HSI's 16 MHz, plus 1 ms for what the emulator does not wait for (the PLL's lock, the
    over-drive, the watchdog's registers)."""
    b = boot_board(elf, boot_elf)
    board = Board(b.bus)
    board.goto(800, -850)
    b.sleep(1.2)
    b.cpu.count_instructions(True)
    b.cpu.insns = 0
    b.reset(BROWN_OUT)
    insns = b.cpu.insns
    b.cpu.count_instructions(False)
    assert b.boot_modes[-1] == "app"
    info = board.reset_info()
    assert (info.cause, info.count, info.pose_lost) == (ResetCause.BROWN_OUT, 1, False)
    assert board.check_busy() & Status.PB_MOTEUR
    start_ms = insns * 4 / 16_000 + 1.0
    print(
        f"\nstart-up through the bootloader: {insns} instructions, {start_ms:.1f} ms at most; "
        f"STM32_START_MS {START_MS}"
    )
    assert start_ms <= START_MS


# The moment of the reset after SET_ODOMETRIE: ``us`` microseconds after the n-th control tick
# to come. The main loop programs one of the record's four words at a tick, for 16 us (0..15
# lands inside a word's program); more ticks than four reach past the record.
_TICKS = st.one_of(st.integers(0, 3), st.integers(0, 3), st.integers(0, 8))
_US = st.one_of(st.integers(0, 15), st.integers(0, 15), st.integers(0, 999))


@settings(
    max_examples=10,
    deadline=None,
    phases=[Phase.explicit, Phase.generate],  # no shrinking: each example runs for a second
    suppress_health_check=[HealthCheck.too_slow],
)
@given(
    seed=st.integers(0, 10_000),
    kept=st.booleans(),
    moving=st.booleans(),
    ticks=_TICKS,
    us=_US,
    cause=st.sampled_from([ResetCause.WATCHDOG, ResetCause.BROWN_OUT]),
    keep_ram=st.booleans(),
    down_ms=st.integers(0, START_MS),
    rng_seed=st.integers(0, 2**32 - 1),
)
def test_a_reset_during_a_calibration_write_keeps_the_old_or_the_new(
    elf: Path,
    seed: int,
    kept: bool,
    moving: bool,
    ticks: int,
    us: int,
    cause: ResetCause,
    keep_ram: bool,
    down_ms: int,
    rng_seed: int,
) -> None:
    """SET_ODOMETRIE, at rest or in a GOTO, then a watchdog reset or a brown-out at a random
    moment of its record's write (inside a word's program, what the cut leaves of it drawn at
    random), the RAM kept or scrambled. At the master's next poll: the reset reported
    (PB_MOTEUR, moving or not), the calibration the old one
    or the new one (the newest whole record of the logs), never a mix, never none once one was
    kept; the pose within the radius or refused. The master sends the calibration again: kept."""
    rng = Random(rng_seed)
    sim = Simulator(seed=seed, randomize=True)
    ideal = ideal_calibration(sim)

    def near_ideal() -> Cal:  # a calibration as the procedure leaves it (asserv.sim.soak)
        return (
            ideal.ratio_ppm + rng.randint(-290, 290),
            ideal.track_10um + rng.randint(-6, 6),
            ideal.scale_ppm + rng.randint(-440, 440),
        )

    old = near_ideal() if kept else None
    new = near_ideal()
    bc, sc, f = robot(seed=seed, randomize=True, start_uncertainty=(3, 0.5))
    b = Stm32Board(elf, sc, f, bc, nvm=None if old is None else encode(old))
    board = Board(b.bus)
    assert installed(ram_board(b)) == old
    if moving:
        board.set_vitesse_traj(100, 100)
        board.goto(-200, -500)  # 0.6 s at least: it runs at the reset
        b.sleep(0.05 + rng.random() * 0.3)
    board.set_odometrie(*new)
    b.advance_ns((b.ticks + ticks) * TICK_NS + us * 1000 + 1 - b.now_ns)
    was_busy = ram_board(b).planner.orders.state != 0
    assert was_busy == moving
    before = newest(b.flash)  # the records completed before the reset
    mid_write = b.flash.busy()
    event(f"reset {'mid-word' if mid_write else 'between words'}, {ticks} ticks")
    scramble = None if keep_ram else Random(rng.getrandbits(32))
    b.reset(FLAGS[cause], scramble, down_ms * 1_000_000, cut=Random(rng.getrandbits(32)))

    # The master's next poll.
    status = board.check_busy()
    info = board.reset_info()
    assert (info.cause, info.count, info.pose_lost) == (cause, 1, not keep_ram)
    # board_restart(): said after any reset but a power-on, an order running or not.
    assert status & Status.PB_MOTEUR
    assert not status & Status.BUSY_TRAJET
    loaded = installed(ram_board(b))
    assert loaded == newest(b.flash), "not the newest whole record"
    assert loaded in (old, new), f"a mix installed: {loaded}"
    assert loaded == before or (mid_write and loaded == new)
    assert (Capability.CALIBRATED in board.version().capabilities) == (loaded is not None)
    if keep_ram:
        assert error_mm(b, board) <= board.position().radius_mm
    else:
        assert board.position().radius_mm == 255
        with pytest.raises(OrderRejected) as e:
            board.goto(0, 0)
        assert e.value.reason == Reject.REFUSED_NO_POSE

    # The board does not finish a torn record (the RAM that held the new one was started
    # afresh): what it runs with is what the flash holds. The master sends it again.
    b.sleep(0.02)
    assert installed(ram_board(b)) == loaded == newest(b.flash)
    board.set_odometrie(*new)
    b.sleep(0.3)  # the record written; the robot, motors off, comes to rest
    assert installed(ram_board(b)) == new == newest(b.flash)
    if keep_ram:
        assert error_mm(b, board) <= board.position().radius_mm
    b.power_cycle(Random(rng.getrandbits(32)))
    assert installed(ram_board(b)) == new


@pytest.mark.parametrize("seed", range(4))
def test_a_reset_during_the_log_switch_keeps_the_full_logs_record(elf: Path, seed: int) -> None:
    """The active log full, SET_ODOMETRIE at rest starts the erase of the other sector; a
    watchdog reset or a brown-out, the RAM kept or scrambled, comes during the erase (the
    model leaves a random part of its bits erased) or during the first record's words in the
    erased sector. At the next poll: the reset reported (PB_MOTEUR, though no order ran), the
    full log's record or the new one installed, the pose kept or
    refused; the master's second send is kept."""
    rng = Random(seed)
    cause = (ResetCause.WATCHDOG, ResetCause.BROWN_OUT)[seed % 2]
    keep_ram = seed // 2 % 2 == 0
    used = SLOTS - START_FREE
    log = b"".join(encode((i, 28000, 0)) for i in range(used))
    bc, sc, f = robot()
    b = Stm32Board(elf, sc, f, bc, nvm=log)
    board = Board(b.bus)
    fill_until_full(b, board)
    last = newest(b.flash)
    new = (rng.randint(-3000, 3000), rng.randint(27500, 28500), rng.randint(-3000, 3000))
    board.set_odometrie(*new)
    while not erasing(b):
        b.advance_ns(100_000)  # the erase starts in the main loop, after a tick
        assert b.now_ns < 5e9
    word = rng.choice([None, 0, 1, 2, 3])  # None: within the erase
    if word is not None:
        while erasing(b):
            b.advance_ns(1_000_000)
        b.advance_ns((b.ticks + word) * TICK_NS + rng.randint(0, 15) * 1000 + 1 - b.now_ns)
    before = newest(b.flash)
    mid_op = b.flash.busy()
    scramble = None if keep_ram else Random(rng.getrandbits(32))
    b.reset(FLAGS[cause], scramble, cut=Random(rng.getrandbits(32)))
    print(
        f"\nreset {cause.name} in {'the erase' if word is None else f'word {word}'}, "
        f"RAM {'kept' if keep_ram else 'scrambled'}: erases {b.flash.erased}"
    )

    status = board.check_busy()
    info = board.reset_info()
    assert (info.cause, info.count, info.pose_lost) == (cause, 1, not keep_ram)
    assert status & Status.PB_MOTEUR
    assert b.watchdog_resets == 0  # the start-up's compaction, if any, within the watchdog
    loaded = installed(ram_board(b))
    assert loaded == newest(b.flash)
    assert loaded in (last, new)
    assert loaded == before or (mid_op and loaded == new)
    if keep_ram:
        assert error_mm(b, board) <= board.position().radius_mm
    else:
        assert board.position().radius_mm == 255
    board.set_odometrie(*new)
    b.sleep(0.05)  # the start-up compacted the logs again: the record goes into sector 7
    b.power_cycle(Random(rng.getrandbits(32)))
    assert installed(ram_board(b)) == new == newest(b.flash)
