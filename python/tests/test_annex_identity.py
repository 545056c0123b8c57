"""Issue 31's promise to the 2002 masters: with none of its messages used, the board behaves bit
for bit as before it.

A random master of the messages that existed before issue 31 (GOTO with its two recalibration
bits, GOTO_REVERSE, GOTO_PANIER and STOP in their old frames, the settings, the replies, malformed
frames) drives a randomized robot at both rates; the whole trace (truth, estimate, set points,
duties, status) and every byte read are hashed. ``EXPECTED`` holds the hashes the board gave
before issue 31 (commit ab41e8a): any change of behaviour in the old protocol changes them.
"""

from __future__ import annotations

import hashlib
import random

import pytest

from asserv.sim import AVR_RATES, Simulator

# Recorded with `python python/tests/test_annex_identity.py` on ab41e8a (before issue 31).
EXPECTED: dict[tuple[int, bool], str] = {
    (1, False): "8222462729dc26c6",
    (1, True): "845d171f8db2f840",
    (2, False): "b6391503956f109c",
    (2, True): "74dc9a21c72a41d2",
    (3, False): "87a82b83a7336176",
    (3, True): "043619401507418d",
    (4, False): "8f126f80a07a7b9e",
    (4, True): "5918f31167db1b95",
    (5, False): "e4a36a9d9017cfb5",
    (5, True): "598a5bfb49f515f0",
    (6, False): "c9628396be2ab252",
    (6, True): "6f0f124cfc79f32f",
    (7, False): "25abf2dcbd118129",
    (7, True): "b8f0cc2d01088325",
    (8, False): "8ce2a2097dc3ab85",
    (8, True): "51cc5eaa4a40b359",
}


def _frame(rng: random.Random) -> bytes:
    k = rng.randrange(12)
    s16 = lambda v: [(v >> 8) & 0xFF, v & 0xFF]  # noqa: E731
    if k < 3:
        x, y = rng.randint(-900, 900), rng.randint(-600, 600)
        return bytes([0, *s16(x & 0xFFFF), *s16(y & 0xFFFF), rng.choice([0, 0, 0, 1, 2])])
    if k == 3:
        return bytes([1, rng.randint(0, 200)])
    if k == 4:
        return bytes([2, rng.randint(-90, 90) & 0xFF])
    if k == 5:
        return bytes([12])
    if k == 6:
        return bytes([6, rng.randint(5, 120), rng.randint(5, 200)])
    if k == 7:
        return bytes([7, rng.randint(5, 100)])
    if k == 8:
        return bytes([8, rng.randint(0, 2)])
    if k == 9:  # a reply selection, read below
        return bytes([rng.choice([3, 4, 5, 14, 200])])
    if k == 10:  # malformed: too long, a reserved option bit, out of range
        return rng.choice(
            [bytes([0, 0, 0, 0, 0, 0x10]), bytes([0, 0, 0, 0, 0, 0x10, 1, 2]), bytes([8, 7])]
        )
    return bytes([15, 0, rng.randint(0, 3)])


def trace_hash(seed: int, avr: bool) -> str:
    rng = random.Random(seed)
    sim = Simulator(seed=seed, randomize=True, board_config=AVR_RATES if avr else None)
    h = hashlib.sha256()
    for _ in range(40):
        frame = _frame(rng)
        sim.i2c_write(frame, stop=True)
        h.update(sim.i2c_read(rng.choice([1, 4, 10, 22])))
        sim.advance(rng.choice([0.002, 0.05, 0.3, 0.8]))
    h.update(sim.trace.tobytes())
    return h.hexdigest()[:16]


CASES = [(seed, avr) for seed in range(1, 9) for avr in (False, True)]


@pytest.mark.parametrize(("seed", "avr"), CASES)
def test_an_old_master_sees_the_board_of_before(seed: int, avr: bool) -> None:
    assert trace_hash(seed, avr) == EXPECTED[(seed, avr)]


if __name__ == "__main__":
    for seed, avr in CASES:
        print(f"    ({seed}, {avr}): {trace_hash(seed, avr)!r},")
