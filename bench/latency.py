"""Latency of the simulated board, measured through the Python API (issue 23, item 8).

    python bench/latency.py [--moves N] [--seed K] [--shift S ...] [--per-move]

Straight moves of 50..1600 mm on the simulated board (``asserv.sim.Simulator``, driven by the
master driver ``asserv.driver.Board``), each with its own SET_VITESSE_TRAJ limits and its GOTO
sent at a random phase of the planner period, for each rate setting (``--shift``: the board's
``slow_shift``; 0, one rate at 1 kHz, is the simulator's default; 3, the planner every 8 ticks,
is the AVR board's). For each setting it prints (docs/latency.md defines them):

- an order's latency: from the moment the board takes the GOTO's write (at its STOP or
  repeated start) to the first tick at which the servo's set point moves;
- a reply's age: how long before a DEBUG reply was prepared the tick it shows ran;
- the end of a move: from the tick the robot settles (from the truth: slow, and within the
  arrival window of the target from then on) to the first CHECK_BUSY poll, every 1 ms, that
  reports the order done;
- the straight moves: the time from the GOTO being taken to that poll, against the
  time-optimal bound of the move's limits: the worst ratio and the worst excess, and whether
  every move meets issue 23's goal (1.02 times the bound + 20 ms).

Asserts nothing: python/tests/test_latency.py tests the measurement functions, and holds the
issue's goals as expected failures until the redesign meets them.
"""

from __future__ import annotations

import argparse
import math
import random
import sys
import time
from collections.abc import Iterable, Sequence
from dataclasses import dataclass

import numpy as np

from asserv import Status, codec, field
from asserv.driver import Board
from asserv.goals import Goals, add_strict_flag
from asserv.sim import AVR_RATES, Frame, Simulator

# The random moves: distances of issue 23, and the limits SET_VITESSE_TRAJ takes (1..255 cm/s
# and cm/s^2) at speeds the motors carry (1.5 m/s: above their top speed, about 1.64 m/s, the
# following error is the limit, docs/failure-model.md) and at least 20 cm/s and 20 cm/s^2, so
# that a move lasts at most a few seconds.
DISTANCE_MM = (50, 1600)
SPEED_CM_S = (20, 150)
ACCEL_CM_S2 = (20, 255)
START = (-800.0, 0.0, 0.0)  # facing +X on the default table's centre line: 1600 mm clear ahead

# The board setting of the planner's period: every 2^slow_shift ticks (firmware/core/board.h).
RATE_SETTING = "slow_shift"
BUS_HZ = 100_000  # the I2C bit rate (the simulator's default)
POLL_S = 0.001  # CHECK_BUSY every 1 ms near the end of a move
POLL_AHEAD_S = 0.05  # polls start this long before the bound (the move cannot end earlier)
HOLD_S = 0.1  # the robot watched after the board reports the end: it stays in the window
DEBUG_READS = 3  # DEBUG replies read at random times during each move

# The arrival window and speed of board_default_config() (firmware/core/board_config.c, orders.c
# settled()): here applied to the truth, the robot's true pose and speeds.
ARRIVE_WINDOW_MM = 0.5
ARRIVE_SPEED_MM_S = 5.0

# Issue 23's goals, for the report (python/tests/test_latency.py holds them as expected
# failures until the redesign meets them).
GOAL_RATIO = 1.02
GOAL_EXTRA_S = 0.020
GOAL_END_MS = 10.0

BUSY = Status.BUSY_TRAJET | Status.BUSY_GOTO_PANIER
GOTO = codec.message("GOTO").designation
DEBUG = codec.message("DEBUG").designation


# ---- what the board's limits are -------------------------------------------------------------


def line_accel_cap_um_s2(grip_um_s2: int) -> int:
    """The largest acceleration of a straight line whatever SET_VITESSE_TRAJ asks, from the
    board's grip (orders.grip_um_s2): 7/8 of the grip for the trajectories, of which the
    distance axis takes at most 3/4 (firmware/core/orders.c, grip_share(); docs/control.md,
    "Grip"), in the firmware's integer arithmetic."""
    grip = grip_um_s2 - (grip_um_s2 >> 3)
    return grip - (grip >> 2)


