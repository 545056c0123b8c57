"""Fault injection on the simulated board (docs/failure-model.md): each hardware fault is
detected and reported with the right status bits within the documented time, the motors stop
driving into it, and it does not turn into something worse while the robot stands.

Times are counted in simulated control ticks (1 ms), so they do not depend on the machine. The
robot drives along a clear lane, y = -300 mm from x = -1000 to x = 1000, away from the baskets
and the borders, at 1 m/s unless said otherwise.
"""

from __future__ import annotations

import dataclasses
import math
import re
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pytest

from asserv import EndReason, OrderRejected, OrderState, Status, field
from asserv.driver import Board
from asserv.sim import Simulator

START = (-1000, -300, 0)
TARGET = (1000, -300)
MOTOR_BITS = Status.PB_MOTEUR | Status.PB_GRAVE
CAUSES = ("NONE", "FOLLOWING", "OVERCURRENT", "SLIP", "ENCODER_LOST", "REPEATED")


def lane(config: dict[str, object] | None = None, **kw: object) -> Simulator:
    return Simulator({"start": START, **(config or {})}, **kw)  # type: ignore[arg-type]


def drive(sim: Simulator, speed_cm_s: int = 100) -> Board:
    board = Board(sim.bus)
    board.set_vitesse_traj(speed_cm_s, 100)
    board.goto(*TARGET)
    return board


def cause(sim: Simulator) -> str:
    """Which check fired last (firmware/core/faults.h), from the board's memory."""
    return CAUSES[sim._h.board.planner.faults.cause]


def status_bits(sim: Simulator) -> np.ndarray:
    return sim.trace["status"].astype(int)


def first_tick(sim: Simulator, mask: int, after_s: float = 0.0) -> int:
    """Index in the trace of the first tick at or after after_s whose status has a bit of mask."""
    tr = sim.trace
    hit = np.nonzero(((status_bits(sim) & mask) != 0) & (tr["t_s"] >= after_s))[0]
    assert len(hit), f"no status bit of 0x{mask:02x} after {after_s} s"
    return int(hit[0])


def latency_ms(sim: Simulator, t0_s: float, mask: int) -> int:
    """From the instant the fault appears to the first tick that reports it, in ticks (ms)."""
    return round(float(sim.trace["t_s"][first_tick(sim, mask, t0_s)] - t0_s) * 1000)


def inject_at(
    sim: Simulator, board: Board, t_s: float, fault: Callable[[Simulator], None]
) -> float:
    sim.advance(t_s - sim.time_s)
    assert board.check_busy() & Status.BUSY_TRAJET  # still driving: the fault hits a motion
    fault(sim)
    return sim.time_s


def check_motors_off_and_stays(sim: Simulator, detected: int, expect: int) -> None:
    """From the tick of the report on, both duties are 0 and the status keeps the same fault
    bits: no PB_GRAVE grows out of a PB_MOTEUR while the robot stands (2 s)."""
    sim.advance(2.0)
    tr = sim.trace[detected:]
    assert np.all(tr["duty_left"] == 0) and np.all(tr["duty_right"] == 0)
    assert np.all((tr["status"].astype(int) & (MOTOR_BITS | Status.BUSY_TRAJET)) == expect)
    # At most the braking current of a wheel still turning (the bridge shorts the motor).
    assert abs(tr["current_left_A"][-500:]).max() < 0.1
    assert abs(tr["current_right_A"][-500:]).max() < 0.1


def box_field(x_mm: float) -> field.Field:
    """The default field with a 40 x 200 mm box across the lane at x_mm."""
    base = field.load(field.DEFAULT)
    box = field.Obstacle("box", x_mm, -300, half_x_mm=20, half_y_mm=100)
    return dataclasses.replace(base, obstacles=(box,))


def test_shock_sensor_stops_in_the_tick_it_closes() -> None:
    sim = lane(field=box_field(200))
    board = drive(sim)
    status = board.wait_idle(10)
    sim.advance(2.5)
    tr = sim.trace
    closed = int(np.nonzero(tr["shocks"])[0][0])
    assert first_tick(sim, Status.CHOC_BORD) == closed  # 0 ms: the same control tick
    assert status == Status.CHOC_BORD and cause(sim) == "NONE"
    assert tr["duty_left"][closed + 1] < -0.999  # full braking from the next tick
    assert np.all(tr["status"][closed:].astype(int) == Status.CHOC_BORD)  # nothing added
    # It holds where it came to rest after the bounce, never pulled back against the box
    # (docs/failure-model.md; test_endings_sim.py checks the stop at any speed).
    assert tr["contact_force_N"][closed + 300 : closed + 2500].max() < 10
    assert np.abs(tr["current_left_A"][closed + 300 :]).mean() < 0.5
    assert tr["contact_force_N"][closed + 1000] < 1.5
    assert tr["contact_force_N"][closed + 2000 :].max() == 0


