"""Progress bars (tqdm) on the long commands: on stderr when it is a terminal, nothing at all
when it is not (a log, a pipe, CI)."""

from __future__ import annotations

import io

import pytest
from hypothesis import given
from hypothesis import strategies as st

from asserv import cli, cli_args


class Terminal(io.StringIO):
    def __init__(self, tty: bool) -> None:
        super().__init__()
        self._tty = tty

    def isatty(self) -> bool:
        return self._tty


@given(st.integers(1, 50), st.booleans())
def test_a_bar_only_on_a_terminal(total: int, tty: bool) -> None:
    err = Terminal(tty)
    with pytest.MonkeyPatch.context() as mp:
        mp.setattr("sys.stderr", err)
        with cli_args.progress_bar(total, "robots") as bar:
            for _ in range(total):
                bar.update(1)
    text = err.getvalue()
    if tty:
        assert f"{total}/{total}" in text and "robots" in text
    else:
        assert text == ""


def test_tune_and_the_bench_are_quiet_in_a_pipe(
    capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    """Their stderr is not a terminal here: one line saying what runs, no bar."""
    assert cli.main(["tune", "--axis", "distance", "--window", "0.5"]) == 0
    err = capsys.readouterr().err
    assert err.splitlines() == ["asserv tune: 1 gain set(s) x distance on the simulated robot 0"]
    assert cli.main(["bench", "accuracy", "--robots", "1", "--jobs", "1", "--no-png"]) == 0
    assert capsys.readouterr().err == ""
