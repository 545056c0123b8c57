"""Issue 31's driver calls (pause, resume, speed scale, MOTION, queued and pass-through orders),
sync and asyncio, against the board's C protocol layer: the frames are the table's, bad
arguments send nothing, a board without a capability is told apart and sent nothing, and the
CLI's commands keep its convention (one line, exit 2, no traceback)."""

from __future__ import annotations

import asyncio
from collections.abc import Callable
from typing import Any

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from test_bus import Recorder, board_bus
from test_cli_bus import Rig

from asserv import (
    Board,
    Capability,
    EndReason,
    Motion,
    ProtocolDevice,
    Unsupported,
    VirtualBus,
    codec,
)
from asserv.aio import AsyncBoard

FAST = settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.too_slow])
VERSION = codec.message("VERSION").designation
NEW_CAPS = ("PAUSE", "SPEED_SCALE", "QUEUE", "CORNERS")


class Without:
    """The C protocol layer, except that its VERSION reply lacks the capability bits ``cut``
    (a build that compiles features out, as the AVR may): a fake at the bus boundary."""

    def __init__(self, cut: int) -> None:
        self.dev = ProtocolDevice()
        self.dev.layer.tick()
        self.cut = cut
        self.version_selected = False

    def i2c_write(self, data: bytes, stop: bool) -> None:
        self.version_selected = bytes(data[:1]) == bytes([VERSION])
        self.dev.i2c_write(data, stop)

    def i2c_read(self, n: int) -> bytes:
        data = bytearray(self.dev.i2c_read(n))
        if self.version_selected and n == 4:  # no PEC in these tests
            caps = int.from_bytes(data[2:4], "big") & ~self.cut
            data[2:4] = caps.to_bytes(2, "big")
        return bytes(data)


def make(pec: bool = False) -> tuple[ProtocolDevice, Recorder, Board]:
    dev, rec, bus = board_bus()
    dev.layer.tick()
    return dev, rec, Board(bus, pec=pec)


def taken(dev: ProtocolDevice) -> list[tuple[int, tuple[int, ...]]]:
    return [(t.designation, t.args) for t in dev.layer.tick()]


def writes(rec: Recorder) -> list[bytes]:
    return [e[1] for e in rec.events if e[0] == "w"]  # type: ignore[misc]


xs = st.integers(-32000, 32000)
recal = st.integers(0, 3)


@st.composite
def calls(draw: st.DrawFn) -> tuple[str, Callable[[Board], None], str, tuple[int, ...]]:
    """A call of the issue 31 surface with valid arguments, and the frame the table says."""
    kind = draw(
        st.sampled_from(["goto", "reverse", "panier", "pause", "resume", "scale", "corner"])
    )
    append = draw(st.booleans())
    if kind == "goto":
        x, y = draw(xs), draw(xs)
        through = draw(st.booleans())
        opts = 0 if through else draw(recal)  # PASS_THROUGH never combines with a recalibration
        bits = opts | (4 if append else 0) | (8 if through else 0)
        return (
            kind,
            lambda b: b.goto(x, y, opts, append=append, through=through),
            "GOTO",
            (x, y, bits),
        )
    if kind == "reverse":
        d = draw(st.integers(0, 255))
        return kind, lambda b: b.goto_reverse(d, append=append), "GOTO_REVERSE", (d, *_app(append))
    if kind == "panier":
        steps = draw(st.integers(-90, 90))
        return (
            kind,
            lambda b: b.goto_panier(2 * steps, append=append),
            "GOTO_PANIER",
            (steps, *_app(append)),
        )
    if kind == "scale":
        pc = draw(st.integers(0, 100))
        return kind, lambda b: b.set_speed_scale(pc), "SET_SPEED_SCALE", (pc,)
    if kind == "corner":
        mm = draw(st.integers(1, 255))
        return kind, lambda b: b.set_corner(mm), "SET_CORNER", (mm,)
    if kind == "pause":
        return kind, lambda b: b.pause(), "PAUSE", ()
    return kind, lambda b: b.resume(), "RESUME", ()


