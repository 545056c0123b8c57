"""The modules of python/asserv import each other without a circle (issue "Structure").

Every import between two modules of the package counts, at the top or inside a function: a
circle means two modules that know each other's insides, whichever imports lazily. An import
for type hints only (under ``if TYPE_CHECKING:``) does not: nothing runs it.

The layout shows what the driver-only install holds: the modules that need the compiled
simulator are in the subpackage ``sim/``, and no module outside it imports it at load time.
"""

from __future__ import annotations

import ast
from pathlib import Path

PKG = Path(__file__).resolve().parents[1] / "asserv"
SIM = "sim"  # the subpackage of the modules that need the compiled simulator (the sim extra)


def module_name(pkg: Path, path: Path) -> str:
    """``driver``, ``log.cli``; a subpackage's __init__.py is the subpackage (``sim``), the
    package's own is ``""``."""
    parts = list(path.relative_to(pkg).with_suffix("").parts)
    if parts[-1] == "__init__":
        parts.pop()
    return ".".join(parts)


def imports(pkg: Path) -> dict[str, list[tuple[str, bool]]]:
    """Each module's imports of the package's modules, as (module, at load time): at load time
    means at the module's top, not inside a function. ``from .sim.cboard import X`` counts as an
    import of ``sim.cboard`` alone: the module whose insides are used. Imports for type hints only
    (under ``if TYPE_CHECKING:``) are left out: nothing runs them. The package's own __init__
    (``from . import __version__``) is left out: it only re-exports."""
    paths = {module_name(pkg, p): p for p in pkg.rglob("*.py")}
    out: dict[str, list[tuple[str, bool]]] = {m: [] for m in paths if m}

    def visit(node: ast.AST, here: str, is_pkg: bool, loading: bool, found: list) -> None:
        for n in ast.iter_child_nodes(node):
            if isinstance(n, ast.If) and ast.unparse(n.test).endswith("TYPE_CHECKING"):
                visit(ast.Module(body=n.orelse, type_ignores=[]), here, is_pkg, loading, found)
                continue
            if isinstance(n, (ast.FunctionDef, ast.AsyncFunctionDef, ast.Lambda)):
                visit(n, here, is_pkg, False, found)
                continue
            if isinstance(n, ast.ImportFrom) and n.level:
                base = here.split(".") if here else []
                if not is_pkg:
                    base = base[:-1]
                base = base[: len(base) - (n.level - 1)] if n.level > 1 else base
                target = [*base, *(n.module.split(".") if n.module else [])]
                names = [".".join([*target, a.name]) for a in n.names]
                found += [
                    (t, loading) for t in [m for m in names if m in paths] or [".".join(target)]
                ]
            visit(n, here, is_pkg, loading, found)

    for name, path in paths.items():
        if not name:
            continue
        found: list[tuple[str, bool]] = []
        visit(ast.parse(path.read_text()), name, path.name == "__init__.py", True, found)
        out[name] = [(t, at_load) for t, at_load in found if t in out and t != name]
    return out


def graph(pkg: Path) -> dict[str, set[str]]:
    """Who imports whom among the package's modules, at load time or inside a function."""
    return {m: {t for t, _ in found} for m, found in imports(pkg).items()}


def in_sim(module: str) -> bool:
    return module == SIM or module.startswith(SIM + ".")


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


def test_only_the_sim_subpackage_loads_the_simulator() -> None:
    """A module outside ``sim/`` imports it only inside the function that runs the simulator, so
    that importing the driver, the CLI, the view or the logs never needs the ``sim`` extra; and
    the modules that need the compiled simulator are all in ``sim/``."""
    found = imports(PKG)
    at_load = sorted(
        f"{m} imports {t}"
        for m, ts in found.items()
        if not in_sim(m)
        for t, loading in ts
        if loading and in_sim(t)
    )
    assert at_load == []
    assert {"sim._core", "sim.cboard", "sim.demo", "sim.plots"} <= set(found)
    direct = sorted(
        module_name(PKG, path)
        for path in PKG.rglob("*.py")
        for n in ast.walk(ast.parse(path.read_text()))
        if (isinstance(n, ast.ImportFrom) and (n.module or "").startswith("asserv_sim"))
        or (isinstance(n, ast.Import) and any(a.name.startswith("asserv_sim") for a in n.names))
    )
    assert direct == ["sim._core"]  # the compiled extension, under the name asserv uses


def test_a_lazy_import_of_the_simulator_is_told_apart() -> None:
    found = imports(PKG)
    assert ("sim", False) in found["scenario"]  # inside the function that plays on it
    assert ("sim.plots", True) in found["sim.demo"]
    assert ("sim", True) in found["sim.accuracy"]


def test_a_circle_is_found() -> None:
    g = {"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": {"a"}}
    assert cycles(g) == [["a", "b", "c"]]
