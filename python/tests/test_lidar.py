"""The simulated lidar (asserv.lidar): what it reports is where the opponents truly are, within
its range noise, beam by beam; it scans at its rate, the same way from the same seed. And the
random crossing opponents: their runs cross our route, at the angles promised, on the table."""

from __future__ import annotations

import itertools
import math

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from asserv.lidar import LIDAR, crossing_path
from asserv.scenario import ScenarioError, parse
from asserv.sim import Simulator
from asserv.sim.arena import Arena

SLOW = settings(max_examples=40, deadline=None, suppress_health_check=[HealthCheck.too_slow])
STEP = 360.0 / LIDAR.beams


def _entry(ox: float, oy: float, a_deg: float, cx: float, cy: float, r: float) -> float | None:
    """Where a ray from (ox, oy) at a_deg enters the disc, by the foot of the perpendicular from
    the centre (None: it misses)."""
    ux, uy = math.cos(math.radians(a_deg)), math.sin(math.radians(a_deg))
    along = (cx - ox) * ux + (cy - oy) * uy
    across = abs(-(cx - ox) * uy + (cy - oy) * ux)
    if across > r or along <= 0:
        return None
    return along - math.sqrt(r * r - across * across)


discs = st.lists(
    st.tuples(st.floats(-1300, 1300), st.floats(-850, 850), st.floats(40, 250)),
    min_size=1,
    max_size=4,
)


@SLOW
@given(
    x=st.floats(-1200, 1200),
    y=st.floats(-800, 800),
    heading=st.floats(-180, 180),
    targets=discs,
    seed=st.integers(0, 2**32),
)
def test_lidar_property_hits_are_the_truth_within_the_noise(
    x: float, y: float, heading: float, targets: list[tuple[float, float, float]], seed: int
) -> None:
    """Each beam reports the nearest opponent it meets within the range limits, to within 3
    sigma along the beam; a beam that reports nothing meets none within them; the bearings are
    the beams' own, 1 degree apart."""
    sim = Simulator(seed=seed, record=False)
    sim.place(x, y, heading)
    for cx, cy, r in targets:
        sim.add_opponent(cx, cy, r)
    pose = sim.true_pose()
    scan = sim.lidar()
    hits = {round(h.bearing_deg / STEP) % LIDAR.beams: h for h in scan.hits}
    assert len(hits) == len(scan.hits)

    def truth(a: float, grow: float) -> float:
        """The nearest entry along the beam at a, every disc's radius grown by ``grow``."""
        inside = any(
            math.hypot(pose.x_mm - cx, pose.y_mm - cy) <= r + grow for cx, cy, r in targets
        )
        if inside:
            return 0.0
        entries = [_entry(pose.x_mm, pose.y_mm, a, cx, cy, r + grow) for cx, cy, r in targets]
        return min((e for e in entries if e is not None), default=math.inf)

    for k in range(LIDAR.beams):
        bearing = k * STEP
        a = pose.heading_deg + bearing
        # A beam that grazes a disc (tangent to within float rounding) may hit it or not: the
        # truth is bracketed by the discs 1e-6 mm smaller and larger.
        strict, loose = truth(a, -1e-6), truth(a, 1e-6)
        if k not in hits:
            seen = LIDAR.min_mm <= strict <= LIDAR.max_mm
            # at the limits, float rounding may put the beam either side
            assert not seen or min(abs(strict - LIDAR.min_mm), abs(strict - LIDAR.max_mm)) < 1e-6
            continue
        h = hits[k]
        assert (h.bearing_deg - bearing + 180) % 360 - 180 == pytest.approx(0, abs=1e-9)
        assert -180 <= h.bearing_deg < 180
        # (the bracket is up to sqrt(2 r 1e-6) wide at a tangent: 0.02 mm for these discs)
        assert min(abs(h.range_mm - strict), abs(h.range_mm - loose)) <= 3 * LIDAR.sigma_mm + 0.05


@SLOW
@given(d=st.floats(300, 3000), bearing=st.floats(-180, 180), r=st.floats(60, 200))
def test_lidar_property_an_opponent_in_range_is_seen(d: float, bearing: float, r: float) -> None:
    """An opponent wider than a beam step and within range is hit by at least one beam, and
    its hits put it where it is: their points lie within 3 sigma of its edge."""
    if d - r < LIDAR.min_mm or math.degrees(math.asin(min(1.0, r / d))) < STEP:
        return
    sim = Simulator(record=False)
    x, y, h = sim.true_pose()
    a = math.radians(h + bearing)
    cx, cy = x + d * math.cos(a), y + d * math.sin(a)
    sim.add_opponent(cx, cy, r)
    scan = sim.lidar()
    assert scan.hits
    for px, py in scan.points(x, y, h):
        assert abs(math.hypot(px - cx, py - cy) - r) <= 3 * LIDAR.sigma_mm + 1e-6


