"""The field description file: one file for the simulator and the board, checked with clear
errors."""

from __future__ import annotations

from pathlib import Path

import pytest

from asserv import field as fieldmod
from asserv.sim._core import ffi, lib


def test_default_file_is_what_the_c_code_is_built_with() -> None:
    f = fieldmod.load()
    c = ffi.new("struct sim_field *")
    lib.sim_field_defaults(c)
    assert (c.length_mm, c.width_mm, bool(c.borders)) == (f.length_mm, f.width_mm, f.borders)
    assert c.obstacle_count == len(f.baskets) + len(f.obstacles)
    for i, b in enumerate(f.baskets):
        o = c.obstacles[i]
        assert (o.kind, o.x_mm, o.y_mm, o.radius_mm) == (
            lib.SIM_OBSTACLE_BASKET,
            b.x_mm,
            b.y_mm,
            b.radius_mm,
        )
    assert c.line_count == len(f.lines)
    for i, ln in enumerate(f.lines):
        cl = c.lines[i]
        assert (cl.x0_mm, cl.y0_mm, cl.x1_mm, cl.y1_mm, cl.width_mm) == (
            ln.x0_mm,
            ln.y0_mm,
            ln.x1_mm,
            ln.y1_mm,
            ln.width_mm,
        )


@pytest.mark.parametrize(
    ("text", "message"),
    [
        ("[table]\nlength_mm = -3\n", "[table]: length_mm must be > 0"),
        ("[[basket]]\nx_mm = 0\ny_mm = 0\n", "basket 1: missing key 'radius_mm'"),
        ("[[basket]]\nx_mm = 0\ny_mm = 0\nraduis_mm = 3\n", "basket 1: unknown key 'raduis_mm'"),
        (
            "[[line]]\nx0_mm = 0\ny0_mm = 0\nx1_mm = 1\ny1_mm = 0\nwidth_mm = 'wide'\n",
            "line 1: width_mm must be a number",
        ),
        ("[[obstacle]]\nshape = 'star'\nx_mm = 0\ny_mm = 0\n", "obstacle 1: shape must be"),
        ("[[basket]]\nx_mm = 40000\ny_mm = 0\nradius_mm = 1\n", "x_mm = 40000 is out of range"),
        ("[tabel]\n", "unknown table 'tabel'"),
        ("[table\n", "not valid TOML"),
        (
            "".join(f"[[basket]]\nx_mm = {i}\ny_mm = 0\nradius_mm = 1\n" for i in range(5)),
            "5 baskets: the board knows at most 4",
        ),
    ],
)
def test_bad_field_files_say_what_and_where(tmp_path: Path, text: str, message: str) -> None:
    p = tmp_path / "bad.toml"
    p.write_text(text)
    with pytest.raises(fieldmod.FieldError) as e:
        fieldmod.load(p)
    assert str(e.value).startswith(str(p))
    assert message in str(e.value)


def test_missing_file() -> None:
    with pytest.raises(fieldmod.FieldError, match="cannot read the field file"):
        fieldmod.load("/nonexistent/field.toml")