def test_a_wall_no_shock_sensor_sees_is_a_motor_problem() -> None:
    sim = lane({"shock_count": 0}, field=box_field(200))
    board = drive(sim)
    assert board.wait_idle(10) == Status.PB_MOTEUR
    tr = sim.trace
    touched = float(tr["t_s"][np.nonzero(tr["contact_force_N"] > 0)[0][0]])
    assert latency_ms(sim, touched, Status.PB_MOTEUR) <= 15  # measured: 9 ms
    assert cause(sim) == "SLIP"  # the drive wheels spin against the free wheels
    check_motors_off_and_stays(sim, first_tick(sim, MOTOR_BITS), Status.PB_MOTEUR)
    assert sim.trace["contact_force_N"][-1] == 0  # it does not press the wall any more


Fault = Callable[[Simulator], None]


def stuck(*wheels: int) -> Fault:
    """Motors locked (both: something wedged under the robot)."""

    def lock(sim: Simulator) -> None:
        for w in wheels:
            sim.set_motor_stuck(w, True)

    return lock


def cut(wheel: int) -> Fault:
    return lambda sim: sim.set_encoder_cut(wheel, True)


def cut_motor(wheel: int) -> Fault:
    return lambda sim: sim.set_motor_encoder_cut(wheel, True)


def sag(volts: float) -> Fault:
    return lambda sim: sim.set_battery_volts(volts)


def injected(
    name: str, fault: Fault, status: Status, why: str, ms: int, at_s: float = 0.8, speed: int = 100
) -> object:
    return pytest.param(at_s, fault, speed, status, why, ms, id=name)


MOTEUR, GRAVE = Status.PB_MOTEUR, Status.PB_GRAVE

# An injected fault: the status bits, the check that fires (firmware/core/faults.h), the
# documented detection time [ms] (docs/failure-model.md; the comment: what the simulator
# measured), when and at what speed [cm/s] if not at 0.8 s and 1 m/s.
INJECTED = [
    injected("stalled left motor", stuck(0), MOTEUR, "SLIP", 35),  # 30 ms
    injected("stalled right motor", stuck(1), MOTEUR, "SLIP", 35),  # 30 ms
    # At 30 cm/s no wheel turns, so nothing slips: the current passes 6 A before the
    # following error has lasted its 100 ms.
    injected("both wheels jammed", stuck(0, 1), MOTEUR, "OVERCURRENT", 90, speed=30),  # 79 ms
    # A suspicion first (PB_MOTEUR): a robot blocked on one side can look the same.
    injected("left free encoder wire cut", cut(0), MOTEUR, "ENCODER_LOST", 10),  # 7 ms
    injected("right free encoder wire cut", cut(1), MOTEUR, "ENCODER_LOST", 10),  # 7 ms
    injected("left motor encoder wire cut", cut_motor(0), MOTEUR, "SLIP", 32),  # 27 ms
    injected("right motor encoder wire cut", cut_motor(1), MOTEUR, "SLIP", 32),  # 27 ms
    # 24 V down to 8 V: about 0.55 m/s at full duty, the profile runs away at 1 m/s.
    injected("battery sag to 8 V", sag(8), MOTEUR, "FOLLOWING", 500, at_s=0.3),  # 460 ms
]


@pytest.mark.parametrize(("at_s", "fault", "speed", "status", "why", "within_ms"), INJECTED)
def test_an_injected_fault_is_reported_in_time(
    at_s: float,
    fault: Fault,
    speed: int,
    status: Status,
    why: str,
    within_ms: int,
) -> None:
    sim = lane()
    board = drive(sim, speed)
    t0 = inject_at(sim, board, at_s, fault)
    assert board.wait_idle(5) == status
    assert latency_ms(sim, t0, MOTOR_BITS) <= within_ms
    assert cause(sim) == why
    check_motors_off_and_stays(sim, first_tick(sim, MOTOR_BITS), status)


