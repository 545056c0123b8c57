"""The code examples of README.md and docs/*.md, as test_docs_examples runs them.

What is collected, from fenced (```) and indented code blocks:
- **Python**: a block fenced as ``python``, or an unfenced block whose first line starts with
  ``import`` or ``from``. It runs whole, in a fresh namespace, from a temporary directory.
- **Commands**: each line of a code block that starts with ``asserv `` or ``$ asserv ``. The
  lines of one block run in order. After ``$ asserv ...``, the lines up to the next ``$`` are the
  expected output (stdout and stderr, exactly); after ``asserv ...  # -> TEXT``, the output
  contains TEXT; otherwise the command must exit 0.

A marker in an HTML comment (invisible on the rendered page) on the line before a block says
how it runs:
- ``<!-- example: board -->``: the example talks to a real board (``SMBus(1)``, ``--bus 1``); in
  the tests, ``smbus2.SMBus(N)`` opens a simulated board instead (one per block, kept from one
  line to the next). ``<!-- example: board calibration -->``: a simulated robot standing where
  ``asserv calibrate`` puts it, rear against the west border.
- ``<!-- example: skip REASON -->``: not run (REASON says why: output of a long benchmark...).
- ``<!-- example: output asserv ARGS -->``: the block is what ``asserv ARGS`` prints: its lines
  must appear in that output, in order and next to each other; a line ``...`` stands for any
  number of lines left out. A figure quoted in a page is so checked against the command.
  ``<!-- example: output python bench/NAME.py ARGS -->``: the same for a bench script.
  ``<!-- example: output ./build/PATH ARGS -->``: the same for a program of the C build that
  ``scripts/test.sh`` makes before pytest (skipped where ``build/`` is not built).
"""

from __future__ import annotations

import re
from dataclasses import dataclass, field
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
DOCS = [ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md"))]

_MARKER = re.compile(r"<!--\s*example:\s*(\w+)\s*(.*?)\s*-->")
_FENCE = re.compile(r"^(\s*)```\s*(\w*)")


@dataclass
class Command:
    argv: str  # the command line after "asserv "
    expected: list[str] | None  # `$` form: the exact output lines
    contains: str | None  # `# ->` form
    line: int


@dataclass
class Example:
    path: Path
    line: int  # of the block's first line, 1-based
    kind: str  # "python", "commands" or "output" (the block is the output of marker_arg)
    code: str = ""
    commands: list[Command] = field(default_factory=list)
    marker: str = ""  # "", "board", "skip", "output"
    marker_arg: str = ""

    @property
    def id(self) -> str:
        return f"{self.path.relative_to(ROOT)}:{self.line}"


def _blocks(text: str) -> list[tuple[int, str, list[str], str, str]]:
    """(first line, language, lines, marker, marker argument) of every code block."""
    lines = text.splitlines()
    out = []
    i = 0
    marker = ("", "")
    prev_blank = True
    while i < len(lines):
        line = lines[i]
        m = _MARKER.search(line)
        if m:
            marker = (m.group(1), m.group(2))
            i += 1
            continue
        f = _FENCE.match(line)
        if f:
            indent = len(f.group(1))
            body = []
            j = i + 1
            while j < len(lines) and not lines[j].strip().startswith("```"):
                body.append(lines[j][indent:])
                j += 1
            out.append((i + 2, f.group(2), body, *marker))
            marker = ("", "")
            i = j + 1
            prev_blank = False
            continue
        if prev_blank and line.startswith("    ") and line.strip():
            body = []
            j = i
            while j < len(lines) and (lines[j].startswith("    ") or not lines[j].strip()):
                body.append(lines[j][4:])
                j += 1
            while body and not body[-1].strip():
                body.pop()
            out.append((i + 1, "", body, *marker))
            marker = ("", "")
            i = j
            prev_blank = True
            continue
        if line.strip():
            marker = marker if line.lstrip().startswith("<!--") else ("", "")
        prev_blank = not line.strip()
        i += 1
    return out


def _commands(first: int, body: list[str]) -> list[Command]:
    cmds: list[Command] = []
    current: Command | None = None
    prompts = any(b.startswith("$ ") for b in body)  # then an output line may start "asserv"
    for k, raw in enumerate(body):
        line = raw.rstrip()
        if line.startswith("$ "):
            current = None
            if line.startswith("$ asserv "):
                current = Command(line[len("$ asserv ") :], [], None, first + k)
                cmds.append(current)
            continue
        if line.startswith("asserv ") and not prompts:
            current = None
            text, _, note = line.partition("# ->")
            text = text.split("  #")[0].strip()
            cmds.append(Command(text[len("asserv ") :], None, note.strip() or None, first + k))
            continue
        if current is not None and current.expected is not None:
            current.expected.append(line)
    for c in cmds:
        while c.expected and not c.expected[-1].strip():
            c.expected.pop()
    return cmds


def collect(paths: list[Path] | None = None) -> list[Example]:
    """Every example of the given pages (README.md and docs/*.md by default)."""
    found = []
    for path in paths or DOCS:
        for first, lang, body, marker, arg in _blocks(path.read_text(encoding="utf-8")):
            code_lines = [b for b in body if b.strip()]
            if not code_lines:
                continue
            head = code_lines[0]
            if marker == "output":
                found.append(Example(path, first, "output", "\n".join(body), [], marker, arg))
                continue
            if lang == "python" or (
                not lang and (head.startswith("import ") or head.startswith("from "))
            ):
                found.append(
                    Example(path, first, "python", "\n".join(body) + "\n", [], marker, arg)
                )
                continue
            if lang in ("", "sh", "console", "shell", "bash"):
                cmds = _commands(first, body)
                if cmds:
                    found.append(Example(path, first, "commands", "", cmds, marker, arg))
    return found


def output_matches(block: str, printed: list[str]) -> bool:
    """Whether the lines of ``block`` appear in ``printed`` in order, each run of lines next to
    each other; a line ``...`` in the block stands for any number of lines."""
    runs: list[list[str]] = [[]]
    for line in block.splitlines():
        if line.strip() == "...":
            runs.append([])
        else:
            runs[-1].append(line.rstrip())
    got = [p.rstrip() for p in printed]
    at = 0
    for run in (r for r in runs if r):
        for k in range(at, len(got) - len(run) + 1):
            if got[k : k + len(run)] == run:
                at = k + len(run)
                break
        else:
            return False
    return True
