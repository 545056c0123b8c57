"""The goals of a bench: each marked met or missed, a summary line, an exit code on a miss.

Every bench that states goals (``asserv bench accuracy``, ``bench/*.py``) keeps them in a
``Goals`` and prints the same marks, so that a reader sees at once what was missed::

    goals = Goals("bench/shock_stop.py")
    goals.check("stop distance at 1 m/s [mm]", 41.2, "<=", 50)   # -> "41.2 <= 50: met"
    for line in goals.lines():
        print(line)
    print(goals.summary())            # "bench/shock_stop.py: goals met: 1 of 1"
    return goals.exit_code(strict)    # 1 on a miss with --strict, else 0

A bench that states no goal (its figures only) ends with the same line, which says so:
``bench/substeps.py: goals met: 0 of 0 (no goal stated: figures only)``.
"""

from __future__ import annotations

import argparse
import math
import operator
from collections.abc import Callable
from dataclasses import dataclass

__all__ = ["MET", "MISSED", "Goal", "Goals", "add_strict_flag"]

MET = "met"
MISSED = "MISSED"

_OPS: dict[str, Callable[[float, float], bool]] = {
    "<=": operator.le,
    "<": operator.lt,
    ">=": operator.ge,
    ">": operator.gt,
    "==": operator.eq,
}


@dataclass(frozen=True)
class Goal:
    """One goal: ``value op limit`` (a NaN value, not measured, is a miss)."""

    name: str
    value: float
    op: str
    limit: float
    unit: str = ""

    @property
    def met(self) -> bool:
        return not math.isnan(self.value) and _OPS[self.op](self.value, self.limit)

    @property
    def mark(self) -> str:
        return MET if self.met else MISSED

    def text(self, digits: int = 3) -> str:
        """``5.9 <= 5 mm: MISSED``; a value of more digits whole: ``3510 >= 2000: met``."""
        unit = f" {self.unit}" if self.unit else ""
        value = f"{self.value:.{digits}g}"
        if "e+" in value:
            value = f"{self.value:.0f}"
        return f"{value} {self.op} {self.limit:g}{unit}: {self.mark}"


class Goals:
    """The goals of one bench run, in the order they were checked."""

    def __init__(self, bench: str) -> None:
        if not bench:
            raise ValueError("a bench has a name")
        self.bench = bench
        self.goals: list[Goal] = []

    def check(self, name: str, value: float, op: str, limit: float, unit: str = "") -> Goal:
        """Record a goal and return it (``goal.mark``: met or MISSED)."""
        if op not in _OPS:
            raise ValueError(f"{op!r} is not one of {', '.join(_OPS)}")
        goal = Goal(name, float(value), op, float(limit), unit)
        self.goals.append(goal)
        return goal

    @property
    def missed(self) -> list[Goal]:
        return [g for g in self.goals if not g.met]

    def lines(self) -> list[str]:
        """One line a goal: ``  name: value op limit: met``."""
        return [f"  {g.name}: {g.text()}" for g in self.goals]

    def summary(self) -> str:
        """The last line of a bench: how many goals were met, and which were missed."""
        n, missed = len(self.goals), self.missed
        line = f"{self.bench}: goals met: {n - len(missed)} of {n}"
        if n == 0:
            return f"{line} (no goal stated: figures only)"
        if missed:
            line += f"; MISSED: {'; '.join(g.name for g in missed)}"
        return line

    def exit_code(self, strict: bool) -> int:
        """1 when ``strict`` and a goal was missed, else 0."""
        return 1 if strict and self.missed else 0


def add_strict_flag(parser: argparse.ArgumentParser) -> None:
    """``--strict``: exit 1 when a goal is missed (a bench reports and exits 0 otherwise)."""
    parser.add_argument(
        "--strict",
        action="store_true",
        help="exit 1 when a goal is missed (default: report it, exit 0)",
    )
