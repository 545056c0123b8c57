"""Protocol demonstration: the specification's annex session, frame by frame, through the
board's C protocol layer.

The master side is this package's codec; the board side is firmware/core/protocol.c compiled
into asserv._core. The board's motion is scripted here (the control core and the simulator run
it for real in ``asserv demo`` once they exist): what is shown is the wire protocol.
"""

from __future__ import annotations

from collections.abc import Callable

from . import codec
from ._protocol import ADDRESS, Status
from .cboard import ProtocolLayer

# The annex session (specification, "Annexe: Exemples et possibilites actuelles").
ANNEX: list[tuple[str, tuple[int, ...], str]] = [
    ("SET_VITESSE_TRAJ", (100,), "100 cm/s"),
    ("SET_VITESSE_ROT", (50,), "50 cm/s"),
    ("GOTO", (200, 100, 0), "to (200, 100) mm, no options"),
    ("GOTO", (100, 50, 0), "to (100, 50) mm, a point in front of the basket"),
    ("GOTO_PANIER", (22,), "angle 22 x 2 = 44 degrees (the annex's 45/2)"),
]


def _hex(data: bytes) -> str:
    return " ".join(f"{b:02x}" for b in data)


def run(out: Callable[[str], None] = print) -> int:
    """Play the session; return 0 when every frame was taken by the C layer as the codec says."""
    board = ProtocolLayer()
    board.set_snapshot(x_mm=0, y_mm=0, angle_2deg=0, radius_mm=0, status=0)
    board.tick()
    failures = 0
    pose = (0, 0)

    def read(name: str) -> codec.Reply:
        request = codec.encode(name)
        board.write(request, stop=False)
        n = codec.reply_length(name) + 1
        data = board.read(n)
        prefix = bytes([codec.write_address(), *request, codec.read_address()])
        reply = codec.decode_reply(name, data, pec_prefix=prefix)
        out(f"  master -> [{_hex(request)}] Sr <- [{_hex(data)}]  {name}: {reply!r}  (PEC ok)")
        return reply

    out(f"asserv protocol demonstration: board at I2C address {ADDRESS}")
    out("board side: firmware/core/protocol.c (cffi); motion scripted, not simulated\n")
    for name, args, meaning in ANNEX:
        frame = codec.encode(name, *args)
        out(f"master -> [{_hex(frame)}]  {codec.decode_write(frame).describe()}  ({meaning})")
        board.write(frame)
        busy = board.read(1)
        out(f"  poll   <- [{_hex(busy)}]  CHECK_BUSY: {Status(busy[0])!r}")
        taken = board.tick()
        want = codec.decode_write(frame)
        ok = len(taken) == 1 and (taken[0].designation, taken[0].args) == (
            want.message.designation,
            want.args,
        )
        failures += not ok
        out(f"  board took {taken}: {'as encoded' if ok else 'MISMATCH'}")
        if name == "GOTO":
            # Scripted motion: the board reports the target reached after the move.
            pose = (args[0], args[1])
            board.set_snapshot(status=int(Status.BUSY_TRAJET))
            board.tick()
            read("CHECK_BUSY")
            board.set_snapshot(x_mm=pose[0], y_mm=pose[1], radius_mm=1, status=0)
            board.tick()
            read("CHECK_BUSY")
            read("POSITION")
        elif name == "GOTO_PANIER":
            board.set_snapshot(status=int(Status.BUSY_TRAJET | Status.BUSY_GOTO_PANIER))
            board.tick()
            read("CHECK_BUSY")
            board.set_snapshot(status=int(Status.CHOC_PANIER), angle_2deg=22)
            board.tick()
            read("CHECK_BUSY")
            read("POSITION")

    out("\nA malformed frame is rejected whole and flagged:")
    bad = bytes([0, 0, 200, 0, 100, 0x04])
    try:
        codec.decode_write(bad)
    except codec.FrameError as e:
        out(f"master -> [{_hex(bad)}]  the codec says: {e}")
    board.write(bad)
    busy = board.read(1)
    out(f"  poll   <- [{_hex(busy)}]  CHECK_BUSY: {Status(busy[0])!r}")
    read("LAST_REJECT")
    taken = board.tick()
    out(f"  board took {taken}: nothing")
    failures += len(taken) != 0
    out(f"\n{'all frames taken as encoded' if not failures else f'{failures} mismatches'}")
    return 1 if failures else 0
