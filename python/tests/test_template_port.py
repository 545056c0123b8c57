"""The template port (firmware/ports/template) stubs every function of the porting contract: each
function declared in firmware/hal/*.h is defined in one of its .c files, or, for hal_nvm.h, in
the byte storage's implementation it links (firmware/ports/common/nvm_bytes.c), whose lower
layer (nvm_bytes.h) the template stubs in turn. The build links the template, which catches a
stub that disagrees with its header or that the common port layer calls; this catches a HAL
function that nothing calls yet."""

from __future__ import annotations

import re
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
HAL = ROOT / "firmware" / "hal"
TEMPLATE = ROOT / "firmware" / "ports" / "template"
NVM_BYTES = ROOT / "firmware" / "ports" / "common" / "nvm_bytes"

pytestmark = pytest.mark.skipif(not TEMPLATE.is_dir(), reason="not run from a checkout")

# A function declaration or definition at the start of a line: return type, then prefix_name(.
FUNCTION = r"^[a-z][\w ]*?\b({prefix}\w+)\("


def names(paths: list[Path], end: str, prefix: str = "hal_") -> set[str]:
    """The functions named prefix... whose declaration (end ";") or definition (end "{") the
    files hold."""
    found = set()
    function = re.compile(FUNCTION.format(prefix=prefix), re.MULTILINE)
    for path in paths:
        text = re.sub(r"/\*.*?\*/", "", path.read_text(encoding="utf-8"), flags=re.DOTALL)
        for m in function.finditer(text):
            rest = text[m.end() :]
            close = rest.index(")")
            if rest[close + 1 :].lstrip().startswith(end):
                found.add(m.group(1))
    return found


def test_every_hal_function_has_a_stub() -> None:
    declared = names(sorted(HAL.glob("*.h")), ";")
    defined = names([*sorted(TEMPLATE.glob("*.c")), NVM_BYTES.with_suffix(".c")], "{")
    assert len(declared) >= 12, declared  # the parser finds the contract
    missing = sorted(declared - defined)
    assert not missing, f"HAL functions without a stub in firmware/ports/template: {missing}"
    assert not defined - declared, "stubs of functions the HAL does not declare"


def test_the_byte_storage_lower_layer_has_a_stub() -> None:
    """hal_nvm.h comes from nvm_bytes.c on the template: the four byte functions it calls are
    the template's to provide."""
    prefix = "nvm_bytes_dev_"
    declared = names([NVM_BYTES.with_suffix(".h")], ";", prefix)
    defined = names(sorted(TEMPLATE.glob("*.c")), "{", prefix)
    assert len(declared) == 4, declared
    assert declared == defined
