"""``bench/fusion.py`` and the fusion property: matches on randomized simulated robots, with a
simulated localisation feeding SET_FIX (asserv.fixes) and without, the estimate's error and the
error radius read from the trace at every tick.

A match: the robot starts where it believes (with the start pose error the simulator draws:
within 2 mm on each axis and 0.5 degree, declared to the board as a start radius of 3 mm and
0.5 degree), then drives GOTOs to random points of the field's middle (clear of the baskets) at
1 m/s and 1 m/s^2, each followed by a pause of 0..1 s, until the match's time is up. The same
robot, targets and pauses run with and without fixes.

- error: |estimate - truth| of the position at every tick (ms), over all robots;
- settled moments: the ticks at rest with no order running (``asserv.sim.soak.settled_mask``, as
  the soak of issue 18): the radius's coverage
  (error <= radius) and its tightness (mean radius / p99 of the error) are taken there;
- the fixes: each drawn outlier or good, and what the board did with it (FixRecord.result).
"""

from __future__ import annotations

import math
import random
from dataclasses import dataclass

import numpy as np

from .._protocol import FixResult
from ..driver import Board
from ..fixes import FixSource
from . import Simulator
from .soak import settled_mask

__all__ = ["MatchResult", "Pooled", "pool", "run_match"]

START_RADIUS = (3.0, 0.5)  # what the simulator's start pose error is bounded by [mm], [degrees]
TARGET_X_MM = 1000
TARGET_Y_MM = 500


@dataclass
class MatchResult:
    """One match on one robot."""

    seed: int
    fixes: bool
    calibrated: bool
    err_mm: np.ndarray  # every tick
    settled_err_mm: np.ndarray
    settled_radius_mm: np.ndarray
    outliers: int = 0
    outliers_rejected: int = 0
    good: int = 0
    good_rejected: int = 0


def run_match(
    seed: int,
    duration_s: float,
    source: FixSource | None,
    *,
    setting: tuple[int, int, int] | None = None,
) -> MatchResult:
    """A match on the robot of ``seed``; ``setting`` (ratio_ppm, track_10um, scale_ppm): a
    calibration to install first (SET_ODOMETRIE)."""
    sim = Simulator(seed=seed, randomize=True, start_uncertainty=START_RADIUS)
    board = Board(sim.bus)
    if setting is not None:
        board.set_odometrie(*setting)
    board.set_vitesse_traj(100, 100)
    board.set_vitesse_rot(50, 100)
    feed = sim.add_fix_source(source) if source is not None else None
    rng = random.Random(seed)
    while sim.time_s < duration_s:
        board.goto(rng.randint(-TARGET_X_MM, TARGET_X_MM), rng.randint(-TARGET_Y_MM, TARGET_Y_MM))
        board.wait_idle(max(0.5, duration_s + 30 - sim.time_s), poll_s=0.02)
        sim.advance(rng.uniform(0.0, 1.0))
    tr = sim.trace
    tr = tr[tr["t_s"] <= duration_s]
    err = np.hypot(tr["est_x_mm"] - tr["x_mm"], tr["est_y_mm"] - tr["y_mm"])
    settled = settled_mask(tr)
    res = MatchResult(
        seed, source is not None, setting is not None, err, err[settled], tr["radius_mm"][settled]
    )
    if feed is not None:
        judged = [r for r in feed.log if r.result >= 0]
        res.outliers = sum(r.outlier for r in judged)
        res.outliers_rejected = sum(r.outlier and r.result != FixResult.FUSED for r in judged)
        res.good = sum(not r.outlier for r in judged)
        res.good_rejected = sum(not r.outlier and r.result != FixResult.FUSED for r in judged)
    return res


@dataclass
class Pooled:
    """The figures over a set of matches."""

    err_p95_mm: float
    err_max_mm: float
    coverage_pct: float
    tightness: float
    outliers: int
    outliers_rejected: int
    good: int
    good_rejected: int


def pool(results: list[MatchResult]) -> Pooled:
    err = np.concatenate([r.err_mm for r in results])
    s_err = np.concatenate([r.settled_err_mm for r in results])
    s_rad = np.concatenate([r.settled_radius_mm for r in results])
    p99 = float(np.percentile(s_err, 99)) if len(s_err) else math.nan
    return Pooled(
        float(np.percentile(err, 95)),
        float(err.max()),
        # 255 reads "255 mm or more" (docs/protocol.md 6.2): it covers any error
        100.0 * float(np.mean((s_err <= s_rad) | (s_rad >= 255))) if len(s_err) else math.nan,
        float(np.mean(s_rad)) / p99 if p99 > 0 else math.nan,
        sum(r.outliers for r in results),
        sum(r.outliers_rejected for r in results),
        sum(r.good for r in results),
        sum(r.good_rejected for r in results),
    )
