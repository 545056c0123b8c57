"""docs/README.md indexes every page of docs/ in one line each, and only pages that exist."""

from __future__ import annotations

import re
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
DOCS = ROOT / "docs"
LINK = re.compile(r"^- \[([^\]]+)\]\(([^)]+)\): \S")


def entries(text: str) -> list[tuple[str, str]]:
    return [(m[1], m[2]) for line in text.splitlines() if (m := LINK.match(line))]


def pages() -> list[str]:
    return sorted(p.name for p in DOCS.glob("*.md") if p.name != "README.md")


def check(text: str, names: list[str]) -> list[str]:
    """What is wrong with an index ``text`` of the pages ``names`` (empty: nothing)."""
    got = entries(text)
    linked = [target for _, target in got]
    problems = [f"{n}: not in docs/README.md" for n in names if n not in linked]
    problems += [f"{t}: no such page" for t in linked if t not in names]
    problems += [f"{t}: listed {linked.count(t)} times" for t in set(linked) if linked.count(t) > 1]
    problems += [f"{label} links to {t}" for label, t in got if label != t]
    return problems


def test_every_page_is_indexed_once() -> None:
    assert check((DOCS / "README.md").read_text(), pages()) == []


@pytest.mark.parametrize("name", pages())
def test_a_missing_page_is_found(name: str) -> None:
    """The check fails when any one page's line is taken out."""
    text = "\n".join(
        line for line in (DOCS / "README.md").read_text().splitlines() if f"({name})" not in line
    )
    assert check(text, pages()) == [f"{name}: not in docs/README.md"]


def test_the_top_readme_points_to_the_index() -> None:
    assert "docs/README.md" in (ROOT / "README.md").read_text()
