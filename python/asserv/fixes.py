"""A simulated position-fix source (a lidar on beacons, a camera) feeding SET_FIX to the board.

    sim = Simulator(seed=1, randomize=True)
    feed = sim.add_fix_source(FixSource(rate_hz=10, sigma_mm=10, sigma_deg=1, latency_ms=100))

Every ``1 / rate_hz`` s the source measures the robot's true pose at that moment (the encoder
axis midpoint, as the board's estimate), adds Gaussian noise of the declared standard deviations,
and with probability ``outlier_rate`` replaces it by an outlier (a reflection, a wrong beacon:
``outlier_mm`` away in a random direction, the heading ``outlier_deg`` off). The fix is written
``latency_ms`` (+- ``latency_jitter_ms``, uniform, within 0..500 ms) later, with its age, as the
master's localisation process would: ``Board.fix(x, y, heading, sigma_mm, sigma_deg, age_ms)``.
Its frame reaches the board at once between two transactions of the master (a second thread's
write; a transaction in progress delays it by 0.5 ms steps). ``feed.log`` keeps every fix with
the truth behind it, for benches and tests (bench/fusion.py).
"""

from __future__ import annotations

import math
import random
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

from . import codec
from ._protocol import FixResult

if TYPE_CHECKING:
    from .sim import Simulator

__all__ = ["FixFeed", "FixRecord", "FixSource"]


@dataclass(frozen=True)
class FixSource:
    """The localisation's model: rate [Hz], noise (standard deviations [mm], [degrees]; None: no
    heading), latency [ms] and its uniform jitter, outlier rate (0..1) and their size, seed."""

    rate_hz: float = 10.0
    sigma_mm: float = 10.0
    sigma_deg: float | None = 1.0
    latency_ms: float = 100.0
    latency_jitter_ms: float = 50.0
    outlier_rate: float = 0.01
    outlier_mm: tuple[float, float] = (150.0, 600.0)
    outlier_deg: tuple[float, float] = (10.0, 60.0)
    seed: int = 0

    def __post_init__(self) -> None:
        if not 0 < self.rate_hz <= 100:
            raise ValueError(f"FixSource: rate_hz={self.rate_hz} must be 0..100")
        if not 1 <= self.sigma_mm <= 255:
            raise ValueError(f"FixSource: sigma_mm={self.sigma_mm} must be 1..255")
        if self.sigma_deg is not None and not 0.1 <= self.sigma_deg <= 25.5:
            raise ValueError(f"FixSource: sigma_deg={self.sigma_deg} must be 0.1..25.5 or None")
        lo, hi = self.latency_ms - self.latency_jitter_ms, self.latency_ms + self.latency_jitter_ms
        if not (self.latency_jitter_ms >= 0 and lo >= 0 and hi <= 500):
            raise ValueError("FixSource: latency_ms +- latency_jitter_ms must stay within 0..500")
        if not 0 <= self.outlier_rate <= 1:
            raise ValueError(f"FixSource: outlier_rate={self.outlier_rate} must be 0..1")
        for name in ("outlier_mm", "outlier_deg"):
            lo, hi = getattr(self, name)
            if not (0 <= lo <= hi < math.inf):
                raise ValueError(
                    f"FixSource: {name}={(lo, hi)} must be (low, high), 0 <= low <= high"
                )


@dataclass
class FixRecord:
    """One fix: when it was measured and sent [s], the truth then, what was sent, and whether it
    was drawn as an outlier."""

    t_measured_s: float
    true_x_mm: float
    true_y_mm: float
    true_heading_deg: float
    x_mm: float
    y_mm: float
    heading_deg: float | None
    outlier: bool
    t_sent_s: float = math.nan
    age_ms: int = -1
    result: int = -1  # FixResult: the first change of the board's counters after the write


@dataclass
class FixFeed:
    """The running source: ``log`` of every fix, ``stop()`` to end it."""

    source: FixSource
    log: list[FixRecord] = field(default_factory=list)
    active: bool = True

    def stop(self) -> None:
        self.active = False


def _wrap_deg(a: float) -> float:
    return (a + 180.0) % 360.0 - 180.0


def start(sim: Simulator, source: FixSource) -> FixFeed:
    """Schedule the source on ``sim`` (``Simulator.add_fix_source``)."""
    feed = FixFeed(source)
    rng = random.Random(source.seed)
    period = 1.0 / source.rate_hz

    def measure(s: Simulator) -> None:
        if not feed.active:
            return
        t = s.true_pose()
        outlier = rng.random() < source.outlier_rate
        x = t.x_mm + rng.gauss(0.0, source.sigma_mm)
        y = t.y_mm + rng.gauss(0.0, source.sigma_mm)
        h = None
        if source.sigma_deg is not None:
            h = t.heading_deg + rng.gauss(0.0, source.sigma_deg)
        if outlier:
            d, a = rng.uniform(*source.outlier_mm), rng.uniform(0, 2 * math.pi)
            x, y = x + d * math.cos(a), y + d * math.sin(a)
            if h is not None:
                h += rng.choice((-1, 1)) * rng.uniform(*source.outlier_deg)
        rec = FixRecord(
            s.time_s,
            t.x_mm,
            t.y_mm,
            t.heading_deg,
            x,
            y,
            None if h is None else _wrap_deg(h),
            outlier,
        )
        feed.log.append(rec)
        latency = source.latency_ms + rng.uniform(-1, 1) * source.latency_jitter_ms
        s.at(s.time_s + latency / 1000.0, lambda s2: send(s2, rec))
        s.at(s.time_s + period, measure)

    def send(s: Simulator, rec: FixRecord) -> None:
        if not feed.active:
            return
        if s.bus_busy:
            s.at(s.time_s + 0.0005, lambda s2: send(s2, rec))
            return
        age = min(500, max(0, round((s.time_s - rec.t_measured_s) * 1000)))
        x = max(-32000, min(32000, round(rec.x_mm)))
        y = max(-32000, min(32000, round(rec.y_mm)))
        heading = 0 if rec.heading_deg is None else round(rec.heading_deg * 100)
        sigma_deg = source.sigma_deg
        frame = codec.encode(
            "SET_FIX",
            x,
            y,
            max(-18000, min(18000, heading)),
            math.ceil(source.sigma_mm),
            0 if sigma_deg is None else math.ceil(sigma_deg * 10 - 1e-9),
            age,
        )
        before = s.fix_counts()
        s.write_now(frame)
        rec.t_sent_s = s.time_s
        rec.age_ms = age
        s.at(s.time_s + 0.001, lambda s2: judge(s2, rec, before, 50))

    def judge(s: Simulator, rec: FixRecord, before: tuple[int, int, int, int], n: int) -> None:
        # The board takes the fixes in the order they came: the first change of its counters
        # after the write is this fix's (within 50 ms: it may wait for the radius's batch).
        after = s.fix_counts()
        if after[:3] == before[:3]:
            if n > 0:
                s.at(s.time_s + 0.001, lambda s2: judge(s2, rec, before, n - 1))
            return
        if after[0] != before[0]:
            rec.result = FixResult.FUSED
        elif after[1] != before[1]:
            rec.result = FixResult.OUTLIER
        elif after[2] != before[2]:
            rec.result = after[3]

    sim.at(sim.time_s + period, measure)
    return feed
