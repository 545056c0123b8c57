"""asserv tune: the step-response figures on known responses, the ranking, the sweep, the CLI."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from asserv import backends as bus_mod
from asserv import cli, tune
from asserv.sim import Simulator

DT = 1e-4
T = np.arange(0, 5, DT)


def test_first_order_response() -> None:
    """y = A (1 - exp(-t/tau)): rise tau ln 9, 2 % settling tau ln 50, no overshoot."""
    tau, amp = 0.2, 150.0
    y = amp * (1 - np.exp(-T / tau))
    m = tune.metrics(T, y, amp)
    assert m.rise_s == pytest.approx(tau * math.log(9), abs=2 * DT)
    assert m.settling_s == pytest.approx(tau * math.log(50), abs=2 * DT)
    assert m.overshoot_pct == 0
    assert m.steady_state_error == pytest.approx(0, abs=1e-6)
    assert math.isnan(m.max_following_mm)


def test_second_order_overshoot_and_settling() -> None:
    """Underdamped: overshoot exp(-pi z / sqrt(1 - z^2)); the 2 % band is left for the last time
    before the envelope exp(-z w t) / sqrt(1 - z^2) falls under 2 %."""
    z, w = 0.3, 12.0
    wd = w * math.sqrt(1 - z * z)
    phi = math.acos(z)
    y = 1 - np.exp(-z * w * T) / math.sqrt(1 - z * z) * np.sin(wd * T + phi)
    m = tune.metrics(T, y, 1.0)
    assert m.overshoot_pct == pytest.approx(100 * math.exp(-math.pi * z / math.sqrt(1 - z * z)))
    envelope = math.log(1 / (0.02 * math.sqrt(1 - z * z))) / (z * w)
    assert m.settling_s <= envelope + DT
    assert m.settling_s > envelope - math.pi / wd  # within the last half period of the envelope
    assert m.rise_s < math.pi / wd  # before the peak


def test_steady_state_error_and_unsettled() -> None:
    y = 0.95 * 100 * (1 - np.exp(-T / 0.1))
    m = tune.metrics(T, y, 100.0, following=[0.0, -3.0, 2.0])
    assert m.steady_state_error == pytest.approx(5.0, abs=1e-3)
    assert not m.settled and math.isnan(m.settling_s)
    assert tune.cost(m) == math.inf
    assert m.max_following_mm == 3.0
    # A wider band takes it as settled.
    assert tune.metrics(T, y, 100.0, band=6.0).settled


def test_a_response_that_never_rises() -> None:
    m = tune.metrics(T, np.zeros_like(T), 10.0)
    assert math.isnan(m.rise_s) and not m.settled


@given(
    st.floats(-500, 500).filter(lambda a: abs(a) > 1),
    st.floats(-1000, 1000),
    st.floats(0.05, 1.0),
    st.floats(0.1, 0.9),
)
def test_metrics_do_not_depend_on_the_step_size_and_start(
    amp: float, start: float, tau: float, z: float
) -> None:
    t = T[::10]
    wd = 8 * math.sqrt(1 - z * z)
    e = 1 - np.exp(-z * 8 * t) / math.sqrt(1 - z * z) * np.sin(wd * t + math.acos(z))
    ref = tune.metrics(t, e, 1.0)
    m = tune.metrics(t, start + amp * e, start + amp, start=start)
    assert m.overshoot_pct == pytest.approx(ref.overshoot_pct, abs=1e-6)
    for a, b in ((m.rise_s, ref.rise_s), (m.settling_s, ref.settling_s)):
        assert (math.isnan(a) and math.isnan(b)) or a == pytest.approx(b, abs=1e-9)
    assert m.steady_state_error == pytest.approx(amp * ref.steady_state_error, abs=1e-6)


def _m(settling: float, overshoot: float = 0.0, sse: float = 0.0) -> tune.StepMetrics:
    return tune.StepMetrics(0.1, overshoot, settling, sse, 0.0)


def test_rank_orders_by_cost() -> None:
    a, b, c, d = (tune.Gains(p, 0, 0) for p in (1, 2, 3, 4))
    ranked = tune.rank(
        [
            (a, [_m(0.5), _m(0.5)]),  # 1.0
            (b, [_m(0.3, overshoot=10), _m(0.3)]),  # 0.8
            (c, [_m(math.nan), _m(0.1)]),  # never settled
            (d, [_m(0.2, sse=1.0), _m(0.2)]),  # 0.5
        ]
    )
    assert [g for g, _ in ranked] == [d, b, a, c]
    assert ranked[0][1] == pytest.approx(0.5)
    assert ranked[-1][1] == math.inf


@given(st.lists(st.tuples(st.floats(0, 5), st.floats(0, 50), st.floats(-5, 5)), max_size=20))
def test_rank_is_a_sorted_permutation(sets: list[tuple[float, float, float]]) -> None:
    results = [(tune.Gains(k, 0, 0), [_m(s, o, e)]) for k, (s, o, e) in enumerate(sets)]
    ranked = tune.rank(results)
    assert sorted(g.p for g, _ in ranked) == list(range(len(sets)))
    costs = [c for _, c in ranked]
    assert costs == sorted(costs)


def test_steps_in_the_simulator_and_the_way_back() -> None:
    sim, board = tune.sim_board()
    start = sim.true_pose()
    for axis, size in (("distance", 150.0), ("angle", -60.0)):
        r = tune.step(board, axis, size, gains=tune.STD, window_s=2.0, limits=(50, 100))
        assert r.metrics.settled, axis
        assert abs(r.y[-1] - size) < max(1.0, abs(size) * 0.02)
        assert r.metrics.overshoot_pct < 5
        back = sim.true_pose()
        assert math.hypot(back.x_mm - start.x_mm, back.y_mm - start.y_mm) < 3
        assert abs(math.remainder(back.heading_deg - start.heading_deg, 360)) < 1


def test_tune_cli_sweeps_and_applies_on_a_board(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    """On a board behind a bus (a simulated one here): the sweep, the table, --apply."""
    sim = Simulator({"start": (-300.0, 0.0, 0.0)})
    monkeypatch.setitem(bus_mod.BACKENDS, "smbus2", lambda n: sim.bus)
    png = tmp_path / "tune.png"
    argv = ["--bus", "1", "tune", "--axis", "distance", "--p", "50,400", "--i", "0", "--d", "160"]
    code = cli.main([*argv, "--window", "1.5", "--apply", "--png", str(png)])
    assert code == 0, capsys.readouterr().err
    out = capsys.readouterr().out
    lines = [ln for ln in out.splitlines() if "P=" in ln and "distance" in ln]
    assert len(lines) == 2
    best = lines[0].split()[1]
    assert "applied: SET_FILTRE_RAW" in out
    p = int(best.removeprefix("P="))
    raw = bytes([9, p >> 8, p & 0xFF, 0, 0, 0, 160])
    assert sim.frames[-1].kind == "R"
    assert any(f.kind == "W" and f.data == raw for f in sim.frames[-4:])
    assert png.read_bytes()[:4] == b"\x89PNG"


@pytest.mark.parametrize(
    "args",
    [
        ["--p", "x"],
        ["--p", "70000"],
        ["--axis", "both", "--step", "100"],
        ["--axis", "distance", "--step", "10"],
        ["--axis", "angle", "--step", "200"],
        ["--window", "0"],
        ["--speed", "0"],
        ["--png", "missing/x.png"],
    ],
)
def test_tune_bad_arguments(args: list[str], capsys: pytest.CaptureFixture[str]) -> None:
    assert cli.main(["tune", *args]) == 2
    err = capsys.readouterr()
    assert err.err.startswith("asserv tune:") and err.out == ""
