"""The board's promises under a match's conditions: a random master drives a random robot.

A *match* is a robot drawn off the shelf (``Simulator(randomize=True)``), calibrated or not, and
a master that sends random orders (GOTO with and without line and border recalibration,
GOTO_REVERSE, GOTO_PANIER, STOP), replaces orders before they end, changes the settings, writes
malformed frames, and injects faults (an encoder wire cut then repaired, a stuck motor, a
slippery patch). Everything random comes from one ``random.Random``: the tests draw it with
hypothesis (``python/tests/test_soak.py``), the bench from a seed (``bench/soak.py``).

What is checked, from the simulator's trace (one row per control tick):

- **the radius bounds the error**: at every *settled* tick (the robot at rest and no order
  running) and at every order's end, the distance between the board's estimate and the truth is
  within the radius the board reports;
- **endings say what happened**: when an order ends, the status's end bits agree with DEBUG's
  end reason;
- **a stop stops**: after a shock that ends an order, the robot never drives back toward the
  obstacle once it has come to rest.

``MatchResult`` keeps the counts, so that a soak of many matches prints its coverage.
"""

from __future__ import annotations

import random
from collections.abc import Callable
from dataclasses import dataclass, field
from functools import partial

import numpy as np

from .. import codec
from .._protocol import EndReason, Status
from ..calibration import OdometrySetting
from ..driver import AsservError, Board
from . import Simulator

__all__ = ["MatchResult", "ideal_calibration", "play_match", "settled_mask"]

#: A tick is settled when the robot is at rest: true speed and turn rate below these.
SETTLED_MM_S = 2.0
SETTLED_DEG_S = 1.0

# The field of field/default.toml: targets are kept this far inside the borders.
HALF_X_MM, HALF_Y_MM = 1500, 1050
MARGIN_MM = 260
END_BITS = Status.CHOC_BORD | Status.CHOC_PANIER | Status.PB_MOTEUR | Status.PB_GRAVE

# Which end bits each DEBUG end reason may come with (docs/protocol.md, the endings table).
ENDING_BITS: dict[int, set[int]] = {
    EndReason.DONE: {0},
    EndReason.STOPPED: {0},
    EndReason.TIMEOUT: {int(Status.PB_MOTEUR)},  # abandoned, not finished (SET_TIMEOUT)
    EndReason.BORDER: {int(Status.CHOC_BORD)},
    EndReason.BASKET: {int(Status.CHOC_PANIER)},
    EndReason.SHOCK: {int(Status.CHOC_BORD), int(Status.CHOC_PANIER)},
    EndReason.MOTOR: {int(Status.PB_MOTEUR)},
    EndReason.FAULT: {int(Status.PB_GRAVE), int(Status.PB_GRAVE | Status.PB_MOTEUR)},
    EndReason.NO_BASKET: {int(Status.PB_MOTEUR)},
    EndReason.RESET: {int(Status.PB_MOTEUR)},
}


@dataclass
class MatchResult:
    """What one match showed."""

    robot: str
    calibrated: bool
    settled_ticks: int = 0
    settled_covered: int = 0
    worst_settled_ratio: float = 0.0  # the largest error / radius at a settled tick, radius < 255
    order_ends: int = 0
    ends_covered: int = 0
    worst_end: tuple[float, int] = (0.0, 0)  # (error mm, radius mm) of the worst end
    bad_endings: list[str] = field(default_factory=list)
    events: list[str] = field(default_factory=list)

    @property
    def settled_coverage(self) -> float:
        return self.settled_covered / self.settled_ticks if self.settled_ticks else 1.0

    @property
    def end_coverage(self) -> float:
        return self.ends_covered / self.order_ends if self.order_ends else 1.0


def ideal_calibration(sim: Simulator) -> OdometrySetting:
    """SET_ODOMETRIE's values for this robot's true wheels (what a perfect calibration finds)."""
    sc = sim.config
    left, right = (1 + sc.enc_radius_error[0], 1 + sc.enc_radius_error[1])
    scale = (left + right) / 2
    ratio = (right - left) / scale
    track_mm = sc.enc_track_mm + sc.enc_track_error_mm
    return OdometrySetting(round(ratio * 1e6), round(track_mm * 100), round((scale - 1) * 1e6))


