"""The master driver against the board's C protocol layer on a VirtualBus: every method's bytes
are taken by the board as meant, every reply is decoded right, errors say what happened."""

from __future__ import annotations

import errno
from collections.abc import Callable
from typing import Any

import pytest
from hypothesis import given
from hypothesis import strategies as st
from smbus2 import i2c_msg
from test_bus import FakeClock, Recorder, board_bus

from asserv import (
    Board,
    BoardTimeout,
    BusError,
    Capability,
    Debug,
    EndReason,
    Filtre,
    GotoOption,
    NoAcknowledge,
    OrderRejected,
    OrderState,
    PecMismatch,
    Pose,
    ProtocolDevice,
    Reject,
    Status,
    VirtualBus,
    codec,
)

PEC = pytest.mark.parametrize("pec", [False, True], ids=["no-pec", "pec"])


def make(pec: bool = False, check: bool = True) -> tuple[ProtocolDevice, Recorder, Board]:
    dev, rec, bus = board_bus()
    dev.layer.tick()
    return dev, rec, Board(bus, pec=pec, check=check)


def taken(dev: ProtocolDevice) -> list[tuple[int, tuple[int, ...]]]:
    return [(t.designation, t.args) for t in dev.layer.tick()]


# Orders and settings: what the board's control tick takes.

CALLS: list[tuple[str, Callable[[Board], None], str, tuple[int, ...]]] = [
    ("goto", lambda b: b.goto(200, 100), "GOTO", (200, 100, 0)),
    ("goto-options", lambda b: b.goto(-1500, -1000, 3), "GOTO", (-1500, -1000, 3)),
    (
        "goto-flags",
        lambda b: b.goto(32000, -32000, GotoOption.RECALAGE_LIGNE),
        "GOTO",
        (32000, -32000, 1),
    ),
    ("goto_reverse", lambda b: b.goto_reverse(255), "GOTO_REVERSE", (255,)),
    ("goto_panier", lambda b: b.goto_panier(44), "GOTO_PANIER", (22,)),
    ("stop", lambda b: b.stop(), "STOP", ()),
    ("set_vitesse_traj", lambda b: b.set_vitesse_traj(100, 40), "SET_VITESSE_TRAJ", (100, 40)),
    ("set_vitesse_rot", lambda b: b.set_vitesse_rot(50, 255), "SET_VITESSE_ROT", (50, 255)),
    ("set_filtre", lambda b: b.set_filtre(Filtre.FILTRE_RAIDE), "SET_FILTRE", (2,)),
    (
        "set_filtre_raw",
        lambda b: b.set_filtre_raw(4660, 0, 65535),
        "SET_FILTRE_RAW",
        (4660, 0, 65535),
    ),
    ("set_new_pos", lambda b: b.set_new_pos(-5, 3, -180), "SET_NEW_POS", (-5, 3, -180)),
    ("set_timeout", lambda b: b.set_timeout(65535), "SET_TIMEOUT", (65535,)),
    ("heartbeat", lambda b: b.heartbeat(), "HEARTBEAT", ()),
]


@PEC
@pytest.mark.parametrize("call", CALLS, ids=[c[0] for c in CALLS])
def test_each_order_and_setting_reaches_the_core(
    pec: bool, call: tuple[str, Callable[[Board], None], str, tuple[int, ...]]
) -> None:
    dev, rec, board = make(pec)
    _, method, name, args = call
    method(board)
    if pec and name in ("GOTO_REVERSE", "GOTO_PANIER"):
        args = (*args, 0)  # with PEC the full form: issue 31's options byte, 0
    assert taken(dev) == [(codec.message(name).designation, args)]
    # One transaction: the frame, then the status by a repeated start (check=True).
    frame = codec.encode(name, *args, pec=pec)
    assert rec.events == [("w", frame, False), ("r", 2 if pec else 1, None)]


@PEC
def test_short_forms_keep_the_acceleration(pec: bool) -> None:
    dev, _, board = make(False)
    board.set_vitesse_traj(100)
    board.set_vitesse_rot(50)
    assert taken(dev) == [(6, (100,)), (7, (50,))]


