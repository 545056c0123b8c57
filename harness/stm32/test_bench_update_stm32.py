"""docs/update.md's figures are what bench/update_stm32.py prints at this commit: its two tables
(the update at 100 and 400 kHz, the bootloader), the goals marked and the summary line. What it
printed goes into the build (bench/update_stm32.txt beside the ELF), which scripts/test.sh shows
after the tests."""

from __future__ import annotations

import importlib
import sys
from pathlib import Path

import pytest
from conftest import ROOT

sys.path.insert(0, str(ROOT / "bench"))
bench = importlib.import_module("update_stm32")

FIRST = "| update of today's image over I2C (emulated, data-sheet flash) | 100 kHz | 400 kHz |"
LAST = "bench/update_stm32.py: goals met:"


def doc_figures(text: str) -> list[str]:
    """The lines of docs/update.md's "Figures" from the first table's head to the summary."""
    lines = text[text.index(FIRST) :].splitlines()
    return lines[: next(i for i, line in enumerate(lines) if line.startswith(LAST)) + 1]


def test_the_figures_in_docs_update_md_are_what_the_bench_prints(
    elf: Path, boot_elf: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    assert boot_elf.parent == elf.parent
    bench.main([str(elf.parent)])
    out = capsys.readouterr().out.splitlines()
    (elf.parent / "bench").mkdir(exist_ok=True)
    (elf.parent / "bench" / "update_stm32.txt").write_text("".join(line + "\n" for line in out))
    printed = out[out.index(FIRST) :]
    doc = doc_figures((ROOT / "docs" / "update.md").read_text())
    assert len(doc) >= 20 and doc[-1].startswith(LAST)
    assert doc == printed