def _calibrate(board: Board, sim: Simulator, rng: random.Random) -> OdometrySetting:
    """A calibration as the procedure of calibration.py leaves it: the ideal values off by
    residuals within what docs/calibration.md measures (ratio 290 ppm, track 65 um, scale
    440 ppm at most), inside the board's calibrated bounds."""
    ideal = ideal_calibration(sim)
    setting = OdometrySetting(
        ideal.ratio_ppm + rng.randint(-290, 290),
        ideal.track_10um + rng.randint(-6, 6),
        ideal.scale_ppm + rng.randint(-440, 440),
    )
    board.set_odometrie(setting.ratio_ppm, setting.track_10um, setting.scale_ppm)
    return setting


def _target(rng: random.Random) -> tuple[int, int]:
    return (
        rng.randint(-HALF_X_MM + MARGIN_MM, HALF_X_MM - MARGIN_MM),
        rng.randint(-HALF_Y_MM + MARGIN_MM, HALF_Y_MM - MARGIN_MM),
    )


def _border_target(rng: random.Random, pose: codec.Pose) -> tuple[int, int]:
    """A point on a border near the robot: a GOTO with border recalibration drives into it."""
    side = rng.randrange(4)
    if side < 2:
        x = HALF_X_MM if side else -HALF_X_MM
        return x, max(-700, min(700, pose.y_mm + rng.randint(-300, 300)))
    y = HALF_Y_MM if side == 3 else -HALF_Y_MM
    return max(-1100, min(1100, pose.x_mm + rng.randint(-300, 300))), y


def _line_target(rng: random.Random, pose: codec.Pose) -> tuple[int, int]:
    """A target across a painted line (x = -750, 0, 750 or y = 0), with line recalibration."""
    if rng.random() < 0.75:
        line_x = rng.choice((-750, 0, 750))
        x = line_x + (300 if pose.x_mm < line_x else -300)
        return x, max(-700, min(700, pose.y_mm + rng.randint(-150, 150)))
    y = 300 if pose.y_mm < 0 else -300
    return max(-1200, min(1200, pose.x_mm + rng.randint(-150, 150))), y


def _malformed(rng: random.Random) -> bytes:
    kind = rng.randrange(3)
    if kind == 0:  # random bytes
        return bytes(rng.randrange(256) for _ in range(rng.randint(1, 9)))
    frame = codec.encode("GOTO", *_target(rng), 0)
    if kind == 1:  # truncated
        return frame[: rng.randint(1, len(frame) - 1)]
    return frame + bytes([rng.randrange(256)])  # a wrong PEC (or a wrong length)