def line_limits(speed_cm_s: int, accel_cm_s2: int, grip_um_s2: int) -> tuple[float, float]:
    """The speed [m/s] and acceleration [m/s^2] of a straight line for SET_VITESSE_TRAJ's
    values: the speed as given (orders.c limits_of(): 1 cm/s = 10 000 um/s), the acceleration
    as given unless the grip caps it (line_accel_cap_um_s2)."""
    accel_um_s2 = min(accel_cm_s2 * 10_000, line_accel_cap_um_s2(grip_um_s2))
    return speed_cm_s / 100.0, accel_um_s2 / 1e6


def time_bound_s(distance_m: float, speed_m_s: float, accel_m_s2: float) -> float:
    """The time-optimal rest-to-rest move over ``distance_m`` at most ``speed_m_s`` and
    ``accel_m_s2``: d/v + v/a when the speed is reached (d >= v^2/a), else 2 sqrt(d/a)."""
    d, v, a = distance_m, speed_m_s, accel_m_s2
    if not (d >= 0 and v > 0 and a > 0):
        raise ValueError(f"time_bound_s: needs d >= 0, v > 0, a > 0, not {d}, {v}, {a}")
    return d / v + v / a if d >= v * v / a else 2.0 * math.sqrt(d / a)


def within_goal(time_s: float, bound_s: float) -> bool:
    """Issue 23's goal for a straight move: it ends within 1.02 times its bound + 20 ms."""
    return time_s <= GOAL_RATIO * bound_s + GOAL_EXTRA_S


# ---- what the trace says -----------------------------------------------------------------------


def first_move_row(trace: np.ndarray, t_order_s: float) -> int | None:
    """The first row (tick) after ``t_order_s`` whose servo set point differs from the one
    before the order (its speed on either axis, ``v_set_mm_s`` or ``omega_set_deg_s``: at rest
    both are 0, and the set point moves from the tick either is not); None if none does."""
    t = trace["t_s"]
    before = np.nonzero(t < t_order_s)[0]
    if len(before) == 0:
        raise ValueError("first_move_row: the trace has no tick before the order")
    ref = before[-1]
    after = slice(ref + 1, len(trace))
    moved = (trace["v_set_mm_s"][after] != trace["v_set_mm_s"][ref]) | (
        trace["omega_set_deg_s"][after] != trace["omega_set_deg_s"][ref]
    )
    hit = np.nonzero(moved)[0]
    return int(ref + 1 + hit[0]) if len(hit) else None


def arrival_flags(
    trace: np.ndarray,
    target: tuple[float, float, float],
    half_track_mm: float,
    window_mm: float = ARRIVE_WINDOW_MM,
    speed_mm_s: float = ARRIVE_SPEED_MM_S,
) -> tuple[np.ndarray, np.ndarray]:
    """Per row, the firmware's arrival test (orders.c settled()) on the truth, in two parts:
    whether the robot is within the window of ``target`` (x mm, y mm, heading degrees), its
    true position within ``window_mm`` of the target's and its true heading within
    ``window_mm`` of wheel arc (on the drive wheels, ``half_track_mm`` from the middle) of the
    target's; and whether it is slow, its true speeds, the linear one and the turn rate as
    wheel speed, below ``speed_mm_s``."""
    x, y, heading = target
    dpos = np.hypot(trace["x_mm"] - x, trace["y_mm"] - y)
    dhead = (trace["heading_deg"] - heading + 180.0) % 360.0 - 180.0
    arc = np.abs(np.radians(dhead)) * half_track_mm
    turn = np.abs(np.radians(trace["omega_deg_s"])) * half_track_mm
    inside = (dpos < window_mm) & (arc < window_mm)
    slow = (np.abs(trace["v_mm_s"]) < speed_mm_s) & (turn < speed_mm_s)
    return np.asarray(inside), np.asarray(slow)


def settle_row(inside: np.ndarray, slow: np.ndarray) -> int | None:
    """The tick the robot settled (arrival_flags()): the first row at which it is slow and from
    which it stays within the window to the end of the trace; None if there is none. Its
    speed is not required to stay low: holding the target, the control creeps the robot by a
    few tenths of a millimetre at about the arrival speed (docs/latency.md)."""
    ins, slw = np.asarray(inside, dtype=bool), np.asarray(slow, dtype=bool)
    if ins.shape != slw.shape:
        raise ValueError(f"settle_row: {ins.shape} window flags, {slw.shape} speed flags")
    outside = np.nonzero(~ins)[0]
    first = int(outside[-1] + 1) if len(outside) else 0  # within the window from here on
    hit = np.nonzero(slw[first:])[0]
    return first + int(hit[0]) if len(hit) else None


