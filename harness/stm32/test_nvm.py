"""The odometry calibration across a power cycle on the STM32 binary (firmware/ports/stm32/nvm.c:
a log of 16-byte records in flash sector 1), on the emulated flash interface (periph.Flash).

- SET_ODOMETRIE through the I2C master, the main loop writes the record (the host port's
  record, byte for byte), a power cycle keeping the flash: VERSION says CALIBRATED and the
  odometry's factors in RAM are the host build's after the same, bit for bit.
- A corrupt or torn record is never installed: the board starts on the last valid one, or
  uncalibrated, and answers.
- A full log is erased only while no order runs, the motors off and the watchdog widened for
  the stall.
- Power cuts at random instants, mid-write included, always load the last completed record
  or, when the cut tore the record being written, the one before: never anything else.
"""

from random import Random
from typing import Any

import pytest
from board import TICK_NS, Stm32Board, robot
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from test_sessions import assert_same_runs, pair

from asserv import Board, Capability
from asserv._core import ffi
from asserv.sim import Simulator

SLOT = 16
SLOTS = 1024
START_FREE = 64  # STM32_NVM_START_FREE, stm32_nvm.h
CAL = (1500, 28037, -700)  # ratio [ppm], track [10 um], scale [ppm]: SET_ODOMETRIE's order

Cal = tuple[int, int, int]  # (ratio_ppm, track_10um, scale_ppm)


def crc16(data: bytes) -> int:
    """CRC-16/CCITT-FALSE (calib_store.h)."""
    crc = 0xFFFF
    for byte in data:
        crc ^= byte << 8
        for _ in range(8):
            crc = ((crc << 1) ^ 0x1021) & 0xFFFF if crc & 0x8000 else (crc << 1) & 0xFFFF
    return crc


def encode(cal: Cal) -> bytes:
    """calib_store_encode(), written here from calib_store.h's layout."""
    ratio, track, scale = cal
    body = b"ac\x01\x00" + ratio.to_bytes(4, "big", signed=True)
    body += scale.to_bytes(4, "big", signed=True) + track.to_bytes(2, "big")
    return body + crc16(body).to_bytes(2, "big")


def decode(rec: bytes) -> Cal | None:
    if rec[:4] != b"ac\x01\x00" or crc16(rec[:14]) != int.from_bytes(rec[14:16], "big"):
        return None
    ratio = int.from_bytes(rec[4:8], "big", signed=True)
    scale = int.from_bytes(rec[8:12], "big", signed=True)
    if not (-30000 <= ratio <= 30000 and -30000 <= scale <= 30000):
        return None
    return ratio, int.from_bytes(rec[12:14], "big"), scale


def last_valid(data: bytes) -> Cal | None:
    """The calibration of the last slot of the log that holds a valid record."""
    found = None
    for i in range(0, len(data), SLOT):
        cal = decode(bytes(data[i : i + SLOT]))
        if cal is not None:
            found = cal
    return found


def ram_board(b: Stm32Board) -> Any:
    """The STM32's struct board, read from its RAM (the layouts are checked equal at boot)."""
    board = ffi.new("struct board *")
    ffi.memmove(board, b.board_bytes(), ffi.sizeof("struct board"))
    return board


def factors(board: Any) -> tuple[int, int, int]:
    oc = board.servo.counter.cfg
    return int(oc.left_um_per_count_q16), int(oc.right_um_per_count_q16), int(oc.track_um)


def installed(board: Any) -> Cal | None:
    if not board.planner.calibrated:
        return None
    c = board.planner.calibration
    return int(c.ratio_ppm), int(c.track_10um), int(c.scale_ppm)


def calibrated(master: Board) -> bool:
    return Capability.CALIBRATED in master.version().capabilities


def new_board(elf: Any, nvm: bytes | None = None) -> tuple[Stm32Board, Board]:
    bc, sc, f = robot()
    b = Stm32Board(elf, sc, f, bc, nvm=nvm)
    return b, Board(b.bus)


def test_calibration_survives_a_power_cycle_as_on_the_host(elf: Any) -> None:
    b, master = new_board(elf)
    b.sleep(0.02)
    assert not calibrated(master)
    nominal = factors(ram_board(b))
    assert bytes(b.flash.data) == b"\xff" * len(b.flash.data)

    sim = Simulator(seed=0)  # the host build, on the same robot (robot() copies its config)
    host = Board(sim.bus)
    for m in (master, host):
        m.set_odometrie(*CAL)
    b.sleep(0.05)
    sim.advance(0.05)
    assert calibrated(master)
    # The host port's record, byte for byte, in the log's first slot; nothing else written.
    assert bytes(b.flash.data[:SLOT]) == sim.nvm[:SLOT] == encode(CAL)
    assert bytes(b.flash.data[SLOT:]) == b"\xff" * (len(b.flash.data) - SLOT)
    assert b.flash.programs == SLOT // 4 and b.flash.erases == 0
    assert max(b.stalls, default=0) <= b.flash.PROGRAM_NS  # a word at most, never an erase

    programs = b.flash.programs
    b.power_cycle()
    sim.power_cycle()
    b.sleep(0.02)
    sim.advance(0.02)
    assert calibrated(master) and calibrated(host)
    mine = ram_board(b)
    assert installed(mine) == CAL
    assert factors(mine) == factors(sim._h.board)
    assert factors(mine) != nominal
    assert b.flash.programs == programs  # the record loaded is the stored one: not rewritten
    assert master.check_busy() == 0


