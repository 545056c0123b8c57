"""bench/latency.py (issue 23, item 8): its measurement functions on generated traces, its
reading of the board's limits against the simulated board, and real runs whose figures must be
finite and consistent, and issue 23's goals: all met at one rate; at the AVR's rates the order's
and the end's are held as expected failures (the AVR aims a step later for its CPU budget, and
the end waits for its 125 Hz planner)."""

from __future__ import annotations

import functools
import math
import random
import sys
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from asserv import field
from asserv.driver import Board
from asserv.sim import AVR_RATES, TRACE_DTYPE, Frame, Simulator

sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "bench"))
import latency

PROPS = settings(max_examples=200, deadline=None, suppress_health_check=[HealthCheck.too_slow])


# ---- the time-optimal bound ----------------------------------------------------------------------


def integrated_time_s(d: float, v: float, a: float) -> float:
    """The fastest rest-to-rest move over d by brute force: steps of dt, each at the largest
    speed the limits allow and from which braking at a still stops at d."""
    # The fastest move takes at least d/v and 2 sqrt(d/a), and at most their sum: 10 000 to
    # 20 000 steps.
    dt = (d / v + 2 * math.sqrt(d / a)) / 20000
    x, speed, t = 0.0, 0.0, 0.0
    while x < d * (1 - 1e-12):
        brake = math.sqrt(2 * a * max(d - x, 0.0))
        new = min(speed + a * dt, v, brake)
        x += (speed + new) / 2 * dt
        speed, t = new, t + dt
    return t


@PROPS
@given(
    d=st.floats(0.001, 2.0),
    v=st.floats(0.05, 3.0),
    a=st.floats(0.05, 10.0),
)
def test_the_bound_is_the_brute_force_fastest_move(d: float, v: float, a: float) -> None:
    bound = latency.time_bound_s(d, v, a)
    brute = integrated_time_s(d, v, a)
    assert brute == pytest.approx(bound, rel=1e-3, abs=1e-9)


@given(d=st.floats(0.01, 2.0), v=st.floats(0.05, 3.0), a=st.floats(0.05, 10.0))
def test_the_bound_grows_with_the_distance_and_shrinks_with_the_limits(
    d: float, v: float, a: float
) -> None:
    t = latency.time_bound_s(d, v, a)
    assert latency.time_bound_s(d * 1.1, v, a) > t
    assert latency.time_bound_s(d, v * 1.1, a) <= t
    assert latency.time_bound_s(d, v, a * 1.1) < t


@pytest.mark.parametrize("d, v, a", [(1.0, 0.0, 1.0), (1.0, 1.0, 0.0), (-1.0, 1.0, 1.0)])
def test_the_bound_refuses_limits_that_do_not_move(d: float, v: float, a: float) -> None:
    with pytest.raises(ValueError, match="time_bound_s"):
        latency.time_bound_s(d, v, a)


def test_the_bound_of_no_distance_is_0() -> None:
    assert latency.time_bound_s(0.0, 1.0, 1.0) == 0.0


def test_the_bound_of_the_accuracy_bench() -> None:
    # bench/README.md's figures: 1.8 m at 1 m/s^2, 0.2, 0.5 and 1 m/s: 9.20, 4.10, 2.80 s
    for v, t in ((0.2, 9.20), (0.5, 4.10), (1.0, 2.80)):
        assert latency.time_bound_s(1.8, v, 1.0) == pytest.approx(t)


# ---- the limits, as the board applies them -----------------------------------------------------


@given(
    speed=st.integers(1, 255),
    accel=st.integers(1, 255),
    grip=st.integers(100_000, 50_000_000),
)
def test_line_limits_are_the_setting_within_the_grip(speed: int, accel: int, grip: int) -> None:
    v, a = latency.line_limits(speed, accel, grip)
    cap = latency.line_accel_cap_um_s2(grip)
    assert v == speed / 100
    assert a == min(accel / 100, cap / 1e6)
    assert 0.65 * grip <= cap <= 0.66 * grip  # 3/4 of 7/8


def set_point_limits(
    speed: int, accel: int, board_config: dict[str, int]
) -> tuple[float, float, int]:
    """The largest speed [m/s] of the servo's distance set point, and its acceleration [m/s^2]
    while it speeds up, in a long straight on the simulated board; and the board's grip."""
    sim = Simulator({"start": latency.START}, field=field.Field(), board_config=board_config)
    board = Board(sim.bus)
    board.set_vitesse_traj(speed, accel)
    board.goto(round(latency.START[0]) + 1600, 0)
    sim.advance(2.5)
    vel = sim.trace["v_set_mm_s"] / 1000
    t = sim.trace["t_s"]
    top = float(vel.max())
    rising = np.nonzero((vel > 0.1 * top) & (vel < 0.9 * top))[0]
    rising = rising[rising < np.argmax(vel)]  # before braking
    i, j = rising[0], rising[-1]
    assert np.all(np.diff(vel[i : j + 1]) >= 0)  # one acceleration phase
    slope = float((vel[j] - vel[i]) / (t[j] - t[i]))
    return top, slope, int(sim.board_config.orders.grip_um_s2)


