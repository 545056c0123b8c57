"""The odometry calibration kept in the simulated board's storage (hal_nvm.h as
firmware/ports/common/nvm_bytes.h does it, the host port's 64 bytes, two record slots):
SET_ODOMETRIE, a power cycle or a new Simulator given the storage, and the calibration is back,
with its factors and its error radius bounds; a blank or corrupt storage leaves the board
uncalibrated and running; each new calibration goes into the slot that does not hold the
newest."""

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from asserv import Board, Capability
from asserv.sim import NVM_SIZE, Calibration, Simulator

MAGIC = b"ac\x02\x00"  # calib_store.h: magic, version 2, generation 0 (the first record)


def factors(sim: Simulator) -> tuple[int, int, int]:
    oc = sim._h.board.servo.counter.cfg
    return (int(oc.left_um_per_count_q16), int(oc.right_um_per_count_q16), int(oc.track_um))


def calibrated_flag(board: Board) -> bool:
    return Capability.CALIBRATED in board.version().capabilities


def calibrate(sim: Simulator, ratio: int, track: int, scale: int) -> Board:
    board = Board(sim.bus)
    board.set_odometrie(ratio, track, scale)
    sim.advance(0.05)  # the slow steps install it, the next tick writes the record
    return board


def test_fresh_board_is_uncalibrated_with_blank_storage() -> None:
    sim = Simulator(seed=1)
    board = Board(sim.bus)
    sim.advance(0.02)
    assert sim.calibration is None
    assert not calibrated_flag(board)
    assert sim.nvm == b"\xff" * NVM_SIZE


def test_set_odometrie_then_power_cycle_keeps_it() -> None:
    sim = Simulator(seed=1)
    board = calibrate(sim, 1200, 28040, -800)
    installed = factors(sim)
    assert sim.calibration == Calibration(1200, 28040, -800)
    assert calibrated_flag(board)
    assert sim.nvm.startswith(MAGIC)

    sim.power_cycle()
    sim.advance(0.02)
    assert sim.calibration == Calibration(1200, 28040, -800)
    assert calibrated_flag(board)
    assert factors(sim) == installed

    # The same storage in a new simulator (a team's tooling saved it).
    other = Simulator(seed=1, nvm=sim.nvm)
    other.advance(0.02)
    assert other.calibration == Calibration(1200, 28040, -800)
    assert factors(other) == installed
    assert other.nvm == sim.nvm


def test_power_cycle_restarts_the_board_where_the_robot_is() -> None:
    sim = Simulator(seed=2)
    board = calibrate(sim, 0, 28000, 0)
    board.goto(0, -700)
    board.wait_idle(10)
    truth = sim.true_pose()
    sim.power_cycle()
    sim.advance(0.05)
    # The robot did not move; the board believes its power-on pose again.
    after = sim.true_pose()
    assert after.x_mm == pytest.approx(truth.x_mm, abs=0.5)
    assert after.y_mm == pytest.approx(truth.y_mm, abs=0.5)
    pos = board.position()
    start = sim.board_config.start
    assert (pos.x_mm, pos.y_mm) == (round(start.x_um / 1000), round(start.y_um / 1000))
    assert sim.calibration == Calibration(0, 28000, 0)


def radius_after_path(sim: Simulator) -> float:
    board = Board(sim.bus)
    for x, y in ((0, -700), (600, -700), (600, 300), (-600, 300), (0, -300)):
        board.goto(x, y)
        board.wait_idle(15)
    return float(sim.trace["radius_mm"][-1])


def test_radius_uses_the_calibrated_bounds_after_a_power_cycle() -> None:
    # The same robot and path, powered on with and without the kept calibration (its nominal
    # values: what changes is only that a calibration is installed).
    first = Simulator(seed=5)
    calibrate(first, 0, 28000, 0)
    first.power_cycle()
    kept = first.nvm

    uncalibrated = radius_after_path(Simulator(seed=5))
    calibrated = radius_after_path(Simulator(seed=5, nvm=kept))
    assert calibrated < uncalibrated


