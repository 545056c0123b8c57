"""The command line's one convention (asserv.cli_args): names in any case, degrees everywhere,
every argument and output path checked before a bus opens or a run starts, exit 0/1/2, and no
traceback for anything a user can type."""

from __future__ import annotations

import contextlib
import errno
import io
import tomllib
from collections.abc import Iterator
from pathlib import Path

import pytest
import smbus2
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from test_bus import Recorder

import asserv
from asserv import Board, ProtocolDevice, VirtualBus, cli, codec
from asserv._protocol import MESSAGES

ROOT = Path(__file__).resolve().parents[2]


class RunReachedError(Exception):
    """Raised by the stand-ins of the long runs: the command got past its checks."""


def run(argv: list[str]) -> tuple[int, str, str]:
    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        code = cli.main(argv)
    return code, out.getvalue(), err.getvalue()


@pytest.fixture
def no_runs(monkeypatch: pytest.MonkeyPatch, tmp_path: Path) -> Iterator[list[int]]:
    """The long runs and the bus replaced by stand-ins that record that they were reached."""
    from asserv import calibration, scenario, server, sim
    from asserv.sim import accuracy, demo

    reached: list[int] = []

    def ran(*_: object, **__: object) -> None:
        reached.append(1)
        raise RunReachedError

    def no_bus(n: int) -> None:
        reached.append(1)
        raise OSError(errno.ENOENT, "no bus here")

    for mod, name in (
        (demo, "run"),
        (scenario, "play"),
        (accuracy, "bench"),
        (calibration, "calibrate"),
        (sim, "Simulator"),
    ):
        monkeypatch.setattr(mod, name, ran)
    monkeypatch.setattr(smbus2, "SMBus", no_bus)
    monkeypatch.setattr(server, "RemoteBus", lambda *_: no_bus(0))  # --sim HOST:PORT
    monkeypatch.chdir(tmp_path)
    yield reached


# The inputs of issue 22, each a one-line message and exit 2, before any run or bus.
BAD = [
    (["demo", "--png", "/nonexistent/x.png"], "/nonexistent/x.png: cannot write the file"),
    (["demo", "--png", "x.txt"], "must end in .png"),
    (["sim", "run", "annex", "--png", "x.txt"], "must end in .png"),
    (["bench", "accuracy", "--out", "/proc/nope"], "/proc/nope: cannot write"),
    (["bench", "accuracy", "--turns", "0"], "--turns: '0' must be at least 1"),
    (["calibrate", "--turns", "0"], "--turns: '0' must be at least 1"),
    (["calibrate", "--seed", "-1"], "--seed: '-1' must be within 0..2^64-1"),
    (["calibrate", "--bus", "1", "--address", "200"], "not a 7-bit address"),
    (["calibrate", "--track-mm", "10"], "OUT_OF_RANGE: SET_ODOMETRIE.track_10um=1000"),
    (["--bus", "1", "goto", "40000", "0"], "OUT_OF_RANGE: GOTO.x_mm=40000"),
    (["--bus", "1", "goto-panier", "181"], "OUT_OF_RANGE: GOTO_PANIER.angle_deg=181"),
    (["--bus", "1", "goto-panier", "91", "--raw"], "OUT_OF_RANGE: GOTO_PANIER.angle_2deg=91"),
    (["encode", "gotto", "1"], "no message 'gotto' (did you mean GOTO?)"),
    (["encode", "goto-panier", "nan"], "is not a number of degrees"),
    (["sim", "run", "no-such-scenario"], "cannot read the scenario"),
    (["sim", "run", "annex", "--zoom", "0", "1", "2", "inf", "--png", "a.png"], "not a finite"),
    # asserv log, tune and view (issue 20) keep the same convention.
    (["sim", "run", "annex", "--mcap", "x.txt"], "must end in .mcap"),
    (["sim", "run", "annex", "--csv", "/proc/x.csv"], "/proc/x.csv: cannot write the file"),
    (["--bus", "1", "log", "--mcap", "/proc/x.mcap"], "/proc/x.mcap: cannot write the file"),
    (["--bus", "1", "log", "--csv", "x.txt"], "must end in .csv"),
    (["--bus", "x", "log", "--csv", "x.csv"], "--bus ('x') is not an integer"),
    (["--sim", "h:p", "log", "--csv", "x.csv"], "--sim 'h:p': the port 'p' is not a number"),
    (["tune", "--seed", "-1"], "--seed: '-1' must be within 0..2^64-1"),
    (["tune", "--png", "x.txt"], "must end in .png"),
    (["tune", "--png", "/nonexistent/x.png"], "/nonexistent/x.png: cannot write the file"),
    (["--bus", "1", "tune", "--address", "200"], "not a 7-bit address"),
    (["view", "--port", "70000"], "--port must be 0..65535"),
    (["--bus", "1", "view", "--address", "x"], "--address ('x') is not an integer"),
    (["--sim", ":1", "--bus", "1", "view"], "give --bus N or --sim HOST:PORT, not both"),
]


