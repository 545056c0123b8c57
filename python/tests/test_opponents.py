"""Opponents, two robots on one field, and timed events: contact with an opponent closes the
shock switches it touches, each robot sees the other, events happen at their time."""

from __future__ import annotations

import math
import threading

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from asserv import Board, Status
from asserv.driver import Outcome
from asserv.sim import Simulator
from asserv.sim.arena import Arena

SLOW = settings(max_examples=20, deadline=None, suppress_health_check=[HealthCheck.too_slow])
START = (-1000.0, -300.0, 0.0)


def lane() -> tuple[Simulator, Board]:
    sim = Simulator({"start": START})
    return sim, Board(sim.bus)


def test_an_opponent_in_the_way_is_a_shock_on_the_front_bumper() -> None:
    sim, board = lane()
    i = sim.add_opponent(-400, 500, 150, path=[(-400, -300)], speed_mm_s=400)
    assert board.complete(board.goto, 200, -300, timeout_s=20) is Outcome.SHOCK
    assert sim.obstacles()[i] == (-400, -300)  # it arrived and stays
    assert sim.true_pose().x_mm == pytest.approx(-400 - 150 - 125, abs=2)
    front = 0b111  # CAPTEUR_0..2, the front bumper (sim/config.c)
    assert int(sim.trace["shocks"].max()) & front


def test_an_opponent_follows_its_path_and_loops() -> None:
    sim, _ = lane()
    i = sim.add_opponent(500, 0, 100, path=[(800, 0), (800, 300)], speed_mm_s=300, loop=True)
    sim.advance(1.0)
    assert sim.obstacles()[i] == pytest.approx((800, 0), abs=1e-6)
    sim.advance(1.0)
    assert sim.obstacles()[i] == pytest.approx((800, 300), abs=1e-6)
    sim.advance(1.0)  # back to the first point: 300 mm in 1 s at 300 mm/s
    x, y = sim.obstacles()[i]
    assert math.hypot(x - 800, y - 0) < 1e-6 or (x, y) == pytest.approx((800, 0), abs=1e-3)


def test_a_scripted_opponent() -> None:
    sim, board = lane()
    i = sim.add_opponent(-400, 800, 150)  # stands still until the script moves it
    sim.at(1.0, lambda s: s.set_opponent_path(i, [(-400, -300)], 600))
    sim.at(5.0, lambda s: s.move_obstacle(i, 1000, 800))
    board.goto(200, -300)
    sim.advance(4.0)
    assert board.check_busy() & Status.CHOC_BORD
    board.sleep(1.5)  # the script took it away at 5 s
    assert sim.obstacles()[i] == (1000, 800)
    assert board.complete(board.goto, 200, -300, timeout_s=20) is Outcome.DONE


def test_an_opponent_does_not_crush_the_robot() -> None:
    sim, board = lane()  # standing still; the opponent drives at it
    i = sim.add_opponent(-400, -300, 150, path=[(-1400, -300)], speed_mm_s=300)
    board.sleep(3.0)
    assert sim.true_pose().x_mm == pytest.approx(-1000, abs=0.01)
    assert sim.obstacles()[i][0] == pytest.approx(-1000 + 125 + 150, abs=0.5)
    assert board.info_choc() & 0b111


@SLOW
@given(angle=st.floats(-180, 180), dist=st.floats(400, 800), speed=st.floats(100, 900))
def test_opponent_property_never_overlaps_and_closes_what_it_touches(
    angle: float, dist: float, speed: float
) -> None:
    """From any direction and speed, an opponent driving at the standing robot stops touching
    it: no overlap, the robot not pushed, and exactly the shock switches it reaches (within
    the 1 mm of shock_range_mm) are closed."""
    sim, board = lane()
    a = math.radians(angle)
    x0, y0 = START[0] + dist * math.cos(a), START[1] + dist * math.sin(a)
    i = sim.add_opponent(x0, y0, 100, path=[(START[0], START[1])], speed_mm_s=speed)
    board.sleep(dist / speed + 0.5)
    ox, oy = sim.obstacles()[i]
    lx, ly = ox - START[0], oy - START[1]  # robot frame (heading 0)
    dx, dy = max(abs(lx) - 125, 0.0), max(abs(ly) - 150, 0.0)
    gap = math.hypot(dx, dy) - 100
    assert -1e-6 <= gap <= speed * 1e-3 + 1e-6  # touching, to within one tick's travel
    assert sim.drive_pose().x_mm == pytest.approx(START[0], abs=0.01)
    closed = board.info_choc()
    cfg = sim.config
    for k in range(cfg.shock_count):
        d = math.hypot(START[0] + cfg.shock[k].x_mm - ox, START[1] + cfg.shock[k].y_mm - oy) - 100
        if d <= 0.99:
            assert closed >> k & 1, f"switch {k} at {d:.2f} mm is open"
        elif d >= 1.01:
            assert not closed >> k & 1, f"switch {k} at {d:.2f} mm is closed"


