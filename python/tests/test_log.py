"""Run logs (asserv.log): the MCAP file read back with the mcap library, the CSV, the CLI."""

from __future__ import annotations

import itertools
import json
import math
import time
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from asserv import backends as bus_mod
from asserv import cli, log, scenario
from asserv.driver import Board
from asserv.sim import Simulator

ROOT = Path(__file__).resolve().parents[2]


def _run(goto: tuple[int, int] = (-600, 300), seconds: float = 3.0) -> Simulator:
    sim = Simulator()
    board = Board(sim.bus)
    board.goto(*goto)
    sim.advance(seconds)
    return sim


@pytest.fixture(scope="module")
def sim_run() -> Simulator:
    return _run()


def _same(a: np.ndarray, b: np.ndarray) -> None:
    assert len(a) == len(b)
    for name in log.LOG_FIELDS:
        np.testing.assert_array_equal(a[name], b[name], err_msg=name)


def test_mcap_schemas_and_values_against_the_trace(sim_run: Simulator, tmp_path: Path) -> None:
    rows = log.from_sim(sim_run)
    path = tmp_path / "run.mcap"
    log.save(rows, mcap=path, field=sim_run.field, outline=log.Outline.of(sim_run))
    back = log.read_mcap(path)
    assert back.schemas == log.TOPICS
    for topic in log.TOPICS:
        assert back.encodings[topic] == ("jsonschema", "json"), topic
    # /asserv carries every column of every tick, exactly (JSON keeps a float's repr).
    tr = sim_run.trace
    assert len(back.rows) == len(tr)
    for name in tr.dtype.names or ():
        if name in log.LOG_FIELDS:
            np.testing.assert_array_equal(back.rows[name], tr[name], err_msg=name)
    # The poses in metres, the heading as a quaternion about z.
    est = back.messages["/pose/estimate"]
    tru = back.messages["/pose/true"]
    assert len(est) == len(tru) == len(tr)
    for i in (0, len(tr) // 2, len(tr) - 1):
        p = est[i]["pose"]
        assert p["position"]["x"] == pytest.approx(tr["est_x_mm"][i] / 1000)
        assert p["position"]["y"] == pytest.approx(tr["est_y_mm"][i] / 1000)
        q = p["orientation"]
        heading = math.degrees(2 * math.atan2(q["z"], q["w"]))
        assert math.remainder(heading - tr["est_heading_deg"][i], 360) == pytest.approx(0, abs=1e-9)
        assert tru[i]["pose"]["position"]["x"] == pytest.approx(tr["x_mm"][i] / 1000)
        assert est[i]["frame_id"] == "field"
    tf = back.messages["/tf"]
    assert {m["child_frame_id"] for m in tf} == {"robot", "robot_true"}
    # The field: its border as a closed line strip at the table's size, one cylinder a basket.
    (scene,) = back.messages["/field"]
    (entity,) = scene["entities"]
    xs = [pt["x"] for pt in entity["lines"][0]["points"]]
    assert max(xs) == pytest.approx(sim_run.field.length_mm / 2000)
    assert len(entity["cylinders"]) == len(sim_run.field.baskets)
    assert len(entity["lines"]) == 1 + len(sim_run.field.lines)
    assert back.field is not None and back.field.baskets == sim_run.field.baskets
    assert back.field.lines == sim_run.field.lines and back.outline == log.Outline.of(sim_run)
    (robot,) = back.messages["/robot"]
    assert {e["frame_id"] for e in robot["entities"]} == {"robot", "robot_true"}
    # Each schema is JSON and says which fields the messages have.
    for schema in log.SCHEMAS.values():
        assert json.loads(json.dumps(schema))["type"] == "object"


def test_csv_has_the_same_values_and_a_following_error(sim_run: Simulator, tmp_path: Path) -> None:
    rows = log.from_sim(sim_run)
    path = tmp_path / "run.csv"
    log.save(rows, csv=path)
    header = path.read_text().splitlines()[0].split(",")
    assert "dist_err_mm" in header and "angle_err_mm" in header
    _same(log.read_csv(path), rows)


def _debug_while_playing(name: str) -> tuple[Simulator, list[tuple[int, float, float]]]:
    """Play a scenario of scenarios/ reading DEBUG every 5 ms while it waits."""
    scn = scenario.load(ROOT / "scenarios" / f"{name}.txt")
    sim = scn.simulator()
    board = Board(sim.bus)
    seen: list[tuple[int, float, float]] = []

    def debug() -> None:
        d = board.debug()
        seen.append((d.tick, d.dist_err_um / 1000, d.angle_err_um / 1000))
        sim.advance(0.005)

    for step in scn.steps:
        if step.command == "wait":
            while board.check_busy() & 6:
                debug()
        elif step.command == "sleep":
            sim.advance(step.args[0])
        else:
            getattr(board, scenario.BUS_COMMANDS[step.command][0])(*step.args)
    for _ in range(100):
        debug()
    return sim, seen


@pytest.mark.parametrize("name", ["annex", "recal_basket", "recal_line", "recal_border"])
def test_following_errors_rebuilt_are_the_boards(name: str) -> None:
    """The simulator log's following errors (rebuilt from the trace) against the board's own,
    read with DEBUG while the scenario plays: within 0.35 mm, or unknown (NaN) only from a
    border recalibration's SQUARE state to the next order."""
    sim, seen = _debug_while_playing(name)
    rows = log.from_sim(sim)
    ticks = np.round(rows["t_s"] * 1000).astype(int) % 65536
    known = 0
    largest = 0.0
    for tick, dist, angle in seen:
        (i,) = np.nonzero(ticks == tick)
        assert len(i) == 1
        r = rows[i[0]]
        if np.isnan(r["dist_err_mm"]):
            assert np.isnan(r["angle_err_mm"]) and name == "recal_border"
            continue
        # 0.35 mm: the annex's worst tick is the basket's impact (9.069 s, 296 N), 0.24 mm off
        # with 100 us substeps everywhere, 0.32 mm with the simulator's default long step
        assert r["dist_err_mm"] == pytest.approx(dist, abs=0.35), r["t_s"]
        assert r["angle_err_mm"] == pytest.approx(angle, abs=0.35), r["t_s"]
        largest = max(largest, abs(dist), abs(angle))
        known += 1
    assert known > 0.75 * len(seen)
    assert largest > 0.35  # the comparison saw following errors larger than its tolerance
    unknown = np.isnan(rows["dist_err_mm"])
    states = set(rows["order_state"][unknown].astype(int))
    assert not unknown.any() or 6 in states  # SQUARE


@given(st.lists(st.integers(1, 3000), max_size=8))
@settings(max_examples=25, deadline=None)
def test_following_errors_do_not_depend_on_the_chunks(cuts: list[int]) -> None:
    tr = _border_trace()
    whole = log.following_errors(tr, 160.0)
    fe = log.FollowingErrors(160.0)
    bounds = sorted({0, len(tr), *(c % len(tr) for c in cuts)})
    parts = [fe.update(tr[a:b]) for a, b in itertools.pairwise(bounds)]
    for k in (0, 1):
        np.testing.assert_allclose(np.concatenate([p[k] for p in parts]), whole[k], atol=1e-9)


_BORDER: list[np.ndarray] = []


def _border_trace() -> np.ndarray:
    if not _BORDER:
        res = scenario.play(scenario.load(ROOT / "scenarios/recal_border.txt"), out=lambda s: None)
        _BORDER.append(res.sim.trace)
    return _BORDER[0]


_value = st.one_of(
    st.floats(allow_nan=False, allow_infinity=False, width=64),
    st.just(math.nan),
)


_integer = st.one_of(st.integers(0, 255).map(float), st.just(math.nan))
_row = st.tuples(*[_integer if n in log.INTEGER else _value for n in log.LOG_FIELDS])


@given(st.lists(_row, max_size=30))
@settings(suppress_health_check=[HealthCheck.function_scoped_fixture], deadline=None)
def test_any_rows_round_trip(tmp_path: Path, data: list[tuple[float, ...]]) -> None:
    rows = np.array(data, dtype=log.LOG_DTYPE) if data else log.empty(0)
    # A log's times go forwards (the MCAP reader gives messages in time order).
    rows["t_s"] = np.cumsum(np.abs(np.nan_to_num(rows["t_s"])) % 1000 + 0.001)
    m, c = tmp_path / "r.mcap", tmp_path / "r.csv"
    log.save(rows, mcap=m, csv=c)
    _same(log.read_mcap(m).rows, rows)
    _same(log.read_csv(c), rows)
    # the integer columns are written as integers: no "5.0" in the CSV or the JSON
    lines = c.read_text().splitlines()
    k = [log.LOG_FIELDS.index(n) for n in sorted(log.INTEGER & set(log.LOG_FIELDS))]
    for line in lines[1:]:
        cells = line.split(",")
        assert all("." not in cells[i] for i in k), line


def test_an_integer_column_refuses_a_fraction(tmp_path: Path) -> None:
    rows = log.empty(1)
    rows["t_s"], rows["status"] = 0.0, 2.5
    with pytest.raises(log.LogError, match=r"the column status holds integers, not 2\.5"):
        log.save(rows, csv=tmp_path / "r.csv")


@given(
    st.integers(-1300, 1300),
    st.integers(-900, 900),
    st.integers(1, 10),
)
@settings(
    max_examples=6, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture]
)
def test_any_recorded_run_round_trips(tmp_path: Path, x: int, y: int, every: int) -> None:
    sim = _run((x, y), 2.0)
    rows = log.from_sim(sim)
    m = tmp_path / "run.mcap"
    log.save(rows, mcap=m, field=sim.field, every=every)
    back = log.read_mcap(m)
    _same(back.rows, rows[::every])
    assert len(back.messages["/pose/estimate"]) == len(rows[::every])


