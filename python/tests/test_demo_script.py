"""scripts/demo.sh, as the README's first command: it installs once, then re-runs with no
packaging output at all, and writes its PNG in the folder it is run from, saying where by its
absolute path (issue 30)."""

from __future__ import annotations

import os
import subprocess
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]


def demo(cwd: Path) -> subprocess.CompletedProcess[str]:
    env = {k: v for k, v in os.environ.items() if k not in ("VIRTUAL_ENV", "PYTHONPATH")}
    env["MPLBACKEND"] = "Agg"
    return subprocess.run(
        ["bash", str(ROOT / "scripts" / "demo.sh")],
        cwd=cwd,
        capture_output=True,
        text=True,
        timeout=900,
        env=env,
        stdin=subprocess.DEVNULL,
        check=False,
    )


def _stamp(path: Path) -> int | None:
    return path.stat().st_mtime_ns if path.exists() else None


def test_the_demo_reruns_quietly_and_says_where_its_png_is(tmp_path: Path) -> None:
    in_checkout = _stamp(ROOT / "asserv-demo.png")
    first = demo(tmp_path)  # may install (the demo profile's first set-up on this checkout)
    assert first.returncode == 0, first.stderr[-3000:]
    (tmp_path / "asserv-demo.png").unlink()
    again = demo(tmp_path)
    assert again.returncode == 0, again.stderr[-3000:]
    printed = again.stdout + again.stderr
    # nothing from the set-up: pip did not run, and no packaging warning
    assert "setup:" not in printed and "arning" not in printed, printed[:3000]
    assert again.stderr == ""
    # the plot in the folder the demo was run from, named by its absolute path
    png = tmp_path / "asserv-demo.png"
    assert png.read_bytes()[:4] == b"\x89PNG"
    assert again.stdout.splitlines()[-1] == f"plot: {png.resolve()}"
    assert _stamp(ROOT / "asserv-demo.png") == in_checkout  # none written into the checkout