def test_the_lidar_scans_at_its_rate_and_sees_the_opponent_move() -> None:
    sim = Simulator(record=False)
    sim.advance(0.123)
    sim.add_opponent(600, -850, 100, path=[(600, 500)], speed_mm_s=300)
    first = sim.lidar()
    assert (first.number, first.t_s) == (0, pytest.approx(0.123))
    sim.advance(0.05)
    assert sim.lidar() == first  # no new scan within a period
    sim.advance(1.0)
    last = sim.lidar()
    assert last.number == 10
    assert last.t_s == pytest.approx(0.123 + 1.0, abs=1e-9)
    assert abs(last.nearest().bearing_deg) > abs(first.nearest().bearing_deg) + 10  # type: ignore[union-attr]


def test_the_lidar_is_deterministic_from_the_seed() -> None:
    def scans(seed: int) -> list[object]:
        sim = Simulator(seed=seed, record=False)
        sim.add_crossing_opponent([(0, -850), (600, -600), (900, 300)])
        out = [sim.lidar()]
        for _ in range(5):
            sim.advance(0.1)
            out.append(sim.lidar())
        return out

    assert scans(4) == scans(4)
    assert scans(4) != scans(5)


def test_the_noise_is_centred_and_has_its_sigma() -> None:
    sim = Simulator(seed=1, record=False)
    sim.add_opponent(1500 - 300, -850, 250)  # a wide target straight ahead, many beams
    errors = []
    x, y, _ = sim.true_pose()
    for _ in range(40):
        scan = sim.lidar()
        for px, py in scan.points(x, y, sim.true_pose().heading_deg):
            errors.append(math.hypot(px - 1200, py + 850) - 250)
        sim.advance(0.1)
    e = np.array(errors)
    assert len(e) > 500
    assert abs(e.mean()) < 1.5  # the range along a beam, seen radially: a tiny bias
    assert 0.7 * LIDAR.sigma_mm < e.std() < 1.1 * LIDAR.sigma_mm


def test_the_lidar_sees_the_other_robot_of_an_arena() -> None:
    a = Simulator({"start": (-1000, -300, 0)})
    b = Simulator({"start": (0, -300, 180)}, seed=1)
    Arena([a, b])
    ahead = [h for h in a.lidar().hits if h.bearing_deg == 0]
    assert ahead
    cfg = b.config  # b faces a: the front of its outline, from a's lidar
    front_x = b.drive_pose().x_mm - cfg.outline_offset_x_mm - cfg.outline_length_mm / 2
    assert abs(ahead[0].range_mm - (front_x - a.true_pose().x_mm)) <= 3 * LIDAR.sigma_mm + 1e-6


routes = st.lists(
    st.tuples(st.floats(-1200, 1200), st.floats(-700, 700)), min_size=2, max_size=6
).filter(lambda r: sum(math.dist(p, q) for p, q in itertools.pairwise(r)) > 200)


def _cross(p: tuple[float, float], q: tuple[float, float], a: object, b: object) -> float | None:
    """The angle (degrees, 0..90) at which segment pq crosses segment ab, or None."""
    (ax, ay), (bx, by) = a, b  # type: ignore[misc]
    rx, ry, sx, sy = q[0] - p[0], q[1] - p[1], bx - ax, by - ay
    den = rx * sy - ry * sx
    if abs(den) < 1e-9:
        return None
    t = ((ax - p[0]) * sy - (ay - p[1]) * sx) / den
    u = ((ax - p[0]) * ry - (ay - p[1]) * rx) / den
    if not (-1e-9 <= t <= 1 + 1e-9 and -1e-9 <= u <= 1 + 1e-9):
        return None
    cos = abs(rx * sx + ry * sy) / (math.hypot(rx, ry) * math.hypot(sx, sy))
    return math.degrees(math.acos(min(1.0, cos)))


