"""A real board's log: its rows from POSITION, DEBUG and CHECK_BUSY polls."""

from __future__ import annotations

from collections.abc import Callable, Iterator
from typing import TYPE_CHECKING, Any

import numpy as np

from ..bus import Clock
from .format import empty

if TYPE_CHECKING:
    from ..driver import Board

# ---- a real board -----------------------------------------------------------------------------


def board_row(
    board: Board, t_s: float, truth: Callable[[], tuple[float, float, float, float]] | None = None
) -> np.void:
    """One row from a board: POSITION, DEBUG and CHECK_BUSY read now. The truth is unknown
    (NaN) unless ``truth()`` gives it (``RemoteBus.truth``: the simulator server's robot)."""
    pose = board.position()
    d = board.debug()
    status = board.check_busy()
    row: np.void = empty(1)[0]
    row["t_s"] = t_s
    if truth is not None:
        _, row["x_mm"], row["y_mm"], row["heading_deg"] = truth()
    # POSITION's angle is in 2-degree steps; DEBUG's heading is finer: take DEBUG's.
    row["est_x_mm"], row["est_y_mm"] = pose.x_mm, pose.y_mm
    row["est_heading_deg"] = d.heading_cdeg / 100
    row["radius_mm"] = pose.radius_mm
    row["v_mm_s"] = d.speed_mm_s
    row["omega_deg_s"] = d.turn_rate_cdeg_s / 100
    row["dist_err_mm"] = d.dist_err_um / 1000
    row["angle_err_mm"] = d.angle_err_um / 1000
    row["duty_left"] = d.duty_left_q15 / 32767
    row["duty_right"] = d.duty_right_q15 / 32767
    row["current_left_A"] = d.current_left_ma / 1000
    row["current_right_A"] = d.current_right_ma / 1000
    row["status"] = int(status)
    row["order_state"] = int(d.order_state)
    row["end_reason"] = int(d.end_reason)
    return row


def poll_clock(bus: Any) -> Clock:
    """Time for polling a board on ``bus``: its own clock (``asserv.bus.clock_of``: a simulated
    bus's, the simulator server's) or the system's."""
    from ..bus import clock_of

    return clock_of(bus)


def bus_truth(bus: Any) -> Callable[[], tuple[float, float, float, float]] | None:
    """The bus's ``truth()`` (the simulator server's true pose: ``RemoteBus``), or None."""
    truth = getattr(bus, "truth", None)
    return truth if callable(truth) else None


def poll_board(
    board: Board,
    hz: float = 50.0,
    *,
    duration_s: float | None = None,
    until: Callable[[], bool] | None = None,
    on_row: Callable[[np.void], None] | None = None,
    clock: Clock | None = None,
) -> Iterator[np.void]:
    """Poll the board at ``hz`` rows a second (each row: POSITION, DEBUG, CHECK_BUSY, and the
    truth where the bus knows it) for ``duration_s`` (None: until ``until()`` says so, or
    forever); yields the rows. ``clock`` paces it (default ``poll_clock(board.bus)``). A row is
    38 bytes on the bus (44 with PEC), 3.4 ms at 100 kHz: up to about 290 rows a second fit
    (``bench/poll_rate.py`` prints it; a real adapter adds its own time per transaction)."""
    if not hz > 0:
        raise ValueError(f"hz must be > 0, not {hz}")
    clock = clock or poll_clock(board.bus)
    truth = bus_truth(board.bus)
    period = 1.0 / hz
    t0 = clock.monotonic()
    next_t = t0
    while True:
        now = clock.monotonic()
        if duration_s is not None and now - t0 >= duration_s:
            return
        if until is not None and until():
            return
        row = board_row(board, now - t0, truth)
        if on_row is not None:
            on_row(row)
        yield row
        next_t += period
        wait = next_t - clock.monotonic()
        if wait > 0:
            clock.sleep(wait)
        else:
            next_t = clock.monotonic()
