"""``asserv demo``: the specification's annex session on the simulated board, end to end.

The master is this package's driver (``asserv.Board``) on the simulator's smbus2-compatible bus;
the board is the firmware core (C, compiled into ``asserv.sim._core``) on the physics of ``sim/``.
Every I2C frame is printed with its meaning, then the status over time, the final estimated and
true poses and the error radius; a PNG shows the field, both paths and the speed profiles.
"""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

from .. import scenario
from .._protocol import Status
from . import plots

ANNEX = scenario.SCENARIO_DIR / "annex.txt"


def run(out: Callable[[str], None] = print, png: str | Path | None = "asserv-demo.png") -> int:
    """Play the annex session; returns 0 when it ends as the annex says (basket touched)."""
    scn = scenario.load(ANNEX)
    out("asserv demo: the specification's annex session on the simulated board")
    out(
        f"  master: asserv.Board on the simulator's bus (I2C address 2, {scn.bus_hz // 1000} kHz); "
        "board: firmware/core at 1 kHz; physics: sim/, 100 us steps"
    )
    out(f"  scenario: {ANNEX.name}; field: {scn.field.source}")
    out("")
    res = scenario.play(scn, out)
    scenario.summary(res, out)
    if png is not None and len(res.sim.trace):
        path = plots.plot_run(
            res.sim.trace,
            scn.field,
            png,
            title="asserv demo: the annex session (GOTO 200,100; GOTO 100,50; GOTO_PANIER 44 deg)",
            targets=res.targets,
        )
        out(f"plot: {Path(path).resolve()}")
    touched = bool(res.final_status & Status.CHOC_PANIER)
    if not (res.ok and touched):
        out("the session did not end on the basket as the annex describes")
        return 1
    return 0