@SLOW
@given(route=routes, seed=st.integers(0, 2**32), n=st.integers(1, 8), r=st.floats(50, 200))
def test_crossing_path_property(
    route: list[tuple[float, float]], seed: int, n: int, r: float
) -> None:
    """Each run of the path (points 2k to 2k+1) crosses the route at 45 degrees or more, and
    every point keeps the opponent on the table, radius + 20 mm from the borders."""
    path = crossing_path(
        route, np.random.default_rng(seed), length_mm=3000, width_mm=2000, radius_mm=r, crossings=n
    )
    assert len(path) == 2 * n
    for x, y in path:
        assert abs(x) <= 1500 - r - 20 + 1e-6 and abs(y) <= 1000 - r - 20 + 1e-6
    for k in range(n):
        p, q = path[2 * k], path[2 * k + 1]
        angles = [_cross(p, q, a, b) for a, b in itertools.pairwise(route)]
        assert any(a is not None and a >= 45 - 1e-6 for a in angles), (p, q, angles)


def test_crossing_opponents_keep_clear_and_are_reproducible() -> None:
    route = [(0, -850), (600, -600), (900, 300), (200, 600)]
    zone = (0.0, -850.0, 450.0)
    for seed in range(30):
        path = crossing_path(
            route,
            np.random.default_rng(seed),
            length_mm=3000,
            width_mm=2000,
            radius_mm=150,
            keep_clear=[zone],
        )
        for p, q in zip(path[::2], path[1::2], strict=True):
            for t in np.linspace(0, 1, 200):
                x, y = p[0] + t * (q[0] - p[0]), p[1] + t * (q[1] - p[1])
                assert math.hypot(x - zone[0], y - zone[1]) > zone[2] - 1
    a, b = Simulator(seed=7, record=False), Simulator(seed=7, record=False)
    ia, ib = a.add_crossing_opponent(route), b.add_crossing_opponent(route)
    a.advance(2.0)
    b.advance(2.0)
    assert a.obstacles()[ia] == b.obstacles()[ib]
    ic = a.add_crossing_opponent(route)  # the second one is another draw
    assert a.obstacles()[ic] != a.obstacles()[ia]


@pytest.mark.parametrize(
    "kwargs",
    [
        {"route": [(0, 0)]},
        {"route": [(0, 0), (0, 0)]},
        {"route": [(0, 0), (500, 0)], "speed_mm_s": 0},
        {"route": [(0, 0), (500, 0)], "radius_mm": -1},
        {"route": [(0, 0), (500, 0)], "crossings": 9},
        {"route": [(0, 0), (500, 0)], "keep_clear": [(0, 0, 5000)]},
    ],
)
def test_bad_crossing_opponents_are_refused_and_change_nothing(kwargs: dict[str, object]) -> None:
    sim = Simulator(record=False)
    before = sim.obstacles()
    with pytest.raises(ValueError):
        sim.add_crossing_opponent(**kwargs)  # type: ignore[arg-type]
    assert sim.obstacles() == before
    assert sim.lidar_targets == set()


def test_the_scenario_command() -> None:
    text = "seed 3\ncrossing_opponent 150 random 0 -850 600 -600 900 300\ngoto 600 -600\nwait\n"
    scn = parse(text)
    sim = scn.simulator(record=False)
    scn.prepare(sim, out=lambda _: None)
    direct = Simulator(seed=3, record=False)
    i = direct.add_crossing_opponent([(0, -850), (600, -600), (900, 300)])
    assert sim.obstacles()[i] == direct.obstacles()[i]
    fixed = parse("crossing_opponent 100 250 0 0 500 0\ngoto 600 -600\n").opponents[0]
    assert (fixed.radius_mm, fixed.speed_mm_s, fixed.route) == (100, 250, [(0, 0), (500, 0)])
    for bad in (
        "crossing_opponent 150 random 0 0\n",
        "crossing_opponent 0 300 0 0 500 0\n",
        "crossing_opponent 150 fast 0 0 500 0\n",
        "crossing_opponent 150 300 0 0 500\n",
        "crossing_opponent 150 300 0 0 5000 0\n",
        "crossing_opponent 150 300 0 0 500 0 loop\n",
    ):
        with pytest.raises(ScenarioError, match=r"<scenario>:1:"):
            parse(bad + "goto 600 -600\n")