@PEC
@given(
    x=st.integers(-32000, 32000),
    y=st.integers(-32000, 32000),
    options=st.integers(0, 3),
)
def test_any_goto_reaches_the_core(pec: bool, x: int, y: int, options: int) -> None:
    dev, _, board = make(pec)
    board.goto(x, y, options)
    assert taken(dev) == [(0, (x, y, options))]


@pytest.mark.parametrize(
    ("degrees", "steps"),
    [
        (44, 22),
        (45, 22),  # the annex's "45/2 == 22"
        (-45, -22),
        (47, 23),
        (44.9, 22),
        (1, 0),
        (3, 1),
        (-3, -1),
        (180, 90),
        (-180, -90),
        (0, 0),
        (179.4, 90),
    ],
)
def test_goto_panier_rounds_to_2_degree_steps_ties_towards_zero(degrees: float, steps: int) -> None:
    dev, _, board = make()
    board.goto_panier(degrees)
    assert taken(dev) == [(2, (steps,))]


def test_check_false_writes_the_frame_alone() -> None:
    dev, rec, board = make(check=False)
    board.goto(200, 100)
    assert rec.events == [("w", codec.encode("GOTO", 200, 100, 0), True)]
    assert taken(dev) == [(0, (200, 100, 0))]


# Replies: what the snapshot says, decoded.


@PEC
@given(
    x=st.integers(-32768, 32767),
    y=st.integers(-32768, 32767),
    a=st.integers(-128, 127),
    r=st.integers(0, 255),
)
def test_position_is_decoded(pec: bool, x: int, y: int, a: int, r: int) -> None:
    dev, rec, board = make(pec)
    dev.layer.set_snapshot(x_mm=x, y_mm=y, angle_2deg=a, radius_mm=r)
    dev.layer.tick()
    rec.events.clear()
    pose = board.position()
    assert pose == Pose(x, y, a, r)
    assert pose.angle_deg == 2 * a
    # The designation, then the reply by a repeated start.
    assert rec.events == [("w", codec.encode("POSITION", pec=pec), False), ("r", 6 + pec, None)]


@PEC
@given(status=st.integers(0, 0x3F), sensors=st.integers(0, 255))
def test_status_and_sensors_are_decoded(pec: bool, status: int, sensors: int) -> None:
    dev, _, board = make(pec)
    dev.layer.set_snapshot(status=status, sensors=sensors)
    dev.layer.tick()
    s = board.check_busy()
    assert isinstance(s, Status)
    assert s == Status(status)
    assert board.info_choc() == sensors


@PEC
def test_version_last_reject_and_debug(pec: bool) -> None:
    dev, _, board = make(pec)
    v = board.version()
    assert (v.major, v.minor) == (1, 0)
    assert v.capabilities == Capability.PEC | Capability.STOP | Capability.LAST_REJECT | (
        Capability.DEBUG | Capability.TIMEOUT | Capability.HEARTBEAT | Capability.FIX
    ) | (Capability.PAUSE | Capability.SPEED_SCALE | Capability.QUEUE | Capability.CORNERS) | (
        Capability.QUIET_SERVO
    )
    assert board.last_reject().reason == Reject.NONE
    fields: dict[str, Any] = {
        "tick": 65535,
        "heading_cdeg": -17999,
        "speed_mm_s": 1234,
        "turn_rate_cdeg_s": -300,
        "dist_err_um": 32767,
        "angle_err_um": -32768,
        "duty_left_q15": 32767,
        "duty_right_q15": -32767,
        "current_left_ma": 1500,
        "current_right_ma": -20,
        "order_state": int(OrderState.PUSH),
        "end_reason": int(EndReason.BASKET),
    }
    dev.layer.set_snapshot(debug=fields)
    dev.layer.tick()
    d = board.debug()
    assert d == Debug(
        **{
            **fields,
            "order_state": OrderState.PUSH,
            "end_reason": EndReason.BASKET,
        }
    )


