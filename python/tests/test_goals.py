"""asserv.goals: each goal marked met or MISSED as its comparison says, a summary that counts
them and names the missed ones, and an exit code that only --strict makes 1."""

from __future__ import annotations

import importlib
import math
import operator
import re
import sys
from pathlib import Path

import pytest
from hypothesis import given
from hypothesis import strategies as st

from asserv.goals import MET, MISSED, Goals

OPS = {"<=": operator.le, "<": operator.lt, ">=": operator.ge, ">": operator.gt, "==": operator.eq}
number = st.floats(allow_infinity=False, width=32)
goal = st.tuples(st.text(min_size=1, max_size=8), number, st.sampled_from(sorted(OPS)), number)


@given(st.lists(goal, max_size=12), st.booleans())
def test_marks_summary_and_exit_code(
    goals: list[tuple[str, float, str, float]], strict: bool
) -> None:
    g = Goals("bench/x.py")
    for name, value, op, limit in goals:
        got = g.check(name, value, op, limit)
        want = not math.isnan(value) and OPS[op](value, limit)
        assert got.met is want and got.mark == (MET if want else MISSED)
        assert g.lines()[-1].endswith(f": {got.mark}")
    n_missed = sum(1 for _, v, op, lim in goals if math.isnan(v) or not OPS[op](v, lim))
    summary = g.summary()
    assert summary.startswith(f"bench/x.py: goals met: {len(goals) - n_missed} of {len(goals)}")
    assert ("; MISSED: " in summary) == (n_missed > 0)
    assert g.exit_code(strict) == (1 if strict and n_missed else 0)


def test_a_goal_not_measured_is_missed() -> None:
    g = Goals("b")
    assert g.check("stop [mm]", math.nan, "<=", 50, "mm").text() == "nan <= 50 mm: MISSED"
    assert g.summary() == "b: goals met: 0 of 1; MISSED: stop [mm]"


def test_large_values_print_whole_and_no_goal_says_so() -> None:
    g = Goals("bench/sim_speed.py")
    assert g.summary() == "bench/sim_speed.py: goals met: 0 of 0 (no goal stated: figures only)"
    assert g.exit_code(True) == 0
    assert g.check("speed [x]", 3510.4, ">=", 2000).text() == "3510 >= 2000: met"
    assert g.check("speed [x]", 1999.6, ">=", 2000).text() == "2000 >= 2000: MISSED"
    assert g.check("ratio", 0.9574, "<=", 0.75).text() == "0.957 <= 0.75: MISSED"


def test_bad_goals_are_refused() -> None:
    with pytest.raises(ValueError, match="'=<' is not one of"):
        Goals("b").check("x", 1, "=<", 2)
    with pytest.raises(ValueError, match="a bench has a name"):
        Goals("")


# ---- the benches of bench/ print their goals the same way ----------------------------------------

sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "bench"))


@pytest.mark.parametrize(
    ("module", "argv"),
    [
        ("latency", ["--moves", "2", "--shift", "0", "3"]),
        ("soak", ["--matches", "2", "--seconds", "3", "--jobs", "1"]),
        ("shock_stop", ["--random", "2"]),
        ("slip_latency", []),
        ("detection", []),
        ("poll_rate", []),
        ("sim_speed", ["--robots", "1", "--jobs", "1"]),  # a wall-clock goal: marked, not asserted
        ("course", ["--robots", "1"]),
        ("pause", ["--robots", "1"]),
        ("quiet", ["--robots", "1"]),
        ("fusion", ["--robots", "1", "--seconds", "5", "--jobs", "1"]),
        ("substeps", ["--quick"]),  # no goal stated: its summary says so
    ],
)
def test_a_bench_marks_its_goals_and_ends_with_the_summary(
    module: str, argv: list[str], capsys: pytest.CaptureFixture[str]
) -> None:
    bench = importlib.import_module(module)
    assert bench.main(argv) == 0  # a miss is reported, not an error, without --strict
    check_marks(module, capsys.readouterr().out)
    # With --strict, 1 exactly when that run printed a miss (a wall-clock figure may differ
    # from the first run's, so the second run is checked against its own output).
    strict = bench.main([*argv, "--strict"])
    assert strict == (1 if check_marks(module, capsys.readouterr().out) else 0)


def check_marks(module: str, out: str) -> bool:
    """The marks and the summary line agree; True when a goal was missed."""
    marks = re.findall(r"\b(met|MISSED)\b", out.rsplit("\n", 2)[0])
    last = out.strip().splitlines()[-1]
    m = re.fullmatch(
        rf"bench/{module}\.py: goals met: (\d+) of (\d+)"
        r"(; MISSED: .+| \(no goal stated: figures only\))?",
        last,
    )
    assert m is not None, last
    if m[2] == "0":
        assert not marks and m[3] is not None and m[3].startswith(" (no goal")
        return False
    assert 0 < len(marks) <= int(m[2])  # a mark a goal, or a line's mark for its goals
    assert ("MISSED" in marks) == (m[1] != m[2]) == (m[3] is not None)
    return m[1] != m[2]
