#!/usr/bin/env python3
"""Write the seed corpus of a fuzz target from the shared test vectors (protocol/vectors.toml).

    python3 fuzz/seed_corpus.py protocol OUT_DIR
    python3 fuzz/seed_corpus.py board OUT_DIR

Each vector becomes one input in the fuzz targets' event language (fuzz/fuzz_events.h): every
write vector as a write followed by a LAST_REJECT read, every sequence step by step, so that the
fuzzer starts from frames that pass or fail each check of the protocol layer. The board target's
seeds also let the control ticks run after the frames, and add a few whole sessions (the annex,
a basket, a STOP), so that the orders run to their end. Standard library only; nothing generated
here is committed.
"""

from __future__ import annotations

import argparse
import hashlib
import sys
import tomllib
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
VECTORS = ROOT / "protocol" / "vectors.toml"

START_W, DATA, START_R, READ, STOP, ABORT, TICK, ENV = range(8)
LAST_REJECT = 14


def event(kind: int, n: int = 1) -> bytes:
    """One event byte: the kind in the low 3 bits, n - 1 (n in 1..32) in the high 5."""
    assert 1 <= n <= 32
    return bytes([kind | (n - 1) << 3])


def data(payload: list[int]) -> bytes:
    out = b""
    for i in range(0, len(payload), 32):
        chunk = payload[i : i + 32]
        out += event(DATA, len(chunk)) + bytes(chunk)
    return out


def write(payload: list[int], restart: bool = False) -> bytes:
    """S addr+W [payload] then P, or the repeated start that follows, as the AVR's TWI reports
    it (the STOP event with an even count)."""
    out = event(START_W) + (data(payload) if payload else b"")
    return out + event(STOP, 2 if restart else 1)


def read(n: int) -> bytes:
    out = event(START_R)
    while n > 0:
        out += event(READ, min(n, 32))
        n -= 32
    return out + event(STOP)


def ticks(target: str, n: int, status: int = 0) -> bytes:
    """Control ticks: the protocol target takes the messages, then publishes `status`; the board
    target runs n ticks of its robot model."""
    if target == "protocol":
        return event(TICK) + event(ENV) + bytes([status & 0x3F])
    out = b""
    while n > 0:
        out += event(TICK, min(n, 32))
        n -= 32
    return out


def seeds(target: str) -> list[bytes]:
    with VECTORS.open("rb") as f:
        v = tomllib.load(f)
    run = 600 if target == "board" else 1
    out = []
    for w in v["write"]:
        out.append(
            write(w["bytes"]) + read(1) + write([LAST_REJECT]) + read(4) + ticks(target, run)
        )
    for s in v["sequence"]:
        status = s.get("snapshot", {}).get("status", 0)
        seq = ticks(target, 1, status)
        for st in s["steps"]:
            if st.get("tick"):
                seq += ticks(target, run, status)
                continue
            if "write" in st:
                seq += write(st["write"], restart="expect" in st and st.get("restart", False))
            if "expect" in st:
                seq += read(len(st["expect"]))
        out.append(seq)
    if target == "board":
        # Whole sessions: the annex, a GOTO_PANIER with the basket switch, a STOP mid-move,
        # a move with the disturbances of the ENV event.
        annex = write([6, 100]) + write([7, 50]) + write([0, 0, 200, 0, 100, 0])
        out.append(annex + ticks(target, 4000) + read(1) + write([4]) + read(7))
        panier = write([2, 22]) + ticks(target, 1500) + event(ENV) + bytes([0x00, 0x01])
        out.append(panier + ticks(target, 300) + read(1))
        stop = write([6, 50, 50]) + write([0, 3, 232, 0, 0, 0]) + ticks(target, 500)
        out.append(stop + write([12]) + ticks(target, 1500) + read(1))
        for flags in (0x02, 0x08, 0x10, 0x20, 0x40, 0x80):
            move = write([0, 3, 232, 0, 0, 0]) + ticks(target, 300)
            out.append(move + event(ENV) + bytes([0, flags]) + ticks(target, 600) + read(1))
        shock = write([0, 3, 232, 0, 0, 0]) + ticks(target, 300) + event(ENV) + bytes([4, 0])
        out.append(shock + ticks(target, 50) + read(1))
        # SET_TIMEOUT 500 ms, then a master that only polls while the robot drives.
        polls = b"".join(read(1) + ticks(target, 100) for _ in range(20))
        out.append(write([15, 1, 0xF4]) + write([0, 3, 232, 0, 0, 0]) + polls + ticks(target, 900))
        # SET_NEW_POS -32 m, 70 times: the estimate stays within POSITION's range.
        far = b"".join(write([10, 0x83, 0, 0x83, 0, 0, 0]) + ticks(target, 1) for _ in range(70))
        out.append(far + write([0, 0, 0, 0, 0, 0]) + ticks(target, 64))
    return out


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("target", choices=("protocol", "board"))
    ap.add_argument("out", type=Path)
    args = ap.parse_args()
    args.out.mkdir(parents=True, exist_ok=True)
    inputs = seeds(args.target)
    for s in inputs:
        (args.out / hashlib.sha1(s).hexdigest()).write_bytes(s)
    print(f"seed_corpus.py: {len(inputs)} {args.target} seeds in {args.out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
