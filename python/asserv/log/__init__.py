"""Run logs: the same values as an MCAP file (Foxglove, Lichtblick, PlotJuggler) and as CSV.

A log is a table with one row per sample and the columns ``LOG_FIELDS`` (``LOG_DTYPE``), from a
simulated run (``from_trace``: every control tick, the truth included) or from a real board polled
over I2C (``poll_board``: POSITION, DEBUG and CHECK_BUSY; the truth is unknown, NaN). A value that
is not known is NaN in the table and an empty cell in the CSV.

    sim = Simulator()
    board = Board(sim.bus)
    board.goto(500, 0)
    board.wait_idle(10)
    log.save(log.from_sim(sim), mcap="run.mcap", csv="run.csv", field=sim.field)

The MCAP file has, with JSON-encoded messages and a JSON schema per channel:

- ``/field`` (``foxglove.SceneUpdate``): the table, its borders, lines, baskets and obstacles;
- ``/robot`` (``foxglove.SceneUpdate``): the robot's outline, in the frames ``robot`` (the board's
  estimate) and ``robot_true`` (the simulated truth), as the 3D panel draws them;
- ``/tf`` (``foxglove.FrameTransform``): ``field`` to ``robot`` and to ``robot_true``;
- ``/pose/estimate`` and ``/pose/true`` (``foxglove.PoseInFrame``): the two poses;
- ``/asserv`` (``asserv.Sample``): every column of the table, for plots (mm, degrees, s).

Positions in the Foxglove messages are in metres (their convention); in ``/asserv`` and the CSV
they are in millimetres.

The package: ``format`` (the table, its columns and types, a simulated run's rows), ``write`` (the
MCAP file and the CSV), ``read`` (reading them back), ``poll`` (a real board's rows) and ``cli``
(``asserv log``, and the board options it shares with ``view`` and ``tune``).
"""

from __future__ import annotations

from .._columns import INTEGER, LOG_FIELDS, UNITS
from .cli import (
    board_where,
    bus_options,
    check_output,
    open_board,
    register,
    wants_board,
    write_outputs,
)
from .format import (
    CORRECTION_DEG,
    CORRECTION_MM,
    LOG_DTYPE,
    PROFILE,
    FollowingErrors,
    LogError,
    Outline,
    empty,
    following_errors,
    from_sim,
    from_trace,
)
from .poll import board_row, bus_truth, poll_board, poll_clock
from .read import McapLog, read_csv, read_mcap
from .write import (
    SCHEMAS,
    TOPICS,
    LogWriter,
    field_dict,
    field_from_dict,
    field_scene,
    robot_scene,
    sample_json,
    save,
)

__all__ = [
    "CORRECTION_DEG",
    "CORRECTION_MM",
    "INTEGER",
    "LOG_DTYPE",
    "LOG_FIELDS",
    "PROFILE",
    "SCHEMAS",
    "TOPICS",
    "UNITS",
    "FollowingErrors",
    "LogError",
    "LogWriter",
    "McapLog",
    "Outline",
    "board_row",
    "board_where",
    "bus_options",
    "bus_truth",
    "check_output",
    "empty",
    "field_dict",
    "field_from_dict",
    "field_scene",
    "following_errors",
    "from_sim",
    "from_trace",
    "open_board",
    "poll_board",
    "poll_clock",
    "read_csv",
    "read_mcap",
    "register",
    "robot_scene",
    "sample_json",
    "save",
    "wants_board",
    "write_outputs",
]
