"""The odometry calibration across a power cycle on the STM32 binary (firmware/ports/stm32/nvm.c:
two logs of 16-byte records, flash sectors 1 and 7), on the emulated flash interface
(periph.Flash).

- SET_ODOMETRIE through the I2C master, the main loop writes the record (the host port's
  record, byte for byte), a power cycle keeping the flash: VERSION says CALIBRATED and the
  odometry's factors in RAM are the host build's after the same, bit for bit.
- A corrupt or torn record is never installed: the board starts on the last valid one, or
  uncalibrated, and answers.
- A full log is compacted into the other sector, erased only while no order runs, the motors
  off and the watchdog widened for the stall; the full log is left as it is.
- Power cuts at random instants, mid-write and mid-erase included, across log switches, always
  load the newest completed record or, when the cut tore the record being written or the
  sector being erased, the one before: never anything else, never nothing once one was kept.
"""

from random import Random
from typing import Any

import pytest
from board import TICK_NS, Stm32Board, robot
from hypothesis import HealthCheck, event, given, settings
from hypothesis import strategies as st
from test_sessions import assert_same_runs, pair

from asserv import Board, Capability
from asserv.sim import Simulator
from asserv.sim._core import ffi

SLOT = 16
SLOTS = 1024  # of each log
START_FREE = 64  # STM32_NVM_START_FREE, stm32_nvm.h
LOG_A, LOG_B = 0x4000, 0x6_0000  # sectors 1 and 7, as offsets from the flash's base
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


def encode(cal: Cal, gen: int = 0) -> bytes:
    """calib_store_encode(), written here from calib_store.h's layout (version 2)."""
    ratio, track, scale = cal
    body = b"ac\x02" + bytes([gen]) + ratio.to_bytes(4, "big", signed=True)
    body += scale.to_bytes(4, "big", signed=True) + track.to_bytes(2, "big")
    return body + crc16(body).to_bytes(2, "big")


def decode(rec: bytes) -> tuple[Cal, int] | None:
    """The calibration and generation of a valid record (version 1: generation 0), or None."""
    if rec[:2] != b"ac" or not (rec[2] == 2 or rec[2:4] == b"\x01\x00"):
        return None
    if crc16(rec[:14]) != int.from_bytes(rec[14:16], "big"):
        return None
    ratio = int.from_bytes(rec[4:8], "big", signed=True)
    scale = int.from_bytes(rec[8:12], "big", signed=True)
    if not (-30000 <= ratio <= 30000 and -30000 <= scale <= 30000):
        return None
    return (ratio, int.from_bytes(rec[12:14], "big"), scale), rec[3]


def last_valid_gen(data: bytes) -> tuple[Cal, int] | None:
    """The last slot of a log that holds a valid record, with its generation."""
    found = None
    for i in range(0, SLOTS * SLOT, SLOT):
        rec = decode(bytes(data[i : i + SLOT]))
        if rec is not None:
            found = rec
    return found


def last_valid(data: bytes) -> Cal | None:
    found = last_valid_gen(data)
    return None if found is None else found[0]


def newer(a: int, b: int) -> bool:
    """Serial-number order of generations (RFC 1982, 8 bits)."""
    return 0 < (a - b) % 256 < 128


def newest(flash: Any) -> Cal | None:
    """What the board must install from both logs: the record of the newer generation, the
    last valid one of its log (docs/stm32.md)."""
    a, b = last_valid_gen(bytes(flash.data)), last_valid_gen(bytes(flash.data_b[: SLOTS * SLOT]))
    found = (a or b) if a is None or b is None else (b if newer(b[1], a[1]) else a)
    return None if found is None else found[0]


def blank(data: Any) -> bool:
    return bytes(data) == b"\xff" * len(data)


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


def new_board(
    elf: Any, nvm: bytes | None = None, nvm_b: bytes | None = None
) -> tuple[Stm32Board, Board]:
    bc, sc, f = robot()
    b = Stm32Board(elf, sc, f, bc, nvm=nvm, nvm_b=nvm_b)
    return b, Board(b.bus)


def test_calibration_survives_a_power_cycle_as_on_the_host(elf: Any) -> None:
    b, master = new_board(elf)
    b.sleep(0.02)
    assert not calibrated(master)
    nominal = factors(ram_board(b))
    assert blank(b.flash.data) and blank(b.flash.data_b)

    sim = Simulator(seed=0)  # the host build, on the same robot (robot() copies its config)
    host = Board(sim.bus)
    for m in (master, host):
        m.set_odometrie(*CAL)
    b.sleep(0.05)
    sim.advance(0.05)
    assert calibrated(master)
    # The host port's record, byte for byte, in the log's first slot; nothing else written.
    assert bytes(b.flash.data[:SLOT]) == sim.nvm[:SLOT] == encode(CAL)
    assert blank(b.flash.data[SLOT:]) and blank(b.flash.data_b)
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


