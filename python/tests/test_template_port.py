"""The template port (firmware/ports/template) stubs every function of the porting contract: each
function declared in firmware/hal/*.h is defined in one of its .c files. The build links the
template, which catches a stub that disagrees with its header or that the common port layer
calls; this catches a HAL function that nothing calls yet."""

from __future__ import annotations

import re
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
HAL = ROOT / "firmware" / "hal"
TEMPLATE = ROOT / "firmware" / "ports" / "template"

pytestmark = pytest.mark.skipif(not TEMPLATE.is_dir(), reason="not run from a checkout")

# A function declaration or definition at the start of a line: return type, then hal_name(.
FUNCTION = re.compile(r"^[a-z][\w ]*?\b(hal_\w+)\(", re.MULTILINE)


def names(paths: list[Path], end: str) -> set[str]:
    """The hal_ functions whose declaration (end ";") or definition (end "{") the files hold."""
    found = set()
    for path in paths:
        text = re.sub(r"/\*.*?\*/", "", path.read_text(encoding="utf-8"), flags=re.DOTALL)
        for m in FUNCTION.finditer(text):
            rest = text[m.end() :]
            close = rest.index(")")
            if rest[close + 1 :].lstrip().startswith(end):
                found.add(m.group(1))
    return found


def test_every_hal_function_has_a_stub() -> None:
    declared = names(sorted(HAL.glob("*.h")), ";")
    defined = names(sorted(TEMPLATE.glob("*.c")), "{")
    assert len(declared) >= 13, declared  # the parser finds the contract
    missing = sorted(declared - defined)
    assert not missing, f"HAL functions without a stub in firmware/ports/template: {missing}"
    assert not defined - declared, "stubs of functions the HAL does not declare"