def _app(append: bool) -> tuple[int, ...]:
    return (4,) if append else ()


def _needs(name: str, args: tuple[int, ...]) -> set[str]:
    """The capabilities a frame takes, from the table's capability docs (messages.toml)."""
    if name in ("PAUSE", "RESUME"):
        return {"PAUSE"}
    if name == "SET_SPEED_SCALE":
        return {"SPEED_SCALE"}
    if name == "SET_CORNER":
        return {"CORNERS"}
    opts = args[-1] if (name == "GOTO" or len(args) == 2) else 0
    return ({"QUEUE"} if opts & 4 else set()) | ({"CORNERS"} if opts & 8 else set())


@FAST
@given(call=calls(), pec=st.booleans())
def test_property_each_call_sends_the_tables_frame(
    call: tuple[str, Callable[[Board], None], str, tuple[int, ...]], pec: bool
) -> None:
    """The board's C layer takes exactly the table's designation and parameters; the frame is
    codec.encode's (the full form with a PEC), after one VERSION read for the capabilities."""
    dev, rec, board = make(pec)
    _, method, name, args = call
    method(board)
    msg = codec.message(name)
    if pec and len(args) < len(msg.params):
        args = (*args, 0)  # a PEC needs the full form: the options byte, 0
    assert taken(dev) == [(msg.designation, args)]
    sent = [w for w in writes(rec) if w[0] != VERSION]
    assert sent == [codec.encode(name, *args, pec=pec)]
    assert len(writes(rec)) == len(sent) + (1 if _needs(name, args) else 0)


@FAST
@given(call=calls(), cut=st.sets(st.sampled_from(NEW_CAPS)))
def test_property_a_board_without_the_capability_is_sent_nothing(
    call: tuple[str, Callable[[Board], None], str, tuple[int, ...]], cut: set[str]
) -> None:
    """A call that needs a capability the board's VERSION lacks raises Unsupported naming it,
    and only VERSION went out; the others are sent as usual."""
    bits = sum(int(Capability[c]) for c in cut)
    fake = Without(bits)
    rec = Recorder(fake)
    board = Board(VirtualBus({2: rec}))
    _, method, name, args = call
    missing = _needs(name, args) & cut
    if missing:
        with pytest.raises(Unsupported) as e:
            method(board)
        assert e.value.capability in missing
        assert f"this board has no {e.value.capability}" in str(e.value)
        assert writes(rec) == [bytes([VERSION])]
        assert fake.dev.layer.tick() == []
    else:
        method(board)
        assert [(t.designation, t.args) for t in fake.dev.layer.tick()] == [
            (codec.message(name).designation, args)
        ]


def test_motion_without_pause_is_unsupported() -> None:
    board = Board(VirtualBus({2: Without(int(Capability.PAUSE))}))
    with pytest.raises(Unsupported, match="MOTION: this board has no PAUSE"):
        board.motion()


bad_calls: list[tuple[Callable[[Board], None], type[Exception]]] = [
    (lambda b: b.set_speed_scale(101), ValueError),
    (lambda b: b.set_speed_scale(-1), ValueError),
    (lambda b: b.set_speed_scale(50.0), TypeError),  # type: ignore[arg-type]
    (lambda b: b.set_corner(0), ValueError),
    (lambda b: b.set_corner(256), ValueError),
    (lambda b: b.goto(0, 0, 1, through=True), codec.FrameError),  # BAD_OPTIONS
    (lambda b: b.goto(0, 0, 16), codec.FrameError),  # RESERVED_BIT
    (lambda b: b.goto(0, 0, append=1), TypeError),  # type: ignore[arg-type]
    (lambda b: b.goto_reverse(256, append=True), ValueError),
    (lambda b: b.goto_panier(200, append=True), ValueError),
    (lambda b: b.goto_panier(10, append="yes"), TypeError),  # type: ignore[arg-type]
]


