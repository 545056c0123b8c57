"""asserv view's match-play state (issue 31): the queue's points, the pause, the braking
distance and the lidar's hits, as the page receives them."""

from __future__ import annotations

import json
import math

from asserv import view
from asserv.driver import Board
from asserv.scenario import parse
from asserv.sim import Simulator

SCENARIO = """\
set_vitesse_traj 60 60
goto 600 -600 through
goto 900 0 append+through
goto 400 400 append
sleep 1.5
pause
sleep 1
resume
wait
"""


def test_the_state_follows_the_queue_and_the_pause() -> None:
    src = view.SimSource(parse(SCENARIO))
    states = []
    for _ in range(400):
        src.advance(1 / 30)
        states.append(json.loads(json.dumps(src.state())))  # what the page gets
    m = [s["match"] for s in states]
    assert all(x is not None for x in m)
    queues = [x["queue"] for x in m]
    assert [[600, -600], [900, 0], [400, 400]] in queues  # all three ahead at first
    assert [[400, 400]] in queues and queues[-1] == []  # then the last one, then none
    paused = [x["paused"] for x in m]
    assert any(paused) and not paused[-1]
    braking = [x["braking_mm"] for x, p in zip(m, paused, strict=True) if not p]
    assert max(braking) > 50  # at 0.6 m/s
    assert [x for x in m if x["paused"]][-1]["braking_mm"] == 0  # at rest, a second later
    assert all(x["lidar"] == [] for x in m)  # no opponent


def test_the_state_carries_the_lidar_hits_on_the_field() -> None:
    sim = Simulator(record=True)
    sim.add_opponent(600, -850, 100)
    src = view.SimSource(sim=sim)
    src.advance(0.2)
    hits = src.state()["match"]["lidar"]
    assert hits
    for x, y in hits:  # on the opponent's edge, within the lidar's 3 sigma
        assert abs(math.hypot(x - 600, y + 850) - 100) <= 30 + 0.1


def test_a_board_without_pause_has_no_match_state() -> None:
    from test_driver_match import Without

    from asserv import Capability, VirtualBus

    state = view.read_match(Board(VirtualBus({2: Without(int(Capability.PAUSE))})), None)
    assert state is None
