"""Issue 31's promise to the 2002 masters: with none of its messages used, the board behaves bit
for bit as before it.

A random master of the messages that existed before issue 31 (GOTO with its two recalibration
bits, GOTO_REVERSE, GOTO_PANIER and STOP in their old frames, the settings, the replies, malformed
frames) drives a randomized robot at both rates; the whole trace (truth, estimate, set points,
duties, status) and every byte read are hashed. ``EXPECTED`` holds the hashes the board gave
before issue 31 (commit ab41e8a): any change of behaviour in the old protocol changes them.

Two settings changed their behaviour on purpose since, and are sent as SET_VITESSE_ROT instead
(drawn the same, so that the rest of the session is the same): SET_TIMEOUT, which only writes
feed now and whose stop ends PB_MOTEUR (issue 28, item 5), and SET_FILTRE, whose new gains
are taken in at the grip's pace in the middle of a move (issue 31, item 7). With them, and only
with them, the hashes differ from ab41e8a's. And the one-rate board runs with the derivative read
raw (``control.d_filter_ms`` 0, the AVR's): the quiet servo (issue 32) changes the control's
dynamics on purpose; without it the board is the same bit for bit.
"""

from __future__ import annotations

import hashlib
import random

import pytest

from asserv.sim import AVR_RATES, Simulator

#: The derivative without its low-pass (docs/control.md "PID"), as AVR_RATES has it.
RAW_D = {"control.d_filter_ms": 0}

# Recorded with this master on ab41e8a (before issues 28 and 31), its simulator built apart.
EXPECTED: dict[tuple[int, bool], str] = {
    (1, False): "2e0cdfc572a5e6ea",
    (1, True): "aa6172d5ddc73c8a",
    (2, False): "a27920a2dea33de7",
    (2, True): "4e02953a9699c88b",
    (3, False): "c16a20f774ea48fd",
    (3, True): "ba94733a1dc26a04",
    (4, False): "59e3bcf3e781ce86",
    (4, True): "1c634a1c1449a6c2",
    (5, False): "8077a61c74ac270e",
    (5, True): "f02b90ea7165aa3a",
    (6, False): "084120dfe566a199",
    (6, True): "518de2b7fb073b18",
    (7, False): "dfa83cf8b293c2a4",
    (7, True): "a52496219b724298",
    (8, False): "1269647783b72b2b",
    (8, True): "dddabe2749935288",
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
    if k == 8:  # SET_FILTRE's draw, sent as SET_VITESSE_ROT (above)
        return bytes([7, 40 + rng.randint(0, 2)])
    if k == 9:  # a reply selection, read below
        return bytes([rng.choice([3, 4, 5, 14, 200])])
    if k == 10:  # malformed: too long, a reserved option bit, out of range
        return rng.choice(
            [bytes([0, 0, 0, 0, 0, 0x10]), bytes([0, 0, 0, 0, 0, 0x10, 1, 2]), bytes([8, 7])]
        )
    return bytes([7, 5 + rng.randint(0, 3)])  # SET_TIMEOUT's draw, sent as SET_VITESSE_ROT


def trace_hash(seed: int, avr: bool) -> str:
    rng = random.Random(seed)
    sim = Simulator(seed=seed, randomize=True, board_config=AVR_RATES if avr else RAW_D)
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
