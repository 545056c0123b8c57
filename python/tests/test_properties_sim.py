"""The simulated board under abuse from the bus: replies read slowly across control ticks, and
random sequences of valid and invalid frames, reads without writes, transactions cut by a bus
error, repeated starts in the middle of a frame and reads longer than the reply (hypothesis).
docs/failure-model.md says what the board promises; these tests check it on the board's own C
code, tick by tick.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from asserv import Filtre, OrderState, Reject, Status, codec
from asserv.driver import Board
from asserv.sim import Simulator

ADDR_W, ADDR_R = codec.write_address(), codec.read_address()


def tick_of(sim: Simulator, t_s: float) -> int:
    """The trace row of the last control tick at or before t_s."""
    return int(np.searchsorted(sim.trace["t_s"], t_s + 1e-9, side="right")) - 1


def test_a_position_read_byte_by_byte_is_one_snapshot() -> None:
    # Driving diagonally at 1 m/s, the master selects POSITION, then reads it one byte at a time
    # with 7 ms between bytes: about 60 control ticks per reply. Every reply must be the
    # estimate of the tick when the designation arrived, all six bytes: a byte from a later
    # tick puts x or y off by up to 60 mm, and by 256 mm across a boundary of the high byte.
    sim = Simulator({"start": (-1000, -700, 0)})
    board = Board(sim.bus)
    board.set_vitesse_traj(100, 100)
    board.set_vitesse_rot(100, 100)
    board.goto(1000, 700)
    reads = []
    while sim.time_s < 3.5:
        sim.bus_start(read=False)
        sim.bus_write_byte(codec.message("POSITION").designation)
        sim.bus_stop()
        selected = sim.time_s
        sim.advance(0.004)
        sim.bus_start(read=True)
        got = []
        for _ in range(7):  # the reply and its PEC
            got.append(sim.bus_read_byte())
            sim.advance(0.007)
        sim.bus_stop()
        reads.append((selected, sim.time_s, bytes(got)))
    tr = sim.trace
    crossings = 0
    for selected, ended, data in reads:
        pose = codec.decode_reply("POSITION", data, pec_prefix=bytes([ADDR_R]))
        assert isinstance(pose, codec.Pose)
        row = tr[tick_of(sim, selected)]
        assert abs(pose.x_mm - row["est_x_mm"]) <= 0.5
        assert abs(pose.y_mm - row["est_y_mm"]) <= 0.5
        assert abs(2 * pose.angle_2deg - row["est_heading_deg"]) <= 1.0
        assert pose.radius_mm == row["radius_mm"]
        last = tr[tick_of(sim, ended)]
        for axis in ("est_x_mm", "est_y_mm"):
            crossings += (round(row[axis]) >> 8) != (round(last[axis]) >> 8)
    assert len(reads) > 40
    assert tr["est_x_mm"][-1] - tr["est_x_mm"][0] > 1500  # it did drive across
    assert crossings >= 4  # replies that a torn read would have put 256 mm off


# ---- random bus traffic (hypothesis) ------------------------------------------------------


@dataclass(frozen=True)
class Segment:
    """One part of a transaction: a write of these bytes, or a read of n bytes."""

    read: bool
    data: bytes = b""
    n: int = 0


@dataclass(frozen=True)
class Transaction:
    """START, the segments joined by repeated STARTs, then STOP, or a bus error after
    ``abort_after`` bytes of the last segment (a write); then the bus idles ``idle_s``."""

    segments: tuple[Segment, ...]
    abort_after: int | None
    idle_s: float
    port_restart: bool = False  # the port reports each repeated start (the AVR's TWI does)


def frame(name: str, *args: int) -> st.SearchStrategy[bytes]:
    """A valid write, with or without its PEC (the short forms never carry one)."""
    full = len(args) == len(codec.message(name).params)
    return st.booleans().map(lambda pec: codec.encode(name, *args, pec=pec and full))


# Orders keep the robot in the middle of the field, so that it reaches no border: on a healthy
# robot nothing the master writes may end in PB_GRAVE. Options stay 0: a recalibration may
# move the estimate on purpose.
VALID = st.one_of(
    st.tuples(st.integers(-900, 900), st.integers(-500, 500)).flatmap(
        lambda p: frame("GOTO", p[0], p[1], 0)
    ),
    st.integers(0, 255).flatmap(lambda d: frame("GOTO_REVERSE", d)),
    st.integers(-90, 90).flatmap(lambda a: frame("GOTO_PANIER", a)),
    frame("STOP"),
    st.sampled_from(["SET_VITESSE_TRAJ", "SET_VITESSE_ROT"]).flatmap(
        lambda name: st.one_of(
            st.integers(20, 150).flatmap(lambda v: frame(name, v)),
            st.tuples(st.integers(20, 150), st.integers(20, 200)).flatmap(
                lambda va: frame(name, *va)
            ),
        )
    ),
    st.integers(0, 2).flatmap(lambda p: frame("SET_FILTRE", p)),
    st.tuples(st.integers(-50, 50), st.integers(-50, 50), st.integers(-10, 10)).flatmap(
        lambda e: frame("SET_NEW_POS", *e)
    ),
    st.sampled_from([0, 150, 2000]).flatmap(lambda ms: frame("SET_TIMEOUT", ms)),
)


@st.composite
def damaged(draw: st.DrawFn) -> bytes:
    """A valid write cut short, lengthened, or with one byte changed."""
    good = bytearray(draw(VALID))
    how = draw(st.sampled_from(["cut", "grow", "flip"]))
    if how == "cut":
        return bytes(good[: draw(st.integers(0, len(good) - 1))])
    if how == "grow":
        return bytes(good + draw(st.binary(min_size=1, max_size=3)))
    i = draw(st.integers(0, len(good) - 1))
    good[i] ^= draw(st.integers(1, 255))
    return bytes(good)


ETAT = st.sampled_from([3, 3, 3, 4, 5, 11, 13, 14, 14, 200]).map(lambda d: bytes([d]))
WRITES = st.one_of(VALID, ETAT, damaged(), st.binary(min_size=0, max_size=10))
# Reads: mostly what masters do (the status byte, with or without its PEC), sometimes any
# length, past the reply.
READS = st.one_of(st.just(1), st.just(2), st.integers(0, 30))
SEGMENTS = st.one_of(
    WRITES.map(lambda d: Segment(read=False, data=d)),
    READS.map(lambda n: Segment(read=True, n=n)),
)


@st.composite
def transactions(draw: st.DrawFn) -> Transaction:
    if draw(st.integers(0, 2)) == 0:  # the driver's way: a write, then the status after Sr
        segments: tuple[Segment, ...] = (
            Segment(read=False, data=draw(WRITES)),
            Segment(read=True, n=draw(READS)),
        )
    else:
        segments = tuple(draw(st.lists(SEGMENTS, min_size=1, max_size=3)))
    abort_after = None
    last = segments[-1]
    if not last.read and draw(st.integers(0, 5)) == 0:
        abort_after = draw(st.integers(0, len(last.data)))
    idle = draw(st.sampled_from([0.0, 0.0003, 0.002, 0.05, 0.3]))
    return Transaction(segments, abort_after, idle, draw(st.booleans()))


class Model:
    """What docs/protocol.md says the master sees: how each write is judged, which reply a read
    returns, COMMANDE_REJETEE and LAST_REJECT."""

    def __init__(self) -> None:
        self.rejected = False
        self.count = 0
        self.last: tuple[int, int] = (Reject.NONE, 0)
        self.selected: str | None = None
        self.new_pos_at: list[float] = []  # when each accepted SET_NEW_POS was judged
        # when the first accepted SET_ODOMETRIE was judged: from then on the board measures
        # with the master's calibration, which may be far from the robot's wheels
        self.recalibrated_at = math.inf

    def reject(self, reason: Reject, data: bytes) -> None:
        self.rejected = True
        self.count += 1
        self.last = (reason, data[0] if data else 0xFF)

    def judge(self, data: bytes, now_s: float) -> None:
        if not data:
            return  # an address-only write is not a frame
        self.selected = None
        try:
            w = codec.decode_write(data)
        except codec.FrameError as e:
            self.reject(e.reason, data)
            return
        if w.message.kind == "ETAT":
            self.selected = w.message.name
            return
        self.rejected = False
        if w.message.name == "SET_NEW_POS":
            self.new_pos_at.append(now_s)
        if w.message.name == "SET_ODOMETRIE":
            self.recalibrated_at = min(self.recalibrated_at, now_s)

    def check_read(self, data: bytes, prefix: bytes) -> None:
        name = self.selected or "CHECK_BUSY"
        n = codec.reply_length(name)
        if len(data) > n:
            assert data[n] == codec.crc8(prefix + bytes([ADDR_R]) + data[:n]), "read PEC"
            assert set(data[n + 1 :]) <= {0xFF}, "bytes past the PEC"
        if name == "CHECK_BUSY" and data:
            s = data[0]
            assert not s & 0x80 and bool(s & Status.COMMANDE_REJETEE) == self.rejected
            assert not s & Status.BUSY_GOTO_PANIER or s & Status.BUSY_TRAJET
        if name == "LAST_REJECT" and len(data) >= 3:
            assert (data[0], data[1], data[2]) == (*self.last, min(self.count, 255))
        self.selected = None


def play(sim: Simulator, model: Model, tx: Transaction) -> None:
    """One transaction on the simulated bus, checked against the model as it goes."""
    last_write = b""
    prev_read: bool | None = None
    for k, seg in enumerate(tx.segments):
        if k and tx.port_restart:
            sim.bus_restart()  # the port reports the repeated start: the write ends here
            if prev_read is False:
                model.judge(last_write, sim.time_s)
        sim.bus_start(read=seg.read)
        if prev_read is False and not tx.port_restart:
            model.judge(last_write, sim.time_s)  # the next address ended that write
        if seg.read:
            prefix = bytes([ADDR_W]) + last_write if prev_read is False else b""
            model.check_read(bytes(sim.bus_read_byte() for _ in range(seg.n)), prefix)
        else:
            cut = tx.abort_after if k == len(tx.segments) - 1 else None
            last_write = seg.data if cut is None else seg.data[:cut]
            for b in last_write:
                sim.bus_write_byte(b)
        prev_read = seg.read
    if tx.abort_after is not None:
        sim.bus_abort()
        model.reject(Reject.ABORTED, last_write)
        model.selected = None
    else:
        sim.bus_stop()
        if prev_read is False:
            model.judge(last_write, sim.time_s)
    sim.advance(tx.idle_s)


def check_trace(sim: Simulator, model: Model) -> None:
    tr = sim.trace
    # The board kept controlling: one tick every millisecond, none missed.
    assert len(tr) == sim.ticks
    assert np.allclose(np.diff(tr["t_s"]), 1e-3)
    # The status stayed consistent.
    s = tr["status"].astype(int)
    busy = (s & Status.BUSY_TRAJET) != 0
    assert not np.any(s & (0x80 | Status.PB_GRAVE))
    assert np.all(busy | ((s & Status.BUSY_GOTO_PANIER) == 0))
    assert np.all(~busy | ((s & (Status.CHOC_BORD | Status.CHOC_PANIER | Status.PB_MOTEUR)) == 0))
    assert np.array_equal(busy, tr["order_state"] != OrderState.IDLE)
    # The estimate moved with the robot, tick by tick, but where the master corrected it
    # (SET_NEW_POS) or the basket recalibrated it.
    jumps = np.zeros(len(tr) - 1, dtype=bool)
    for t in model.new_pos_at:
        jumps |= (tr["t_s"][1:] >= t - 1e-9) & (tr["t_s"][1:] <= t + 1.001e-3)
    jumps |= (np.diff(s & Status.CHOC_PANIER) > 0) & (tr["order_state"][:-1] == OrderState.PUSH)
    # A calibration the master made up (a 16 mm track, say) is followed faithfully: the estimate
    # then moves as those wheels would, not as the robot does.
    jumps |= tr["t_s"][1:] >= model.recalibrated_at
    d_est = np.hypot(np.diff(tr["est_x_mm"]), np.diff(tr["est_y_mm"]))
    d_true = np.hypot(np.diff(tr["x_mm"]), np.diff(tr["y_mm"]))
    assert np.all(jumps | (np.abs(d_est - d_true) <= 0.3))
    turn = (np.diff(tr["est_heading_deg"]) - np.diff(tr["heading_deg"]) + 180) % 360 - 180
    assert np.all(jumps | (np.abs(turn) <= 0.05))


@settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(st.lists(transactions(), min_size=6, max_size=20))
def test_random_bus_traffic_changes_nothing_it_should_not(txs: list[Transaction]) -> None:
    sim = Simulator({"start": (0, -300, 0)})
    model = Model()
    for tx in txs:
        play(sim, model, tx)
    sim.advance(0.01)
    check_trace(sim, model)
    # Every rejected write was counted, the last one named.
    board = Board(sim.bus)
    why = board.last_reject()
    assert (why.reason, why.designation, why.count) == (*model.last, min(model.count, 255))
    # And the board still takes an order and carries it out (with the standard gains: the soft
    # ones, for pushing, may settle a millimetre off).
    board.set_filtre(Filtre.FILTRE_STD)
    board.set_timeout(0)
    board.set_vitesse_traj(100, 100)
    board.set_vitesse_rot(100, 100)
    target = (600 if board.position().x_mm < 0 else -600, 200)  # far enough to aim at
    board.goto(*target)
    end = board.wait_idle(20)
    assert not end & (Status.PB_GRAVE | Status.BUSY_TRAJET)
    if not end:
        pose = board.position()
        assert (pose.x_mm, pose.y_mm) == target
