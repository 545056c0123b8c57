"""asserv.goals: each goal marked met or MISSED as its comparison says, a summary that counts
them and names the missed ones, and an exit code that only --strict makes 1."""

from __future__ import annotations

import math
import operator

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


def test_bad_goals_are_refused() -> None:
    with pytest.raises(ValueError, match="'=<' is not one of"):
        Goals("b").check("x", 1, "=<", 2)
    with pytest.raises(ValueError, match="a bench has a name"):
        Goals("")
