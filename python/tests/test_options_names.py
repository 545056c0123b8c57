"""GOTO's options have the same names in the CLI (--options, encode) and in scenario files:
a number, or ligne, bord, ligne+bord (issue 30: the CLI refused bord and ligne)."""

from __future__ import annotations

import contextlib
import io

from hypothesis import given
from hypothesis import strategies as st

from asserv import cli, scenario
from asserv.driver import GotoOption

NAMES = {1: ["ligne", "recalage_ligne"], 2: ["bord", "recalage_bord"]}


@st.composite
def spelled(draw: st.DrawFn) -> tuple[str, int]:
    """Options as a user may write them, and their value."""
    bits = draw(st.sets(st.sampled_from([1, 2]), min_size=1))
    words = [draw(st.sampled_from(NAMES[b])) for b in sorted(bits)]
    words = [draw(st.sampled_from([w, w.upper(), w.capitalize()])) for w in words]
    if draw(st.booleans()):
        words.reverse()
    return draw(st.sampled_from(["+", "|"])).join(words), sum(bits)


def encode(argv: list[str]) -> tuple[int, str, str]:
    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        code = cli.main(argv)
    return code, out.getvalue().strip(), err.getvalue()


@given(spelled())
def test_the_cli_and_scenarios_read_the_same_names(option: tuple[str, int]) -> None:
    text, value = option
    assert GotoOption.parse(text) == value
    scn = scenario.parse(f"goto 200 100 {text}\nwait\n")
    assert scn.steps[0].args == [200, 100, value] or tuple(scn.steps[0].args) == (200, 100, value)
    code, out, _ = encode(["encode", "goto", "200", "100", text])
    assert code == 0 and out == f"00 00 c8 00 64 {value:02x}"
    assert encode(["encode", "goto", "200", "100", str(value)])[1] == out


@given(st.text(min_size=1, max_size=12).filter(lambda t: t.strip() and "\n" not in t))
def test_anything_else_is_refused_in_one_line(text: str) -> None:
    try:
        value = GotoOption.parse(text)
    except ValueError as e:
        assert repr(text) in str(e)
        code, _, err = encode(["--bus", "1", "goto", "200", "100", "--options", text])
        assert code == 2 and len(err.strip().splitlines()) == 1 and "--options" in err
    else:
        assert isinstance(value, int)
