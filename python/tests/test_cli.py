"""The command line: demonstration and protocol tools, including their error messages."""

from pathlib import Path

import pytest

from asserv.cli import main


def test_demo_runs_the_annex_session(capsys: pytest.CaptureFixture[str], tmp_path: Path) -> None:
    png = tmp_path / "demo.png"
    assert main(["demo", "--png", str(png)]) == 0
    out = capsys.readouterr().out
    # every frame with its meaning, the annex's orders among them
    assert "W 00 00 c8 00 64 00 | R 02          GOTO x_mm=200 y_mm=100 options=0" in out
    assert "W 02 16 | R 06" in out and "GOTO_PANIER angle_deg=44" in out
    assert "order ended: CHOC_PANIER" in out
    # the status over time, the final poses and the error radius
    assert "BUSY_TRAJET|BUSY_GOTO_PANIER" in out
    assert "truth (simulator)" in out and "error radius" in out
    assert png.stat().st_size > 10_000 and png.read_bytes()[:4] == b"\x89PNG"


def test_encode_and_decode(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["encode", "GOTO", "200", "100", "0", "--pec"]) == 0
    assert capsys.readouterr().out.strip() == "00 00 c8 00 64 00 ce"
    assert main(["decode", "00", "00", "c8", "00", "64", "00", "ce"]) == 0
    assert capsys.readouterr().out.strip() == "GOTO x_mm=200 y_mm=100 options=0 +PEC"


def test_bad_arguments_say_what_is_wrong(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["encode", "GOTO", "200", "100", "16"]) == 2
    assert "RESERVED_BIT: GOTO.options=0x10" in capsys.readouterr().err
    assert main(["encode", "GOTO", "1", "x", "0"]) == 2
    assert "asserv encode: param 2 ('x') is not an integer" in capsys.readouterr().err
    assert main(["decode", "00", "zz"]) == 2
    assert "asserv decode: byte 2 ('zz') is not hexadecimal" in capsys.readouterr().err