def reply_age_s(prepared_s: float, reply_tick: int, tick_s: float) -> float:
    """How long before ``prepared_s`` the tick a reply shows ran. ``reply_tick`` is DEBUG's
    tick, the board's tick counter (16 bits) when its snapshot was taken: ticks counted from 0
    at power-on, one every ``tick_s`` from time 0, the snapshot's tick the one counted last."""
    ran = math.ceil(round(prepared_s / tick_s, 9))  # ticks run when the reply was prepared
    ago = (ran - reply_tick) % 65536  # ticks since the counter read reply_tick
    return prepared_s - (ran - ago - 1) * tick_s


# ---- the runs ----------------------------------------------------------------------------------


@dataclass(frozen=True)
class Move:
    """One straight move: its distance and limits, the phase its GOTO is sent at (ns after a
    planner tick, before the write's bytes), and when (fractions of its bound) DEBUG is read."""

    distance_mm: int
    speed_cm_s: int
    accel_cm_s2: int
    phase_ns: int
    debug_at: tuple[float, ...]


@dataclass(frozen=True)
class MoveResult:
    move: Move
    slow_shift: int
    period_ms: float  # the planner's period
    bound_s: float
    time_s: float  # from the GOTO's write being taken to the poll that reports the end
    order_ms: float  # from the GOTO's write being taken to the first tick the set point moves
    end_ms: float  # from the tick the robot settled to the poll that reports the end
    reply_ages_ms: tuple[float, ...]
    status: int  # the final status byte
    inside_at_report: bool  # the robot within the arrival window at the tick the poll showed

    @property
    def ratio(self) -> float:
        return self.time_s / self.bound_s

    @property
    def excess_ms(self) -> float:
        return (self.time_s - self.bound_s) * 1000.0


class MoveError(RuntimeError):
    """A move did not end as a straight move should (a fault, no end within its time)."""


def draw_moves(rng: random.Random, n: int, period_ns: int = 8_000_000) -> list[Move]:
    """``n`` random straight moves (DISTANCE_MM, SPEED_CM_S, ACCEL_CM_S2), each sent at a
    random phase of a planner period of ``period_ns``."""
    return [
        Move(
            rng.randint(*DISTANCE_MM),
            rng.randint(*SPEED_CM_S),
            rng.randint(*ACCEL_CM_S2),
            rng.randrange(period_ns),
            tuple(sorted(rng.uniform(0.05, 0.95) for _ in range(DEBUG_READS))),
        )
        for _ in range(n)
    ]


def taken_at(frames: Sequence[Frame], designation: int, byte_s: float) -> float:
    """When the board took the last write of ``designation`` among ``frames``: at its STOP, or
    at the repeated start that followed it (one byte later: the next address byte), as
    docs/protocol.md section 1 says."""
    for f in reversed(frames):
        if f.kind == "W" and f.data[:1] == bytes([designation]):
            return f.t_s if f.stop else f.t_s + byte_s
    raise MoveError(f"no write of designation 0x{designation:02x} on the bus")