@pytest.mark.parametrize("wheel", [0, 1])
def test_a_cut_free_encoder_wire_is_grave_at_the_next_order(wheel: int) -> None:
    sim = lane()
    board = drive(sim)
    inject_at(sim, board, 0.8, cut(wheel))
    assert board.wait_idle(5) == Status.PB_MOTEUR  # the suspicion
    sim.advance(0.5)
    t1 = sim.time_s
    board.goto(0, -300)  # the wheel has not counted since: confirmed
    assert board.wait_idle(5) == Status.PB_GRAVE
    assert latency_ms(sim, t1 + 0.002, Status.PB_GRAVE) <= 120  # measured: 97 ms from the order
    assert cause(sim) == "ENCODER_LOST"
    check_motors_off_and_stays(sim, first_tick(sim, Status.PB_GRAVE), Status.PB_GRAVE)
    with pytest.raises(OrderRejected, match="REFUSED_PB_GRAVE"):
        board.goto(0, -300)


# The known false PB_GRAVE "encoder lost": a corner against a wall no shock sensor sees, the
# robot pivoting on it with the drive wheel of that side spinning and its free wheel still or
# twitching. Each case below gave PB_GRAVE; it is a motor problem the robot recovers from.
CORNERS = [
    pytest.param(10, 30, False, id="10 deg at 30 cm/s"),
    pytest.param(40, 30, False, id="40 deg at 30 cm/s"),
    pytest.param(75, 200, False, id="75 deg at 2 m/s"),
    pytest.param(95, 10, True, id="backing into a basket at 10 cm/s"),
]


@pytest.mark.parametrize(("heading", "speed", "backwards"), CORNERS)
def test_a_corner_against_a_wall_is_not_a_cut_wire(
    heading: int, speed: int, backwards: bool
) -> None:
    sim = Simulator({"start": (1000, -300, heading), "shock_count": 0})
    board = Board(sim.bus)
    board.set_vitesse_traj(speed, 150)
    if backwards:
        board.goto_reverse(255)
    else:
        rad = math.radians(heading)
        board.goto(round(1000 + 2000 * math.cos(rad)), round(-300 + 2000 * math.sin(rad)))
    assert board.wait_idle(20) == Status.PB_MOTEUR
    assert sim.trace["contact_force_N"].max() > 0  # it did hit something
    check_motors_off_and_stays(sim, first_tick(sim, MOTOR_BITS), Status.PB_MOTEUR)
    # It backs off: the free wheels count again, and nothing is left suspected.
    if backwards:  # 100 mm forwards along the heading, no turn into the basket
        x, y, h = sim.true_pose()
        board.goto(
            round(x + 100 * math.cos(math.radians(h))), round(y + 100 * math.sin(math.radians(h)))
        )
    else:
        board.goto_reverse(100)
    assert not board.wait_idle(10) & MOTOR_BITS
    assert sim._h.board.planner.faults.lost_suspect == 0


def test_a_low_friction_patch_makes_a_wheel_slip() -> None:
    # The left drive wheel on a patch of x = -700..-400 mm where the grip is 5 % of normal.
    sim = lane()
    board = drive(sim)
    entered = None
    while board.check_busy() & Status.BUSY_TRAJET and sim.time_s < 5:
        on_patch = -700 <= sim.true_pose().x_mm <= -400
        sim.set_friction_scale(0, 0.05 if on_patch else 1.0)
        if on_patch and entered is None:
            entered = sim.time_s
        sim.advance(0.001)
    assert entered is not None
    assert board.check_busy() == Status.PB_MOTEUR
    assert latency_ms(sim, entered, MOTOR_BITS) <= 100  # measured: 75 ms (105 ms per axis)
    assert cause(sim) == "SLIP"
    check_motors_off_and_stays(sim, first_tick(sim, MOTOR_BITS), Status.PB_MOTEUR)


def test_a_battery_sag_the_motors_can_carry_is_no_fault() -> None:
    # 24 V down to 18 V: the top speed falls to about 1.2 m/s, above the 1 m/s asked for.
    sim = lane()
    board = drive(sim)
    inject_at(sim, board, 0.3, sag(18))
    assert board.wait_idle(10) == 0
    x, y, _ = sim.true_pose()
    assert abs(x - TARGET[0]) < 1 and abs(y - TARGET[1]) < 1


