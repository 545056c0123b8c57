"""The long substep (1 ms, the simulator's default away from contacts and from the tyres' grip)
keeps the physics' results: the same orders end in the same outcome, within a millimetre of where
the 100 us substep everywhere ends them; and contacts, sliding tyres and a robot on a stand still
run the 100 us substep."""

from __future__ import annotations

import dataclasses
import math
from pathlib import Path

import numpy as np
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from asserv import Board, GotoOption, Status, field, scenario
from asserv.driver import Outcome
from asserv.sim import COARSE_SUBSTEP_NS, Simulator, lib

SLOW = settings(max_examples=10, deadline=None, suppress_health_check=[HealthCheck.too_slow])


def run(
    coarse_ns: int | None, seed: int, targets: list[tuple[int, int]]
) -> list[tuple[object, ...]]:
    # Systematic wheel errors, no random noise: the noise is drawn at the same ticks from the
    # same random numbers with either substep, but for slightly different distances rolled.
    errors = (seed % 7 - 3) * 0.001, (seed % 5 - 2) * -0.001
    config: dict[str, object] = {
        "start": (0, -600, 0),
        "enc_radius_error": errors,
        "enc_track_error_mm": (seed % 3 - 1) * 0.5,
    }
    if coarse_ns is not None:
        config["coarse_substep_ns"] = coarse_ns
    sim = Simulator(config, seed)
    board = Board(sim.bus)
    board.set_vitesse_traj(100, 100)
    ends = []
    for x, y in targets:
        out = board.complete(board.goto, x, y, timeout_s=20)
        ends.append((out, *sim.true_pose()))
    return ends


@SLOW
@given(
    seed=st.integers(0, 1000),
    targets=st.lists(
        st.tuples(st.integers(-800, 800), st.integers(-700, 700)), min_size=1, max_size=3
    ),
)
def test_the_default_long_substep_ends_free_moves_where_the_fine_one_does(
    seed: int, targets: list[tuple[int, int]]
) -> None:
    # Free moves: targets 275 mm and more from the baskets' edges and 350 mm from the borders,
    # more than the robot's reach (196 mm). (A GOTO into a basket ends in a fault whose stop
    # hangs on the last micrometres, with any substep: seed 94's (1000, -699) stops at (941.9,
    # -597.4) -64.08 degrees with 100 us substeps, (942.2, -599.6) -62.87 with 50 and 20 us,
    # (942.2, -599.3) -62.97 with the default.)
    fine = run(0, seed, targets)
    default = run(None, seed, targets)
    for f, c in zip(fine, default, strict=True):
        assert f[0] == c[0] == Outcome.DONE
        assert math.hypot(f[1] - c[1], f[2] - c[2]) < 2.0  # type: ignore[operator]
        assert abs(f[3] - c[3]) < 0.5  # type: ignore[operator]


@SLOW
@given(
    seed=st.integers(0, 2**16),
    duty=st.tuples(st.integers(-60, 100), st.integers(-60, 100)),
    ms=st.integers(200, 1500),
)
def test_the_long_substep_follows_the_fine_one_on_the_open_floor(
    seed: int, duty: tuple[int, int], ms: int
) -> None:
    # The physics alone, open-loop: a randomized robot on an endless floor gets the same duties
    # (ramped over 100 ms, a third of the battery at most: within the grip) with either substep.
    # The long step is first order: measured against 10 us substeps, it ends 0.02 to 0.18 mm
    # and 0.05 to 0.19 degree off (the 100 us one 0.002 to 0.017 mm and 0.005 to 0.017 degree),
    # nearly all of it from the accelerations; the bounds have some margin over that.
    poses = []
    for coarse in (0, COARSE_SUBSTEP_NS):
        sim = Simulator(
            {"start": (0, 0, 0), "coarse_substep_ns": coarse, "enc_noise_mm2_per_m": (0, 0)},
            seed,
            randomize=True,
            field=field.Field(borders=False),
            record=False,
        )
        for k in range(ms):
            ramp = min(1.0, k / 100)
            lib.sim_set_duty(sim._sim, round(duty[0] * 80 * ramp), round(duty[1] * 80 * ramp))
            lib.sim_advance_ns(sim._sim, 1_000_000)
        poses.append((sim.drive_pose(), sim.substeps))
    (fine, fine_steps), (fast, fast_steps) = poses
    assert fine_steps.long == 0 and fast_steps.long > 0.9 * ms
    dist = math.hypot(fine.x_mm, fine.y_mm)
    assert math.hypot(fine.x_mm - fast.x_mm, fine.y_mm - fast.y_mm) < 0.3 + 0.005 * dist
    turn = (fine.heading_deg - fast.heading_deg + 180) % 360 - 180
    assert abs(turn) < 0.3 + 0.003 * abs(fine.heading_deg)


