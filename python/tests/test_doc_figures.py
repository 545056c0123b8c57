"""Figures that a page restates from an output block it quotes: each is the block's own.

test_docs_examples runs the command of each ``<!-- example: output ... -->`` block and compares
the block with what it prints; the tests here compare a table or a sentence of the same page
with that block, so that neither can drift from the command. They read the pages only: no
command runs here.
"""

from __future__ import annotations

import re
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
_NUMBER = re.compile(r"\d+(?:\.\d+)?")


def page(name: str) -> str:
    return (ROOT / "docs" / name).read_text(encoding="utf-8")


def block(name: str, command: str) -> list[str]:
    """The lines of the page's output block of command, as the command prints them."""
    lines = page(name).splitlines()
    i = lines.index(f"<!-- example: output {command} -->") + 2
    out = []
    while i < len(lines) and lines[i].startswith("    "):
        out.append(lines[i][4:])
        i += 1
    assert out, (name, command)
    return out


def table_row(name: str, first_cell: str) -> list[str]:
    """The cells of the page's table row whose first cell is first_cell."""
    for line in page(name).splitlines():
        cells = [c.strip() for c in line.strip().strip("|").split(" | ")]
        if line.startswith("|") and cells[0] == first_cell:
            return cells
    raise AssertionError(f"{name}: no row {first_cell!r}")


def numbers(text: str) -> list[str]:
    return _NUMBER.findall(text)


def m_s(mm_s: str) -> str:
    """A speed in mm/s as the pages write it in m/s: 1367 -> '1.37', 1001 -> '1', 99 -> '0.1'."""
    return f"{round(int(mm_s) / 1000, 2):g}"


def newtons(n: str) -> str:
    """0.0 -> '0', 2.3 -> '2.3'."""
    return f"{float(n):g}"


_STOP = re.compile(
    r"(?P<what>.*?): +(?P<speed>\d+) mm/s +braking +(?P<braking>\d+) ms +rest +(?P<rest>\d+) ms "
    r"\([\d.]+x\) +back +(?P<back>[\d.]+) mm +(?P<force>[\d.]+) N"
)
_RANDOM = re.compile(
    r"random, (?P<rate>[^,]+), (?P<low>\d+)-\d+ cm/s: \d+ hits: rest up to (?P<times>[\d.]+)x .*"
    r"back (?P<back>[\d.]+) mm at most .*; (?P<force>[\d.]+) N at most"
)


def test_the_stop_table_is_what_shock_stop_prints() -> None:
    """docs/failure-model.md, "A stop that stops": the column "measured" of the table, figure by
    figure, from bench/shock_stop.py's lines at 1 kHz (the disc at each speed limit from 10 cm/s
    up, the seed-7 robot, the random hits)."""
    lines = block("failure-model.md", "python bench/shock_stop.py --random 150")
    one_rate = lines[: next(i for i, line in enumerate(lines) if "AVR_RATES" in line)]
    disc = {}
    seed7 = None
    for line in one_rate:
        m = _STOP.match(line)
        assert m, line
        if m["what"].startswith("seed 7"):
            seed7 = m
        else:
            disc[int(m["what"].split()[1])] = m
    assert seed7 is not None
    (rand,) = [m for line in lines if (m := _RANDOM.match(line)) and m["rate"] == "1 kHz"]

    rest = [m_s(disc[150]["speed"]), disc[150]["rest"], disc[150]["braking"]]
    rest += [m_s(disc[100]["speed"]), disc[100]["rest"], disc[100]["braking"]]
    rest += ["7", seed7["rest"], seed7["braking"]]
    for limit in (60, 30, 20, 10):
        rest += [m_s(disc[limit]["speed"]), disc[limit]["rest"], disc[limit]["braking"]]
    rest += [m_s(str(int(rand["low"]) * 10)), rand["times"]]
    cells = table_row("failure-model.md", "at rest")
    assert numbers(cells[2]) == rest, cells[2]

    back = max((m["back"] for m in disc.values()), key=float)
    cells = table_row("failure-model.md", "never back towards the obstacle")
    assert numbers(cells[2]) == [back, rand["back"]], cells[2]

    force = max((m["force"] for m in disc.values()), key=float)
    cells = table_row("failure-model.md", "no push")
    assert numbers(cells[2]) == [newtons(force), rand["force"]], cells[2]