def test_declare_pose_sends_estimate_minus_truth() -> None:
    dev, _, board = make()
    dev.layer.set_snapshot(x_mm=100, y_mm=50, angle_2deg=45, debug={"heading_cdeg": 9040})
    dev.layer.tick()
    board.declare_pose(90, 60, 80)
    assert taken(dev) == [(10, (10, -10, 10))]
    # The angle error wraps: estimate 179 degrees, truth -179 degrees: 2 degrees too much.
    dev.layer.set_snapshot(debug={"heading_cdeg": 17900})
    dev.layer.tick()
    board.declare_pose(100, 50, -179)
    assert taken(dev) == [(10, (0, 0, -2))]


# Rejections.


@PEC
def test_an_order_under_pb_grave_is_rejected_with_the_reason(pec: bool) -> None:
    dev, _, board = make(pec)
    dev.layer.set_snapshot(status=int(Status.PB_GRAVE))
    dev.layer.tick()
    with pytest.raises(OrderRejected) as e:
        board.goto(200, 100)
    assert e.value.reason == Reject.REFUSED_PB_GRAVE
    assert e.value.designation == 0
    assert e.value.name == "GOTO"
    assert e.value.count == 1
    assert str(e.value).startswith("GOTO rejected by the board: REFUSED_PB_GRAVE")
    assert "x_mm=200 y_mm=100 options=0" in str(e.value)
    assert taken(dev) == []
    board.set_vitesse_traj(20, 40)  # settings are still accepted under PB_GRAVE
    assert taken(dev) == [(6, (20, 40))]


def test_a_ninth_write_in_one_tick_is_queue_full() -> None:
    dev, _, board = make()
    for speed in range(10, 18):
        board.set_vitesse_traj(speed)
    with pytest.raises(OrderRejected) as e:
        board.set_vitesse_traj(18)
    assert e.value.reason == Reject.QUEUE_FULL
    assert e.value.designation == 6
    assert len(taken(dev)) == 8


def test_check_false_does_not_notice_a_rejection() -> None:
    dev, _, board = make(check=False)
    dev.layer.set_snapshot(status=int(Status.PB_GRAVE))
    dev.layer.tick()
    board.goto(1, 2)
    assert board.check_busy() & Status.COMMANDE_REJETEE
    assert board.last_reject().count == 1


class Corrupt:
    """Flips bit 0 of the first byte of chosen writes (by index) or reads (by index)."""

    def __init__(self, inner: ProtocolDevice, writes: set[int], reads: set[int]) -> None:
        self.inner, self.writes, self.reads = inner, writes, reads
        self.nw = self.nr = 0

    def i2c_write(self, data: bytes, stop: bool) -> None:
        if self.nw in self.writes and data:
            data = bytes([data[0], *data[1:-1], data[-1] ^ 1]) if len(data) > 1 else data
        self.nw += 1
        self.inner.i2c_write(data, stop)

    def i2c_read(self, n: int) -> bytes:
        data = self.inner.i2c_read(n)
        if self.nr in self.reads:
            data = bytes([data[0] ^ 1, *data[1:]])
        self.nr += 1
        return data


def corrupt_board(writes: set[int], reads: set[int]) -> tuple[ProtocolDevice, Board]:
    dev = ProtocolDevice()
    dev.layer.tick()
    return dev, Board(VirtualBus({2: Corrupt(dev, writes, reads)}), pec=True)


def test_a_corrupted_reply_is_a_pec_mismatch_with_pec_and_garbage_without() -> None:
    dev, board = corrupt_board(set(), {0})
    dev.layer.set_snapshot(x_mm=200)
    dev.layer.tick()
    with pytest.raises(PecMismatch, match="POSITION: corrupted reply from 0x02"):
        board.position()
    assert board.position().x_mm == 200  # the next read is clean
    plain = Board(VirtualBus({2: Corrupt(dev, set(), {0})}))
    assert plain.position().x_mm == 200 + 256  # bit 0 of the high byte: nothing can tell