@pytest.mark.parametrize(
    "speed, accel, board_config",
    [
        (100, 150, {}),
        (60, 40, {"slow_shift": 3}),
        (120, 200, {"orders.grip_um_s2": 1_500_000}),  # capped by the grip: 0.984 m/s^2
    ],
)
def test_line_limits_are_those_of_the_board_set_point(
    speed: int, accel: int, board_config: dict[str, int]
) -> None:
    top, slope, grip = set_point_limits(speed, accel, board_config)
    v, a = latency.line_limits(speed, accel, grip)
    assert top == pytest.approx(v, abs=1e-6)
    assert slope == pytest.approx(a, rel=0.01)


# ---- the trace: when the set point moves, when the robot settles -------------------------------


def trace_of(**columns: np.ndarray) -> np.ndarray:
    n = len(next(iter(columns.values())))
    tr = np.zeros(n, dtype=TRACE_DTYPE)
    tr["t_s"] = np.arange(n) * 1e-3
    for name, values in columns.items():
        tr[name] = values
    return tr


@PROPS
@given(
    v=st.lists(st.sampled_from([0.0, 0.0, 0.0, 1.0, -2.5]), min_size=2, max_size=60),
    w=st.lists(st.sampled_from([0.0, 0.0, 0.0, 3.0]), min_size=60, max_size=60),
    order_ms=st.floats(0.001, 59.0),
)
def test_first_move_row_is_the_first_change_after_the_order(
    v: list[float], w: list[float], order_ms: float
) -> None:
    tr = trace_of(v_set_mm_s=np.array(v), omega_set_deg_s=np.array(w[: len(v)]))
    t_order = order_ms * 1e-3
    before = [i for i in range(len(v)) if tr["t_s"][i] < t_order]
    if not before:
        with pytest.raises(ValueError, match="no tick before"):
            latency.first_move_row(tr, t_order)
        return
    ref = before[-1]
    expect = next(
        (
            i
            for i in range(ref + 1, len(v))
            if (v[i], w[i]) != (v[ref], w[ref])  # brute force: row by row
        ),
        None,
    )
    assert latency.first_move_row(tr, t_order) == expect


@PROPS
@given(
    inside=st.lists(st.booleans(), min_size=1, max_size=80),
    slow=st.lists(st.booleans(), min_size=80, max_size=80),
)
def test_settle_row_is_the_first_slow_row_within_the_window_for_good(
    inside: list[bool], slow: list[bool]
) -> None:
    n = len(inside)
    expect = next((k for k in range(n) if slow[k] and all(inside[k:])), None)
    assert latency.settle_row(np.array(inside), np.array(slow[:n])) == expect


def test_settle_row_refuses_flags_of_two_lengths() -> None:
    with pytest.raises(ValueError, match="settle_row"):
        latency.settle_row(np.ones(3, dtype=bool), np.ones(4, dtype=bool))


@PROPS
@given(
    target=st.tuples(st.floats(-1500, 1500), st.floats(-1000, 1000), st.floats(-180, 180)),
    direction=st.floats(0, 2 * math.pi),
    scale=st.floats(0.0, 3.0).filter(lambda s: abs(s - 1) > 1e-6),
    half_track=st.floats(40.0, 200.0),
)
def test_arrival_flags_are_the_window_and_the_speed(
    target: tuple[float, float, float], direction: float, scale: float, half_track: float
) -> None:
    # Rows off the target by scale times the window (position, heading as wheel arc) or at
    # scale times the arrival speed (linear, turn rate as wheel speed): inside, or slow,
    # exactly when scale < 1.
    w, s = latency.ARRIVE_WINDOW_MM, latency.ARRIVE_SPEED_MM_S
    x, y, h = target
    n = 5
    tr = trace_of(x_mm=np.full(n, x), y_mm=np.full(n, y), heading_deg=np.full(n, h))
    tr["x_mm"][1] += scale * w * math.cos(direction)
    tr["y_mm"][1] += scale * w * math.sin(direction)
    tr["heading_deg"][2] += math.degrees(scale * w / half_track) * (1 if direction < 3 else -1)
    tr["v_mm_s"][3] = scale * s * (1 if direction < 3 else -1)
    tr["omega_deg_s"][4] = math.degrees(scale * s / half_track) * (1 if direction < 3 else -1)
    inside, slow = latency.arrival_flags(tr, target, half_track)
    near = scale < 1
    assert list(inside) == [True, near, near, True, True]
    assert list(slow) == [True, True, True, near, near]


