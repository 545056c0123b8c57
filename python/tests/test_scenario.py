"""Scenario files: checked whole before anything runs, errors name the file and line, and a good
scenario plays on the simulated board."""

from __future__ import annotations

from pathlib import Path

import pytest

from asserv import ResetCause, Status, scenario
from asserv.cli import main


@pytest.mark.parametrize(
    ("text", "line", "message"),
    [
        ("goto 200 100\nfly 3\n", 2, "unknown command 'fly'"),
        ("goto 200\n", 1, "goto takes goto X_MM Y_MM [OPTIONS], got 1 argument(s)"),
        ("goto 200 abc\n", 1, "argument 2 of goto ('abc') is not valid"),
        ("goto 40000 0\n", 1, "goto: "),
        ("# fine\n\ngoto 0 0 bord+nope\n", 3, "argument 3 of goto"),
        ("goto_panier 200\n", 1, "outside -180..180"),
        ("set_vitesse_traj 0\n", 1, "set_vitesse_traj: "),
        ("goto 0 0\nseed 3\n", 2, "'seed' is a setup line"),
        ("field nowhere\ngoto 0 0\n", 1, "bad field file"),
        ("config mass_kgg 3\ngoto 0 0\n", 1, "unknown simulator setting 'mass_kgg'"),
        ("start 0 0\ngoto 0 0\n", 1, "start takes three numbers"),
        ("wait -1\n", 1, "positive number of seconds"),
        ("pec maybe\ngoto 0 0\n", 1, "pec takes on or off"),
        ("board slow_shiftt 3\ngoto 0 0\n", 1, "unknown board setting 'slow_shiftt'"),
        ("board slow_shift 4\ngoto 0 0\n", 1, "the simulator refused this configuration"),
        ("board slow_shift\ngoto 0 0\n", 1, "board takes a setting and its value"),
        ("goto 0 0\nat 1 reset POWER_ON\n", 2, "at 1 reset takes reset BROWN_OUT|"),
        ("goto 0 0\nat 1 reset UNPLUGGED\n", 2, "at 1 reset takes"),
        ("goto 0 0\nat 1 reset WATCHDOG maybe\n", 2, "at 1 reset takes"),
        ("goto 0 0\nat 1 reset WATCHDOG kept 1001\n", 2, "at 1 reset takes"),
        ("goto 0 0\nat 1 reset WATCHDOG kept 30 5\n", 2, "at 1 reset takes"),
        ("set_timeout -1\n", 1, "set_timeout: "),
    ],
)
def test_bad_lines_are_named(text: str, line: int, message: str) -> None:
    with pytest.raises(scenario.ScenarioError) as e:
        scenario.parse(text, "s.txt")
    assert str(e.value).startswith(f"s.txt:{line}: ")
    assert message in str(e.value)


def test_empty_scenario_is_refused() -> None:
    with pytest.raises(scenario.ScenarioError, match="no bus command"):
        scenario.parse("# nothing\nseed 3\n", "s.txt")


def test_options_by_name_or_number() -> None:
    scn = scenario.parse("goto 1 2 ligne+bord\ngoto 1 2 1\nset_filtre souple\n")
    assert [s.args for s in scn.steps] == [[1, 2, 3], [1, 2, 1], [1]]


def test_annex_scenario_plays_to_the_basket() -> None:
    scn = scenario.load(scenario.SCENARIO_DIR / "annex.txt")
    lines: list[str] = []
    res = scenario.play(scn, lines.append)
    assert res.ok
    assert res.final_status & Status.CHOC_PANIER
    assert res.targets == [(200.0, 100.0), (100.0, 50.0)]
    err = scenario.summary(res, lines.append)
    assert err <= res.board.position().radius_mm  # the truth lies within the reported radius
    assert any("GOTO x_mm=100 y_mm=50" in ln for ln in lines)


@pytest.mark.parametrize("name", ["annex", "recal_line", "recal_border", "recal_basket"])
def test_scenarios_with_slow_steps_at_125_hz(name: str) -> None:
    """The slow steps every 8th tick (the AVR's schedule, docs/control.md): every scenario ends
    as it does with them at every tick, its final estimate within 2 mm of that one's and the
    truth within the reported radius."""
    ends = []
    for shift in (0, 3):
        scn = scenario.load(scenario.SCENARIO_DIR / f"{name}.txt")
        scn.board["slow_shift"] = shift
        res = scenario.play(scn, lambda _line: None)
        assert res.ok
        err = scenario.summary(res, lambda _line: None)
        pose = res.board.position()
        assert err <= pose.radius_mm
        ends.append((res.final_status, pose.x_mm, pose.y_mm, pose.angle_2deg))
    (s0, x0, y0, a0), (s3, x3, y3, a3) = ends
    assert s3 == s0
    assert abs(x3 - x0) <= 2 and abs(y3 - y0) <= 2 and abs(a3 - a0) <= 1