def test_a_nearly_full_log_is_compacted_into_sector_7_at_start_up(elf: Any) -> None:
    used = SLOTS - START_FREE + 1
    log = b"".join(encode((i, 28000, -i)) for i in range(used))
    last = (used - 1, 28000, 1 - used)
    b, master = new_board(elf, nvm=log)
    assert b.flash.erased == [7] and b.boot_stall_ns >= b.flash.ERASE_B_NS[2]
    assert bytes(b.flash.data_b[:SLOT]) == encode(last, 1)  # one generation on
    assert blank(b.flash.data_b[SLOT:])
    assert bytes(b.flash.data[: len(log)]) == log  # the full log untouched
    assert b.watchdog_resets == 0
    b.sleep(0.02)
    assert calibrated(master) and installed(ram_board(b)) == last
    # The next record goes into sector 7, after it.
    master.set_odometrie(*CAL)
    b.sleep(0.02)
    assert bytes(b.flash.data_b[SLOT : 2 * SLOT]) == encode(CAL, 1)
    b.power_cycle()
    b.sleep(0.02)
    assert installed(ram_board(b)) == CAL and b.flash.erased == [7]


def test_a_version_1_log_is_kept_and_continued(elf: Any) -> None:
    """A board updated from a firmware of before the generation: its log of version-1 records
    (byte 3 reserved, 0) is installed, and the next record follows it, generation 0."""
    old = (-2000, 27990, 400)
    body = b"ac\x01\x00" + encode(old)[4:14]
    v1 = body + crc16(body).to_bytes(2, "big")
    b, master = new_board(elf, nvm=v1)
    b.sleep(0.02)
    assert calibrated(master) and installed(ram_board(b)) == old
    master.set_odometrie(*CAL)
    b.sleep(0.02)
    assert bytes(b.flash.data[:SLOT]) == v1
    assert bytes(b.flash.data[SLOT : 2 * SLOT]) == encode(CAL, 0)


@pytest.mark.parametrize("newest_in", ["sector 1", "sector 7"])
def test_the_newest_generation_wins_across_the_logs(elf: Any, newest_in: str) -> None:
    """Both logs hold records (a switch happened): the newer generation is installed, across
    the wrap of the generation (255 then 0), whichever sector it is in."""
    older, newer_cal = (-2000, 27990, 400), (1200, 28040, -800)
    a = encode((5, 28000, 5), 255) + encode(older, 255)
    bb = encode(newer_cal, 0)
    if newest_in == "sector 7":
        b, _ = new_board(elf, nvm=a, nvm_b=bb)
    else:
        b, _ = new_board(elf, nvm=bb, nvm_b=a)
    b.sleep(0.02)
    assert installed(ram_board(b)) == newer_cal == newest(b.flash)


def test_a_zeroed_sector_1_is_left_and_the_board_runs_uncalibrated(elf: Any) -> None:
    """What flashing asserv_stm32.bin leaves in sector 1 (objcopy fills the gap between the
    vectors and the code with zeros): no record, no free slot. The board goes on in sector 7,
    blank: no erase."""
    b, master = new_board(elf, nvm=bytes(SLOTS * SLOT))
    assert b.flash.erases == 0
    b.sleep(0.02)
    assert not calibrated(master) and master.check_busy() == 0
    master.set_odometrie(*CAL)
    b.sleep(0.02)
    assert bytes(b.flash.data_b[:SLOT]) == encode(CAL, 0)
    b.power_cycle()
    b.sleep(0.02)
    assert installed(ram_board(b)) == CAL


def fill_until_full(b: Stm32Board, master: Board) -> None:
    """START_FREE calibrations at run time: the log of SLOTS - START_FREE records is full."""
    for i in range(START_FREE):
        master.set_odometrie(-i, 28010, 0)
        b.sleep(0.008)
    assert bytes(b.flash.data[-SLOT:]) == encode((-(START_FREE - 1), 28010, 0))