def test_the_long_substep_is_the_default_and_changes_the_integration() -> None:
    assert Simulator({"start": (0, 0, 0)}).config.coarse_substep_ns == COARSE_SUBSTEP_NS
    a = Simulator({"start": (0, 0, 0)}, record=False)
    b = Simulator({"start": (0, 0, 0), "coarse_substep_ns": 0}, record=False)
    for s in (a, b):
        Board(s.bus).goto(1000, 0)
        s.advance(3.0)
    assert b.substeps.long == 0 and a.substeps.long > 1500
    assert a.true_pose() != b.true_pose()  # it did change the integration ...
    assert math.hypot(a.true_pose().x_mm - b.true_pose().x_mm, a.true_pose().y_mm) < 2


def test_the_default_is_deterministic() -> None:
    traces = []
    for _ in range(2):
        sim = Simulator({"start": (0, -600, 0)}, 3, randomize=True)
        board = Board(sim.bus)
        board.complete(board.goto, 700, 300, timeout_s=20)
        board.complete(board.goto, 700, 900, GotoOption.RECALAGE_BORD, timeout_s=20)
        traces.append(sim.trace)
    assert np.array_equal(traces[0], traces[1])


def long_steps_per_tick(sim: Simulator, seconds: float) -> float:
    before, t0 = sim.substeps.long, sim.ticks
    sim.advance(seconds)
    return (sim.substeps.long - before) / max(1, sim.ticks - t0)


def tick_by_tick(sim: Simulator, seconds: float) -> tuple[np.ndarray, np.ndarray]:
    """Per tick: whether the physics ran it as one long step, and the contact force. (From the
    next tick on: a bus transaction leaves the clock between two ticks, and the physics runs
    the parts of a tick that a call splits with short substeps.)"""
    sim.advance((-round(sim.time_s * 1e9) % 1_000_000) * 1e-9)
    long, force = [], []
    for _ in range(round(seconds * 1000)):
        before = sim.substeps.long
        sim.advance(0.001)
        long.append(sim.substeps.long > before)
        force.append(sim.trace["contact_force_N"][-1])
    return np.array(long), np.array(force)


def check_fine_near_contacts(long: np.ndarray, force: np.ndarray) -> None:
    """No long step in a tick with a contact force, nor within 0.5 s after one."""
    touching = np.nonzero(force > 0)[0]
    for t in np.nonzero(long)[0]:
        earlier = touching[touching <= t]
        assert len(earlier) == 0 or t - earlier[-1] > 500, (t, earlier[-1:])


def test_a_push_on_a_border_runs_the_fine_substep() -> None:
    # Border recalibration: the robot drives into the border and pushes; from the first contact
    # on, and 0.5 s after the last, every tick is ten 100 us substeps.
    sim = Simulator({"start": (1100, 0, 0)})
    board = Board(sim.bus)
    board.set_vitesse_traj(30, 50)
    board.goto(1500, 0, GotoOption.RECALAGE_BORD)
    long, force = tick_by_tick(sim, 4.0)
    assert force.max() > 0 and long[: int(np.nonzero(force > 0)[0][0])].any()
    check_fine_near_contacts(long, force)
    assert board.wait_idle(20) == Status.CHOC_BORD


@SLOW
@given(lateral=st.integers(-140, 140), speed=st.integers(20, 150))
def test_a_shock_runs_the_fine_substep_until_half_a_second_after_it(
    lateral: int, speed: int
) -> None:
    # A disc across the path, hit head-on or obliquely at any speed: the approach runs long
    # steps, the contact and the stop after it the 100 us substep.
    disc = field.Obstacle("circle", 0, lateral, radius_mm=150)
    f = dataclasses.replace(field.load(field.DEFAULT), obstacles=(disc,))
    sim = Simulator({"start": (-900, 0, 0.0)}, field=f)
    board = Board(sim.bus)
    board.set_vitesse_traj(speed, 150)
    board.goto(600, 0)
    long, force = tick_by_tick(sim, 1.5 + 600 / speed / 10)
    assert long.any()
    check_fine_near_contacts(long, force)


def test_a_sliding_tyre_runs_the_fine_substep() -> None:
    # No grip on the left wheel (oil): its tyre slides from the first push of the motor; the
    # ticks where a tyre slid or came within 10 % of its grip are run with 100 us substeps.
    sim = Simulator({"start": (0, 0, 0)}, field=field.Field(borders=False), record=False)
    sim.set_friction_scale(0, 0.0)
    board = Board(sim.bus)
    board.goto(500, 0)
    assert long_steps_per_tick(sim, 1.0) == 0


def test_a_robot_on_a_stand_runs_the_fine_substep() -> None:
    sim = Simulator({"start": (0, 0, 0), "lifted": True}, record=False)
    Board(sim.bus).goto(500, 0)
    assert long_steps_per_tick(sim, 1.0) == 0


def test_a_scenario_config_line_sets_the_substep(tmp_path: Path) -> None:
    # A scenario's numbers are read as floats: a whole number sets an integer setting.
    for line, long_steps in (("config coarse_substep_ns 0", False), ("", True)):
        path = tmp_path / "s.txt"
        path.write_text(f"{line}\nstart 0 0 0\ngoto 300 0\nwait\n", encoding="utf-8")
        sim = scenario.load(path).simulator()
        Board(sim.bus).goto(300, 0)
        sim.advance(1.0)
        assert (sim.substeps.long > 0) == long_steps
