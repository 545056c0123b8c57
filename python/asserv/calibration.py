"""Odometry calibration against the field's borders, in the spirit of UMBmark (Borenstein and
Feng, "UMBmark: a benchmark test for measuring odometry errors in mobile robots", SPIE 1995):
runs whose true end pose is known, from which the systematic errors are solved for.

Here the reference is a border: a robot pushed flat against it with a soft gain knows its true
heading exactly, and its true position along the border's normal. The procedure
(docs/calibration.md) runs, from a robot standing with its rear against the west border facing
east:

1. **Full turns** in place, then back flat against the border: the true heading turned by
   exactly n turns, the odometry by ``G`` times that: ``G`` gives the encoder track. One turn
   first, whose track is written at once, then N (default 10).
2. **Out and back**, R times (default 3): straight to the east border (front flat against it),
   back to the west border (rear flat against it). The true heading change of a round trip is
   zero; the odometry's is ``(qR - qL) S / b``, with S the distance driven: the wheel ratio.
   The first round trip's ratio is written at once, so that the next ones drive straight: the
   distance between their west (rear) and east (front) contacts is the table's length minus
   the robot's, which gives the common wheel scale.

Everything goes through the driver (``asserv.Board``): the same code calibrates the simulated
board and a real one, and ends with SET_ODOMETRIE.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from dataclasses import dataclass, field, replace

from ._protocol import Filtre, Status
from .driver import Board

__all__ = ["Calibration", "CalibrationError", "Geometry", "OdometrySetting", "Plan", "calibrate"]

PPM = 1e6
_STRAIGHT_MM = 25  # a GOTO within the board's freeze radius (30 mm) moves straight
# A push aims this far beyond the border, with these gains (SET_FILTRE_RAW, on both axes): P
# 25 is 0.6 % of duty per mm, some 12 % of duty against the border, 13 N per wheel, where the
# tyres hold about 19 N (at 15 % and more the drive wheels creep while the free wheels stand
# still, which the board's encoder check takes for a lost encoder: PB_GRAVE). The angle loop
# is as soft, so that the border turns the robot flat (with FILTRE_SOUPLE and less than 15 mm,
# some robots stay 1-2 degrees off). Below the following-error limit (20 mm). A push is left
# as soon as the robot stands still.
_PUSH_MM = 19.0
_PUSH_GAINS = (25, 0, 60)
_APPROACH_MM = 60.0  # legs end this far before the border; the rest is pushed slowly
_TURN_END_MM = 100.0  # after turning near the west border, forward this far before backing
_TURN_BIAS_MM = 1.5  # ... aiming this far to the side, which decides the way of the turn


class CalibrationError(RuntimeError):
    """The procedure could not go on: a border was not found, or a motor problem."""


@dataclass(frozen=True)
class Geometry:
    """What the procedure must know of the field and the robot."""

    table_length_mm: float = 3000.0  # between the two borders driven between (field file)
    robot_length_mm: float = 250.0  # rear bumper to front bumper, along the heading
    turn_radius_mm: float = 200.0  # encoder midpoint to the outline's farthest point, or more
    lane_step_mm: float = 50.0  # each round trip comes back this far to the left

    @property
    def flush_to_flush_mm(self) -> float:
        """Travel of the encoder midpoint from rear-flat on one border to front-flat on the
        other (it does not depend on where the encoder axis sits along the robot)."""
        return self.table_length_mm - self.robot_length_mm


@dataclass(frozen=True)
class OdometrySetting:
    """SET_ODOMETRIE's three values: absolute, from the board's nominal (build) factors."""

    ratio_ppm: int = 0
    track_10um: int = 28000
    scale_ppm: int = 0

    @property
    def track_mm(self) -> float:
        return self.track_10um / 100.0

    @property
    def ratio(self) -> float:
        """Right/left wheel factor ratio relative to the nominal: (1 + r/2) / (1 - r/2)."""
        r = self.ratio_ppm / PPM
        return (1 + r / 2) / (1 - r / 2)

    def __str__(self) -> str:
        return (
            f"ratio {self.ratio_ppm:+d} ppm, track {self.track_mm:.2f} mm,"
            f" scale {self.scale_ppm:+d} ppm"
        )


@dataclass(frozen=True)
class Plan:
    """How much to drive: more turns and round trips average more encoder noise away."""

    turns: int = 10
    round_trips: int = 3
    leg_speed_cm_s: int = 50
    leg_accel_cm_s2: int = 50
    rot_speed_cm_s: int = 40
    rot_accel_cm_s2: int = 80
    push_speed_cm_s: int = 10
    push_accel_cm_s2: int = 40
    poll_s: float = 0.05
    still_polls: int = 4  # polls without motion against a border: flat


@dataclass(frozen=True)
class Contact:
    """The pose the board reports while flat against a border."""

    wall: str  # "west" or "east"
    side: str  # "rear" or "front"
    x_mm: int
    y_mm: int
    heading_cdeg: int


@dataclass(frozen=True)
class Segment:
    """From one rear-flat contact on the west border to the next."""

    name: str
    true_turn_deg: float  # exactly known: the border fixes the heading at both ends
    odo_turn_deg: float  # what the odometry measured
    travel_mm: float  # signed distance driven (forward positive), from POSITION
    setting: OdometrySetting  # what the board ran with

    def gain(self) -> float:
        """Odometry heading change over the true one (turns: the track's error)."""
        return self.odo_turn_deg / self.true_turn_deg

    def true_ratio(self) -> float:
        """The true right/left wheel factor ratio (relative to the nominal factors) from a
        segment that turned by zero: the odometry saw (qR - qL) S / b of heading change."""
        err = math.radians(self.odo_turn_deg) * self.setting.track_mm / self.travel_mm
        return self.setting.ratio / (1 + err)


@dataclass
class Calibration:
    """What the procedure measured, and the setting it computed."""

    before: OdometrySetting
    after: OdometrySetting
    ratio_error: float  # before: configured right/left ratio over the true one, minus 1
    track_gain: float  # odometry heading change over the true one, over the N turns
    scale: float  # odometry distance over the true distance (with the first ratio)
    segments: list[Segment] = field(default_factory=list)
    distances_mm: list[float] = field(default_factory=list)  # west-rear to east-front, measured
    expected_distance_mm: float = 0.0
    contacts: list[Contact] = field(default_factory=list)

    def lines(self) -> list[str]:
        """The result, for a log (the segments are logged as they are measured)."""
        out = [
            f"  west-rear to east-front: {d:.0f} mm measured, {self.expected_distance_mm:.0f} mm"
            " true"
            for d in self.distances_mm
        ]
        out += [
            f"  wheel ratio: configured/true - 1 = {self.ratio_error * PPM:+.0f} ppm",
            f"  heading gain over {self.segments[1].true_turn_deg / 360:.0f} turns, with the first"
            f" track: {(self.track_gain - 1) * PPM:+.0f} ppm",
            f"  distance scale: {(self.scale - 1) * PPM:+.0f} ppm",
            f"  before: {self.before}",
            f"  after:  {self.after}",
        ]
        return out


def _same(a: tuple[int, int, int], b: tuple[int, int, int]) -> bool:
    """Two (x mm, y mm, heading 0.01 deg) readings of a robot standing still."""
    return a[0] == b[0] and a[1] == b[1] and abs(a[2] - b[2]) <= 1


def _wrap180(deg: float) -> float:
    return (deg + 180.0) % 360.0 - 180.0


class _Procedure:
    """The moves of the procedure, with the bookkeeping of the distance driven."""

    def __init__(self, board: Board, plan: Plan, log: Callable[[str], None]) -> None:
        self.b = board
        self.p = plan
        self.log = log
        sleep = getattr(board.bus, "sleep", None)
        self.sleep: Callable[[float], None] = sleep if callable(sleep) else time.sleep
        self.travel_mm = 0.0  # signed, since the last west-rear contact

    # ---- reading -----------------------------------------------------------------------------
    def pose(self) -> tuple[int, int, float]:
        """x mm, y mm (POSITION) and the heading in degrees at DEBUG's 0.01 degree."""
        p = self.b.position()
        return p.x_mm, p.y_mm, self.b.debug().heading_cdeg / 100.0

    def ahead(self, distance_mm: float, left_mm: float = 0.0) -> tuple[int, int]:
        """A point ahead of the robot (and to its left), from the estimate."""
        x, y, h = self.pose()
        c, s = math.cos(math.radians(h)), math.sin(math.radians(h))
        return round(x + distance_mm * c - left_mm * s), round(y + distance_mm * s + left_mm * c)

    # ---- moves -------------------------------------------------------------------------------
    def _wait(self, what: str, timeout_s: float = 60.0) -> Status:
        status = self.b.wait_idle(timeout_s, self.p.poll_s)
        if status & (Status.PB_MOTEUR | Status.PB_GRAVE):
            raise CalibrationError(f"{what}: the board stopped on a motor problem ({status!r})")
        return status

    def add_travel(self, x0: int, y0: int) -> None:
        """Add the travel since (x0, y0): the displacement along the heading now (every move of
        the procedure turns in place first, if at all, then goes straight)."""
        x1, y1, h1 = self.pose()
        h = math.radians(h1)
        self.travel_mm += (x1 - x0) * math.cos(h) + (y1 - y0) * math.sin(h)

    def move(self, what: str, order: Callable[[], None]) -> None:
        """Run one order to its end, and add its travel."""
        x0, y0, _ = self.pose()
        order()
        status = self._wait(what)
        if status & (Status.CHOC_BORD | Status.CHOC_PANIER):
            raise CalibrationError(f"{what}: a shock sensor stopped the robot ({status!r})")
        self.add_travel(x0, y0)

    def goto(self, what: str, x: int, y: int) -> None:
        self.move(what, lambda: self.b.goto(x, y))

    def speeds(self, speed_cm_s: int, accel_cm_s2: int) -> None:
        self.b.set_vitesse_traj(speed_cm_s, accel_cm_s2)

    def _push_order(self, side: str, d: int) -> Status | None:
        """One push towards the border; returns the status if the order ended by itself, or
        None once the robot has stood still (position and heading) for ``still_polls`` polls
        while the order still runs, its set point beyond: held against the border. It is then
        left running, so that the robot is not pushed longer than needed."""
        x0, y0, _ = self.pose()
        if side == "rear":
            self.b.goto_reverse(d)
        else:
            x, y = self.ahead(d)
            self.b.goto(x, y)
        last: tuple[int, int, int] | None = None
        still = 0
        result: Status | None = None
        for _ in range(round(30 / self.p.poll_s)):
            self.sleep(self.p.poll_s)
            status = self.b.check_busy()
            if not status & Status.BUSY_TRAJET:
                if status & (Status.PB_MOTEUR | Status.PB_GRAVE):
                    raise CalibrationError(f"pushing: a motor problem ({status!r})")
                result = status
                break
            pos, dbg = self.b.position(), self.b.debug()
            now = (pos.x_mm, pos.y_mm, dbg.heading_cdeg)
            # Standing still with the set point well beyond: held by the border (standing
            # still short of it, settling, the following error is small).
            held = abs(dbg.dist_err_um) > 1000 * _PUSH_MM / 3
            still = still + 1 if held and last is not None and _same(now, last) else 0
            last = now
            if still >= self.p.still_polls:
                break
        else:
            raise CalibrationError("pushing: the order never ended")
        self.add_travel(x0, y0)
        return result

    def push(self, side: str, wall: str, gap_mm: float, away_mm: float) -> Contact:
        """Drive the rear or the front flat against a border about ``gap_mm`` away, read the
        pose, and leave it by ``away_mm``. Soft gains let the border turn the robot flat. A
        shock sensor stops the order that meets the border; the next push ignores the sensors
        pressed when it starts (docs/control.md, Gating), and a push that no longer moves the
        robot, nor turns it, has it flat: the same holds without sensors."""
        self.speeds(self.p.push_speed_cm_s, self.p.push_accel_cm_s2)
        self.b.set_filtre_raw(*_PUSH_GAINS)
        d = round(max(gap_mm - 10.0, 5.0))  # the approach, which should stop short of it
        # A push that ends on a shock sensor touched the border: after a shock the board holds
        # the robot and never drives it back towards the obstacle (docs/failure-model.md), so
        # squaring up takes a push per switch that closes, up to 60 of them. One that ends
        # without a contact did not reach the border: 20 of those (380 mm) and it is not there.
        misses = contacts = 0
        while True:
            status = self._push_order(side, d)
            if status is None:
                break  # held still against the border by a running push: flat
            if status & (Status.CHOC_BORD | Status.CHOC_PANIER):
                contacts += 1
            else:
                misses += 1
            if misses >= 20 or contacts >= 60:
                raise CalibrationError(f"the {wall} border was not found behind the {side}")
            d = round(_PUSH_MM)  # ended (a sensor, or not there yet): push again
        x, y, h = self.pose()
        contact = Contact(wall, side, x, y, round(h * 100))
        self.log(f"  {side} flat on the {wall} border: x {x} mm, y {y} mm, heading {h:.2f} deg")
        # Leave with the soft gains (the set point is still inside the border) and the heading
        # held: a GOTO this close is a straight move, where a GOTO to a point farther away
        # would first turn towards its bearing, rounded to the millimetre, and could touch the
        # border with a corner. Then back to the standard gains.
        if side == "rear":
            ax, ay = self.ahead(_STRAIGHT_MM)
            self.goto("leaving the border", ax, ay)
        else:
            self.move("leaving the border", lambda: self.b.goto_reverse(_STRAIGHT_MM))
        self.b.set_filtre(Filtre.FILTRE_STD)
        if away_mm > _STRAIGHT_MM:
            self.speeds(self.p.leg_speed_cm_s, self.p.leg_accel_cm_s2)
            if side == "rear":
                ax, ay = self.ahead(away_mm - _STRAIGHT_MM)
                self.goto("leaving the border", ax, ay)
            else:
                d = round(away_mm - _STRAIGHT_MM)
                self.move("leaving the border", lambda: self.b.goto_reverse(d))
        return contact

    def turns(self, n: int) -> None:
        """Turn in place n full turns counter-clockwise, then face the start heading again, by
        GOTOs to far points whose bearing keeps ahead of the robot (no order turns more than
        half a turn): each is replaced before the robot comes within the heading window."""
        b, p = self.b, self.p
        x0, y0, h0 = self.pose()
        total = 360.0 * n
        last = b.position().angle_deg
        turned = 0.0
        target = 0.0

        def aim(rel_deg: float, distance_mm: float) -> None:
            # From the current estimate: the position moves a little while turning.
            x, y, _ = self.pose()
            a = math.radians(h0 + rel_deg)
            b.goto(round(x + distance_mm * math.cos(a)), round(y + distance_mm * math.sin(a)))

        while target < total:
            if turned >= target - 60.0:
                target = min(target + 90.0, total)
                if target < total:
                    aim(target, 1000.0)
                else:
                    aim(target, _TURN_END_MM)  # the last one: face h0, then forward
                    break
            self.sleep(p.poll_s)
            a = b.position().angle_deg
            turned += _wrap180(a - last)
            last = a
        self._wait("turning")
        self.add_travel(x0, y0)


def calibrate(
    board: Board,
    geometry: Geometry | None = None,
    plan: Plan | None = None,
    current: OdometrySetting | None = None,
    *,
    write: bool = True,
    log: Callable[[str], None] = print,
) -> Calibration:
    """Run the procedure on a robot standing with its rear against a border (the west one),
    facing the opposite border across the table, and return what it measured and computed.

    ``current``: the odometry setting the board runs with (SET_ODOMETRIE's last values, or the
    nominal ones after a reset: ratio 0, the build's track, scale 0); the board cannot report it,
    and the new setting is computed from it. The procedure writes intermediate settings as it
    goes (SET_ODOMETRIE), and at the end the new one, or ``current`` again if not ``write``."""
    g = geometry or Geometry()
    p = plan or Plan()
    cur = current or OdometrySetting()
    if p.turns < 1 or p.round_trips < 2:
        raise ValueError("the procedure needs at least 1 turn and 2 round trips")
    run = _Procedure(board, p, log)
    d_flush = g.flush_to_flush_mm
    turn_gap = g.turn_radius_mm - g.robot_length_mm / 2  # flat on a border -> room to turn
    setting = cur

    def use(s: OdometrySetting, why: str) -> None:
        nonlocal setting
        setting = s
        board.set_odometrie(s.ratio_ppm, s.track_10um, s.scale_ppm)
        log(f"  {why}: SET_ODOMETRIE {s}")

    board.set_vitesse_rot(p.rot_speed_cm_s, p.rot_accel_cm_s2)
    board.set_filtre(Filtre.FILTRE_STD)
    log("contact: the rear against the west border")
    contacts = [run.push("rear", "west", 5.0, turn_gap)]
    segments: list[Segment] = []

    def close(name: str, true_turn_deg: float, a: Contact) -> Segment:
        """The segment from the west-rear contact a to the last one."""
        b = contacts[-1]
        odo = (b.heading_cdeg - a.heading_cdeg) / 100.0
        odo = true_turn_deg + _wrap180(odo - true_turn_deg)  # the truth is known to +/-180
        seg = Segment(name, true_turn_deg, odo, run.travel_mm, setting)
        segments.append(seg)
        log(
            f"  {name}: odometry turned {odo:+.2f} deg for {true_turn_deg:+.0f},"
            f" {run.travel_mm:+.0f} mm driven"
        )
        run.travel_mm = 0.0
        return seg

    def turn_run(n: int) -> Segment:
        log(f"{n} full turn{'s' if n > 1 else ''} in place, counter-clockwise")
        run.speeds(p.leg_speed_cm_s, p.leg_accel_cm_s2)
        start = contacts[-1]
        run.turns(n)
        contacts.append(run.push("rear", "west", turn_gap + _TURN_END_MM, turn_gap))
        return close(f"{n} turn{'s' if n > 1 else ''}", 360.0 * n, start)

    # 1. One turn gives a first track, written at once so that the heading stays close to the
    # truth over the N turns (the robot must end them facing the border to lie flat on it
    # again); then N full turns measure what is left.
    run.travel_mm = 0.0
    one = turn_run(1)
    use(replace(setting, track_10um=round(setting.track_10um * one.gain())), "first track")
    turns = turn_run(p.turns)

    # 2. Round trips: to the east border (front flat), back to the west one (rear flat). The
    # first gives a first wheel ratio, written at once so that the next ones drive straight:
    # their west-to-east distances give the scale (a robot that curves drives farther).
    distances: list[float] = []
    trips: list[Segment] = []
    for i in range(p.round_trips):
        start = contacts[-1]
        log(f"round trip {i + 1} of {p.round_trips}")
        run.speeds(p.leg_speed_cm_s, p.leg_accel_cm_s2)
        x, y = _from(start, d_flush - _APPROACH_MM, 0.0)
        run.goto("to the east border", x, y)
        east = run.push("front", "east", _APPROACH_MM, turn_gap)
        contacts.append(east)
        if i > 0:
            distances.append(math.hypot(east.x_mm - start.x_mm, east.y_mm - start.y_mm))
        # Back towards the west border, to the left of the way out: the bearing is a little
        # less than half a turn, so the robot turns counter-clockwise; there it turns back
        # clockwise (the target a little to its left again), so the round trip turns by zero.
        run.speeds(p.leg_speed_cm_s, p.leg_accel_cm_s2)
        x, y = _from(start, turn_gap, g.lane_step_mm)
        run.goto("back to the west border", x, y)
        x, y = run.ahead(-_TURN_END_MM, -_TURN_BIAS_MM)
        run.goto("turning to face east", x, y)
        contacts.append(run.push("rear", "west", turn_gap + _TURN_END_MM, turn_gap))
        trips.append(close(f"round trip {i + 1}", 0.0, start))
        if i == 0:
            use(replace(setting, ratio_ppm=_ratio_ppm(trips[0].true_ratio())), "first ratio")

    # The estimates (docs/calibration.md, "Computation").
    rho = sum(t.true_ratio() * t.travel_mm for t in trips) / sum(t.travel_mm for t in trips)
    scale = sum(distances) / (len(distances) * d_flush)
    scale_ppm = round(((1 + setting.scale_ppm / PPM) / scale - 1) * PPM)
    track = (
        turns.setting.track_mm
        * turns.gain()
        * (1 + scale_ppm / PPM)
        / (1 + turns.setting.scale_ppm / PPM)
    )
    after = OdometrySetting(_ratio_ppm(rho), round(track * 100), scale_ppm)
    result = Calibration(
        cur,
        after,
        cur.ratio / rho - 1,
        turns.gain(),
        scale,
        segments,
        distances,
        d_flush,
        contacts,
    )
    use(after if write else cur, "result" if write else "dry run, the setting before")
    return result


def _ratio_ppm(rho: float) -> int:
    """SET_ODOMETRIE's ratio for a right/left factor ratio rho: the inverse of
    rho = (1 + r/2) / (1 - r/2)."""
    return round(2 * (rho - 1) / (rho + 1) * PPM)


def _from(c: Contact, forward_mm: float, left_mm: float) -> tuple[int, int]:
    """A point ahead of (and to the left of) a border contact, along its heading."""
    h = math.radians(c.heading_cdeg / 100.0)
    return (
        round(c.x_mm + forward_mm * math.cos(h) - left_mm * math.sin(h)),
        round(c.y_mm + forward_mm * math.sin(h) + left_mm * math.cos(h)),
    )
