"""The cffi declarations of asserv-sim against the C headers they copy (issue "Structure").

cffi's API mode already checks the struct fields that python/asserv-sim/_build_ffi.py declares
(their types and offsets, at build time). Its function declarations are only checked where the
generated wrappers happen to call them with incompatible types, so this test compiles every one
of them after the headers: a redeclaration that differs from the header (a parameter's type, a
return type, a missing parameter) is a compile error.
"""

from __future__ import annotations

import importlib.util
import re
import shutil
import subprocess
from pathlib import Path
from types import ModuleType

import pytest

ROOT = Path(__file__).resolve().parents[2]
BUILD_FFI = ROOT / "python" / "asserv-sim" / "_build_ffi.py"

pytestmark = pytest.mark.skipif(shutil.which("cc") is None, reason="needs a C compiler")


def _build_ffi() -> ModuleType:
    pytest.importorskip("cffi")
    spec = importlib.util.spec_from_file_location("asserv_build_ffi", BUILD_FFI)
    assert spec is not None and spec.loader is not None
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


def prototypes(cdef: str) -> list[str]:
    """The function declarations of a cdef, one per entry, whitespace normalised."""
    found = re.findall(r"^[A-Za-z_][^;{}#=]*\([^;{}]*\)\s*;", cdef, re.M)
    return [" ".join(p.split()) for p in found]


def compile_checks(mod: ModuleType, decls: list[str], tmp: Path) -> subprocess.CompletedProcess:
    # The repository's sources, not the sdist's links: the same files.
    includes = [
        ROOT / "firmware" / "core",
        ROOT / "firmware" / "arch" / "generic",
        ROOT / "firmware" / "hal",
        ROOT / "firmware" / "ports" / "common",
        ROOT / "firmware" / "ports" / "host",
        ROOT / "sim",
    ]
    src = tmp / "decls.c"
    head = "#include <stdbool.h>\n#include <stddef.h>\n#include <stdint.h>\n"
    src.write_text(head + mod.PREAMBLE + "\n" + "\n".join(decls) + "\n")
    cmd = ["cc", "-std=c99", "-fsyntax-only", "-Werror", "-Wall", "-Wextra"]
    cmd += [f"-I{i}" for i in includes] + [str(src)]
    return subprocess.run(cmd, capture_output=True, text=True, check=False)


def test_every_cffi_function_matches_its_header(tmp_path: Path) -> None:
    mod = _build_ffi()
    decls = prototypes(mod.CDEF)
    # Enough of them to be the real list (the core's, the simulator's, the host port's).
    assert len(decls) >= 30, decls
    names = {re.search(r"(\w+)\s*\(", d).group(1) for d in decls}  # type: ignore[union-attr]
    assert {"board_init", "board_tick", "host_init", "sim_init", "proto_on_byte"} <= names
    r = compile_checks(mod, decls, tmp_path)
    assert r.returncode == 0, r.stderr


def test_a_declaration_that_differs_is_caught(tmp_path: Path) -> None:
    """The check can fail: board_init() with a parameter of another type."""
    mod = _build_ffi()
    bad = "int board_init(struct board *b, const struct board_config *cfg, int in);"
    r = compile_checks(mod, [bad], tmp_path)
    assert r.returncode != 0
    assert "board_init" in r.stderr