def test_a_corrupted_write_is_rejected_as_bad_pec() -> None:
    dev, board = corrupt_board({0}, set())
    with pytest.raises(OrderRejected) as e:
        board.goto(200, 100)
    assert e.value.reason == Reject.BAD_PEC
    assert taken(dev) == []
    board.goto(200, 100)  # sent again, clean
    assert taken(dev) == [(0, (200, 100, 0))]


def test_a_corrupted_status_after_a_write_is_read_again() -> None:
    dev, board = corrupt_board(set(), {0})
    board.goto(200, 100)  # the status read back is corrupted; the driver reads it once more
    assert taken(dev) == [(0, (200, 100, 0))]
    dev, board = corrupt_board(set(), {0, 1})
    with pytest.raises(PecMismatch, match="may or may not have taken it"):
        board.goto(200, 100)
    assert taken(dev) == [(0, (200, 100, 0))]


# Bus errors.


def test_no_device_is_no_acknowledge() -> None:
    board = Board(VirtualBus({}))
    with pytest.raises(NoAcknowledge) as e:
        board.goto(200, 100)
    assert e.value.address == 2
    assert e.value.errno == errno.ENXIO
    assert "no acknowledge from address 0x02 on the bus" in str(e.value)
    assert "is the board powered and wired?" in str(e.value)
    assert isinstance(e.value.__cause__, OSError)
    with pytest.raises(NoAcknowledge):
        Board(VirtualBus({3: ProtocolDevice()})).position()


class FailingBus:
    """A bus whose every transfer fails with one errno (and that has no clock)."""

    def __init__(self, code: int) -> None:
        self.code = code

    def i2c_rdwr(self, *msgs: i2c_msg) -> None:
        raise OSError(self.code, "adapter says no")


@pytest.mark.parametrize("code", [errno.ENXIO, errno.EREMOTEIO, errno.EIO])
def test_nack_errnos_of_the_adapters(code: int) -> None:
    with pytest.raises(NoAcknowledge) as e:
        Board(FailingBus(code)).check_busy()
    assert e.value.errno == code
    assert errno.errorcode[code] in str(e.value)


def test_other_bus_errors() -> None:
    with pytest.raises(BusError) as e:
        Board(FailingBus(errno.ETIMEDOUT)).stop()
    assert not isinstance(e.value, NoAcknowledge)
    assert e.value.errno == errno.ETIMEDOUT
    assert "STOP: bus error talking to 0x02: ETIMEDOUT" in str(e.value)


# Bad arguments: ValueError or TypeError, and nothing on the bus.

BAD: list[tuple[str, Callable[[Board], None], type[Exception]]] = [
    ("x>32000", lambda b: b.goto(32001, 0), ValueError),
    ("y<-32000", lambda b: b.goto(0, -32001), ValueError),
    ("option bit 4", lambda b: b.goto(0, 0, 0x10), ValueError),
    ("x float", lambda b: b.goto(1.5, 0), TypeError),  # type: ignore[arg-type]
    ("reverse 256", lambda b: b.goto_reverse(256), ValueError),
    ("reverse -1", lambda b: b.goto_reverse(-1), ValueError),
    ("panier 181", lambda b: b.goto_panier(181), ValueError),
    ("panier -180.5", lambda b: b.goto_panier(-180.5), ValueError),
    ("panier str", lambda b: b.goto_panier("90"), TypeError),  # type: ignore[arg-type]
    ("speed 0", lambda b: b.set_vitesse_traj(0), ValueError),
    ("speed 256", lambda b: b.set_vitesse_rot(256), ValueError),
    ("accel 0", lambda b: b.set_vitesse_traj(10, 0), ValueError),
    ("preset 3", lambda b: b.set_filtre(3), ValueError),
    ("raw p 65536", lambda b: b.set_filtre_raw(65536, 0, 0), ValueError),
    ("raw d -1", lambda b: b.set_filtre_raw(0, 0, -1), ValueError),
    ("new pos angle 181", lambda b: b.set_new_pos(0, 0, 181), ValueError),
    ("new pos x", lambda b: b.set_new_pos(-32001, 0, 0), ValueError),
    ("timeout 65536", lambda b: b.set_timeout(65536), ValueError),
    ("timeout -1", lambda b: b.set_timeout(-1), ValueError),
]


