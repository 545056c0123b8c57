"""Several of our robots on one field, each with its own simulated board.

    a = Simulator({"start": (-1000, -300, 0)})
    b = Simulator({"start": (1000, -300, 180)}, seed=1)
    arena = Arena([a, b])            # before the Boards: it gives each bus the arena's clock
    board_a, board_b = Board(a.bus), Board(b.bus)

Each robot sees the others as obstacles: a box the size of their outline, where they truly are,
moved every millisecond (each control tick). The contact stops the robot and closes its shock
switches, as a border or an obstacle would; a robot is not pushed by another (each is an
immovable obstacle for the other, for the time of a tick), which is right for a collision that
the shock switches end and rough for robots shoving each other for long.

The arena's clock is shared: sleeping on any robot's bus (``Board.sleep``, ``wait_idle``,
``complete``) runs every robot to the time waited for, tick by tick. The strategies of the
robots can run in threads, one per Board: the simulated time then moves while any of them
sleeps, each wakes when its time comes, and every slice of simulation holds all the buses'
locks (``asserv.driver.bus_lock``), so no transaction is cut by it.
"""

from __future__ import annotations

import math
import threading
from collections.abc import Sequence

from ..driver import bus_lock
from . import Simulator

__all__ = ["Arena"]

_TICK_NS = 1_000_000


class _ArenaClock:
    """One robot's view of the arena's clock: its own simulated time; sleeping runs them all."""

    drives_simulation = False  # Board.sleep must not hold one bus's lock: the arena takes all

    def __init__(self, arena: Arena, index: int) -> None:
        self.arena, self.index = arena, index

    def monotonic(self) -> float:
        return self.arena.sims[self.index].time_s

    def sleep(self, seconds: float) -> None:
        if not seconds >= 0 or seconds == math.inf:
            raise ValueError(f"sleep: seconds must be finite and >= 0, not {seconds}")
        sim = self.arena.sims[self.index]
        self.arena.advance_to_ns(int(sim._h.now_ns) + round(seconds * 1e9))


class Arena:
    """``sims`` (two or more Simulators on fields of the same size) on one field."""

    def __init__(self, sims: Sequence[Simulator]) -> None:
        if len(sims) < 2:
            raise ValueError("an arena holds two robots or more")
        if len({id(s) for s in sims}) != len(sims):
            raise ValueError("the same Simulator twice in an arena")
        f0 = sims[0].field
        for s in sims[1:]:
            if (s.field.length_mm, s.field.width_mm) != (f0.length_mm, f0.width_mm):
                raise ValueError("the robots of an arena must be on fields of the same size")
        self.sims = list(sims)
        self._lock = threading.Lock()
        self._locks = [bus_lock(s.bus) for s in self.sims]
        # _others[i][j]: the index, in robot i's field, of the obstacle that is robot j.
        self._others: list[dict[int, int]] = []
        for i, s in enumerate(self.sims):
            mine = {}
            for j, o in enumerate(self.sims):
                if j != i:
                    cfg = o.config
                    mine[j] = s.add_obstacle(
                        *self._outline_centre(o)[:2],
                        half_x_mm=cfg.outline_length_mm / 2,
                        half_y_mm=cfg.outline_width_mm / 2,
                        heading_deg=self._outline_centre(o)[2],
                    )
                    s.lidar_targets.add(mine[j])  # its lidar sees the others
            self._others.append(mine)
        for i, s in enumerate(self.sims):
            s.bus.clock = _ArenaClock(self, i)
        self._sync()

    @staticmethod
    def _outline_centre(sim: Simulator) -> tuple[float, float, float]:
        x, y, h = sim.drive_pose()
        c, s = math.cos(math.radians(h)), math.sin(math.radians(h))
        ox, oy = sim.config.outline_offset_x_mm, sim.config.outline_offset_y_mm
        return x + ox * c - oy * s, y + ox * s + oy * c, h

    def _sync(self) -> None:
        centres = [self._outline_centre(s) for s in self.sims]
        for i, s in enumerate(self.sims):
            for j, k in self._others[i].items():
                s.move_obstacle(k, *centres[j])

    @property
    def time_s(self) -> float:
        """The arena's time: the latest of its robots' (a bus transaction moves one robot
        ahead by its bytes until the next sleep)."""
        return max(s.time_s for s in self.sims)

    def advance(self, seconds: float) -> None:
        """Run every robot for ``seconds`` from the arena's time."""
        if not seconds >= 0 or seconds == math.inf:
            raise ValueError(f"advance: seconds must be finite and >= 0, not {seconds}")
        self.advance_to_ns(max(int(s._h.now_ns) for s in self.sims) + round(seconds * 1e9))

    def advance_to_ns(self, target_ns: int) -> None:
        """Run every robot behind ``target_ns`` up to it, tick by tick, the obstacles that are
        the other robots moved at each tick."""
        while True:
            with self._lock:
                for lock in self._locks:
                    lock.acquire()
                try:
                    low = min(int(s._h.now_ns) for s in self.sims)
                    if low >= target_ns:
                        return
                    step = min(target_ns, (low // _TICK_NS + 1) * _TICK_NS)
                    for s in self.sims:
                        now = int(s._h.now_ns)
                        if now < step:
                            s._advance_ns(step - now)
                    self._sync()
                finally:
                    for lock in reversed(self._locks):
                        lock.release()
