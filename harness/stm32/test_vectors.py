"""The shared protocol vectors (protocol/vectors.toml) on the STM32 binary in the emulator, over
its I2C1 slave, each against the native reference run: the replies and the whole board (every
byte of struct board in the chip's RAM) bit-identical after each step, and the replies the
vectors expect. Bus bytes take no time here (byte_ns 0), so that no tick runs inside a frame and
the vectors' snapshots stand, as in python/tests/test_vectors.py; a vector's tick is one control
period, after which both snapshots are published again."""

import tomllib
from typing import Any

import pytest
from board import TICK_NS, Reference, Stm32Board, robot
from conftest import ROOT

from asserv import Reject, codec
from asserv.sim._core import ffi, lib

with (ROOT / "protocol" / "vectors.toml").open("rb") as _f:
    VECTORS: dict[str, Any] = tomllib.load(_f)


class Pair:
    """The binary and its reference, stepped together and compared after each step."""

    def __init__(self, elf: Any) -> None:
        bc, sc, f = robot()
        self.b = Stm32Board(elf, sc, f, bc, byte_ns=0)
        self.r = Reference(bc, sc, f, byte_ns=0)
        self.same()

    def same(self) -> None:
        assert self.b.board_state() == self.r.board_state(self.b.padding)

    def write(self, data: list[int], stop: bool = True) -> None:
        self.b.i2c_write(bytes(data), stop)
        self.r.i2c_write(bytes(data), stop)
        self.same()

    def read(self, n: int) -> bytes:
        got = self.b.i2c_read(n)
        assert got == self.r.i2c_read(n)
        self.same()
        return got

    def publish(self, snapshot: dict[str, Any]) -> None:
        """The vector's snapshot published in the reference, and the protocol state copied
        into the chip's RAM (the layouts are the same: Stm32Board checks it at boot)."""
        snap = ffi.new("struct proto_snapshot *")
        for k, v in snapshot.items():
            setattr(snap, k, v)
        lib.proto_publish(self.r.proto, snap)
        off = self.b.proto_addr - self.b.cpu.symbols["asserv_board"]
        size = ffi.sizeof("struct proto")
        self.b.cpu.uc.mem_write(self.b.proto_addr, self.r.board_bytes()[off : off + size])
        self.same()

    def tick(self) -> None:
        self.b.advance_ns(TICK_NS)
        self.r.advance_ns(TICK_NS)
        self.same()


@pytest.fixture(scope="module")
def pair_factory(elf: Any) -> Any:
    return lambda: Pair(elf)


WRITES = VECTORS["write"]
SEQUENCES = VECTORS["sequence"]


@pytest.mark.parametrize("v", WRITES, ids=[w["name"] for w in WRITES])
def test_write_vector(pair_factory: Any, v: dict[str, Any]) -> None:
    p = pair_factory()
    p.tick()
    p.write(v["bytes"])
    status = p.read(1)[0]
    if "accept" not in v:
        assert status & 0x40
        p.write([codec.message("LAST_REJECT").designation])
        assert p.read(3)[0] == Reject[v["reject"]]
    else:
        assert not status & 0x40
    p.tick()
    p.read(1)


@pytest.mark.parametrize("s", SEQUENCES, ids=[s["name"] for s in SEQUENCES])
def test_sequence_vector(pair_factory: Any, s: dict[str, Any]) -> None:
    p = pair_factory()
    p.tick()
    p.publish(s.get("snapshot", {}))
    for step in s["steps"]:
        if step.get("tick"):
            p.tick()
            p.publish(s.get("snapshot", {}))
            continue
        if "write" in step:
            p.write(step["write"], stop=not ("expect" in step and step.get("restart")))
        if "expect" in step:
            assert list(p.read(len(step["expect"]))) == step["expect"]


def test_other_address_is_not_acknowledged(pair_factory: Any) -> None:
    p = pair_factory()
    assert not p.b.i2c.start(3, True)
    assert p.b.i2c.sr1 == 0
    assert p.read(1) == bytes([0])