def test_bad_files_are_reported(tmp_path: Path) -> None:
    with pytest.raises(log.LogError, match="not an asserv MCAP"):
        (tmp_path / "x.mcap").write_bytes(b"not mcap at all")
        log.read_mcap(tmp_path / "x.mcap")
    with pytest.raises(log.LogError, match="not an asserv CSV"):
        (tmp_path / "x.csv").write_text("a,b\n1,2\n")
        log.read_csv(tmp_path / "x.csv")
    with pytest.raises(log.LogError, match="cannot write"):
        log.save(log.empty(1), mcap=tmp_path / "no" / "x.mcap")
    with pytest.raises(log.LogError, match="nothing to write"):
        log.save(log.empty(1))


def test_sim_run_writes_mcap_and_csv(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    m, c = tmp_path / "run.mcap", tmp_path / "run.csv"
    code = cli.main(
        ["sim", "run", str(ROOT / "scenarios/annex.txt"), "--mcap", str(m), "--csv", str(c)]
    )
    assert code == 0
    rows = log.read_csv(c)
    _same(log.read_mcap(m).rows, rows)
    assert len(rows) > 1000 and not np.isnan(rows["x_mm"]).any()
    assert f"mcap: {m}" in capsys.readouterr().out


@pytest.mark.parametrize("bad", ["missing/run.mcap", "."])
def test_sim_run_bad_output_changes_nothing(
    tmp_path: Path, bad: str, capsys: pytest.CaptureFixture[str]
) -> None:
    target = tmp_path / bad
    code = cli.main(["sim", "run", str(ROOT / "scenarios/annex.txt"), "--mcap", str(target)])
    assert code == 2
    err = capsys.readouterr()
    assert "asserv sim run:" in err.err and "Traceback" not in err.err
    assert err.out == ""  # nothing was played


def test_log_a_board(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    """``asserv --bus N log`` on a simulated board behind the bus: 50 rows a second, the board's
    estimate and its DEBUG values, the truth unknown."""
    sim = Simulator()
    Board(sim.bus).goto(400, -850)
    monkeypatch.setitem(bus_mod.BACKENDS, "smbus2", lambda n: sim.bus)
    m, c = tmp_path / "b.mcap", tmp_path / "b.csv"
    before = time.time_ns()
    code = cli.main(["--bus", "1", "log", "--mcap", str(m), "--csv", str(c), "--duration", "2"])
    after = time.time_ns()
    assert code == 0, capsys.readouterr().err
    rows = log.read_csv(c)
    assert 95 <= len(rows) <= 101
    assert np.isnan(rows["x_mm"]).all()
    assert np.all(np.diff(rows["t_s"]) > 0.015)
    # The robot moved towards x = 400 and the log saw it, with a speed and a busy status.
    assert rows["est_x_mm"][-1] > 100
    assert rows["v_mm_s"].max() > 100
    assert (rows["status"].astype(int) & 2).any()
    back = log.read_mcap(m)
    _same(back.rows, rows)
    assert "/pose/true" not in back.schemas
    # a board's log is dated on the wall clock too: the log opened between before and after
    assert back.start_ns is not None and before <= back.start_ns <= after
    assert back.profile == log.PROFILE


@pytest.mark.parametrize(
    "argv",
    [
        ["log", "--mcap", "x.mcap"],  # no --bus
        ["--bus", "1", "log"],  # no output
        ["--bus", "x", "log", "--csv", "x.csv"],
        ["--bus", "1", "log", "--csv", "x.csv", "--hz", "0"],
        ["--bus", "1", "log", "--csv", "missing/x.csv"],
    ],
)
def test_log_bad_arguments(
    argv: list[str], monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    def no_bus(n: int) -> None:
        raise AssertionError("the bus must not be opened")

    monkeypatch.setitem(bus_mod.BACKENDS, "smbus2", no_bus)
    assert cli.main(argv) == 2
    assert "asserv log:" in capsys.readouterr().err


@given(st.binary(max_size=300))
@settings(suppress_health_check=[HealthCheck.function_scoped_fixture], deadline=None)
def test_any_bytes_read_as_a_log_or_a_log_error(tmp_path: Path, data: bytes) -> None:
    path = tmp_path / "x.mcap"
    path.write_bytes(b"\x89MCAP0\r\n" + data)
    try:
        log.read_mcap(path)
    except log.LogError as e:
        assert str(path) in str(e)