def test_cli_reports_a_bad_scenario_and_runs_nothing(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    p = tmp_path / "bad.txt"
    p.write_text("set_vitesse_traj 100\ngoto 200 100\nwait 5\ngoto 1\n")
    assert main(["sim", "run", str(p)]) == 2
    captured = capsys.readouterr()
    assert f"{p}:4: goto takes" in captured.err
    assert captured.out == ""  # nothing was played


def test_cli_runs_a_scenario_and_plots(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    p = tmp_path / "s.txt"
    p.write_text("seed 3\nrandomize\nset_vitesse_traj 50 50\ngoto 0 -500\nwait\nposition\n")
    png = tmp_path / "s.png"
    assert main(["sim", "run", str(p), "--png", str(png)]) == 0
    out = capsys.readouterr().out
    assert "order ended: idle" in out and "POSITION -> Pose(x_mm=0, y_mm=-500" in out
    assert png.read_bytes()[:4] == b"\x89PNG"


def test_cli_missing_scenario(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["sim", "run", "/nonexistent.txt"]) == 2
    assert "cannot read the scenario" in capsys.readouterr().err


def test_cli_zoom_is_checked(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    p = tmp_path / "s.txt"
    p.write_text("goto 0 -800\nwait\n")
    png = tmp_path / "s.png"
    assert main(["sim", "run", str(p), "--png", str(png), "--zoom", "5", "1", "0", "1"]) == 2
    assert "needs XMIN < XMAX" in capsys.readouterr().err
    assert main(["sim", "run", str(p), "--zoom", "0", "1", "0", "1"]) == 2
    assert "give --png too" in capsys.readouterr().err
    assert not png.exists()
    assert (
        main(["sim", "run", str(p), "--png", str(png), "--zoom", "-200", "200", "-1000", "-600"])
        == 0
    )
    assert png.read_bytes()[:4] == b"\x89PNG"


def test_start_uncertainty_lines(tmp_path: Path) -> None:
    text = "board_start 0 -850 0\nstart_uncertainty 2 1\ngoto 0 -800\n"
    scn = scenario.parse(text, "s.txt")
    assert scn.board_start == (0, -850, 0) and scn.start_uncertainty == (2, 1)
    with pytest.raises(scenario.ScenarioError, match=r"s.txt:1: start_uncertainty takes two"):
        scenario.parse("start_uncertainty 2\n", "s.txt")
    with pytest.raises(scenario.ScenarioError, match=r"s.txt:1: bad start_uncertainty line"):
        scenario.parse("start_uncertainty 2 100\n", "s.txt")
    with pytest.raises(scenario.ScenarioError, match=r"s.txt:2: 'board_start' is a setup line"):
        scenario.parse("goto 0 -800\nboard_start 0 0 0\n", "s.txt")


def test_a_reset_rehearsed_mid_goto() -> None:
    """scenarios/reset_mid_goto.txt: a watchdog reset during a GOTO, the RAM kept; the order
    ends abandoned, RESET_INFO says why, and the GOTO sent again ends where it should."""
    scn = scenario.load(scenario.SCENARIO_DIR / "reset_mid_goto.txt")
    lines: list[str] = []
    res = scenario.play(scn, lines.append)
    assert res.ok, lines[-5:]
    info = res.board.reset_info()
    assert (info.cause, info.count, info.pose_lost) == (ResetCause.WATCHDOG, 1, False)
    assert any("event (line" in ln and "reset WATCHDOG kept 30" in ln for ln in lines)
    assert any("RESET_INFO -> ResetInfo(cause=<ResetCause.WATCHDOG" in ln for ln in lines)


def test_a_reset_that_loses_the_ram_refuses_the_next_goto() -> None:
    scn = scenario.parse(
        "goto 600 -500\nat 0.5 reset BROWN_OUT lost 0\nwait\nexpect motor\ngoto 0 -500\n"
    )
    lines: list[str] = []
    res = scenario.play(scn, lines.append)
    assert not res.ok
    assert any("REFUSED_NO_POSE" in ln for ln in lines), lines[-5:]
    assert res.board.reset_info().pose_lost


def test_the_fix_source_draws_from_the_seed_wherever_its_line_is() -> None:
    first = scenario.parse("fixes 10 10 1 100\nseed 7\nposition\n")
    last = scenario.parse("seed 7\nfixes 10 10 1 100\nposition\n")
    seeds = []
    for scn in (first, last):
        sim = scn.simulator(record=False)
        feeds: list[object] = []
        sim.add_fix_source = feeds.append  # type: ignore[method-assign,assignment]
        scn.prepare(sim, lambda _: None)
        seeds.append(feeds[0].seed)  # type: ignore[attr-defined]
    assert seeds == [7, 7]