@pytest.mark.parametrize(("argv", "message"), BAD)
def test_bad_input_is_one_line_and_exit_2_before_anything_runs(
    no_runs: list[int], argv: list[str], message: str
) -> None:
    code, out, err = run(argv)
    assert code == 2, (out, err)
    assert message in err
    assert len(err.strip().splitlines()) == 1 and err.startswith("asserv")
    assert no_runs == []  # no run started, no bus opened
    assert list(Path().iterdir()) == []  # and no file left behind


def test_a_good_output_path_gets_to_the_run(no_runs: list[int]) -> None:
    with pytest.raises(RunReachedError):
        cli.main(["demo", "--png", "out.png"])
    assert not Path("out.png").exists()  # the check leaves nothing behind


def test_bus_failure_is_exit_1(no_runs: list[int]) -> None:
    code, _, err = run(["--bus", "1", "status"])
    assert code == 1 and "cannot open /dev/i2c-1" in err


def test_version() -> None:
    code, out, _ = run(["--version"])
    assert code == 0 and out.strip() == f"asserv {asserv.__version__}"


def test_the_versions_agree() -> None:
    """asserv and asserv-sim are released together: asserv[sim] pins the same version."""
    with (ROOT / "pyproject.toml").open("rb") as f:
        main = tomllib.load(f)["project"]
    with (ROOT / "python" / "asserv-sim" / "pyproject.toml").open("rb") as f:
        sim = tomllib.load(f)["project"]
    assert sim["version"] == main["version"]
    assert f"asserv-sim=={main['version']}" in main["optional-dependencies"]["sim"]
    if asserv.__version__ != "0+unknown":
        assert asserv.__version__ == main["version"]


@given(
    name=st.sampled_from([m.name for m in MESSAGES]),
    flips=st.lists(st.booleans(), min_size=32, max_size=32),
    dash=st.booleans(),
)
def test_message_names_in_any_case(name: str, flips: list[bool], dash: bool) -> None:
    typed = "".join(c.lower() if f else c for c, f in zip(name, flips, strict=False))
    if dash:
        typed = typed.replace("_", "-")
    assert codec.message(typed).name == name


def _bus_frames(argv: list[str], monkeypatch: pytest.MonkeyPatch) -> list[bytes]:
    dev = ProtocolDevice()
    dev.layer.tick()
    rec = Recorder(dev)
    monkeypatch.setattr(smbus2, "SMBus", lambda n: VirtualBus({2: rec}))
    code, _, err = run(argv)
    assert code == 0, err
    return [e[1] for e in rec.events if e[0] == "w" and isinstance(e[1], bytes) and len(e[1]) > 1]


