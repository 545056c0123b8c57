"""A smoke run of the accuracy bench (``asserv bench accuracy``) on a handful of robots: the
format of its table, and figures that a working board must give."""

from __future__ import annotations

import re
from pathlib import Path

import pytest

from asserv.cli import main
from asserv.sim import accuracy


def cells(out: str, title: str) -> dict[str, list[str]]:
    """The rows under a block title: speed label -> its cells."""
    lines = out.splitlines()
    i = next(k for k, line in enumerate(lines) if line.startswith(title))
    rows: dict[str, list[str]] = {}
    for line in lines[i + 1 :]:
        m = re.match(r"  (\d\.\d m/s)", line)
        if not m:
            break
        rows[m.group(1)] = line[accuracy._LABEL :].split()
    return rows


def test_bench_accuracy_smoke(capsys: pytest.CaptureFixture[str], tmp_path: Path) -> None:
    assert main(["bench", "accuracy", "--robots", "3", "--out", str(tmp_path)]) == 0
    out = capsys.readouterr().out
    assert out.startswith("asserv bench accuracy: 3 robots (seeds 0..2), a 1.8 m straight")
    assert re.search(r"spec 2002 +legacy +asserv +asserv +goal", out)
    assert re.search(r"P-only +nominal +calibrated", out)
    # the specification's figures beside ours
    odo = cells(out, "odometry error |estimate - truth|")
    assert [r[0] for r in odo.values()] == ["+/-20"] * 3
    arrival = cells(out, "arrival error |target - estimate|")
    spec, _legacy, asserv, calibrated, *goal = arrival["1.0 m/s"]
    assert (spec, goal) == ("+/-70", ["<=", "2", "met"])
    assert float(asserv) < 2 and float(calibrated) < 2
    times = cells(out, "trajectory time / time-optimal bound")
    for row in times.values():
        # A move ends once the robot is within the arrival window (0.5 mm) of the target: a few
        # ms before the bound of the whole distance (2.8 s at 1 m/s) at most.
        assert all(0.995 <= float(c) <= 1.05 for c in row[:3])
    own = cells(out, "  without the start pose error")
    for row in own.values():
        assert float(row[2]) < 40 and float(row[1]) > float(row[2])  # calibration helps
    # the odometry's goal: a ratio to the encoder noise alone, printed below the table
    floor = float(
        re.findall(r"encoder noise alone over 1.8 m on these robots, p95: ([\d.]+) mm", out)[0]
    )
    ratios = cells(out, "  the same / the encoder noise alone")
    for speed, row in ratios.items():
        assert float(row[2]) == pytest.approx(float(own[speed][2]) / floor, abs=0.02)
        assert row[3:5] == ["<=", str(accuracy.ODOMETRY_OVER_NOISE)]
        assert row[6] == ("met" if float(row[2]) <= accuracy.ODOMETRY_OVER_NOISE else "MISSED")
    cover = cells(out, "error radius: coverage")
    assert all(row[0] == "-" and float(row[2]) == 100.0 for row in cover.values())
    assert "runs not finished cleanly: 0" in out
    assert re.search(r"odometry calibration \(10 turns, 3 round trips .*\) on 3 robots", out)
    ratio = re.search(r"wheel ratio error \[%\] +([\d.]+) +([\d.]+) +([\d.]+) +([\d.]+)", out)
    assert ratio and float(ratio.group(3)) <= 0.05 < float(ratio.group(1))
    assert re.search(r"wall time: \d+\.\d s", out)
    # every goal is marked, and the summary line is the last
    marked = re.findall(r" (met|MISSED)$", out, re.M)
    last = out.strip().splitlines()[-1]
    m = re.fullmatch(r"asserv bench accuracy: goals met: (\d+) of (\d+)(; MISSED: .+)?", last)
    assert m is not None, last
    assert len(marked) == 17 <= int(m[2])  # a mark a row; a goal a controller the row checks
    assert ("MISSED" in marked) == (m[1] != m[2]) == (m[3] is not None)
    for name in ("accuracy.png", "accuracy-run.png", "calibration.png"):
        png = tmp_path / name
        assert png.read_bytes()[:4] == b"\x89PNG" and f"plot: {png}" in out


def test_time_bound() -> None:
    assert accuracy.time_bound_s(100) == pytest.approx(2.8)  # physics.md: 1.8 m, 1 m/s, 1 m/s^2
    assert accuracy.time_bound_s(20) == pytest.approx(9.2)
    assert accuracy.time_bound_s(255, 10) == pytest.approx(2 * (1.8 / 0.1) ** 0.5)


def test_a_missed_goal_is_marked_and_strict_exits_1(
    capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    """A goal no robot can meet: marked MISSED, named in the summary; --strict makes it exit 1."""
    monkeypatch.setattr(accuracy, "ODOMETRY_OVER_NOISE", 0.01)
    argv = ["bench", "accuracy", "--robots", "2", "--no-png", "--jobs", "1"]
    assert main(argv) == 0
    out = capsys.readouterr().out
    assert re.search(r"<= 0\.01 calibrated MISSED$", out, re.M)
    last = out.strip().splitlines()[-1]
    assert "MISSED: " in last and "the encoder noise alone" in last
    assert main([*argv, "--strict"]) == 1
    assert main([*argv[:-2], "--jobs", "1", "--strict"]) == 1
