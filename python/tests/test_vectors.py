"""The shared protocol vectors (protocol/vectors.toml), run by the Python codec and, through
cffi, by the board's C protocol layer."""

import tomllib
from pathlib import Path
from typing import Any

import pytest

from asserv import Reject, codec
from asserv.sim.cboard import ProtocolLayer

ROOT = Path(__file__).resolve().parents[2]
with (ROOT / "protocol" / "vectors.toml").open("rb") as _f:
    VECTORS: dict[str, Any] = tomllib.load(_f)

WRITES = VECTORS["write"]
SEQUENCES = VECTORS["sequence"]


@pytest.mark.parametrize("v", WRITES, ids=[w["name"] for w in WRITES])
def test_codec_judges_writes_as_the_vectors_say(v: dict[str, Any]) -> None:
    frame = bytes(v["bytes"])
    if "accept" in v:
        w = codec.decode_write(frame)
        assert w.message.name == v["accept"]
        assert list(w.args) == v.get("args", [])
        # And the encoder produces these very bytes from the meaning (aliases aside).
        if frame[0] == w.message.designation:
            assert codec.encode(v["accept"], *w.args, pec=w.pec) == frame
    else:
        with pytest.raises(codec.FrameError) as e:
            codec.decode_write(frame)
        assert e.value.reason == Reject[v["reject"]]


@pytest.mark.parametrize("v", WRITES, ids=[w["name"] for w in WRITES])
def test_c_layer_judges_writes_as_the_vectors_say(v: dict[str, Any]) -> None:
    board = ProtocolLayer()
    board.write(v["bytes"])
    status = board.read(1)[0]
    taken = board.tick()
    if "accept" not in v:
        assert status & 0x40
        assert taken == []
        board.write([codec.message("LAST_REJECT").designation])
        assert board.read(3)[0] == Reject[v["reject"]]
        return
    assert not status & 0x40
    msg = codec.message(v["accept"])
    if msg.kind == "ETAT":
        assert taken == []
    else:
        assert [(t.designation, list(t.args)) for t in taken] == [
            (msg.designation, v.get("args", []))
        ]


@pytest.mark.parametrize("s", SEQUENCES, ids=[s["name"] for s in SEQUENCES])
def test_c_layer_runs_the_sequences(s: dict[str, Any]) -> None:
    board = ProtocolLayer()
    board.set_snapshot(**s.get("snapshot", {}))
    board.tick()
    for step in s["steps"]:
        if step.get("tick"):
            board.tick()
            continue
        if "write" in step:
            board.write(step["write"], stop=not ("expect" in step and step.get("restart")))
        if "expect" in step:
            assert list(board.read(len(step["expect"]))) == step["expect"]


@pytest.mark.parametrize("c", VECTORS["crc"])
def test_crc8(c: dict[str, Any]) -> None:
    assert codec.crc8(bytes(c["bytes"])) == c["crc"]


def test_position_vector_decodes_to_its_snapshot() -> None:
    s = next(s for s in SEQUENCES if s["name"] == "POSITION in a separate transaction")
    pose = codec.decode_reply("POSITION", s["steps"][0]["expect"])
    assert pose == codec.Pose(**s["snapshot"])
    assert pose.angle_deg == -90


def test_reply_pec_is_checked() -> None:
    s = next(s for s in SEQUENCES if s["name"].startswith("POSITION plus PEC, repeated"))
    data = s["steps"][0]["expect"]
    prefix = bytes([codec.write_address(), 4, codec.read_address()])
    assert codec.decode_reply("POSITION", data, pec_prefix=prefix).x_mm == 200
    corrupted = [data[0] ^ 0x10, *data[1:]]
    with pytest.raises(codec.PecError):
        codec.decode_reply("POSITION", corrupted, pec_prefix=prefix)
