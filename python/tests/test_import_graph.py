"""The modules of python/asserv import each other without a circle (issue "Structure").

Every import between two modules of the package counts, at the top or inside a function: a
circle means two modules that know each other's insides, whichever imports lazily. An import
for type hints only (under ``if TYPE_CHECKING:``) does not: nothing runs it.
"""

from __future__ import annotations

import ast
from pathlib import Path

PKG = Path(__file__).resolve().parents[1] / "asserv"


def graph(pkg: Path) -> dict[str, set[str]]:
    """Who imports whom among the package's modules; a subpackage (``log/``) is one node."""
    nodes = {p.stem for p in pkg.glob("*.py")} | {
        p.name for p in pkg.iterdir() if (p / "__init__.py").is_file()
    }
    out: dict[str, set[str]] = {n: set() for n in nodes}
    for path in pkg.rglob("*.py"):
        rel = path.relative_to(pkg)
        node = rel.parts[0] if len(rel.parts) > 1 else path.stem
        depth = len(rel.parts) - 1  # 0: a top module, 1: a subpackage's
        tree = ast.parse(path.read_text())
        typing_only = {
            id(m)
            for n in ast.walk(tree)
            if isinstance(n, ast.If) and ast.unparse(n.test).endswith("TYPE_CHECKING")
            for b in n.body
            for m in ast.walk(b)
        }
        for n in ast.walk(tree):
            if id(n) in typing_only:
                continue
            if not isinstance(n, ast.ImportFrom) or n.level != depth + 1:
                continue  # absolute, or within the subpackage
            targets = [n.module.split(".")[0]] if n.module else [a.name for a in n.names]
            out[node] |= {t for t in targets if t in nodes and t != node}
    return out


def cycles(g: dict[str, set[str]]) -> list[list[str]]:
    """The groups of modules that import each other round a circle: the strongly connected
    components of more than one module (Tarjan), each sorted."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    out: list[list[str]] = []

    def visit(v: str) -> None:
        index[v] = low[v] = len(index)
        stack.append(v)
        for w in sorted(g.get(v, ())):
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in stack:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            comp = []
            while True:
                w = stack.pop()
                comp.append(w)
                if w == v:
                    break
            if len(comp) > 1:
                out.append(sorted(comp))

    for v in sorted(g):
        if v not in index:
            visit(v)
    return sorted(out)


def test_the_package_has_no_import_circle() -> None:
    g = graph(PKG)
    assert len(g) > 20  # the real package
    assert cycles(g) == []


def test_a_circle_is_found() -> None:
    g = {"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": {"a"}}
    assert cycles(g) == [["a", "b", "c"]]
