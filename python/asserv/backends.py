"""The buses a command opens by kind: one registry, ``BACKENDS``, as python-can's.

``asserv --bus N ...`` opens Linux I2C bus N with smbus2, ``asserv --sim HOST:PORT ...`` the
board of the simulator server (``asserv sim serve``); each backend is imported when it is
opened, so that the driver-only install never imports the simulator or the server. An
in-process simulator is no kind of its own: its ``Simulator.bus`` is the bus.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

__all__ = ["BACKENDS", "open_bus"]


def _open_smbus2(number: int) -> Any:
    """Linux I2C bus ``number`` (/dev/i2c-N), looked up at each call (tests replace it)."""
    import smbus2

    return smbus2.SMBus(number)


def _open_served(where: tuple[str, int]) -> Any:
    """The board of the simulator server (``asserv sim serve``) at ``(host, port)``."""
    from .server import RemoteBus

    return RemoteBus(*where)


#: The buses a command can open, by kind, as python-can's ``BACKENDS``: each opens lazily, so
#: that the driver-only install imports neither the simulator nor the server. ``"smbus2"``
#: takes a bus number (``--bus N``), ``"sim"`` a ``(host, port)`` (``--sim HOST:PORT``). An
#: in-process simulator is no kind of its own: its ``Simulator.bus`` is the bus. Tests put a
#: simulated bus in the place of a kind (``monkeypatch.setitem(BACKENDS, "smbus2", ...)``).
BACKENDS: dict[str, Callable[[Any], Any]] = {"smbus2": _open_smbus2, "sim": _open_served}


def open_bus(kind: str, where: Any) -> Any:
    """The bus of ``kind`` (a key of ``BACKENDS``) at ``where``; its ``close()`` releases it.
    Raises ``OSError`` when it cannot be opened, ``ValueError`` for an unknown kind."""
    try:
        backend = BACKENDS[kind]
    except KeyError:
        raise ValueError(f"no bus of kind {kind!r} (known: {', '.join(BACKENDS)})") from None
    return backend(where)