@PROPS
@given(
    approach_ms=st.integers(1, 200),
    overshoot=st.floats(0.0, 3.0),
    rest_ms=st.integers(1, 200),
)
def test_settle_row_of_an_approach_is_where_it_stays_still(
    approach_ms: int, overshoot: float, rest_ms: int
) -> None:
    # A robot that drives to the target, overshoots it by `overshoot` mm (within the window
    # or not), comes back at 10 mm/s and rests: it settles at its first tick at rest.
    half = latency.ARRIVE_WINDOW_MM
    braking = np.linspace(-200.0, overshoot, approach_ms)
    back = np.arange(overshoot, 0.0, -0.01)  # 10 mm/s back
    x = np.concatenate([braking, back, np.zeros(rest_ms)])
    v = np.concatenate([np.full(approach_ms, 100.0), np.full(len(back), -10.0), np.zeros(rest_ms)])
    tr = trace_of(x_mm=x, v_mm_s=v)
    row = latency.settle_row(*latency.arrival_flags(tr, (0.0, 0.0, 0.0), 80.0))
    assert row == approach_ms + len(back)
    assert all(abs(x[row:]) < half)


# ---- replies and frames --------------------------------------------------------------------------


@PROPS
@given(
    shown=st.integers(1, 10**6),
    later=st.integers(0, 65535),
    into=st.floats(1e-6, 1.0),  # the simulator's clock counts ns
    tick_ms=st.sampled_from([0.5, 1.0, 2.0]),
)
def test_reply_age_reads_the_wrapping_tick(
    shown: int, later: int, into: float, tick_ms: float
) -> None:
    # DEBUG shows the state after `shown` ticks (its tick field, modulo 2^16); the reply was
    # prepared `into` a tick after `shown + later` ticks had run.
    tick = tick_ms * 1e-3
    prepared = (shown + later - 1 + into) * tick
    age = latency.reply_age_s(prepared, shown % 65536, tick)
    assert age == pytest.approx(prepared - (shown - 1) * tick, rel=1e-9, abs=1e-12)


def test_taken_at_is_the_stop_or_the_repeated_start() -> None:
    byte = 9e-5
    frames = [
        Frame(0.010, "W", b"\x00\x00\x10\x00\x00\x00", True),
        Frame(0.020, "W", b"\xc8", False),
        Frame(0.022, "R", bytes(22), True),
        Frame(0.030, "W", b"\x06\x10", True),
    ]
    assert latency.taken_at(frames, 0x00, byte) == 0.010
    assert latency.taken_at(frames, 0xC8, byte) == pytest.approx(0.020 + byte)
    with pytest.raises(latency.MoveError, match="0x01"):
        latency.taken_at(frames, 0x01, byte)


@given(bound=st.floats(0.01, 30.0), extra=st.floats(-1.0, 1.0).filter(lambda e: abs(e) > 1e-9))
def test_within_goal_is_1_02_bound_plus_20_ms(bound: float, extra: float) -> None:
    limit = 1.02 * bound + 0.020
    assert latency.within_goal(limit + extra, bound) == (extra <= 0)


# ---- real runs -----------------------------------------------------------------------------------

# The first 60 of the bench's 200 moves (seed 0).
MOVES = latency.draw_moves(random.Random(0), 60)


@functools.cache
def results(shift: int) -> tuple[latency.MoveResult, ...]:
    return tuple(latency.run_move(m, shift) for m in MOVES)


@pytest.mark.parametrize("shift", [0, 3])
def test_todays_latencies_are_finite_and_consistent(shift: int) -> None:
    tick_ms = 1.0
    grip = int(Simulator().board_config.orders.grip_um_s2)
    for r in results(shift):
        assert r.status == 0 and r.period_ms == tick_ms * (1 << shift)
        # The set point cannot move before the order, nor the move end before the set point
        # has covered the bound, but for its last braking from the arrival speed (the board
        # settles from there on) and the profile's rounding, within two planner periods.
        _, a = latency.line_limits(r.move.speed_cm_s, r.move.accel_cm_s2, grip)
        early_ms = latency.ARRIVE_SPEED_MM_S / 1000 / a * 1000 + 2 * r.period_ms
        assert 0 < r.order_ms < 1000
        assert r.time_s * 1000 >= r.order_ms + r.bound_s * 1000 - early_ms
        assert r.ratio >= 1 - early_ms / (r.bound_s * 1000)
        # A reply shows a tick that ran before it was prepared.
        assert all(0 < age < 1000 for age in r.reply_ages_ms)
        # The board reports the end with the robot in the arrival window, which it stays in.
        assert r.inside_at_report
        assert math.isfinite(r.end_ms) and abs(r.end_ms) < 1000


