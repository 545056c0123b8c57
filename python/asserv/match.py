"""The match timer: the end of the match stops the robot, on the board's own clock.

    with MatchTimer(board, duration_s=100) as match:   # the simulated time on a simulated bus
        while match.remaining() > 5:
            board.complete(board.goto, 600, 0)
    # here the match is over or the strategy ended: the robot was sent STOP

The timer sets ``board.deadline``. Every wait of the driver (``Board.sleep``, hence
``wait_idle`` and ``complete``) is cut at the deadline; there, and at the first transaction after
it, the board is sent STOP and ``MatchOver`` is raised, which the ``with`` block swallows. On a
wall clock a watchdog thread also sends STOP at the deadline, in case the strategy is busy
elsewhere (a long computation, a camera) and makes no call to the board. All the Boards on the
same bus share the bus lock, not the deadline: give each Board its timer (or one Board to the
threads). docs/strategy.md shows a whole match.
"""

from __future__ import annotations

import threading
from types import TracebackType

from .driver import AsservError, Board, MatchOver

__all__ = ["MATCH_S", "MatchOver", "MatchTimer"]

#: Length of a Eurobot match, seconds.
MATCH_S = 100.0


class MatchTimer:
    """``duration_s`` seconds of match on ``board``'s clock, from ``start()`` (or the ``with``).

    ``stop_on_exit``: also send STOP when the ``with`` block ends before the deadline (the
    strategy finished or raised): the robot never runs on after its strategy."""

    def __init__(
        self, board: Board, duration_s: float = MATCH_S, *, stop_on_exit: bool = True
    ) -> None:
        if not 0 < duration_s < 1e6:
            raise ValueError(f"duration_s must be > 0 and finite, not {duration_s}")
        self.board = board
        self.duration_s = float(duration_s)
        self.stop_on_exit = stop_on_exit
        self.start_s: float | None = None
        self._watchdog: threading.Timer | None = None

    def start(self) -> MatchTimer:
        """Start the match now (on the board's clock); a timer starts once."""
        if self.start_s is not None:
            raise RuntimeError("this match timer was started already")
        self.start_s = self.board.now()
        self.board.deadline = self.start_s + self.duration_s
        self.board._match_stopped = False
        if not getattr(self.board.clock, "drives_simulation", False):
            # A clock that moves by itself (wall, or a server's): a watchdog too.
            self._watchdog = threading.Timer(self.duration_s, self._watch)
            self._watchdog.daemon = True
            self._watchdog.start()
        return self

    def _watch(self) -> None:
        try:
            while self.remaining() > 0:  # the clock may run slower than the wall (a server)
                threading.Event().wait(min(self.remaining(), 0.05))
            self.board._check_deadline("match timer")
        except (MatchOver, AsservError):
            pass

    def elapsed(self) -> float:
        """Seconds since the start (0 before it)."""
        return 0.0 if self.start_s is None else self.board.now() - self.start_s

    def remaining(self) -> float:
        """Seconds left, >= 0 (the whole duration before the start)."""
        return max(0.0, self.duration_s - self.elapsed())

    @property
    def over(self) -> bool:
        """True once the deadline has passed."""
        return self.start_s is not None and self.remaining() <= 0.0

    def __enter__(self) -> MatchTimer:
        return self.start()

    def __exit__(
        self,
        exc_type: type[BaseException] | None,
        exc: BaseException | None,
        tb: TracebackType | None,
    ) -> bool:
        if self._watchdog is not None:
            self._watchdog.cancel()
        try:
            if self.stop_on_exit and not self.board._match_stopped:
                self.board._match_stopped = True
                self.board.stop()
        except AsservError:
            if exc_type is None:
                raise
        finally:
            self.board.deadline = None
        return exc_type is not None and issubclass(exc_type, MatchOver)