@pytest.mark.parametrize("bit", [0, 9, 17, 40, 70, 101, 127])
def test_corrupt_storage_leaves_it_uncalibrated(bit: int) -> None:
    good = Simulator(seed=1)
    calibrate(good, 1200, 28040, -800)
    raw = bytearray(good.nvm)
    raw[bit // 8] ^= 1 << (bit % 8)
    sim = Simulator(seed=1, nvm=bytes(raw))
    board = Board(sim.bus)
    sim.advance(0.02)
    assert sim.calibration is None
    assert not calibrated_flag(board)
    assert factors(sim) == factors(Simulator(seed=1))
    board.goto(0, -800)  # and it runs
    board.wait_idle(10)
    assert abs(board.position().y_mm - -800) <= 2


def test_torn_record_is_lost_not_installed() -> None:
    # A power-off in the middle of a write: the first half of a new record over an old one.
    old = Simulator(seed=1)
    calibrate(old, 1200, 28040, -800)
    new = Simulator(seed=1)
    calibrate(new, -500, 27990, 300)
    torn = new.nvm[:8] + old.nvm[8:]
    sim = Simulator(seed=1, nvm=torn)
    assert sim.calibration is None


def test_each_calibration_goes_into_the_other_slot() -> None:
    """Two slots written in turn, the generation one on each time: the newest is installed after
    a power cycle, and the previous one stays whole in the other slot until the next."""
    sim = Simulator(seed=1)
    board = Board(sim.bus)
    cals = [(1200, 28040, -800), (-500, 27990, 300), (10, 28000, 20)]
    for i, (ratio, track, scale) in enumerate(cals):
        board.set_odometrie(ratio, track, scale)
        sim.advance(0.05)
        slot = i % 2
        assert sim.nvm[16 * slot : 16 * slot + 4] == b"ac\x02" + bytes([i])
        if i:
            prev = (i - 1) % 2
            assert sim.nvm[16 * prev + 3] == i - 1  # the previous record, untouched
        sim.power_cycle()
        sim.advance(0.02)
        assert sim.calibration == Calibration(ratio, track, scale)


def test_nvm_argument_is_checked() -> None:
    with pytest.raises(ValueError, match="at most 64 bytes"):
        Simulator(nvm=bytes(NVM_SIZE + 1))
    with pytest.raises(ValueError, match="nvm must be bytes"):
        Simulator(nvm="ac")  # type: ignore[arg-type]
    short = Simulator(nvm=b"")
    assert short.nvm == b"\xff" * NVM_SIZE
    assert short.calibration is None


# SET_ODOMETRIE's ranges (protocol/messages.toml).
calibrations = st.tuples(
    st.integers(-30000, 30000), st.integers(1639, 65535), st.integers(-30000, 30000)
)


@settings(max_examples=100, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(calibrations)
def test_stored_calibration_gives_set_odometries_factors(cal: tuple[int, int, int]) -> None:
    """For any valid calibration: store, power cycle, and the board's odometry factors are those
    SET_ODOMETRIE installed directly (or, if the board refused it, nothing is stored)."""
    ratio, track, scale = cal
    direct = Simulator(seed=0)
    calibrate(direct, ratio, track, scale)
    if direct.calibration is None:  # outside the odometry's ranges: refused, nothing kept
        assert direct.nvm == b"\xff" * NVM_SIZE
        return
    installed = factors(direct)
    assert direct.calibration == Calibration(ratio, track, scale)

    direct.power_cycle()
    direct.advance(0.02)
    assert factors(direct) == installed
    reborn = Simulator(seed=0, nvm=direct.nvm)
    reborn.advance(0.02)
    assert reborn.calibration == Calibration(ratio, track, scale)
    assert factors(reborn) == installed


@settings(max_examples=60, deadline=None)
@given(st.binary(max_size=NVM_SIZE))
def test_any_storage_powers_on(nvm: bytes) -> None:
    """Whatever the storage holds, the board starts and answers; it is calibrated only from a
    record with the magic."""
    sim = Simulator(seed=0, nvm=nvm)
    board = Board(sim.bus)
    sim.advance(0.02)
    assert board.version().major == 1
    if sim.calibration is not None:
        assert nvm[0:2] == b"ac" or nvm[16:18] == b"ac"
    assert calibrated_flag(board) == (sim.calibration is not None)
