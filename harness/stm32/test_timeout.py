"""SET_TIMEOUT fed by accepted writes only (issue 28, item 5) on the STM32 binary in the
emulator: a master whose order thread writes after random gaps, under or over the timeout, while
its polling thread reads at its own period and rejected writes come between (asserv.sim.silence,
the sessions python/tests/test_timeout_sim.py plays on the simulator). At every poll the order
runs, or has been stopped and ends PB_MOTEUR with DEBUG end_reason TIMEOUT, as the last accepted
write says; and the binary's state after every tick and its replies are the native run's, bit
for bit."""

from typing import Any

from board import robot
from hypothesis import HealthCheck, Phase, given, settings
from hypothesis import strategies as st
from test_sessions import assert_same_runs, pair

from asserv import Board
from asserv.sim.silence import START, Gap, Session, play

LATE_MS = 5  # one rate at 1 kHz, as the host: the write's period, the rounding, the snapshot


@st.composite
def sessions(draw: st.DrawFn) -> Session:
    timeout = draw(st.integers(50, 300))
    n = draw(st.integers(0, 4))
    hang = draw(st.booleans())
    gaps = []
    for i in range(n + hang):
        is_hang = i == n
        ms = (
            draw(st.integers(timeout + LATE_MS + 10, timeout + 150))
            if is_hang
            else draw(st.integers(1, timeout - 8))
        )
        poll = draw(st.integers(5, 40))
        gaps.append(
            Gap(
                ms,
                poll,
                draw(st.integers(0, poll - 1)),
                tuple(draw(st.lists(st.integers(0, ms), max_size=2))),
                draw(st.booleans()),
                is_hang,
            )
        )
    return Session(timeout, tuple(gaps))


@settings(
    max_examples=8,
    phases=[Phase.explicit, Phase.generate],  # no shrinking: each example runs for a second
    suppress_health_check=[HealthCheck.too_slow],
)
@given(s=sessions(), seed=st.integers(0, 10_000))
def test_only_accepted_writes_feed_the_timeout(elf: Any, s: Session, seed: int) -> None:
    b, r = pair(elf, *robot({"start": START}, seed=seed, randomize=True))
    for dev in (b, r):
        assert play(Board(dev.bus), dev.i2c_write, s, LATE_MS) == []
    assert_same_runs(b, r)