def run_move(move: Move, slow_shift: int, seed: int = 0) -> MoveResult:
    """Drive one straight move on a new simulated board (``slow_shift``) and measure it."""
    sim = Simulator(
        {"start": START, "enc_noise_mm2_per_m": (0.0, 0.0)},
        seed=seed,
        field=field.Field(),
        # at the AVR's slow_shift, the AVR's planner_ticks too (the planner in the main loop)
        board_config=AVR_RATES
        if slow_shift == AVR_RATES[RATE_SETTING]
        else {RATE_SETTING: slow_shift},
        bus_hz=BUS_HZ,
    )
    board = Board(sim.bus)
    cfg = sim.board_config
    tick_s = 1.0 / int(cfg.tick_hz)
    period_s = tick_s * (1 << slow_shift)
    half_track_mm = int(cfg.orders.drive_track_um) / 2000.0
    byte_s = 9.0 / BUS_HZ  # one byte on the bus: 8 bits and the acknowledge
    board.set_vitesse_traj(move.speed_cm_s, move.accel_cm_s2)
    # The setting taken, then the GOTO at the move's phase of a planner period.
    t_goto = (math.floor(sim.time_s / period_s) + 3) * period_s + move.phase_ns * 1e-9 % period_s
    sim.advance(t_goto - sim.time_s)
    target = (START[0] + move.distance_mm, START[1], START[2])
    board.goto(round(target[0]), round(target[1]))
    t_order = taken_at(sim.frames, GOTO, byte_s)

    v, a = line_limits(move.speed_cm_s, move.accel_cm_s2, int(cfg.orders.grip_um_s2))
    bound = time_bound_s(move.distance_mm / 1000.0, v, a)
    ages = []
    for frac in move.debug_at:
        sim.advance(max(0.0, t_order + frac * bound - sim.time_s))
        reply = board.debug()
        prepared = taken_at(sim.frames, DEBUG, byte_s)  # its reply is prepared then
        ages.append(reply_age_s(prepared, reply.tick, tick_s) * 1000.0)
    # Polls every POLL_S from shortly before the bound: the move cannot end before it.
    t_poll = max(sim.time_s, t_order + bound - POLL_AHEAD_S)
    deadline = t_order + 2 * bound + 2.0
    first = True
    while True:
        sim.advance(max(0.0, t_poll - sim.time_s))
        status = board.check_busy()
        if not status & BUSY:
            if first:
                raise MoveError(f"{move}: not busy {POLL_AHEAD_S} s before its bound")
            break
        first = False
        if sim.time_s > deadline:
            raise MoveError(f"{move}: still busy {sim.time_s - t_order:.3f} s after the GOTO")
        t_poll += POLL_S
    t_end = sim.frames[-1].t_s  # the end of the poll's read
    if status:
        raise MoveError(f"{move}: ended with status 0x{int(status):02x}")
    sim.advance(HOLD_S)
    trace = sim.trace
    moved = first_move_row(trace, t_order)
    inside, slow = arrival_flags(trace, target, half_track_mm)
    settled = settle_row(inside, slow)
    # The poll's status byte was built when its read started, a byte before its end.
    report_row = int(np.nonzero(trace["t_s"] < t_end - byte_s)[0][-1])
    if moved is None or settled is None:
        raise MoveError(f"{move}: the set point never moved, or the robot never settled")
    t_settle = float(trace["t_s"][settled])
    return MoveResult(
        move,
        slow_shift,
        period_s * 1000.0,
        bound,
        t_end - t_order,
        (float(trace["t_s"][moved]) - t_order) * 1000.0,
        (t_end - t_settle) * 1000.0,
        tuple(ages),
        int(status),
        bool(inside[report_row]),
    )


# ---- the report --------------------------------------------------------------------------------


@dataclass(frozen=True)
class Summary:
    slow_shift: int
    period_ms: float
    moves: int
    order_ms: tuple[float, float]
    reply_age_ms: tuple[float, float]
    end_ms: tuple[float, float]
    ratio_max: float
    excess_ms: tuple[float, float]
    within_goal: int  # moves within 1.02 bound + 20 ms
    worst: Move  # the move with the largest excess


def _span(values: Iterable[float]) -> tuple[float, float]:
    v = list(values)
    return (min(v), max(v))


def summarize(results: Sequence[MoveResult]) -> Summary:
    if not results:
        raise ValueError("summarize: no moves")
    return Summary(
        results[0].slow_shift,
        results[0].period_ms,
        len(results),
        _span(r.order_ms for r in results),
        _span(a for r in results for a in r.reply_ages_ms),
        _span(r.end_ms for r in results),
        max(r.ratio for r in results),
        _span(r.excess_ms for r in results),
        sum(within_goal(r.time_s, r.bound_s) for r in results),
        max(results, key=lambda r: r.excess_ms).move,
    )