def _gap(sim: Simulator, i: int) -> float:
    """The gap between opponent i's disc and our robot's outline, from the truth."""
    ox, oy = sim.obstacles()[i]
    x, y, h = sim.drive_pose()
    c, s = math.cos(math.radians(h)), math.sin(math.radians(h))
    lx, ly = (ox - x) * c + (oy - y) * s, -(ox - x) * s + (oy - y) * c
    cfg = sim.config
    dx = max(abs(lx - cfg.outline_offset_x_mm) - cfg.outline_length_mm / 2, 0.0)
    dy = max(abs(ly - cfg.outline_offset_y_mm) - cfg.outline_width_mm / 2, 0.0)
    return math.hypot(dx, dy) - sim.opponent_radius(i)


ROUTE = [(-900, -400), (-300, 300), (400, -200), (900, 400)]


@settings(max_examples=12, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(seed=st.integers(0, 2**32), where=st.floats(0, 1), heading=st.floats(-180, 180))
def test_yielding_property_a_crossing_opponent_stops_for_a_standing_robot(
    seed: int, where: float, heading: float
) -> None:
    """Our robot stands on the route the opponent crosses: the opponent never touches it (it
    stops about yield_mm away, to within its travel in 10 ms)."""
    sim = Simulator(seed=seed, record=False)
    k = min(int(where * 3), 2)
    f = where * 3 - k
    (ax, ay), (bx, by) = ROUTE[k], ROUTE[k + 1]
    sim.place(ax + f * (bx - ax), ay + f * (by - ay), heading)
    i = sim.add_crossing_opponent(ROUTE, crossings=8)
    gaps: list[float] = []

    def watch(s: Simulator) -> None:
        gaps.append(_gap(s, i))
        s.at(s.time_s + 0.005, watch)

    sim.at(0.0, watch)
    sim.advance(40.0)
    assert min(gaps) > 100 - 0.4 * 10 - 1e-6  # 400 mm/s at most, checked every 10 ms


def test_a_blind_crossing_opponent_may_touch_a_standing_robot() -> None:
    """Without yielding the same opponents do touch (the test above can fail)."""
    touched = 0
    for seed in range(6):
        sim = Simulator(seed=seed, record=False)
        sim.place(-300, 300, 45)
        i = sim.add_crossing_opponent(ROUTE, crossings=8, yield_mm=None)
        gaps: list[float] = []

        def watch(s: Simulator, i: int = i, gaps: list[float] = gaps) -> None:
            gaps.append(_gap(s, i))
            s.at(s.time_s + 0.01, watch)

        sim.at(0.0, watch)
        sim.advance(40.0)
        touched += min(gaps) < 1
    assert touched >= 1


def test_the_server_gives_the_same_scan() -> None:
    from asserv.server import RemoteBus, SimServer

    sim = Simulator(seed=2, record=False)
    sim.add_crossing_opponent(ROUTE)
    with SimServer(sim, "127.0.0.1", 0, speed=0) as server, RemoteBus(*server.address) as bus:
        bus.clock.sleep(0.35)
        remote, local = bus.lidar(), sim.lidar()
    assert (remote.t_s, remote.number) == (pytest.approx(local.t_s, abs=1e-9), local.number)
    assert len(remote.hits) == len(local.hits) > 0
    for r, h in zip(remote.hits, local.hits, strict=True):
        assert r.bearing_deg == h.bearing_deg
        assert r.range_mm == pytest.approx(h.range_mm, abs=0.05)


def test_a_blocked_crossing_opponent_turns_back_after_give_up_s() -> None:
    sim = Simulator(seed=11, record=False)
    i = sim.add_crossing_opponent(ROUTE, crossings=2, speed_mm_s=300)
    y = sim.yielding[i]
    (ax, ay), (bx, by) = y.path[-1], y.path[0]  # its first run: from its start to path[0]
    heading = math.degrees(math.atan2(by - ay, bx - ax)) + 90
    sim.place((ax + bx) / 2, (ay + by) / 2, heading)  # across its way, half-way
    gaps: list[tuple[float, float]] = []

    def watch(s: Simulator) -> None:
        gaps.append((s.time_s, _gap(s, i)))
        s.at(s.time_s + 0.01, watch)

    sim.at(0.0, watch)
    run_s = math.dist((ax, ay), (bx, by)) / 2 / 300
    sim.advance(run_s + 2.0)
    assert y.standing and y.stops == 1 and y.turns == 0
    assert 100 - 3 - 1e-6 <= gaps[-1][1] <= 100
    sim.advance(y.give_up_s + 2.0)
    assert y.turns == 1 and not y.standing
    assert gaps[-1][1] > 100 + 300 * 1.5  # it went back the way it came
    assert min(g for _, g in gaps) > 96
