"""The compiled simulator ``asserv_sim._core`` (the ``sim`` extra), under the name asserv uses.

``pip install asserv`` is the driver alone; ``pip install "asserv[sim]"`` adds asserv-sim, the
board's C code and the physics compiled with cffi. Without it, importing this module raises an
ImportError that says how to install it.
"""

from __future__ import annotations

try:
    from asserv_sim._core import ffi, lib
except ImportError as e:
    raise ImportError(
        f'the simulator is not installed: pip install "asserv[sim]" (it needs a C compiler): {e}'
    ) from e

__all__ = ["ffi", "lib"]