@settings(
    suppress_health_check=[HealthCheck.function_scoped_fixture], max_examples=60, deadline=None
)
@given(angle=st.integers(-360, 360) | st.floats(-180, 180))
def test_encode_and_goto_panier_agree_in_degrees(
    monkeypatch: pytest.MonkeyPatch, angle: float
) -> None:
    """``encode GOTO_PANIER A``, ``goto-panier A`` and ``Board.goto_panier(A)`` send the same
    bytes for every angle in degrees, and refuse the same angles (exit 2, OUT_OF_RANGE)."""
    text = repr(angle)
    code, out, err = run(["encode", "GOTO_PANIER", "--", text])
    if not -180 <= angle <= 180:
        assert code == 2 and "OUT_OF_RANGE: GOTO_PANIER.angle_deg" in err
        code, _, err = run(["--bus", "1", "goto-panier", "--", text])
        assert code == 2 and "OUT_OF_RANGE" in err
        return
    assert code == 0, err
    encoded = bytes.fromhex(out)
    assert _bus_frames(["--bus", "1", "goto-panier", "--", text], monkeypatch) == [encoded]
    rec = Recorder()
    Board(VirtualBus({2: rec}), check=False).goto_panier(angle)
    assert [e[1] for e in rec.events if e[0] == "w"] == [encoded]
    code, out, _ = run(["decode", *encoded.hex(" ").split()])
    assert out.strip() == f"GOTO_PANIER angle_deg={2 * codec.steps_2deg(angle)}"


def test_raw_steps_only_when_asked(monkeypatch: pytest.MonkeyPatch) -> None:
    assert run(["encode", "stop"])[1].strip() == "0c"  # names in any case
    assert run(["encode", "goto_panier", "45"])[1].strip() == "02 16"  # 44 degrees
    assert run(["encode", "goto_panier", "45", "--raw"])[1].strip() == "02 2d"  # 90 degrees
    assert run(["decode", "02", "2d"])[1].strip() == "GOTO_PANIER angle_deg=90"
    assert run(["decode", "02", "2d", "--raw"])[1].strip() == "GOTO_PANIER angle_2deg=45"
    assert _bus_frames(["--bus", "1", "goto-panier", "45", "--raw"], monkeypatch) == [b"\x02\x2d"]


def test_pose_shows_degrees() -> None:
    pose = codec.Pose(200, 100, 13, 4)
    assert repr(pose) == str(pose) == "Pose(x_mm=200, y_mm=100, angle_deg=26, radius_mm=4)"
    assert pose.angle_2deg == 13 and pose.angle_deg == 26


# Random command lines ---------------------------------------------------------------------------


def _words() -> list[str]:
    ap = cli.parser()
    words: set[str] = set()

    def walk(p: object) -> None:
        for action in getattr(p, "_actions", []):
            words.update(action.option_strings)
            choices = getattr(action, "choices", None)
            if not isinstance(choices, dict):  # a value's choices, not subcommands
                words.update(str(c) for c in choices or ())
                continue
            for name, sub in choices.items():
                words.add(name)
                walk(sub)

    walk(ap)
    return sorted(words - {"-h", "--help"})


WORDS = _words()
VALUES = [
    "0", "1", "-1", "2", "45", "-45", "181", "255", "256", "40000", "0x10", "1e400", "nan", "inf",
    "-inf", "x", "", " ", "--", "-", "00", "ff", "zz", "GOTO", "goto-panier", "stop", "annex",
    "out.png", "x.txt", "/nonexistent/x.png", "/proc/nope", "/", ".", "std", "raide", "3.5",
    "18446744073709551616", "-0", "1_000",
]  # fmt: skip
TOKENS = st.sampled_from(WORDS) | st.sampled_from(VALUES) | st.text(max_size=12)


@settings(
    suppress_health_check=[HealthCheck.function_scoped_fixture], max_examples=400, deadline=None
)
@given(
    command=st.sampled_from([w for w in WORDS if not w.startswith("-")]),
    before=st.lists(TOKENS, max_size=3),
    after=st.lists(TOKENS, max_size=6),
)
def test_random_command_lines_never_give_a_traceback(
    no_runs: list[int], command: str, before: list[str], after: list[str]
) -> None:
    """Whatever is typed: an exit code in {0, 1, 2}, a message with every exit 2, and no
    exception out of main (a run or a bus reached is a stand-in that says so)."""
    argv = [*before, command, *after]
    no_runs.clear()
    try:
        code, out, err = run(argv)
    except RunReachedError:
        return  # every check passed and the run was about to start
    assert code in (0, 1, 2), (argv, code, err)
    assert "Traceback" not in err
    if code == 2:
        assert len(err.strip().splitlines()) == 1, (argv, err)
    for leftover in Path().iterdir():  # a check never leaves a file behind
        assert leftover.name in ("bench-out",) or leftover.is_dir(), (argv, leftover)
    assert code != 0 or out or argv  # --help and --version print on stdout