def play_match(
    rng: random.Random,
    *,
    duration_s: float = 30.0,
    calibrated: bool | None = None,
    faults: bool = True,
    on_step: Callable[[Simulator], None] | None = None,
) -> MatchResult:
    """One match of ``duration_s`` simulated seconds; returns what was checked."""
    seed = rng.randrange(2**32)
    calibrated = rng.random() < 0.5 if calibrated is None else calibrated
    sim = Simulator(seed=seed, randomize=True, start_uncertainty=(3.0, 0.5))
    board = Board(sim.bus)
    result = MatchResult(sim.describe_robot(), calibrated)
    if calibrated:
        result.events.append(f"calibrated: {_calibrate(board, sim, rng)}")
    board.set_vitesse_traj(rng.randint(30, 120), rng.randint(40, 150))
    board.set_vitesse_rot(rng.randint(30, 100), rng.randint(40, 150))
    ends: list[tuple[int, int, int]] = []  # (tick, status, end reason) of each order end
    busy = False
    cut: list[tuple[float, Callable[[], None]]] = []  # pending repairs

    def poll() -> None:
        nonlocal busy
        status = board.check_busy()
        now_busy = bool(status & Status.BUSY_TRAJET)
        if busy and not now_busy:
            ends.append((sim.ticks, int(status & END_BITS), int(board.debug().end_reason)))
        busy = now_busy

    def wait(seconds: float) -> None:
        end = sim.time_s + seconds
        while sim.time_s < end:
            for when, repair in list(cut):
                if sim.time_s >= when:
                    repair()
                    cut.remove((when, repair))
            sim.advance(min(0.01, end - sim.time_s))
            poll()
            if on_step is not None:
                on_step(sim)

    while sim.time_s < duration_s:
        roll = rng.random()
        try:
            pose = board.position()
            if roll < 0.35:
                board.goto(*_target(rng))
            elif roll < 0.47:
                board.goto(*_line_target(rng, pose), 1)
            elif roll < 0.55:
                board.goto(*_border_target(rng, pose), 2)
            elif roll < 0.62:
                board.goto_reverse(rng.randint(0, 255))
            elif roll < 0.67:
                board.goto_panier(rng.choice((45, 90, 135, -45, -90, -135, 0, 180)))
            elif roll < 0.71:
                board.stop()
            elif roll < 0.77:
                board.set_vitesse_traj(rng.randint(10, 150), rng.randint(20, 200))
                board.set_vitesse_rot(rng.randint(10, 100), rng.randint(20, 150))
            elif roll < 0.80:
                board.set_filtre(rng.randrange(3))
            elif roll < 0.85:
                sim.i2c_write(_malformed(rng), True)
            elif roll < 0.92 and faults:
                what, wheel = rng.randrange(3), rng.randrange(2)
                at = sim.time_s + rng.uniform(0.05, 2.0)  # repaired then
                if what == 0:
                    sim.set_encoder_cut(wheel, True)
                    cut.append((at, partial(sim.set_encoder_cut, wheel, False)))
                    result.events.append(f"{sim.time_s:.2f} s: free wheel {wheel} cut")
                elif what == 1:
                    sim.set_motor_stuck(wheel, True)
                    cut.append((at, partial(sim.set_motor_stuck, wheel, False)))
                    result.events.append(f"{sim.time_s:.2f} s: motor {wheel} stuck")
                else:
                    sim.set_friction_scale(wheel, rng.uniform(0.0, 0.3))
                    cut.append((at, partial(sim.set_friction_scale, wheel, 1.0)))
                    result.events.append(f"{sim.time_s:.2f} s: wheel {wheel} slips")
        except AsservError as e:  # a refused order (PB_GRAVE, out of range) is an answer too
            result.events.append(f"{sim.time_s:.2f} s: {type(e).__name__}")
        # Replace the order soon, or let it run to its end.
        wait(rng.choice((0.05, 0.3, 1.0, 3.0, 6.0)))
    for _, repair in cut:
        repair()
    wait(3.0)  # settle
    _check(sim, ends, result)
    return result


def settled_mask(trace: np.ndarray) -> np.ndarray:
    """The settled ticks: at rest (true speeds below the thresholds) and no order running."""
    busy = (trace["status"].astype(np.int64) & int(Status.BUSY_TRAJET)) != 0
    mask: np.ndarray = (
        (np.abs(trace["v_mm_s"]) < SETTLED_MM_S)
        & (np.abs(trace["omega_deg_s"]) < SETTLED_DEG_S)
        & ~busy
    )
    return mask


def _check(sim: Simulator, ends: list[tuple[int, int, int]], r: MatchResult) -> None:
    tr = sim.trace
    err = np.hypot(tr["x_mm"] - tr["est_x_mm"], tr["y_mm"] - tr["est_y_mm"])
    radius = tr["radius_mm"]
    settled = settled_mask(tr)
    r.settled_ticks = int(np.count_nonzero(settled))
    # 255 reads "255 mm or more": it bounds any error.
    covered = (err <= radius) | (radius >= 255)
    r.settled_covered = int(np.count_nonzero(settled & covered))
    known = settled & (radius < 255)
    if np.any(known):
        r.worst_settled_ratio = float((err[known] / np.maximum(radius[known], 1e-9)).max())
    first_tick = int(tr["t_s"][0] * 1000 + 0.5) if len(tr) else 0
    for tick, bits, reason in ends:
        row = min(max(tick - first_tick, 0), len(tr) - 1)
        r.order_ends += 1
        e, rad = float(err[row]), int(radius[row])
        if e <= rad or rad >= 255:
            r.ends_covered += 1
        if e - rad > r.worst_end[0] - r.worst_end[1]:
            r.worst_end = (e, rad)
        allowed = ENDING_BITS.get(reason)
        # PB_GRAVE latches: once set it stays with every later ending.
        if allowed is None or (bits & ~int(Status.PB_GRAVE)) not in {
            b & ~int(Status.PB_GRAVE) for b in allowed
        }:
            name = EndReason(reason).name if reason in EndReason._value2member_map_ else reason
            r.bad_endings.append(f"tick {tick}: status end bits {bits:#04x}, end reason {name}")