def test_after_a_motor_problem_the_next_order_runs() -> None:
    sim = lane({"shock_count": 0}, field=box_field(200))
    board = drive(sim)
    assert board.wait_idle(10) == Status.PB_MOTEUR
    sim.advance(0.5)
    x0 = sim.true_pose().x_mm
    board.goto_reverse(200)  # back off: the order clears PB_MOTEUR and the motors run again
    assert board.wait_idle(5) == 0
    assert sim.true_pose().x_mm == pytest.approx(x0 - 200, abs=1)


# The master going silent (SET_TIMEOUT, docs/failure-model.md).


def test_a_silent_master_s_order_completes_by_default() -> None:
    sim = lane()
    drive(sim)
    sim.advance(4.0)  # the master crashed right after its GOTO: not a single transaction
    x, y, _ = sim.true_pose()
    assert abs(x - TARGET[0]) < 1 and abs(y - TARGET[1]) < 1


def test_a_silent_master_stops_the_robot_with_a_timeout() -> None:
    sim = lane()
    board = Board(sim.bus)
    board.set_timeout(300)
    board.set_vitesse_traj(100, 100)
    board.goto(*TARGET)
    last = sim.time_s  # the master's last transaction ends here
    sim.advance(3.0)
    tr = sim.trace
    stopping = tr["t_s"][np.nonzero(tr["order_state"] == OrderState.STOPPING)[0][0]]
    assert 300 <= (stopping - last) * 1000 <= 302  # the tick after 300 ms of silence
    # Braking from 1 m/s at 1 m/s^2: 0.5 m, then at rest short of the target.
    assert np.abs(tr["v_mm_s"][tr["t_s"] > stopping + 1.05]).max() < 5  # holding, at rest
    assert sim.true_pose().x_mm < TARGET[0] - 500
    assert board.check_busy() == Status.PB_MOTEUR  # abandoned, not finished
    assert board.debug().end_reason == EndReason.TIMEOUT


def test_a_master_whose_strategy_hangs_is_stopped_though_it_polls() -> None:
    """The polling thread lives on (CHECK_BUSY and DEBUG every 10 ms, as `asserv view`) while
    the order thread hangs after its GOTO: reads do not feed the timeout."""
    sim = lane()
    board = Board(sim.bus)
    board.set_timeout(300)
    board.set_vitesse_traj(100, 100)
    board.goto(*TARGET)
    last = sim.time_s  # the last write
    status = board.check_busy()
    while status & Status.BUSY_TRAJET:
        board.debug()
        sim.advance(0.01)
        status = board.check_busy()
    tr = sim.trace
    stopping = tr["t_s"][np.nonzero(tr["order_state"] == OrderState.STOPPING)[0][0]]
    assert 300 <= (stopping - last) * 1000 <= 320
    assert status == Status.PB_MOTEUR
    assert board.debug().end_reason == EndReason.TIMEOUT
    assert sim.true_pose().x_mm < TARGET[0] - 500


def test_a_master_that_writes_keeps_the_robot_going() -> None:
    sim = lane()
    board = Board(sim.bus)
    board.set_timeout(50)
    board.set_vitesse_traj(100, 100)
    board.goto(*TARGET)
    while board.check_busy() & Status.BUSY_TRAJET:
        board.heartbeat()  # every 40 ms
        sim.advance(0.04)
    assert board.check_busy() == 0
    assert board.debug().end_reason == EndReason.DONE
    x, y, _ = sim.true_pose()
    assert abs(x - TARGET[0]) < 1 and abs(y - TARGET[1]) < 1


# ---- docs/failure-model.md's table of section 2 is what the benches print ------------------------

DOC = Path(__file__).resolve().parents[2] / "docs" / "failure-model.md"
HEADER = "| Fault | Detected by | Detected within (`bench/detection.py`) |"
# The table's rows (the start of their first cell) and the bench/detection.py line each quotes;
# None: a row with no figure of its own (bounds, with the test that asserts them).
ROWS = {
    "a shock sensor closes": "shock sensor",
    "a wall no shock sensor sees": "wall, no shock sensor",
    "a stalled motor": "stalled motor",
    "both drive wheels jammed": "both drive wheels jammed",
    "a free-wheel encoder wire cut": "free-wheel encoder wire cut",
    "a motor-encoder wire cut": "motor-encoder wire cut",
    "a low-friction patch": None,
    "battery sag": "battery sag",
    "three motor problems": None,
    "a free wheel jumping": None,
}


