"""A simulated 2D lidar on the robot, and opponents on random paths that cross a route.

    sim = Simulator(seed=3)
    sim.add_crossing_opponent([(0, -850), (600, -600), (900, 300)])   # crosses that route
    scan = sim.lidar()                    # the last full scan: range and bearing of each hit
    for hit in scan.hits:
        print(hit.bearing_deg, hit.range_mm)

The lidar (``LIDAR``, docs/simulator.md "Lidar") sits on the robot's reference point (the
encoder axis midpoint, ``Simulator.true_pose``) above the borders and the field's elements, as
Eurobot teams mount theirs on a mast: it sees the opponents only (the discs of
``add_opponent``, and the other robots of an ``Arena``). It turns ``beams`` times per scan, one
beam every ``360 / beams`` degrees from straight ahead, counterclockwise; a scan is taken
``scan_hz`` times per simulated second, all its beams at one instant (the robot's motion within
a scan is neglected). Each range has a noise drawn from a normal law of ``sigma_mm``, cut at
``3 sigma_mm``, from the simulator's seed and the scan's number: the same simulator, driven the
same way, sees the same scans.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any, NamedTuple, Protocol

import numpy as np

__all__ = [
    "LIDAR",
    "LidarHit",
    "LidarScan",
    "LidarSpec",
    "Target",
    "Yielding",
    "crossing_path",
    "scan_targets",
]


class LidarSpec(NamedTuple):
    """What the simulated lidar is: beams per turn, scans per second, range noise and limits."""

    beams: int  # one beam every 360 / beams degrees, the first straight ahead
    scan_hz: float  # full scans per second of simulated time
    sigma_mm: float  # standard deviation of the range noise, cut at 3 sigma
    min_mm: float  # nearer than this, nothing is seen (the mast, the robot's own top)
    max_mm: float  # farther than this, nothing is seen


#: The simulated lidar: 360 beams (1 degree), 10 scans a second, 10 mm of range noise, 0.05 to
#: 3.6 m (the diagonal of the 3 m x 2 m table).
LIDAR = LidarSpec(beams=360, scan_hz=10.0, sigma_mm=10.0, min_mm=50.0, max_mm=3600.0)


class LidarHit(NamedTuple):
    """One beam that met an opponent: its bearing from the robot's heading (degrees,
    counterclockwise, -180..180) and the measured range (mm, noise included)."""

    bearing_deg: float
    range_mm: float


class LidarScan(NamedTuple):
    """A full scan: when it was taken (simulated s), its number since the lidar started, and
    the beams that met something (the nearest opponent along each; the others saw nothing)."""

    t_s: float
    number: int
    hits: tuple[LidarHit, ...]

    def points(self, x_mm: float, y_mm: float, heading_deg: float) -> list[tuple[float, float]]:
        """The hits on the field, seen from the pose (x, y, heading) the robot believes it
        had at the scan (the board's POSITION, or the truth in a test)."""
        out = []
        for h in self.hits:
            a = math.radians(heading_deg + h.bearing_deg)
            out.append((x_mm + h.range_mm * math.cos(a), y_mm + h.range_mm * math.sin(a)))
        return out

    def nearest(self, half_width_deg: float = 180.0) -> LidarHit | None:
        """The nearest hit within ``half_width_deg`` of straight ahead, or None."""
        best = None
        for h in self.hits:
            if abs(h.bearing_deg) <= half_width_deg and (
                best is None or h.range_mm < best.range_mm
            ):
                best = h
        return best


class Target(NamedTuple):
    """What a beam can meet: a disc (``half_x_mm == 0``) or a box turned by ``heading_deg``."""

    x_mm: float
    y_mm: float
    radius_mm: float = 0.0
    half_x_mm: float = 0.0
    half_y_mm: float = 0.0
    heading_deg: float = 0.0


def _ray_distances(ox: float, oy: float, ux: np.ndarray, uy: np.ndarray, t: Target) -> np.ndarray:
    """Distance along each unit ray (ux, uy) from (ox, oy) to where it enters target t; inf
    where it misses, 0 where the origin is inside."""
    if t.half_x_mm > 0 or t.half_y_mm > 0:
        # The slab method in the box's frame (Kay and Kajiya, 1986).
        c, s = math.cos(math.radians(t.heading_deg)), math.sin(math.radians(t.heading_deg))
        px, py = (ox - t.x_mm) * c + (oy - t.y_mm) * s, -(ox - t.x_mm) * s + (oy - t.y_mm) * c
        dx, dy = ux * c + uy * s, -ux * s + uy * c
        near = np.zeros_like(ux)
        far = np.full_like(ux, np.inf)
        for p, d, h in ((px, dx, t.half_x_mm), (py, dy, t.half_y_mm)):
            with np.errstate(divide="ignore", invalid="ignore"):
                t1, t2 = (-h - p) / d, (h - p) / d
            lo, hi = np.minimum(t1, t2), np.maximum(t1, t2)
            parallel = d == 0
            lo = np.where(parallel, np.where(abs(p) <= h, -np.inf, np.inf), lo)
            hi = np.where(parallel, np.where(abs(p) <= h, np.inf, -np.inf), hi)
            near, far = np.maximum(near, lo), np.minimum(far, hi)
        return np.where(near <= far, near, np.inf)
    wx, wy = t.x_mm - ox, t.y_mm - oy
    b = ux * wx + uy * wy  # along the ray to the centre's foot
    c2 = wx * wx + wy * wy - t.radius_mm * t.radius_mm
    if c2 <= 0:
        return np.zeros_like(ux)
    disc = b * b - c2
    with np.errstate(invalid="ignore"):
        d = b - np.sqrt(disc)
    return np.where((disc >= 0) & (b > 0), d, np.inf)


def scan_targets(
    x_mm: float,
    y_mm: float,
    heading_deg: float,
    targets: Sequence[Target],
    rng: np.random.Generator | None,
    spec: LidarSpec = LIDAR,
) -> tuple[LidarHit, ...]:
    """The hits of one scan from (x, y, heading) on ``targets``; ``rng`` draws the range noise
    (None: exact ranges, for tests of the geometry)."""
    bearings = np.arange(spec.beams) * (360.0 / spec.beams)
    a = np.radians(heading_deg + bearings)
    ux, uy = np.cos(a), np.sin(a)
    best = np.full(spec.beams, np.inf)
    for t in targets:
        best = np.minimum(best, _ray_distances(x_mm, y_mm, ux, uy, t))
    noise = np.zeros(spec.beams)
    if rng is not None:
        cut = 3 * spec.sigma_mm
        noise = np.clip(rng.normal(0.0, spec.sigma_mm, spec.beams), -cut, cut)
    seen = (best >= spec.min_mm) & (best <= spec.max_mm)
    wrapped = (bearings + 180.0) % 360.0 - 180.0
    return tuple(
        LidarHit(float(wrapped[i]), float(best[i] + noise[i])) for i in np.flatnonzero(seen)
    )


def crossing_path(
    route: Sequence[tuple[float, float]],
    rng: np.random.Generator,
    *,
    length_mm: float,
    width_mm: float,
    radius_mm: float,
    crossings: int = 4,
    keep_clear: Sequence[tuple[float, float, float]] = (),
) -> list[tuple[float, float]]:
    """A random looping path for an opponent of ``radius_mm`` that crosses ``route`` (a
    polyline of two points or more) ``crossings`` times (1..8): each crossing is a straight run
    from one side of the table to the other through a random point of the route, at 45 to 135
    degrees to the route's leg there, kept ``radius_mm`` + 20 mm inside the borders. A run that
    would pass within r of a point (x, y, r) of ``keep_clear`` (a start area) is drawn again."""
    if len(route) < 2:
        raise ValueError("crossing_path: the route needs two points or more")
    if not 1 <= crossings <= 8:
        raise ValueError(f"crossing_path: crossings must be 1..8, not {crossings}")
    pts = np.asarray(route, dtype=float)
    legs = np.diff(pts, axis=0)
    lengths = np.hypot(legs[:, 0], legs[:, 1])
    if not lengths.sum() > 0:
        raise ValueError("crossing_path: the route has no length")
    hx, hy = length_mm / 2 - radius_mm - 20, width_mm / 2 - radius_mm - 20
    if not (hx > 0 and hy > 0):
        raise ValueError("crossing_path: the opponent does not fit on the table")
    path: list[tuple[float, float]] = []
    for _ in range(crossings):
        for _attempt in range(1000):
            s = rng.uniform(0, lengths.sum())
            k = min(int(np.searchsorted(np.cumsum(lengths), s)), len(legs) - 1)
            f = (s - (np.cumsum(lengths)[k] - lengths[k])) / lengths[k]
            cx, cy = pts[k] + f * legs[k]
            if not (abs(cx) < hx and abs(cy) < hy):
                continue
            leg_angle = math.atan2(legs[k][1], legs[k][0])
            a = leg_angle + math.radians(rng.uniform(45, 135)) * rng.choice((-1, 1))
            dx, dy = math.cos(a), math.sin(a)
            ends = _clip_line(cx, cy, dx, dy, hx, hy)
            if all(_line_clear(ends, k_) for k_ in keep_clear):
                break
        else:
            raise ValueError("crossing_path: no crossing keeps clear of keep_clear")
        # Go on from the end nearer to where the path is.
        if path and math.dist(path[-1], ends[1]) < math.dist(path[-1], ends[0]):
            ends = (ends[1], ends[0])
        path.extend(ends)
    return path


def _clip_line(
    cx: float, cy: float, dx: float, dy: float, hx: float, hy: float
) -> tuple[tuple[float, float], tuple[float, float]]:
    """Where the line through (cx, cy) along (dx, dy) leaves the box |x| <= hx, |y| <= hy."""
    lo, hi = -math.inf, math.inf
    for p, d, h in ((cx, dx, hx), (cy, dy, hy)):
        if abs(d) > 1e-12:
            t1, t2 = (-h - p) / d, (h - p) / d
            lo, hi = max(lo, min(t1, t2)), min(hi, max(t1, t2))
    return (cx + lo * dx, cy + lo * dy), (cx + hi * dx, cy + hi * dy)


def _line_clear(
    ends: tuple[tuple[float, float], tuple[float, float]], zone: tuple[float, float, float]
) -> bool:
    (ax, ay), (bx, by) = ends
    x, y, r = zone
    vx, vy = bx - ax, by - ay
    t = max(0.0, min(1.0, ((x - ax) * vx + (y - ay) * vy) / (vx * vx + vy * vy)))
    return math.hypot(ax + t * vx - x, ay + t * vy - y) > r


def outline_gap(
    cx: float, cy: float, r: float, x: float, y: float, heading_deg: float, hl: float, hw: float
) -> tuple[float, float, float]:
    """The gap (mm) between the disc (cx, cy, r) and a box of half length hl and half width hw
    centred at (x, y) turned by heading_deg, and the box's point nearest the disc's centre."""
    c, s = math.cos(math.radians(heading_deg)), math.sin(math.radians(heading_deg))
    lx, ly = (cx - x) * c + (cy - y) * s, -(cx - x) * s + (cy - y) * c
    nx, ny = max(-hl, min(hl, lx)), max(-hw, min(hw, ly))
    gap = math.hypot(lx - nx, ly - ny) - r
    return gap, x + nx * c - ny * s, y + nx * s + ny * c


class _Sim(Protocol):
    """What Yielding needs of ``asserv.sim.Simulator`` (which imports this module)."""

    @property
    def time_s(self) -> float: ...
    @property
    def config(self) -> Any: ...
    def obstacles(self) -> list[tuple[float, float]]: ...
    def drive_pose(self) -> tuple[float, float, float]: ...
    def opponent_radius(self, i: int) -> float: ...
    def set_opponent_path(
        self, i: int, path: Sequence[tuple[float, float]], speed_mm_s: float = ..., loop: bool = ...
    ) -> None: ...
    def at(self, t_s: float, fn: Any) -> None: ...


class Yielding:
    """An opponent that, as every Eurobot robot must, stops for what is ahead of it: while our
    robot's outline is within ``gap_mm`` of its disc, less than 90 degrees off its direction of
    travel, it stands; it goes on along its loop once the gap is ``gap_mm`` + 50 mm or our robot
    is no longer ahead. After ``give_up_s`` standing it gives its way up, as our strategy does:
    it turns back and runs its loop the other way. It does not stop for a robot that comes at
    its side or its back. ``Simulator.add_crossing_opponent`` runs it every 10 ms of simulated
    time."""

    PERIOD_S = 0.01

    def __init__(
        self,
        index: int,
        path: list[tuple[float, float]],
        speed_mm_s: float,
        gap_mm: float,
        give_up_s: float = 4.0,
    ) -> None:
        self.index, self.path, self.speed_mm_s, self.gap_mm = index, path, speed_mm_s, gap_mm
        self.give_up_s = give_up_s
        self.next = 0  # the point of path it heads for
        self.standing = False
        self.since = 0.0  # when it stopped
        self.stops = 0  # how many times it stood for our robot
        self.turns = 0  # how many times it gave its way up

    def _track(self, ox: float, oy: float) -> None:
        """Follow which point it heads for: it is on the run from the previous point to it."""
        n = len(self.path)
        for _ in range(n):
            (ax, ay), (bx, by) = self.path[self.next - 1], self.path[self.next]
            vx, vy = bx - ax, by - ay
            t = ((ox - ax) * vx + (oy - ay) * vy) / max(vx * vx + vy * vy, 1e-12)
            on = math.hypot(ax + t * vx - ox, ay + t * vy - oy) < 1.0
            if on and -1e-6 <= t < 1 - 1e-9:
                return
            self.next = (self.next + 1) % n

    def step(self, sim: _Sim) -> None:
        """One check (a timed event of ``sim``, which schedules the next)."""
        ox, oy = sim.obstacles()[self.index]
        if not self.standing:
            self._track(ox, oy)
        bx, by = self.path[self.next]
        heading = math.atan2(by - oy, bx - ox)
        cfg = sim.config
        x, y, h = sim.drive_pose()
        c, s = math.cos(math.radians(h)), math.sin(math.radians(h))
        x += cfg.outline_offset_x_mm * c - cfg.outline_offset_y_mm * s
        y += cfg.outline_offset_x_mm * s + cfg.outline_offset_y_mm * c
        r = sim.opponent_radius(self.index)
        gap, px, py = outline_gap(
            ox, oy, r, x, y, h, cfg.outline_length_mm / 2, cfg.outline_width_mm / 2
        )
        ahead = (px - ox) * math.cos(heading) + (py - oy) * math.sin(heading) > 0
        if not self.standing and ahead and gap < self.gap_mm:
            self.standing, self.since = True, sim.time_s
            self.stops += 1
            sim.set_opponent_path(self.index, [], self.speed_mm_s)
        elif self.standing and sim.time_s - self.since > self.give_up_s:
            # Back to the point it came from, round its loop the other way.
            n = len(self.path)
            self.path = self.path[::-1]
            self.next = (n - self.next) % n
            self.turns += 1
            self.since = sim.time_s  # and it may stand again for as long, if still blocked
            bx, by = self.path[self.next]
            heading = math.atan2(by - oy, bx - ox)
            if (px - ox) * math.cos(heading) + (py - oy) * math.sin(heading) <= 0:
                self.standing = False
                rest = self.path[self.next :] + self.path[: self.next]
                sim.set_opponent_path(self.index, rest, self.speed_mm_s, loop=True)
        elif self.standing and (gap > self.gap_mm + 50 or not ahead):
            self.standing = False
            rest = self.path[self.next :] + self.path[: self.next]
            sim.set_opponent_path(self.index, rest, self.speed_mm_s, loop=True)
        sim.at(sim.time_s + self.PERIOD_S, self.step)