def test_a_full_log_is_compacted_only_when_the_board_is_idle(elf: Any) -> None:
    used = SLOTS - START_FREE  # START_FREE slots free: no erase at start-up
    log = b"".join(encode((i, 28000, 0)) for i in range(used))
    b, master = new_board(elf, nvm=log)
    assert b.flash.erases == 0
    fill_until_full(b, master)
    assert newest(b.flash) == (-(START_FREE - 1), 28010, 0)
    assert b.flash.erases == 0 and b.lost_ticks == 0
    full = bytes(b.flash.data)

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
    b.sleep(1.2)
    # The erase of sector 7 stalled the CPU (a second of ticks lost), the watchdog widened
    # for it did not reset the chip, and the record is alone in sector 7, one generation on.
    assert b.flash.erased == [7]
    assert b.watchdog_resets == 0
    long = [d for w, d in zip(b.stalls, b.stall_duties, strict=True) if w > 1_000_000]
    assert long == [(0, 0)]  # one long stall, the erase's, with the motors off
    assert max(b.stalls) >= b.flash.ERASE_B_NS[2] - 1_000_000
    assert b.lost_ticks >= 990
    assert bytes(b.flash.data_b[:SLOT]) == encode(CAL, 1)
    assert blank(b.flash.data_b[SLOT:])
    assert bytes(b.flash.data) == full  # sector 1 untouched
    assert abs(b.iwdg.reload_ns() - 60e6) < 1  # back to its 60 ms
    assert master.check_busy() == 0
    b.power_cycle()
    b.sleep(0.02)
    assert installed(ram_board(b)) == CAL


@pytest.mark.parametrize("seed", range(6))
def test_a_cut_during_the_erase_keeps_the_full_logs_record(elf: Any, seed: int) -> None:
    """The power goes while sector 7 is being erased (the model leaves a random part of its
    bits erased): the full log's newest record is installed, the start-up compacts again, and
    the record the master sent again is kept."""
    used = SLOTS - START_FREE
    rng = Random(seed)
    # Sector 7 as an older switch left it: a log of generation 255, partly programmed.
    old_b = b"".join(encode((rng.randint(-999, 999), 28000, 0), 255) for _ in range(40))
    log = b"".join(encode((i, 28000, 0)) for i in range(used))
    b, master = new_board(elf, nvm=log, nvm_b=old_b)
    fill_until_full(b, master)
    last = newest(b.flash)
    assert last is not None
    master.set_odometrie(*CAL)
    while not erasing(b):
        b.advance_ns(100_000)  # the erase starts in the main loop, after a tick
        assert b.now_ns < 5e9
    b.power_cycle(Random(seed))  # before the next tick: within the erase
    assert b.flash.erased == [7, 7]  # the cut one, and the start-up's compaction
    assert installed(ram_board(b)) == last == newest(b.flash)
    assert bytes(b.flash.data_b[:SLOT]) == encode(last, 1)
    master.set_odometrie(*CAL)
    b.sleep(0.02)
    b.power_cycle()
    b.sleep(0.02)
    assert installed(ram_board(b)) == CAL == newest(b.flash)


@pytest.mark.parametrize("state", ["torn first record", "partly erased", "erased"])
def test_the_states_a_cut_of_the_start_up_compaction_leaves(elf: Any, state: str) -> None:
    """The start-up's erase and first record cannot be cut in the emulator (the boot runs as
    one step): the states such a cut leaves, sector 1 full and sector 7 erased in part, or
    whole with its first record torn, install sector 1's newest record and compact again."""
    used = SLOTS - START_FREE + 1
    log = b"".join(encode((i, 28000, -i)) for i in range(used))
    last = (used - 1, 28000, 1 - used)
    rng = Random(7)
    if state == "torn first record":  # words 1 to 3 programmed, word 0 in part
        rec = encode(last, 1)
        word0 = bytes(x | rng.getrandbits(8) for x in rec[:4])
        nvm_b = (word0 if word0 != rec[:4] else b"\xff" * 4) + rec[4:]
    elif state == "partly erased":
        old = b"".join(encode((i, 27000, 0), 255) for i in range(SLOTS))
        nvm_b = bytes(x | rng.getrandbits(8) for x in old)
    else:
        nvm_b = b""
    b, _ = new_board(elf, nvm=log, nvm_b=nvm_b)
    assert b.flash.erased == [7]
    assert installed(ram_board(b)) == last == newest(b.flash)
    assert bytes(b.flash.data_b[:SLOT]) == encode(last, 1)


@pytest.mark.parametrize("word", [0, 1, 2, 3])
@pytest.mark.parametrize("seed", [1, 2, 3])
def test_a_cut_inside_each_word_of_a_record_keeps_the_previous_one(
    elf: Any, word: int, seed: int
) -> None:
    older = (-2000, 27990, 400)
    b, master = new_board(elf, nvm=encode(older))
    master.set_odometrie(*CAL)
    b.advance_ns((b.ticks + word) * TICK_NS + 8_000 - b.now_ns)  # 8 us into word `word`
    # The words go 1, 2, 3, then 0 (the magic's).
    at = LOG_A + SLOT + 4 * ((word + 1) % 4)
    assert b.flash.busy() and b.flash.op is not None and b.flash.op[1] == at
    b.power_cycle(Random(seed))
    loaded = installed(ram_board(b))
    assert loaded == newest(b.flash)
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
        before = newest(b.flash)  # completed before the cut
        mid_write = b.flash.busy()
        b.power_cycle(Random(cut))
        after = newest(b.flash)
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
    assert newest(b.flash) == current


