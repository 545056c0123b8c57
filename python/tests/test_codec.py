"""Properties of the codec, and the codec against the board's C layer on arbitrary frames."""

from hypothesis import given, settings
from hypothesis import strategies as st

from asserv import Reject, Status, codec
from asserv._protocol import MESSAGES, Message
from asserv.sim.cboard import ProtocolLayer

ORDERS_AND_SETS = [m for m in MESSAGES if m.kind != "ETAT"]


def valid_args(m: Message) -> st.SearchStrategy[tuple[int, ...]]:
    parts = []
    for f in m.params:
        if f.mask is not None:
            parts.append(st.integers(0, 255).map(lambda v, mask=f.mask: v & mask))
        else:
            parts.append(st.integers(f.min, f.max))
    return st.tuples(*parts)


@st.composite
def valid_write(draw: st.DrawFn) -> tuple[Message, tuple[int, ...], bool]:
    m = draw(st.sampled_from(MESSAGES))
    args = draw(valid_args(m))
    if m.name == "GOTO" and args[2] & 0x08 and args[2] & 0x03:
        args = (*args[:2], args[2] & ~0x08)  # PASS_THROUGH with a recalibration: BAD_OPTIONS
    if m.min_params < len(m.params) and draw(st.booleans()):
        return m, args[: m.min_params], False
    return m, args, draw(st.booleans())


@given(valid_write())
def test_encode_then_decode_is_identity(w: tuple[Message, tuple[int, ...], bool]) -> None:
    m, args, pec = w
    frame = codec.encode(m.name, *args, pec=pec)
    back = codec.decode_write(frame)
    assert (back.message, back.args, back.pec) == (m, args, pec)


@settings(max_examples=400)
@given(st.binary(min_size=1, max_size=12))
def test_codec_and_c_layer_agree_on_any_frame(frame: bytes) -> None:
    """Differential test: the master's codec and the board judge every write alike."""
    board = ProtocolLayer()
    board.write(frame)
    rejected = bool(board.read(1)[0] & Status.COMMANDE_REJETEE)
    taken = board.tick()
    try:
        w = codec.decode_write(frame)
    except codec.FrameError as e:
        assert rejected
        assert taken == []
        board.write([codec.message("LAST_REJECT").designation])
        assert Reject(board.read(3)[0]) == e.reason
        return
    assert not rejected
    if w.message.kind == "ETAT":
        assert taken == []
    else:
        assert [(t.designation, t.args) for t in taken] == [(w.message.designation, w.args)]


@settings(max_examples=200)
@given(st.lists(st.binary(min_size=0, max_size=10), max_size=12))
def test_queue_only_receives_frames_the_codec_accepts(frames: list[bytes]) -> None:
    """A rejected frame never reaches the core, whatever came before it."""
    board = ProtocolLayer()
    expected = []
    for f in frames:
        board.write(f)
        try:
            w = codec.decode_write(f)
        except codec.FrameError:
            continue
        if w.message.kind != "ETAT" and len(expected) < 8:
            expected.append((w.message.designation, w.args))
    assert [(t.designation, t.args) for t in board.tick()] == expected


def test_encode_rejects_out_of_range_with_the_board_reason() -> None:
    for name, args, reason in [
        ("GOTO", (32001, 0, 0), Reject.OUT_OF_RANGE),
        ("GOTO", (0, 0, 0x10), Reject.RESERVED_BIT),
        ("GOTO", (0, 0, 0x09), Reject.BAD_OPTIONS),
        ("SET_VITESSE_TRAJ", (0,), Reject.OUT_OF_RANGE),
        ("SET_VITESSE_TRAJ", (), Reject.BAD_LENGTH),
        ("GOTO_PANIER", (91,), Reject.OUT_OF_RANGE),
    ]:
        try:
            codec.encode(name, *args)
        except codec.FrameError as e:
            assert e.reason == reason, (name, args)
        else:
            raise AssertionError(f"{name}{args} was accepted")


def test_short_form_cannot_carry_a_pec() -> None:
    try:
        codec.encode("SET_VITESSE_TRAJ", 100, pec=True)
    except codec.FrameError as e:
        assert e.reason == Reject.BAD_LENGTH
    else:
        raise AssertionError("accepted")


def test_every_message_has_a_reply_decoder() -> None:
    for m in MESSAGES:
        if m.reply:
            n = codec.reply_length(m.name)
            assert codec.reply_fields(codec.decode_reply(m.name, bytes(n)))