def test_a_move_measures_the_same_twice() -> None:
    m = MOVES[0]
    assert latency.run_move(m, 3) == latency.run_move(m, 3)


def test_summary_spans_the_moves() -> None:
    rs = results(3)
    s = latency.summarize(rs)
    assert s.moves == len(rs) and s.slow_shift == 3 and s.period_ms == 8
    assert s.order_ms == (min(r.order_ms for r in rs), max(r.order_ms for r in rs))
    assert s.ratio_max == max(r.ratio for r in rs)
    assert s.within_goal == sum(latency.within_goal(r.time_s, r.bound_s) for r in rs)
    assert s.worst in [r.move for r in rs if r.excess_ms == s.excess_ms[1]]
    text = latency.report(s)
    assert f"{s.ratio_max:6.4f}" in text and f"{s.within_goal}/{s.moves}" in text


def test_the_bench_prints_its_figures(capsys: pytest.CaptureFixture[str]) -> None:
    assert latency.main(["--moves", "2", "--shift", "0", "3", "--per-move"]) == 0
    out = capsys.readouterr().out
    for line in ("slow_shift 0", "slow_shift 3", "order:", "reply age:", "end:", "time / bound"):
        assert line in out


@pytest.mark.parametrize(
    "argv, message",
    [
        (["--moves", "0"], "--moves must be at least 1"),
        (["--shift", "4"], "--shift takes 0..3"),
        (["--seed", "-1"], "--seed must be >= 0"),
        (["--moves", "x"], "invalid int value"),
    ],
)
def test_bad_arguments_exit_2_with_a_message(
    argv: list[str], message: str, capsys: pytest.CaptureFixture[str]
) -> None:
    with pytest.raises(SystemExit) as e:
        latency.main(argv)
    assert e.value.code == 2
    assert message in capsys.readouterr().err


# ---- issue 23's goals ----------------------------------------------------------------------------

#: At the AVR's rates the end is seen at the planner's next snapshot (up to a period, 8 ms, after
#: the robot settles) and shows at the hand-over planner_ticks (3 ms) later: 10 ms is out of reach
#: there, whatever the settle test does (docs/latency.md).
AVR_END = pytest.mark.xfail(
    strict=True, reason="issue 23: the end waits for the 125 Hz planner and its hand-over"
)


#: The AVR aims a GOTO a planner step after the one that takes it (orders.aim_delay_steps): its
#: 125 Hz planner keeps its CPU budget so (firmware/ports/avr/robot.c, docs/latency.md).
AVR_AIM = pytest.mark.xfail(
    strict=True, reason="issue 23: the AVR aims a step later, for its CPU budget"
)


@pytest.mark.parametrize("shift", [0, pytest.param(3, marks=AVR_AIM)])
def test_goal_an_order_reaches_the_servo_the_tick_after_the_planner_takes_it(
    shift: int,
) -> None:
    # The planner takes an order at its next snapshot at the latest, a period after it came at
    # most; its results reach the servo planner_ticks after the snapshot (0 at one rate, 3 at
    # the AVR's rates: the planner runs in the main loop meanwhile), and the set point moves at
    # that tick.
    planner_ticks = AVR_RATES["planner_ticks"] if shift == AVR_RATES["slow_shift"] else 0
    for r in results(shift):
        assert r.order_ms <= r.period_ms + planner_ticks + 1.0, r.move


@pytest.mark.parametrize("shift", [0, pytest.param(3, marks=AVR_END)])
def test_goal_the_end_shows_in_check_busy_within_10_ms_of_settling(shift: int) -> None:
    # Polled every 1 ms: the poll sees the end up to 1 ms after it shows.
    for r in results(shift):
        assert r.end_ms <= latency.GOAL_END_MS + latency.POLL_S * 1000, r.move


@pytest.mark.parametrize("shift", [0, 3])
def test_goal_every_straight_move_ends_within_1_02_bound_plus_20_ms(shift: int) -> None:
    for r in results(shift):
        assert latency.within_goal(r.time_s, r.bound_s), r.move
