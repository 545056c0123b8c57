"""Shell completion (shtab): `asserv completion bash|zsh` prints a script that completes
every subcommand and option (docs/driver.md, "Shell completion"); bash runs it here. And the
help is plain text: no docstring or Markdown markup in any --help."""

from __future__ import annotations

import argparse
import contextlib
import io
import shutil
import subprocess
from pathlib import Path

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from asserv import cli


def script(shell: str) -> str:
    out = io.StringIO()
    with contextlib.redirect_stdout(out):
        assert cli.main(["completion", shell]) == 0
    return out.getvalue()


def _commands() -> list[str]:
    for action in cli.parser()._actions:
        if isinstance(action, argparse._SubParsersAction):
            return sorted(action.choices)
    raise AssertionError("no subcommands")


COMMANDS = _commands()


def complete(tmp_path: Path, words: list[str]) -> list[str]:
    """What bash offers for the last word of ``asserv WORDS``."""
    bash = shutil.which("bash")
    assert bash is not None
    f = tmp_path / "asserv.bash"
    if not f.exists():
        f.write_text(script("bash"))
    quoted = " ".join(f"'{w}'" for w in ["asserv", *words])
    run = (
        f"source '{f}'; COMP_WORDS=({quoted}); COMP_CWORD={len(words)};"
        f' COMP_LINE="asserv {" ".join(words)}"; COMP_POINT=${{#COMP_LINE}};'
        ' _shtab_asserv; printf "%s\\n" "${COMPREPLY[@]}"'
    )
    p = subprocess.run([bash, "-c", run], capture_output=True, text=True, timeout=60, check=False)
    assert p.returncode == 0, p.stderr
    return [w.strip() for w in p.stdout.splitlines() if w.strip()]


@settings(max_examples=10)
@given(st.sampled_from(COMMANDS), st.integers(1, 3))
def test_bash_completes_every_subcommand(command: str, n: int) -> None:
    """Any subcommand, from any prefix of it, is among what bash offers."""
    import tempfile

    with tempfile.TemporaryDirectory() as d:
        offered = complete(Path(d), [command[:n]])
    assert command in offered
    assert all(w.startswith(command[:n]) for w in offered)


def test_bash_completes_nested_commands_and_options(tmp_path: Path) -> None:
    assert complete(tmp_path, ["sim", "r"]) == ["run"]
    assert "--bus" in complete(tmp_path, ["--b"])
    assert "--mcap" in complete(tmp_path, ["sim", "run", "annex", "--mc"])


def test_zsh_script() -> None:
    z = script("zsh")
    assert z.startswith("#compdef asserv")
    for command in COMMANDS:
        assert command in z


def test_a_shell_it_does_not_know(capsys: pytest.CaptureFixture[str]) -> None:
    assert cli.main(["completion", "cmd"]) == 2
    assert "invalid choice: 'cmd'" in capsys.readouterr().err


def _parsers() -> list[tuple[str, argparse.ArgumentParser]]:
    out: list[tuple[str, argparse.ArgumentParser]] = []

    def walk(name: str, p: argparse.ArgumentParser) -> None:
        out.append((name, p))
        for a in p._actions:
            if isinstance(a, argparse._SubParsersAction):
                for child_name, child in a.choices.items():
                    walk(f"{name} {child_name}", child)

    walk("asserv", cli.parser())
    return out


@pytest.mark.parametrize(("name", "p"), _parsers(), ids=lambda x: x if isinstance(x, str) else "")
def test_help_is_plain_text(name: str, p: argparse.ArgumentParser) -> None:
    text = p.format_help()
    assert "`" not in text, (name, [line for line in text.splitlines() if "`" in line])