def test_pressed_switches_and_events_at_their_time() -> None:
    sim, board = lane()
    seen: list[float] = []
    sim.at(0.25, lambda s: seen.append(s.time_s))
    sim.at(0.5, lambda s: s.press(0b100))
    board.goto(200, -300)
    assert board.complete(lambda: None, timeout_s=10) is Outcome.SHOCK
    assert seen == [pytest.approx(0.25, abs=1e-9)]
    assert board.info_choc() == 0b100
    sim.press(0)
    board.sleep(0.002)  # the next control tick publishes it
    assert board.info_choc() == 0
    with pytest.raises(ValueError):
        sim.at(-1, lambda s: None)
    with pytest.raises(ValueError):
        sim.press(0x100)


@pytest.mark.parametrize(
    ("event", "outcome"),
    [
        (lambda s: s.set_motor_stuck(1, True), Outcome.MOTOR_PROBLEM),
        (lambda s: s.set_encoder_cut(0, True), Outcome.MOTOR_PROBLEM),
    ],
)
def test_timed_faults(event: object, outcome: Outcome) -> None:
    sim, board = lane()
    sim.at(1.0, event)  # type: ignore[arg-type]
    assert board.complete(board.goto, 200, -300, timeout_s=10) is outcome


def test_obstacle_api_checks_its_arguments() -> None:
    sim, _ = lane()
    with pytest.raises(ValueError):
        sim.add_obstacle(0, 0)
    with pytest.raises(ValueError):
        sim.add_obstacle(0, 0, radius_mm=10, half_x_mm=5)
    with pytest.raises(ValueError):
        sim.move_obstacle(99, 0, 0)
    i = sim.add_obstacle(0, 0, radius_mm=10)
    with pytest.raises(ValueError):
        sim.set_opponent_path(i, [(0, 0)], speed_mm_s=0)
    with pytest.raises(ValueError):
        sim.set_opponent_path(i, [(0.0, 0.0)] * 17)
    while len(sim.obstacles()) < 16:
        sim.add_obstacle(0, 900, radius_mm=1)
    with pytest.raises(ValueError, match="full"):
        sim.add_obstacle(0, 0, radius_mm=10)


@pytest.mark.parametrize("turn", [90.0, -90.0, 270.0])
def test_a_box_turned_a_quarter_is_the_box_with_its_sides_swapped(turn: float) -> None:
    ends = []
    for hx, hy, h in ((200, 50, 0.0), (50, 200, turn)):
        sim, board = lane()
        sim.add_obstacle(-300, -320, half_x_mm=hx, half_y_mm=hy, heading_deg=h)
        ends.append((board.complete(board.goto, 200, -300, timeout_s=20), sim.true_pose()))
    assert ends[0][0] is ends[1][0] is Outcome.SHOCK
    assert ends[1][1].x_mm == pytest.approx(ends[0][1].x_mm, abs=1e-6)
    assert ends[1][1].x_mm == pytest.approx(-300 - 200 - 125, abs=1)  # at the box face


# Two robots on one field.


def two_robots() -> tuple[Simulator, Simulator, Board, Board]:
    a = Simulator({"start": (-1000, -300, 0)})
    b = Simulator({"start": (1000, -300, 180)}, seed=1)
    Arena([a, b])
    return a, b, Board(a.bus), Board(b.bus)


def test_two_robots_head_on_both_stop_on_a_shock() -> None:
    a, b, ba, bb = two_robots()
    results: dict[str, Outcome] = {}

    def run(name: str, board: Board, x: int) -> None:
        results[name] = board.complete(board.goto, x, -300, timeout_s=20)

    threads = [
        threading.Thread(target=run, args=("a", ba, 800)),
        threading.Thread(target=run, args=("b", bb, -800)),
    ]
    for t in threads:
        t.start()
    for t in threads:
        t.join(60)
    assert results == {"a": Outcome.SHOCK, "b": Outcome.SHOCK}
    gap = b.true_pose().x_mm - a.true_pose().x_mm
    assert 245 <= gap <= 262  # bumper to bumper: two half lengths of 125 mm
    # One clock: a bus transaction moves its robot ahead by its bytes until the next sleep
    # (arena.py), and which thread ends last, with its last reads, is the scheduler's: 2.6 ms
    # (26 bytes at 100 kHz) in a rehearsal of CI. Not seconds apart.
    assert abs(a.time_s - b.time_s) < 0.005


def test_a_robot_drives_past_the_other() -> None:
    a, b, ba, bb = two_robots()
    assert ba.complete(ba.goto, -200, 300, timeout_s=20) is Outcome.DONE
    assert b.time_s == pytest.approx(a.time_s, abs=0.005)  # b stood still meanwhile
    assert b.true_pose().x_mm == pytest.approx(1000, abs=0.5)
    assert bb.complete(bb.goto, 0, -300, timeout_s=20) is Outcome.DONE


def test_an_arena_checks_its_robots() -> None:
    a = Simulator()
    with pytest.raises(ValueError):
        Arena([a])
    with pytest.raises(ValueError):
        Arena([a, a])