def test_the_random_words_cover_the_parser() -> None:
    """The vocabulary of the random command lines has every subcommand and option."""
    assert {"demo", "sim", "run", "encode", "decode", "calibrate", "bench", "accuracy"} <= set(
        WORDS
    )
    assert {"goto", "goto-panier", "--png", "--bus", "--raw", "--version"} <= set(WORDS)
    assert {"view", "tune", "log", "--sim", "--mcap", "--csv", "--replay"} <= set(WORDS)


OUTSIDE = st.integers(-(2**31), -32001) | st.integers(32001, 2**31)


@settings(
    suppress_health_check=[HealthCheck.function_scoped_fixture], max_examples=50, deadline=None
)
@given(x=OUTSIDE | st.integers(-32000, 32000), y=OUTSIDE)
def test_a_range_error_never_opens_the_bus(no_runs: list[int], x: int, y: int) -> None:
    """``goto X Y`` with a coordinate outside -32000..32000: OUT_OF_RANGE, exit 2, no bus."""
    no_runs.clear()
    code, _, err = run(["--bus", "1", "goto", "--", str(x), str(y)])
    assert code == 2 and "OUT_OF_RANGE: GOTO." in err
    assert no_runs == []


@settings(
    suppress_health_check=[HealthCheck.function_scoped_fixture], max_examples=80, deadline=None
)
@given(
    name=st.text(st.characters(blacklist_characters="\x00"), max_size=16),
    suffix=st.sampled_from([".png", ".PNG", ".txt", "", ".png/", "/x.png"]),
    where=st.sampled_from(["", "sub/", "/nonexistent/", "/proc/", "./"]),
)
def test_any_png_path_is_checked_before_the_run(
    no_runs: list[int], name: str, suffix: str, where: str
) -> None:
    """Whatever ``--png`` names: either the run starts (the file can be written, and the check
    left nothing), or exit 2 with one line and nothing started or written."""
    no_runs.clear()
    Path("sub").mkdir(exist_ok=True)
    before = sorted(Path().rglob("*"))
    path = where + name + suffix
    try:
        code, _, err = run(["demo", "--png", path])
    except RunReachedError:
        assert Path(path).suffix.lower() == ".png"
        assert sorted(Path().rglob("*")) == before
        return
    assert code == 2 and len(err.strip().splitlines()) == 1, (path, err)
    assert no_runs == []
    assert sorted(Path().rglob("*")) == before


def test_the_driver_imports_nothing_of_the_simulator() -> None:
    """``pip install asserv`` has no numpy, matplotlib or cffi: the driver and the CLI must not
    import them (scripts/check_install.sh checks it on a real driver-only install)."""
    import subprocess
    import sys

    code = (
        "import sys, asserv, asserv.cli, asserv.cli_bus, asserv.cli_args, asserv.driver;"
        "print(sorted({'numpy', 'matplotlib', 'cffi', 'asserv_sim'} & set(sys.modules)))"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "[]"


def test_no_png_needs_no_writable_directory(
    no_runs: list[int], monkeypatch: pytest.MonkeyPatch
) -> None:
    """``demo --no-png`` checks no plot path (it writes none); ``demo`` checks the default."""
    monkeypatch.chdir("/proc")
    with pytest.raises(RunReachedError):
        cli.main(["demo", "--no-png"])
    code, _, err = run(["demo"])
    assert code == 2 and "asserv-demo.png: cannot write the file" in err
