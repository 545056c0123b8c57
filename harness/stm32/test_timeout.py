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
from asserv.sim.silence import START, Session, play, sessions

LATE_MS = 5  # one rate at 1 kHz, as the host: the write's period, the rounding, the snapshot


@settings(
    max_examples=8,
    phases=[Phase.explicit, Phase.generate],  # no shrinking: each example runs for a second
    suppress_health_check=[HealthCheck.too_slow],
)
@given(
    s=sessions(
        LATE_MS, max_timeout_ms=300, max_writes=4, max_hang_ms=150, max_poll_ms=40, max_rejected=2
    ),
    seed=st.integers(0, 10_000),
)
def test_only_accepted_writes_feed_the_timeout(elf: Any, s: Session, seed: int) -> None:
    b, r = pair(elf, *robot({"start": START}, seed=seed, randomize=True))
    for dev in (b, r):
        assert play(Board(dev.bus), dev.i2c_write, s, LATE_MS) == []
    assert_same_runs(b, r)