@PEC
@pytest.mark.parametrize("bad", BAD, ids=[b[0] for b in BAD])
def test_bad_arguments_send_nothing(
    pec: bool, bad: tuple[str, Callable[[Board], None], type[Exception]]
) -> None:
    dev, rec, board = make(pec)
    with pytest.raises(bad[2]):
        bad[1](board)
    assert rec.events == []
    assert taken(dev) == []


def test_a_short_form_cannot_carry_a_pec() -> None:
    _, rec, board = make(pec=True)
    with pytest.raises(ValueError, match="full form"):
        board.set_vitesse_traj(100)
    assert rec.events == []


def test_address_must_be_7_bit() -> None:
    with pytest.raises(ValueError):
        Board(VirtualBus({}), address=0x80)


# wait_idle.


def test_wait_idle_times_out_on_the_bus_clock() -> None:
    dev = ProtocolDevice()
    clock = FakeClock(on_sleep=dev.layer.tick)  # the core takes the order but never finishes it
    board = Board(VirtualBus({2: dev}, clock))
    dev.layer.set_snapshot(status=int(Status.BUSY_TRAJET))
    board.goto(200, 100)
    start = clock.now
    with pytest.raises(BoardTimeout) as e:
        board.wait_idle(timeout_s=0.5, poll_s=0.02)
    assert e.value.status == Status.BUSY_TRAJET
    assert clock.now - start == pytest.approx(0.5)
    assert len(clock.sleeps) == 25
    assert max(clock.sleeps) == pytest.approx(0.02)
    assert "still busy after 0.5 s (status 0x02: BUSY_TRAJET)" in str(e.value)


def test_wait_idle_returns_the_final_status_when_the_motion_ends() -> None:
    dev = ProtocolDevice()
    ends_at = 0.3

    def tick() -> None:
        done = clock.now - start >= ends_at
        dev.layer.set_snapshot(status=int(Status.CHOC_PANIER if done else Status.BUSY_TRAJET))
        dev.layer.tick()

    clock = FakeClock(on_sleep=tick)
    start = clock.now
    board = Board(VirtualBus({2: dev}, clock))
    board.goto_panier(44)
    # Accepted but not taken by a tick yet: busy already, so waiting cannot end early.
    assert board.check_busy() == Status.BUSY_TRAJET | Status.BUSY_GOTO_PANIER
    end = board.wait_idle(timeout_s=5)
    assert end == Status.CHOC_PANIER
    assert clock.now - start == pytest.approx(ends_at, abs=0.011)


def test_wait_idle_uses_the_system_clock_without_a_bus_clock(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    import asserv.bus as busmod

    clock = FakeClock()
    monkeypatch.setattr(busmod.time, "monotonic", clock.monotonic)
    monkeypatch.setattr(busmod.time, "sleep", clock.sleep)

    class NoClockBus:
        def __init__(self, bus: VirtualBus) -> None:
            self.bus = bus

        def i2c_rdwr(self, *msgs: i2c_msg) -> None:
            self.bus.i2c_rdwr(*msgs)

    dev = ProtocolDevice()
    dev.layer.set_snapshot(status=int(Status.BUSY_TRAJET))
    dev.layer.tick()
    board = Board(NoClockBus(VirtualBus({2: dev})))
    with pytest.raises(BoardTimeout):
        board.wait_idle(timeout_s=0.1, poll_s=0.04)
    # The last sleep is cut to the deadline.
    assert clock.sleeps == pytest.approx([0.04, 0.04, 0.02])


def test_wait_idle_rejects_bad_periods() -> None:
    _, _, board = make()
    with pytest.raises(ValueError):
        board.wait_idle(timeout_s=-1)
    with pytest.raises(ValueError):
        board.wait_idle(timeout_s=1, poll_s=0)