@pytest.mark.parametrize(("call", "error"), bad_calls)
def test_bad_arguments_raise_and_send_nothing(
    call: Callable[[Board], None], error: type[Exception]
) -> None:
    dev, rec, board = make()
    with pytest.raises(error):
        call(board)
    assert rec.events == []
    assert taken(dev) == []


@FAST
@given(
    values=st.fixed_dictionaries(
        {
            "running_seq": st.integers(0, 255),
            "pending": st.integers(0, 255),
            "flags": st.integers(0, 3),
            "last_seq": st.integers(0, 255),
            "last_end": st.sampled_from([int(e) for e in EndReason]),
            "braking_mm": st.integers(0, 65535),
            "braking_ms": st.integers(0, 65535),
            "scale_percent": st.integers(0, 100),
        }
    ),
    pec=st.booleans(),
)
def test_property_motion_reads_what_the_board_publishes(values: dict[str, int], pec: bool) -> None:
    dev, _, board = make(pec)
    dev.layer.set_snapshot(motion=values)
    dev.layer.tick()
    m = board.motion()
    assert isinstance(m, Motion)
    assert m._asdict() == {**values, "last_end": EndReason(values["last_end"])}
    assert m.paused == bool(values["flags"] & 1) and m.running == bool(values["flags"] & 2)
    assert codec.reply_fields(m) == values


def test_asyncio_sends_the_same_frames() -> None:
    sync_dev, sync_rec, sync_board = make()
    async_dev, async_rec, board = make()
    a = AsyncBoard(board)

    async def run() -> Motion:
        await a.goto(100, 200, append=True, through=True)
        await a.goto_reverse(50, append=True)
        await a.goto_panier(-30, append=True)
        await a.pause()
        await a.resume()
        await a.set_speed_scale(40)
        await a.set_corner(25)
        assert await a.capabilities() & Capability.PAUSE
        return await a.motion()

    asyncio.run(run())
    sync_board.goto(100, 200, append=True, through=True)
    sync_board.goto_reverse(50, append=True)
    sync_board.goto_panier(-30, append=True)
    sync_board.pause()
    sync_board.resume()
    sync_board.set_speed_scale(40)
    sync_board.set_corner(25)
    sync_board.motion()
    assert taken(async_dev) == taken(sync_dev)
    assert writes(async_rec) == writes(sync_rec)


# The CLI.


def test_cli_commands(capsys: pytest.CaptureFixture[str]) -> None:
    rig = Rig()
    for argv, out in (
        (["pause"], "PAUSE: accepted\n"),
        (["resume"], "RESUME: accepted\n"),
        (["scale", "40"], "SET_SPEED_SCALE 40 %: accepted\n"),
        (["goto", "100", "200", "--append", "--through"], "GOTO (100, 200) options 0 append"),
        (["goto-reverse", "30", "--append"], "GOTO_REVERSE 30 mm append: accepted\n"),
        (["goto-panier", "44", "--append"], "GOTO_PANIER 44 deg append: accepted\n"),
    ):
        assert rig.run("--bus", "1", *argv) == 0, argv
        assert out in capsys.readouterr().out
    assert [d for d, _ in rig.taken()] == [17, 18, 19, 0, 1, 2]
    rig.dev.layer.set_snapshot(
        motion={
            "running_seq": 7,
            "pending": 2,
            "flags": 3,
            "last_seq": 6,
            "last_end": int(EndReason.DONE),
            "braking_mm": 312,
            "braking_ms": 520,
            "scale_percent": 40,
        }
    )
    rig.dev.layer.tick()
    assert rig.run("--bus", "1", "motion") == 0
    assert capsys.readouterr().out == (
        "paused: order 7 runs, 2 pending; last ended 6: DONE\n"
        "braking 312 mm in 520 ms; speed scale 40 %\n"
    )


