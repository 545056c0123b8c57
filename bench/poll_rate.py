"""How fast ``asserv --bus N view`` and ``asserv --bus N log`` can poll a board: the bytes of one
row (POSITION, DEBUG, CHECK_BUSY) counted on the simulated bus, their time at 100 and 400 kHz
(9 bit times a byte, as the simulator's bus charges them), and the rows a second that fit.

    python bench/poll_rate.py [--strict]

Also the rows a wall second that this machine's Python reaches on the in-process simulated bus
(a figure of this machine, not of a board). A real adapter adds its own time per transaction
(the kernel's i2c-dev call, START and STOP conditions), which this model does not count.

The goal (docs/view.md): ``view`` and ``log`` poll 50 rows a second on a 100 kHz bus, with PEC
and without; the rows that fit at 100 kHz are marked met or MISSED against it, a summary line
last; --strict exits 1 on a miss. The wall-clock rows are marked against nothing.
"""

from __future__ import annotations

import argparse
import sys
import time
from typing import Any

from smbus2 import i2c_msg

from asserv import Board, log
from asserv.goals import Goals, add_strict_flag
from asserv.sim import Simulator

GOAL_ROWS_S = 50.0  # what view and log poll by default (--hz)


class CountingBus:
    """The simulator's bus, counting the bytes of each transaction: an address byte per message
    and its data bytes (what a byte-level bus puts on the wire, ACKs in each byte's 9 bits)."""

    def __init__(self, sim: Simulator) -> None:
        self.inner = sim.bus
        self.clock = sim
        self.bytes = 0
        self.transactions = 0

    def i2c_rdwr(self, *msgs: i2c_msg) -> None:
        self.transactions += 1
        self.bytes += sum(1 + int(m.len) for m in msgs)
        self.inner.i2c_rdwr(*msgs)

    def __getattr__(self, name: str) -> Any:
        return getattr(self.inner, name)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    add_strict_flag(ap)
    args = ap.parse_args(argv)
    goals = Goals("bench/poll_rate.py")
    for pec in (False, True):
        sim = Simulator(record=False)
        bus = CountingBus(sim)
        board = Board(bus, pec=pec)
        t0 = sim.time_s
        log.board_row(board, 0.0)
        bus_s = sim.time_s - t0
        print(
            f"PEC {'on ' if pec else 'off'}: a row is {bus.bytes} bytes in"
            f" {bus.transactions} transactions; the simulated 100 kHz bus took"
            f" {bus_s * 1e3:.2f} ms"
        )
        for khz in (100, 400):
            row_s = bus.bytes * 9 / (khz * 1e3)
            print(f"  at {khz} kHz: {row_s * 1e3:.2f} ms a row, at most {1 / row_s:.0f} rows/s")
            if khz == 100:
                name = f"PEC {'on' if pec else 'off'}: rows a second at 100 kHz"
                goals.check(name, 1 / row_s, ">=", GOAL_ROWS_S, "rows/s")
        sim = Simulator(record=False)
        board = Board(sim.bus, pec=pec)
        rows = list(log.poll_board(board, 1e6, duration_s=1.0))  # as fast as the bus lets
        print(f"  polled as fast as it goes: {len(rows)} rows in 1 s of the simulated bus")
        n, w0 = 0, time.perf_counter()
        while time.perf_counter() - w0 < 1.0:
            log.board_row(board, 0.0)
            n += 1
        print(f"  this machine's Python: {n / (time.perf_counter() - w0):.0f} rows per wall second")
    print("goals (docs/view.md: 50 rows a second on a 100 kHz bus):")
    for line in goals.lines():
        print(line)
    print(goals.summary())
    return goals.exit_code(args.strict)


if __name__ == "__main__":
    sys.exit(main())