# A round across log switches: a burst of SET_ODOMETRIE 8 ms apart (enough of them fill the
# active log and start the other sector's erase), then either time up to ``us`` after the n-th
# tick to come (inside a word's 16 us program, or anywhere), or until the erase is running;
# then maybe a power cut (its seed draws what the cut leaves of a word or of the sector).
_SWITCH_ROUNDS = st.lists(
    st.tuples(
        st.one_of(st.integers(1, 4), st.integers(60, 110)),  # calibrations in the burst
        st.one_of(st.just("erase"), st.just("erase"), st.integers(0, 3), st.integers(0, 1500)),
        st.one_of(st.integers(0, 15), st.integers(0, 999)),
        st.one_of(st.integers(0, 2**32 - 1), st.integers(0, 2**32 - 1), st.none()),
    ),
    min_size=1,
    max_size=3,
)


def erasing(b: Stm32Board) -> bool:
    return b.flash.busy() and b.flash.op is not None and b.flash.op[0] == "erase"


@settings(max_examples=20, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(
    active=st.sampled_from([1, 7]),
    gen=st.integers(0, 255),
    free=st.integers(START_FREE, START_FREE + 20),
    other=st.sampled_from(["blank", "older log", "partly erased"]),
    rounds=_SWITCH_ROUNDS,
)
def test_power_cuts_across_log_switches_keep_the_newest_record(
    elf: Any,
    active: int,
    gen: int,
    free: int,
    other: str,
    rounds: list[tuple[int, str | int, int, int | None]],
) -> None:
    """Either sector the active log, nearly full, of any generation (the wrap from 255 to 0
    included), the other blank, an older log or partly erased; bursts of calibrations fill it
    and switch to the other sector at run time; power cuts at random instants, mid-word and
    mid-erase included. After each cut the board installs the newest completed record, or the
    one the cut completed; always one the master sent or the log held; never nothing once a
    record was kept."""
    rng = Random(gen * 97 + free)
    full = [(rng.randint(-999, 999), 28000, rng.randint(-999, 999)) for _ in range(SLOTS - free)]
    log = b"".join(encode(c, gen) for c in full)
    older = b"".join(encode((i, 27000, 0), (gen - 1) % 256) for i in range(SLOTS))
    if other == "blank":
        other_bytes = b""
    elif other == "older log":
        other_bytes = older
    else:
        other_bytes = bytes(x | rng.getrandbits(8) for x in older)
    nvm, nvm_b = (log, other_bytes) if active == 1 else (other_bytes, log)
    b, master = new_board(elf, nvm=nvm, nvm_b=nvm_b)
    sent: list[Cal] = [full[-1]]
    current: Cal | None = full[-1]
    assert installed(ram_board(b)) == current == newest(b.flash)
    for burst, when, us, cut in rounds:
        for i in range(burst):
            if i:  # 8 ms between two: the record written, the erase started if one is due
                for _ in range(80):
                    b.advance_ns(100_000)
                    if when == "erase" and erasing(b):
                        break
                if erasing(b) and when == "erase":
                    break  # the burst ends with the erase: the cut comes within it
                while erasing(b):  # the bus is held meanwhile: a master waits
                    b.advance_ns(1_000_000)
            cal = (rng.randint(-3000, 3000), rng.randint(27500, 28500), rng.randint(-3000, 3000))
            master.set_odometrie(*cal)
            sent.append(cal)
        if when == "erase":
            for _ in range(80):  # the erase, if one is due, starts after a tick
                if erasing(b):
                    break
                b.advance_ns(100_000)
        else:
            assert isinstance(when, int)
            b.advance_ns((b.ticks + when) * TICK_NS + us * 1000 + 1 - b.now_ns)
        if cut is None:
            continue
        before = newest(b.flash)
        current = installed(ram_board(b))  # what the board is writing, or has written
        mid_write = b.flash.busy()
        if mid_write and b.flash.op is not None:
            event(f"cut mid-{b.flash.op[0]}")
        b.power_cycle(Random(cut))
        loaded = installed(ram_board(b))
        assert loaded == newest(b.flash), "the board did not install the newest valid record"
        assert loaded == before or (mid_write and loaded == current)
        assert loaded is not None and loaded in sent, f"lost, or garbage installed: {loaded}"
        assert b.watchdog_resets == 0
        assert master.check_busy() == 0
    b.sleep(1.2)  # an erase under way, then the record
    assert installed(ram_board(b)) == newest(b.flash)
    event(f"{len(b.flash.erased)} erases")