@pytest.mark.parametrize(
    ("argv", "message"),
    [
        (["scale", "101"], "OUT_OF_RANGE: SET_SPEED_SCALE.percent=101 is outside 0..100"),
        (["scale", "-1"], "OUT_OF_RANGE"),
        (["scale", "half"], "P ('half') is not an integer"),
        (["scale", "1.5"], "P ('1.5') is not an integer"),
        (["goto", "0", "0", "--options", "2", "--through"], "BAD_OPTIONS"),
        (["goto-reverse", "300", "--append"], "OUT_OF_RANGE"),
    ],
)
def test_cli_bad_arguments(
    argv: list[str], message: str, capsys: pytest.CaptureFixture[str]
) -> None:
    rig = Rig()
    assert rig.run("--bus", "1", *argv) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and message in err
    assert rig.rec.events == [] and rig.taken() == []


@FAST
@given(text=st.text(max_size=12))
def test_cli_property_scale_takes_0_to_100_or_says_why(text: str) -> None:
    """Whatever is typed as P: accepted (0..100) and taken by the board, or exit 2 with one
    line and nothing sent; never a traceback."""
    import contextlib
    import io

    rig = Rig()
    err = io.StringIO()
    with contextlib.redirect_stderr(err), contextlib.redirect_stdout(io.StringIO()):
        try:
            code = rig.run("--bus", "1", "scale", "--", text)
        except SystemExit as e:  # argparse itself: a usage line, exit 2
            code = int(e.code or 0)
    try:
        value: Any = int(text, 0)
    except ValueError:
        value = None
    if value is not None and 0 <= value <= 100:
        assert code == 0
        assert rig.taken() == [(19, (value,))]
    else:
        assert code == 2
        assert rig.taken() == []
        assert "Traceback" not in err.getvalue()


def test_cli_says_the_board_has_no_pause(capsys: pytest.CaptureFixture[str]) -> None:
    from test_cli_bus import parser

    from asserv.cli_bus import run_bus_command

    fake = Without(int(Capability.PAUSE | Capability.SPEED_SCALE))
    for argv in (["pause"], ["motion"], ["scale", "50"]):
        args = parser().parse_args(["--bus", "1", *argv])
        assert run_bus_command(args, lambda _n: VirtualBus({2: fake})) == 1
        err = capsys.readouterr().err
        assert err.count("\n") == 1 and "this board has no" in err
    assert fake.dev.layer.tick() == []


# Scenario files.

QUEUED = """\
set_vitesse_traj 60 60
goto 600 -600 through
goto 900 0 append+through
goto 400 400 append
sleep 2
pause
sleep 1
motion
resume
set_speed_scale 50
set_corner 40
wait
expect done
expect pose 400 400 20
"""


def test_a_scenario_queues_pauses_and_resumes() -> None:
    from asserv import scenario

    lines: list[str] = []
    result = scenario.play(scenario.parse(QUEUED), out=lines.append)
    assert result.ok, "\n".join(lines)
    motion = next(line for line in lines if "MOTION ->" in line)
    # Paused (flags 3), the queue whole: the GOTO running and those waiting are the three (at
    # 2 s the first one's curve may have handed over to the second already).
    running = int(motion.split("running_seq=")[1].split(",")[0])
    pending = int(motion.split("pending=")[1].split(",")[0])
    assert running + pending == 3 and running in (1, 2) and "flags=3" in motion, motion
    gotos = [line for line in lines if "GOTO x_mm" in line]
    assert [g.split("options=")[1].split()[0] for g in gotos] == ["8", "12", "4"]


@pytest.mark.parametrize(
    "line",
    [
        "set_speed_scale 101",
        "set_speed_scale x",
        "set_corner 0",
        "pause 1",
        "goto 0 0 bord+through",
    ],
)
def test_scenario_lines_are_checked(line: str) -> None:
    from asserv import scenario

    with pytest.raises(scenario.ScenarioError, match=r"<scenario>:1: "):
        scenario.parse(line + "\n")