def report(s: Summary, goals: Goals | None = None) -> str:
    """The figures of one rate, issue 23's goals marked met or MISSED (and kept in ``goals``)."""
    goals = goals if goals is not None else Goals("bench/latency.py")
    rate = "one rate" if s.slow_shift == 0 else f"planner every {1 << s.slow_shift} ticks"
    end = goals.check(f"slow_shift {s.slow_shift}: end, worst [ms]", s.end_ms[1], "<=", GOAL_END_MS)
    moves = goals.check(
        f"slow_shift {s.slow_shift}: moves within {GOAL_RATIO:g} x bound + "
        f"{GOAL_EXTRA_S * 1000:g} ms",
        s.within_goal,
        "==",
        s.moves,
    )
    w = s.worst
    lines = [
        f"slow_shift {s.slow_shift} ({rate}, planner period {s.period_ms:g} ms), {s.moves} moves",
        f"  order: GOTO taken -> servo set point moves       {s.order_ms[0]:6.2f} .. "
        f"{s.order_ms[1]:6.2f} ms",
        f"  reply age: tick shown -> DEBUG reply prepared     {s.reply_age_ms[0]:6.2f} .. "
        f"{s.reply_age_ms[1]:6.2f} ms",
        f"  end: robot settled -> CHECK_BUSY not busy         {s.end_ms[0]:6.2f} .. "
        f"{s.end_ms[1]:6.2f} ms   (goal <= {GOAL_END_MS:g} ms: {end.mark})",
        f"  straight moves: time / bound, worst               {s.ratio_max:6.4f}",
        f"  straight moves: time - bound                      {s.excess_ms[0]:6.2f} .. "
        f"{s.excess_ms[1]:6.2f} ms",
        f"  within {GOAL_RATIO:g} x bound + {GOAL_EXTRA_S * 1000:g} ms: "
        f"{s.within_goal}/{s.moves} moves (goal: all, {moves.mark})",
        f"  the largest excess: {w.distance_mm} mm at {w.speed_cm_s} cm/s, {w.accel_cm_s2} cm/s^2",
    ]
    return "\n".join(lines)


def _parse(argv: Sequence[str] | None) -> argparse.Namespace:
    p = argparse.ArgumentParser(prog="bench/latency.py", description=__doc__.split("\n")[0])
    p.add_argument("--moves", type=int, default=200, help="straight moves per rate (200)")
    p.add_argument("--seed", type=int, default=0, help="the moves' random seed (0)")
    p.add_argument(
        "--shift",
        type=int,
        nargs="+",
        default=[0, 3],
        help="the board's slow_shift values to measure, 0..3 (0 3)",
    )
    p.add_argument("--per-move", action="store_true", help="print every move's figures")
    add_strict_flag(p)
    args = p.parse_args(argv)
    if args.moves < 1:
        p.error(f"--moves must be at least 1, not {args.moves}")
    if args.seed < 0:
        p.error(f"--seed must be >= 0, not {args.seed}")
    for s in args.shift:
        if not 0 <= s <= 3:
            p.error(f"--shift takes 0..3 (the board's slow_shift), not {s}")
    return args


def main(argv: Sequence[str] | None = None) -> int:
    args = _parse(argv)
    started = time.process_time()
    moves = draw_moves(random.Random(args.seed), args.moves)
    goals = Goals("bench/latency.py")
    print(
        f"bench/latency.py: {args.moves} straight moves of {DISTANCE_MM[0]}..{DISTANCE_MM[1]} mm"
        f" at {SPEED_CM_S[0]}..{SPEED_CM_S[1]} cm/s, {ACCEL_CM_S2[0]}..{ACCEL_CM_S2[1]} cm/s^2"
        f" (seed {args.seed}), each GOTO at a random phase; CHECK_BUSY polled every"
        f" {POLL_S * 1000:g} ms"
    )
    for shift in args.shift:
        try:
            results = [run_move(m, shift) for m in moves]
        except MoveError as e:
            print(f"slow_shift {shift}: {e}", file=sys.stderr)
            return 1
        if args.per_move:
            for r in results:
                m = r.move
                print(
                    f"  {m.distance_mm:5d} mm {m.speed_cm_s:3d} cm/s {m.accel_cm_s2:3d} cm/s^2:"
                    f" bound {r.bound_s * 1000:8.1f} ms, time {r.time_s * 1000:8.1f} ms,"
                    f" +{r.excess_ms:5.1f} ms, order {r.order_ms:5.2f} ms, end {r.end_ms:5.2f} ms"
                )
        print(report(summarize(results), goals))
    print(f"({time.process_time() - started:.1f} s of CPU)")
    print(goals.summary())
    return goals.exit_code(args.strict)


if __name__ == "__main__":
    sys.exit(main())
