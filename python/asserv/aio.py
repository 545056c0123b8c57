"""The asyncio flavour of the driver: ``AsyncBoard``, the same calls as ``Board``, awaited.

    async def strategy(board: AsyncBoard) -> None:
        outcome = await board.complete(board.board.goto, 600, 0, timeout_s=10)
        pose = await board.position()

    asyncio.run(strategy(AsyncBoard(Board(sim.bus))))

Each call runs the ``Board`` method in a worker thread (``asyncio.to_thread``): the event loop
is never blocked by a bus transaction, and the transactions of concurrent tasks are kept whole by
the Board's bus lock. ``sleep`` is ``asyncio.sleep`` on the wall clock; on a simulated clock it is
``Board.sleep`` in a worker thread (the simulation runs meanwhile, in slices, so the other tasks'
transactions go in between). Errors are the driver's (``asserv.driver``).
"""

from __future__ import annotations

import asyncio
from collections.abc import Callable
from typing import Any, TypeVar

from ._protocol import Capability, Filtre, Status
from .bus import SystemClock
from .codec import Debug, FixInfo, LastReject, Motion, Pose, ResetInfo, Version
from .driver import Board, GotoOption, Outcome

__all__ = ["AsyncBoard"]

T = TypeVar("T")


class AsyncBoard:
    """``board`` (a ``Board``) for asyncio code."""

    def __init__(self, board: Board) -> None:
        self.board = board

    def __repr__(self) -> str:
        return f"AsyncBoard({self.board!r})"

    async def _call(self, fn: Callable[..., T], *args: Any) -> T:
        return await asyncio.to_thread(fn, *args)

    # Time.
    def now(self) -> float:
        """The board's clock (``Board.now``): reading it does not block."""
        return self.board.now()

    async def sleep(self, seconds: float) -> None:
        """``Board.sleep``: ``asyncio.sleep`` on the wall clock, cut at the match deadline."""
        b = self.board
        if isinstance(b.clock, SystemClock):
            if not seconds >= 0 or seconds == float("inf"):
                raise ValueError(f"sleep: seconds must be finite and >= 0, not {seconds}")
            if b.deadline is not None:
                seconds = max(0.0, min(seconds, b.deadline - b.now()))
            await asyncio.sleep(seconds)
            if b.deadline is not None:
                await self._call(b._check_deadline, "sleep")
            return
        await self._call(b.sleep, seconds)

    async def wait_idle(self, timeout_s: float, poll_s: float = 0.01) -> Status:
        """``Board.wait_idle``, polling with ``await self.sleep``."""
        return await self._call(self.board.wait_idle, timeout_s, poll_s)

    async def complete(
        self,
        order: Callable[..., object],
        *args: Any,
        timeout_s: float = 30.0,
        poll_s: float = 0.01,
    ) -> Outcome:
        """``Board.complete``: send, wait, return the Outcome."""
        return await asyncio.to_thread(
            self.board.complete, order, *args, timeout_s=timeout_s, poll_s=poll_s
        )

    # Orders and settings.
    async def goto(
        self,
        x_mm: int,
        y_mm: int,
        options: GotoOption | int = 0,
        *,
        append: bool = False,
        through: bool = False,
    ) -> None:
        await asyncio.to_thread(
            self.board.goto, x_mm, y_mm, options, append=append, through=through
        )

    async def goto_reverse(self, distance_mm: int, *, append: bool = False) -> None:
        await asyncio.to_thread(self.board.goto_reverse, distance_mm, append=append)

    async def goto_panier(self, angle_deg: float, *, append: bool = False) -> None:
        await asyncio.to_thread(self.board.goto_panier, angle_deg, append=append)

    async def pause(self) -> None:
        await self._call(self.board.pause)

    async def resume(self) -> None:
        await self._call(self.board.resume)

    async def set_speed_scale(self, percent: int) -> None:
        await self._call(self.board.set_speed_scale, percent)

    async def set_corner(self, tolerance_mm: int) -> None:
        await self._call(self.board.set_corner, tolerance_mm)

    async def stop(self) -> None:
        await self._call(self.board.stop)

    async def set_vitesse_traj(self, speed_cm_s: int, accel_cm_s2: int | None = None) -> None:
        await self._call(self.board.set_vitesse_traj, speed_cm_s, accel_cm_s2)

    async def set_vitesse_rot(self, speed_cm_s: int, accel_cm_s2: int | None = None) -> None:
        await self._call(self.board.set_vitesse_rot, speed_cm_s, accel_cm_s2)

    async def set_filtre(self, preset: Filtre | int) -> None:
        await self._call(self.board.set_filtre, preset)

    async def set_timeout(self, timeout_ms: int) -> None:
        await self._call(self.board.set_timeout, timeout_ms)

    async def heartbeat(self) -> None:
        await self._call(self.board.heartbeat)

    async def set_new_pos(self, err_x_mm: int, err_y_mm: int, err_angle_deg: int) -> None:
        await self._call(self.board.set_new_pos, err_x_mm, err_y_mm, err_angle_deg)

    async def declare_pose(self, x_mm: int, y_mm: int, angle_deg: int) -> None:
        await self._call(self.board.declare_pose, x_mm, y_mm, angle_deg)

    async def fix(
        self,
        x_mm: float,
        y_mm: float,
        heading_deg: float | None,
        sigma_mm: float,
        sigma_deg: float | None,
        age_ms: float,
    ) -> None:
        await self._call(self.board.fix, x_mm, y_mm, heading_deg, sigma_mm, sigma_deg, age_ms)

    # Queries.
    async def check_busy(self) -> Status:
        return await self._call(self.board.check_busy)

    async def position(self) -> Pose:
        return await self._call(self.board.position)

    async def info_choc(self) -> int:
        return await self._call(self.board.info_choc)

    async def version(self) -> Version:
        return await self._call(self.board.version)

    async def last_reject(self) -> LastReject:
        return await self._call(self.board.last_reject)

    async def debug(self) -> Debug:
        return await self._call(self.board.debug)

    async def fix_info(self) -> FixInfo:
        return await self._call(self.board.fix_info)

    async def reset_info(self) -> ResetInfo:
        return await self._call(self.board.reset_info)

    async def motion(self) -> Motion:
        return await self._call(self.board.motion)

    async def capabilities(self, *, refresh: bool = False) -> Capability:
        return await asyncio.to_thread(self.board.capabilities, refresh=refresh)