def test_writing_the_record_leaves_the_board_bit_identical_to_the_host_build(elf: Any) -> None:
    """The main loop's flash writes change nothing the control sees: struct board after every
    tick and every reply byte stay the native run's while SET_ODOMETRIE is installed and its
    record written, and VERSION then reads CALIBRATED on both."""
    b, r = pair(elf, *robot())
    for dev in (b, r):
        m = Board(dev.bus)
        dev.sleep(0.01)
        m.set_odometrie(*CAL)
        dev.sleep(0.05)
        assert calibrated(m)
        m.check_busy()
    assert_same_runs(b, r)
    assert b.flash.programs == SLOT // 4 and bytes(b.flash.data[:SLOT]) == encode(CAL)


@pytest.mark.parametrize("bit", [0, 13, 37, 74, 111, 127])
def test_a_corrupt_record_leaves_the_board_uncalibrated_and_answering(elf: Any, bit: int) -> None:
    rec = bytearray(encode(CAL))
    rec[bit // 8] ^= 1 << (bit % 8)
    b, master = new_board(elf, nvm=bytes(rec))
    b.sleep(0.02)
    assert not calibrated(master)
    assert installed(ram_board(b)) is None
    assert master.check_busy() == 0
    nominal = factors(ram_board(new_board(elf)[0]))
    assert factors(ram_board(b)) == nominal


def test_a_torn_record_after_a_valid_one_loads_the_valid_one(elf: Any) -> None:
    older = (-2000, 27990, 400)
    torn = encode(CAL)[:8] + b"\xff" * 8  # two words of four written when the power went
    b, master = new_board(elf, nvm=encode(older) + torn)
    b.sleep(0.02)
    assert calibrated(master)
    assert installed(ram_board(b)) == older
    # The next record goes after the torn slot, never over it.
    master.set_odometrie(*CAL)
    b.sleep(0.05)
    assert bytes(b.flash.data[2 * SLOT : 3 * SLOT]) == encode(CAL)
    assert bytes(b.flash.data[SLOT : 2 * SLOT]) == torn


def test_a_nearly_full_log_is_compacted_at_start_up(elf: Any) -> None:
    used = SLOTS - START_FREE + 1
    log = b"".join(encode((i, 28000, -i)) for i in range(used))
    b, master = new_board(elf, nvm=log)
    assert b.flash.erases == 1 and b.boot_stall_ns >= b.flash.ERASE_NS[2]
    assert bytes(b.flash.data[:SLOT]) == encode((used - 1, 28000, 1 - used))
    assert bytes(b.flash.data[SLOT:]) == b"\xff" * (len(b.flash.data) - SLOT)
    b.sleep(0.02)
    assert calibrated(master) and installed(ram_board(b)) == (used - 1, 28000, 1 - used)


def test_a_zeroed_sector_is_erased_at_start_up_and_the_board_runs_uncalibrated(elf: Any) -> None:
    """What flashing asserv_stm32.bin leaves in sector 1 (objcopy fills the gap between the
    vectors and the code with zeros): no record, no free slot."""
    b, master = new_board(elf, nvm=bytes(SLOTS * SLOT))
    assert b.flash.erases == 1
    assert bytes(b.flash.data) == b"\xff" * len(b.flash.data)
    b.sleep(0.02)
    assert not calibrated(master) and master.check_busy() == 0


def test_a_full_log_is_erased_only_when_the_board_is_idle(elf: Any) -> None:
    used = SLOTS - START_FREE  # START_FREE slots free: no erase at start-up
    log = b"".join(encode((i, 28000, 0)) for i in range(used))
    b, master = new_board(elf, nvm=log)
    assert b.flash.erases == 0
    for i in range(START_FREE):  # fill the log at run time
        master.set_odometrie(-i, 28010, 0)
        b.sleep(0.008)
    assert last_valid(bytes(b.flash.data)) == (-(START_FREE - 1), 28010, 0)
    assert bytes(b.flash.data[-SLOT:]) == encode((-(START_FREE - 1), 28010, 0))
    assert b.flash.erases == 0 and b.lost_ticks == 0

    # A calibration while the robot drives: it waits, the log full, the previous record kept.
    master.goto(0, -700)
    b.sleep(0.2)
    assert b.duty != (0, 0)
    master.set_odometrie(*CAL)
    b.sleep(0.3)
    assert b.flash.erases == 0 and b.lost_ticks == 0
    assert calibrated(master)
    while b.flash.erases == 0:
        b.sleep(0.001)
        assert b.now_ns < 20e9, "never erased: the order never ended"
        if b.flash.erases:
            assert ram_board(b).planner.orders.state == 0, "erased while an order runs"
    b.sleep(0.6)
    # The erase stalled the CPU (a quarter of a second of ticks lost), the watchdog widened
    # for it did not reset the chip, and the record is alone in the log.
    assert b.watchdog_resets == 0
    long = [d for w, d in zip(b.stalls, b.stall_duties, strict=True) if w > 1_000_000]
    assert long == [(0, 0)]  # one long stall, the erase's, with the motors off
    assert max(b.stalls) >= b.flash.ERASE_NS[2] - 1_000_000
    assert b.lost_ticks >= 240
    assert bytes(b.flash.data[:SLOT]) == encode(CAL)
    assert bytes(b.flash.data[SLOT:]) == b"\xff" * (len(b.flash.data) - SLOT)
    assert abs(b.iwdg.reload_ns() - 60e6) < 1  # back to its 60 ms
    assert master.check_busy() == 0
    b.power_cycle()
    b.sleep(0.02)
    assert installed(ram_board(b)) == CAL


@pytest.mark.parametrize("word", [0, 1, 2, 3])
@pytest.mark.parametrize("seed", [1, 2, 3])
def test_a_cut_inside_each_word_of_a_record_keeps_the_previous_one(
    elf: Any, word: int, seed: int
) -> None:
    older = (-2000, 27990, 400)
    b, master = new_board(elf, nvm=encode(older))
    master.set_odometrie(*CAL)
    b.advance_ns((b.ticks + word) * TICK_NS + 8_000 - b.now_ns)  # 8 us into word `word`
    assert b.flash.busy() and b.flash.op is not None and b.flash.op[1] == SLOT + 4 * word
    b.power_cycle(Random(seed))
    loaded = installed(ram_board(b))
    assert loaded == last_valid(bytes(b.flash.data))
    assert loaded in (older, CAL)
    assert loaded == older or word == 3  # only the last word can complete the record
    b.sleep(0.02)
    assert master.check_busy() == 0
    # The master sends it again: it goes after the torn slot, and survives the next cut.
    master.set_odometrie(*CAL)
    b.sleep(0.03)
    b.power_cycle(Random(seed))
    assert installed(ram_board(b)) == CAL


_CAL = st.tuples(st.integers(-3000, 3000), st.integers(27500, 28500), st.integers(-3000, 3000))
# A round: maybe a SET_ODOMETRIE, then time up to ``us`` microseconds after the n-th control
# tick to come (the main loop starts a word at a tick: 0..15 us lands inside its 16 us
# program), then maybe a power cut (its seed draws what the cut leaves of a word).
_ROUNDS = st.lists(
    st.tuples(
        st.one_of(st.none(), _CAL),
        st.one_of(st.integers(0, 3), st.integers(0, 3), st.integers(0, 25)),
        st.one_of(st.integers(0, 15), st.integers(0, 15), st.integers(0, 999)),
        st.one_of(st.none(), st.integers(0, 2**32 - 1)),
    ),
    min_size=1,
    max_size=8,
)


@settings(max_examples=25, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(rounds=_ROUNDS)
def test_power_cuts_at_any_instant_load_the_last_record_or_the_one_before(
    elf: Any, rounds: list[tuple[Cal | None, int, int, int | None]]
) -> None:
    """SET_ODOMETRIE and power cuts at any instant, mid-write included: after each cut the
    board installs the calibration of the last record completed before the cut, or the one
    being written if the cut happened to complete it; it is always one the master sent; and
    a record sent 20 ms or more before the cut has been written."""
    b, master = new_board(elf)
    sent: list[Cal] = []
    current: Cal | None = None  # what the board has installed, as the master knows it
    since_ns: int | None = None  # since the last SET_ODOMETRIE, while no cut came after it
    for cal, ticks, us, cut in rounds:
        if cal is not None:
            master.set_odometrie(*cal)
            sent.append(cal)
            current = cal
            since_ns = 0
        ns = (b.ticks + ticks) * TICK_NS + us * 1000 + 1 - b.now_ns
        b.advance_ns(ns)
        since_ns = None if since_ns is None else since_ns + ns
        if cut is None:
            continue
        before = last_valid(bytes(b.flash.data))  # completed before the cut
        mid_write = b.flash.busy()
        b.power_cycle(Random(cut))
        after = last_valid(bytes(b.flash.data))
        loaded = installed(ram_board(b))
        assert loaded == after, "the board did not install the last valid record"
        # The cut completed the record being written (the board's calibration), or left the
        # log as it was.
        assert loaded == before or (mid_write and loaded == current)
        assert loaded is None or loaded in sent, f"garbage installed: {loaded}"
        if since_ns is not None and since_ns >= 20_000_000:
            assert loaded == current, "a record sent 20 ms before the cut was not written"
        assert master.check_busy() == 0
        current = loaded
        since_ns = None
    b.sleep(0.03)
    assert installed(ram_board(b)) == current
    assert last_valid(bytes(b.flash.data)) == current