def doc_table() -> dict[str, list[str]]:
    """Section 2's table: the row's key in ROWS -> its six cells."""
    lines = DOC.read_text().splitlines()
    start = next(i for i, line in enumerate(lines) if line.startswith(HEADER))
    rows: dict[str, list[str]] = {}
    for line in lines[start + 2 :]:
        if not line.startswith("|"):
            break
        cells = [c.strip() for c in line.strip("|").split(" | ")]
        key = next(k for k in ROWS if cells[0].startswith(k))
        assert len(cells) == 6 and key not in rows, line
        rows[key] = cells
    assert list(rows) == list(ROWS)  # every row known, in order
    return rows


def doc_block(command: str) -> list[str]:
    """The lines of the page's output block of command (test_docs_examples compares them with
    what the command prints)."""
    lines = DOC.read_text().splitlines()
    i = lines.index(f"<!-- example: output {command} -->") + 2
    block = []
    while i < len(lines) and lines[i].startswith("    "):
        block.append(lines[i].strip())
        i += 1
    assert block, command
    return block


def test_the_detection_table_is_what_the_bench_prints() -> None:
    """Each figure of the table is a line of bench/detection.py's block, and the shock's rest and
    force bench/shock_stop.py's line at 100 cm/s: the table cannot drift from them."""
    bench = {}
    for line in doc_block("python bench/detection.py")[1:-1]:
        key, figures = line.split(": ", 1)
        bench[key] = figures.split("   (goal")[0]
    rows = doc_table()
    quoted = {k: bench[v] for k, v in ROWS.items() if v is not None}
    assert {k: rows[k][2] for k in quoted} == quoted
    # Every line of the bench in the table; the next order after a cut, in its recovery.
    assert set(bench) == {*ROWS.values(), "the next order after a free-wheel cut"} - {None}
    assert (
        bench["the next order after a free-wheel cut"] in rows["a free-wheel encoder wire cut"][5]
    )
    # The rows that quote no bench quote no time of their own but their bound.
    for key in ("three motor problems", "a free wheel jumping"):
        assert not re.search(r"\d+ ms", " ".join(rows[key])), rows[key]
    assert re.findall(r"\d+ ms", rows["a low-friction patch"][2]) == ["100 ms"]
    shock = next(
        line
        for line in doc_block("python bench/shock_stop.py --random 150")
        if line.startswith("limit 100 cm/s:")
    )
    m = re.search(r"rest +(\d+) ms .* ([\d.]+) N", shock)
    assert m, shock
    assert (
        f"from 1 m/s into a 150 mm disc, at rest {m[1]} ms after the contact, {m[2]} N from "
        "300 ms on" in rows["a shock sensor closes"][4]
    )


def test_the_thresholds_in_the_table_are_the_board_s() -> None:
    """The column "Detected by" (and the repeated rule) against board_default_config()."""
    cfg = Simulator().board_config  # kept: f points into it
    f = cfg.faults
    rows = doc_table()
    words = {2: "two", 3: "three", 4: "four", 5: "five"}
    assert (
        f"overcurrent (above {f.current_max_ma / 1000:g} A for {f.current_ms} ms)"
        in (rows["both drive wheels jammed"][1])
    )
    assert (
        f"following error ({f.following_max_um / 1000:g} mm for {f.following_ms} ms)"
        in (rows["battery sag"][1])
    )
    assert (
        f"while its motor turns {f.lost_min_um / 1000:g} mm"
        in (rows["a free-wheel encoder wire cut"][1])
    )
    within = f"within {f.repeat_window_ms / 1000:g} s"
    assert rows["three motor problems"][0] == f"{words[f.repeat_max]} motor problems {within}"
    assert (
        f"the {'third' if f.repeat_max == 3 else '?'} {within} is PB_GRAVE"
        in (rows["a motor-encoder wire cut"][5])
    )
    # The encoder range: ODOMETRY_STEP_Q16_MAX [um * 2^16] (firmware/core/odometry.h).
    header = (DOC.parents[1] / "firmware" / "core" / "odometry.h").read_text()
    step = re.search(r"#define ODOMETRY_STEP_Q16_MAX (\S+)", header)
    assert step and step[1] == "INT32_MAX"
    assert (
        f"more than {(2**31 - 1) / 2**16 / 1000:.1f} mm in one tick"
        in (rows["a free wheel jumping"][0])
    )
