"""The 1 ms substep away from contacts keeps the physics' results: the same orders end in the
same outcome, within a millimetre of where the 100 us substep everywhere ends them."""

from __future__ import annotations

import math

from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from asserv import Board
from asserv.sim import Simulator

SLOW = settings(max_examples=10, deadline=None, suppress_health_check=[HealthCheck.too_slow])


def run(coarse_ns: int, seed: int, targets: list[tuple[int, int]]) -> list[tuple[object, ...]]:
    # Systematic wheel errors, no random noise: the encoder noise is drawn per 16 substeps, so
    # the two integrations draw different noise (the same statistics), which is no error of
    # the integration.
    errors = (seed % 7 - 3) * 0.001, (seed % 5 - 2) * -0.001
    config = {
        "start": (0, -600, 0),
        "coarse_substep_ns": coarse_ns,
        "enc_radius_error": errors,
        "enc_track_error_mm": (seed % 3 - 1) * 0.5,
    }
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
        st.tuples(st.integers(-1000, 1000), st.integers(-700, 700)), min_size=1, max_size=3
    ),
)
def test_coarse_substep_property_same_ends(seed: int, targets: list[tuple[int, int]]) -> None:
    fine = run(0, seed, targets)
    coarse = run(1_000_000, seed, targets)
    for f, c in zip(fine, coarse, strict=True):
        assert f[0] == c[0]
        assert math.hypot(f[1] - c[1], f[2] - c[2]) < 2.0  # type: ignore[operator]
        assert abs(f[3] - c[3]) < 0.5  # type: ignore[operator]


def test_the_coarse_substep_is_used_away_from_contacts_only() -> None:
    assert Simulator({"start": (0, 0, 0)}).config.coarse_substep_ns == 0  # opt-in
    a = Simulator({"start": (0, 0, 0), "coarse_substep_ns": 1_000_000}, record=False)
    b = Simulator({"start": (0, 0, 0), "coarse_substep_ns": 0}, record=False)
    for s in (a, b):
        Board(s.bus).goto(1000, 0)
        s.advance(3.0)
    assert a.true_pose() != b.true_pose()  # it did change the integration ...
    assert math.hypot(a.true_pose().x_mm - b.true_pose().x_mm, a.true_pose().y_mm) < 2
