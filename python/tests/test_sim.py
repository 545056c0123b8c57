"""The simulated board seen from Python: the driver on the simulator's bus, determinism, bus
timing, traces, configuration errors and fault hooks."""

from __future__ import annotations

import math

import numpy as np
import pytest

from asserv import Status
from asserv.driver import Board
from asserv.sim import SPEC_START, TRACE_FIELDS, Simulator


def annex_session(sim: Simulator) -> Board:
    board = Board(sim.bus)
    board.set_vitesse_traj(100, 100)
    board.set_vitesse_rot(50, 100)
    board.goto(200, 100)
    return board


def test_starts_at_the_power_on_pose() -> None:
    sim = Simulator()
    assert sim.true_pose() == pytest.approx(SPEC_START)
    assert SPEC_START[0] == 0 and SPEC_START[2] == 0  # "0, bout du terrain", angle 0
    assert sim.time_s == 0 and sim.ticks == 0 and len(sim.trace) == 0


def test_goto_reaches_the_target_through_the_driver() -> None:
    sim = Simulator()
    board = annex_session(sim)
    status = board.wait_idle(10)
    assert not status & (Status.BUSY_TRAJET | Status.PB_MOTEUR | Status.PB_GRAVE)
    pose = board.position()
    x, y, _ = sim.true_pose()
    assert (pose.x_mm, pose.y_mm) == (200, 100)
    assert math.hypot(x - 200, y - 100) < 1.0  # reference robot: no wheel errors
    # 1.0 m at 1 m/s and 1 m/s^2, turn included: a couple of seconds, not more
    assert 1.5 < sim.time_s < 3.5


def test_same_seed_same_bits_other_seed_other_robot() -> None:
    def run(seed: int) -> np.ndarray:
        sim = Simulator(seed=seed, randomize=True)
        annex_session(sim).wait_idle(10)
        return sim.trace

    a, b, c = run(7), run(7), run(8)
    assert a.tobytes() == b.tobytes()
    assert len(a) != len(c) or a.tobytes() != c.tobytes()


def test_bytes_take_bus_time() -> None:
    sim = Simulator(bus_hz=100_000)
    board = Board(sim.bus, check=False)
    board.goto(200, 100)  # address + 6 bytes at 9 bits each, 100 kHz
    assert sim.time_s == pytest.approx(7 * 90e-6)
    fast = Simulator(bus_hz=400_000)
    Board(fast.bus, check=False).goto(200, 100)
    assert fast.time_s == pytest.approx(7 * 22.5e-6)
    assert [f.kind for f in sim.frames] == ["W"] and sim.frames[0].data[0] == 0  # GOTO


def test_trace_columns_follow_the_run() -> None:
    sim = Simulator()
    board = Board(sim.bus)
    board.set_vitesse_traj(50, 100)
    board.goto(0, 500)  # 1.35 m straight ahead after a quarter turn
    board.wait_idle(10)
    tr = sim.trace
    assert tr.dtype.names == TRACE_FIELDS
    assert len(tr) == sim.ticks
    assert np.all(np.diff(tr["t_s"]) == pytest.approx(1e-3))
    busy = (tr["status"].astype(int) & Status.BUSY_TRAJET) != 0
    assert busy.any() and not busy[-1]
    # the distance set-point reaches the speed limit set and never passes it
    assert tr["v_set_mm_s"].max() == pytest.approx(500, abs=1)
    assert tr["v_mm_s"].max() == pytest.approx(500, abs=25)
    # truth and estimate stay together on the reference robot
    err = np.hypot(tr["est_x_mm"] - tr["x_mm"], tr["est_y_mm"] - tr["y_mm"])
    assert err.max() < 1.0


def test_board_start_and_truth_can_differ() -> None:
    sim = Simulator({"start": (10, -850, 0)}, board_start=(0, -850, 0))
    board = Board(sim.bus)
    pose = board.position()
    assert (pose.x_mm, pose.y_mm) == (0, -850)
    assert sim.true_pose().x_mm == pytest.approx(10)


@pytest.mark.parametrize(
    ("config", "message"),
    [
        ({"mass_kgg": 3}, "unknown simulator setting 'mass_kgg'"),
        ({"enc_radius_error": (0.1,)}, "enc_radius_error takes 2 values"),
        ({"start": (1, 2)}, "start must be (x_mm, y_mm, heading_deg)"),
        ({"substep_ns": 10}, "refused this configuration"),
        ({"mass_kg": "heavy"}, "mass_kg"),
    ],
)
def test_bad_configuration_is_refused(config: dict[str, object], message: str) -> None:
    with pytest.raises(ValueError, match=message.replace("(", r"\(").replace(")", r"\)")):
        Simulator(config)


def test_a_stuck_motor_is_reported_then_the_next_order_runs() -> None:
    sim = Simulator()
    board = annex_session(sim)
    sim.advance(0.8)
    sim.set_motor_stuck(0, True)
    status = board.wait_idle(5)
    assert status & Status.PB_MOTEUR and not status & Status.BUSY_TRAJET
    sim.set_motor_stuck(0, False)
    sim.advance(1.0)  # the body was still spinning about the locked wheel: let it settle
    board.goto(200, 100)  # one PB_MOTEUR is not PB_GRAVE: the board takes the next order
    status = board.wait_idle(10)
    assert not status & (Status.PB_MOTEUR | Status.PB_GRAVE)
    assert (board.position().x_mm, board.position().y_mm) == (200, 100)


def test_board_config_overrides_and_odometry_errors() -> None:
    sim = Simulator(
        {"enc_radius_error": (0.002, -0.001), "enc_track_error_mm": 0.5},
        board_config={"orders.settle_ms": 7, "odometry.track_um": 280100},
    )
    assert sim.board_config.orders.settle_ms == 7
    e = sim.odometry_errors()
    # configured factors over true ones: 1/1.002 and 1/0.999
    assert e.ratio == pytest.approx(1.002 / 0.999 - 1, rel=1e-6)
    q = (1 / 1.002 + 1 / 0.999) / 2
    assert e.scale == pytest.approx(q - 1, abs=1e-6)  # the nominal factor is rounded: 1e-7
    assert e.track_mm == pytest.approx(280.1 - q * 280.5, abs=1e-4)
    with pytest.raises(ValueError, match=r"unknown board setting 'orders\.settle'"):
        Simulator(board_config={"orders.settle": 1})


def test_set_odometrie_changes_what_the_board_measures() -> None:
    # A robot whose right free wheel is 0.3 % larger: calibrated, its estimate goes straight
    # where the nominal one turns.
    def drift(setting: tuple[int, int, int] | None) -> float:
        sim = Simulator({"enc_radius_error": (0.0, 0.003), "start": (-900, 0, 0)})
        board = Board(sim.bus)
        if setting:
            board.set_odometrie(*setting)
        sim.advance(0.01)
        expected = 0 if setting else 1 / 1.003 - 1
        assert sim.odometry_errors().ratio == pytest.approx(expected, abs=2e-6)
        board.set_vitesse_traj(50, 100)
        board.goto(900, 0)
        board.wait_idle(10)
        return abs(sim.true_pose().y_mm)

    ratio = round(2 * (1.003 - 1) / (1.003 + 1) * 1e6)  # right/left = (1 + r/2) / (1 - r/2)
    assert drift(None) > 15  # 0.3 % over 1.8 m and 280 mm: d^2 Ed / (2 b) = 17 mm
    assert drift((ratio, 28000, 0)) < 1
