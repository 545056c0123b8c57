"""docs/architecture.md's folder table against the tree: every folder of the repository's top two
levels, every port and every module of python/asserv is named in it, and it names nothing that is
gone.

The table is read from the Markdown: its rows' first column names one or more folders in
backquotes (`` `sim/`, `sim/tests/` ``); the python/asserv row names each module as `` `name.py` ``
and each subpackage as `` `name/` ``, with its modules as `` `name/module.py` ``. Build trees,
virtual environments, node_modules, hidden folders and what git ignores are not part of the tree.
"""

from __future__ import annotations

import re
import subprocess
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
DOC = ROOT / "docs" / "architecture.md"

pytestmark = pytest.mark.skipif(not DOC.is_file(), reason="not run from a checkout")

SKIPPED = {".venv", "venv", "node_modules", "__pycache__"}


def table_rows() -> list[tuple[str, str]]:
    """The (first column, second column) of each row of the table under "## Folders"."""
    text = DOC.read_text(encoding="utf-8")
    section = text.split("\n## Folders\n", 1)[1].split("\n## ", 1)[0]
    rows = []
    for line in section.splitlines():
        cells = [c.strip() for c in line.strip().strip("|").split("|")]
        if not line.startswith("|") or len(cells) < 2 or set(cells[0]) <= set("-: "):
            continue
        if cells[0] == "folder":
            continue
        rows.append((cells[0], "|".join(cells[1:])))
    return rows


def named_folders() -> set[str]:
    """The folders the first column names, without their trailing slash."""
    names = set()
    for first, _ in table_rows():
        found = re.findall(r"`([^`]+)/`", first)
        assert found, f"a row names no folder: {first!r}"
        names.update(found)
    return names


def ignored(paths: list[str]) -> set[str]:
    """The paths git ignores (none when git is not there)."""
    try:
        out = subprocess.run(
            ["git", "-C", str(ROOT), "check-ignore", "--stdin"],
            input="\n".join(paths),
            capture_output=True,
            text=True,
            check=False,
        )
    except OSError:
        return set()
    return {p.rstrip("/") for p in out.stdout.splitlines()}


def tree_folders() -> set[str]:
    """The folders of the top two levels, and each port's folder (firmware/ports/<name>)."""
    found = []
    for top in ROOT.iterdir():
        if not top.is_dir() or top.name.startswith((".", "build")) or top.name in SKIPPED:
            continue
        found.append(top.name)
        for sub in top.iterdir():
            if sub.is_dir() and not sub.name.startswith(".") and sub.name not in SKIPPED:
                found.append(f"{top.name}/{sub.name}")
    ports = ROOT / "firmware" / "ports"
    found += [f"firmware/ports/{p.name}" for p in ports.iterdir() if p.is_dir()]
    return {f for f in found if not f.endswith(".egg-info")} - ignored(found)


def python_modules() -> set[str]:
    """python/asserv's modules (`name.py`, __init__.py aside), subpackages (`name/`) and their
    modules (`name/module.py`)."""
    pkg = ROOT / "python" / "asserv"
    names = {p.name for p in pkg.glob("*.py") if p.name != "__init__.py"}
    for sub in (p for p in pkg.iterdir() if (p / "__init__.py").is_file()):
        names.add(f"{sub.name}/")
        names |= {f"{sub.name}/{p.name}" for p in sub.glob("*.py") if p.name != "__init__.py"}
    return names


def python_row() -> str:
    rows = [text for first, text in table_rows() if "`python/asserv/`" in first]
    assert len(rows) == 1, "one row for python/asserv/"
    return rows[0]


def test_every_folder_is_in_the_table() -> None:
    named = named_folders()

    def through_below(f: str) -> bool:
        """A top folder, or one that only holds folders (firmware/ports/), may be named through
        the folders below it (firmware/ by firmware/core/)."""
        holds_files = any(p.is_file() for p in (ROOT / f).iterdir())
        return ("/" not in f or not holds_files) and any(n.startswith(f + "/") for n in named)

    missing = sorted(f for f in tree_folders() if f not in named and not through_below(f))
    assert not missing, f"folders missing from docs/architecture.md's table: {missing}"


def test_the_table_names_no_folder_that_is_gone() -> None:
    gone = sorted(n for n in named_folders() if not (ROOT / n).is_dir())
    assert not gone, f"docs/architecture.md's table names folders that do not exist: {gone}"


def test_every_python_module_is_in_the_table() -> None:
    row = python_row()
    missing = sorted(m for m in python_modules() if f"`{m}`" not in row)
    assert not missing, f"python/asserv modules missing from docs/architecture.md: {missing}"


def test_the_python_row_names_no_module_that_is_gone() -> None:
    named = {
        m  # `name.py` or `sub/name.py`; `bench/fusion.py` is a file of the repository, not a module
        for m in re.findall(r"`((?:[A-Za-z_]\w*/)?[A-Za-z_]\w*\.py)`", python_row())
        if "/" not in m or not (ROOT / m).is_file()
    }
    gone = sorted(named - python_modules())
    assert not gone, f"docs/architecture.md names python/asserv modules that do not exist: {gone}"


def test_the_table_is_read() -> None:
    """The parser finds what is known to be there, so that the tests above can fail."""
    assert {"firmware/core", "firmware/ports/template", "python/asserv", "sim/tests"} <= (
        named_folders()
    )
    assert {"driver.py", "sim/", "sim/demo.py", "log/cli.py", "cli.py"} <= python_modules()
    assert {"firmware", "firmware/ports/stm32", "harness/stm32"} <= tree_folders()
