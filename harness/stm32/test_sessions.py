"""Whole sessions on the STM32 binary in the emulator against the native reference run, at the
bus's real byte times (100 kHz: 90 us a byte, ticks running inside the frames): the
specification's annex (scenarios/annex.txt, played by asserv.Board as `asserv sim run` plays it)
and a fault, a free wheel's encoder cut while the robot drives. The board's whole state (struct
board, padding aside) after every tick and every byte the master reads are bit-identical."""

from typing import Any

from board import Reference, Stm32Board, of_simulator
from conftest import ROOT
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from asserv import Board, ResetCause, Status
from asserv.scenario import BUS_COMMANDS, load
from asserv.sim._core import lib

FAULT_ENCODER_LOST = 4  # FAULTS_CAUSE_ENCODER_LOST, firmware/core/faults.h


def pair(elf: Any, bc: Any, sc: Any, f: Any) -> tuple[Stm32Board, Reference]:
    b = Stm32Board(elf, sc, f, bc)
    r = Reference(bc, sc, f)
    r.padding = b.padding
    b.trace, r.trace = [], []
    return b, r


def play(dev: Any, scn: Any) -> list[int]:
    board = Board(dev.bus, pec=scn.pec)
    ends = []
    for step in scn.steps:
        if step.command == "wait":
            ends.append(int(board.wait_idle(step.args[0] if step.args else 30.0)))
        elif step.command == "sleep":
            dev.sleep(step.args[0])
        else:
            getattr(board, BUS_COMMANDS[step.command][0])(*step.args)
    return ends


def assert_same_runs(b: Stm32Board, r: Reference) -> None:
    assert b.watchdog_resets == 0
    assert b.ticks == r.ticks
    for k, (x, y) in enumerate(zip(b.trace or [], r.trace or [], strict=True)):
        assert x == y, f"struct board differs after tick {k}"
    assert b.replies == r.replies


def test_annex_session_is_bit_identical(elf: Any) -> None:
    scn = load(ROOT / "scenarios" / "annex.txt")
    b, r = pair(elf, *of_simulator(scn.simulator()))
    ends_b = play(b, scn)
    ends_r = play(r, scn)
    assert_same_runs(b, r)
    assert b.ticks > 3000  # the session moved the robot for seconds
    assert len(ends_b) == 3 and ends_b == ends_r
    assert b.cpu.exception_returns > b.ticks  # each tick, and the I2C events


def test_cut_encoder_is_detected_identically(elf: Any) -> None:
    from board import robot

    b, r = pair(elf, *robot())
    for dev in (b, r):
        board = Board(dev.bus)
        board.goto(-700, 0)
        dev.sleep(0.4)
        lib.sim_set_encoder_cut(dev.sim, 0, True)
        dev.sleep(1.5)
        board.check_busy()
    assert_same_runs(b, r)
    assert r.board.planner.faults.cause == FAULT_ENCODER_LOST


def test_watchdog_resets_the_chip_when_the_ticks_stop(elf: Any) -> None:
    from board import robot

    bc, sc, f = robot()
    b = Stm32Board(elf, sc, f, bc)
    board = Board(b.bus)
    board.goto(500, -850)
    b.sleep(0.3)
    assert b.duty != (0, 0) and b.watchdog_resets == 0
    b.ticks_on = False  # the firmware stops ticking (a hung handler)
    b.sleep(0.055)
    assert b.watchdog_resets == 0 and b.duty != (0, 0)  # the PWM still drives: 60 ms
    b.sleep(0.010)
    assert b.watchdog_resets == 1
    assert b.tim[1].pwm_fraction(0)[0] == 0 and b.duty == (0, 0)  # the reset stopped the motors
    b.ticks_on = True
    b.sleep(0.1)
    assert b.watchdog_resets == 1
    # Booted again, answering: the GOTO reported abandoned, the cause and the pose kept
    # (test_resets.py soaks it).
    assert board.check_busy() == Status.PB_MOTEUR
    info = board.reset_info()
    assert (info.cause, info.count, info.pose_lost) == (ResetCause.WATCHDOG, 1, False)


_OPS = st.lists(
    st.one_of(
        st.tuples(st.just("w"), st.binary(max_size=8), st.booleans()),
        st.tuples(st.just("r"), st.integers(1, 8), st.just(True)),
        st.tuples(st.just("s"), st.integers(0, 3000), st.just(True)),
    ),
    max_size=12,
)


@settings(max_examples=25, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(ops=_OPS)
def test_any_bus_traffic_is_bit_identical(elf: Any, ops: list[tuple[str, Any, bool]]) -> None:
    """Whatever the master writes and reads (garbage, orders, reads of any length, repeated
    starts), at any instant: the binary's replies and state follow the native run's."""
    from board import robot

    b, r = pair(elf, *robot())
    for dev in (b, r):
        for op, arg, stop in ops:
            if op == "w":
                dev.i2c_write(arg, stop)
            elif op == "r":
                dev.i2c_read(arg)
            else:
                dev.advance_ns(arg * 1000)
        dev.advance_ns(2_000_000)
    assert_same_runs(b, r)


_FIXES = st.lists(
    st.tuples(
        st.integers(0, 60),  # ms before the fix is sent, after the previous one
        st.integers(-60, 60),  # x off the estimate [mm]
        st.integers(-60, 60),  # y
        st.integers(-18000, 18000),  # heading [0.01 degree]: any sign
        st.integers(1, 80),  # sigma [mm]
        st.integers(0, 60),  # sigma of the heading [0.1 degree]; 0: none
        st.integers(0, 500),  # age [ms]
    ),
    min_size=1,
    max_size=6,
)


@settings(max_examples=6, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(fixes=_FIXES, seed=st.integers(0, 2**16))
def test_position_fixes_are_fused_identically(
    elf: Any, fixes: list[tuple[int, ...]], seed: int
) -> None:
    """SET_FIX on a randomized robot in a GOTO, at random moments, ages, noises and headings
    (outliers among them): the fusion (the error radius's square roots from
    firmware/arch/armv7m on the binary, the reference's on the host) leaves the same bits."""
    from board import robot

    b, r = pair(elf, *robot(seed=seed, randomize=True))
    for dev in (b, r):
        board = Board(dev.bus)
        board.goto(400, -300)
        dev.sleep(0.3)
        for wait_ms, dx, dy, cdeg, sigma, sigma_h, age in fixes:
            dev.sleep(wait_ms / 1000)
            pose = board.position()
            board.fix(pose.x_mm + dx, pose.y_mm + dy, cdeg / 100, sigma, sigma_h / 10, age)
        dev.sleep(0.2)
        board.fix_info()
    assert_same_runs(b, r)
    info = r.board.planner.fix.info
    assert info.fused + info.outliers + info.too_old == len(fixes)  # each fix has its result
