"""The real-board subcommands (``asserv --bus N ...``) on a VirtualBus with the board's C layer:
parsing as the main CLI will wire it, output, exit codes, and that bad arguments send nothing."""

from __future__ import annotations

import argparse
import errno

import pytest
from test_bus import FakeClock, Recorder

from asserv import ProtocolDevice, Status, VirtualBus, codec
from asserv.cli_bus import BUS_COMMANDS, add_bus_arguments, is_bus_command, run_bus_command


def parser() -> argparse.ArgumentParser:
    """The main CLI's shape: its own subcommands, and the bus ones added to the same set."""
    ap = argparse.ArgumentParser(prog="asserv")
    sub = ap.add_subparsers(dest="command", required=True)
    enc = sub.add_parser("encode")
    enc.add_argument("message")
    enc.add_argument("--pec", action="store_true")
    add_bus_arguments(ap, sub)
    return ap


class Rig:
    """The board's C layer behind a Recorder, a fresh VirtualBus per command (the CLI closes it),
    and the bus numbers the CLI asked for."""

    def __init__(self, clock: FakeClock | None = None) -> None:
        self.dev = ProtocolDevice()
        self.dev.layer.tick()
        self.rec = Recorder(self.dev)
        self.clock = clock
        self.opened: list[int] = []

    def factory(self, n: int) -> VirtualBus:
        self.opened.append(n)
        return VirtualBus({2: self.rec}, self.clock)

    def run(self, *argv: str) -> int:
        args = parser().parse_args(list(argv))
        assert is_bus_command(args)
        return run_bus_command(args, self.factory)

    def taken(self) -> list[tuple[int, tuple[int, ...]]]:
        return [(t.designation, t.args) for t in self.dev.layer.tick()]


def test_every_command_is_parsed(capsys: pytest.CaptureFixture[str]) -> None:
    ap = parser()
    for name in BUS_COMMANDS:
        argv = {
            "goto": ["1", "2"],
            "goto-reverse": ["3"],
            "goto-panier": ["44"],
            "set-vitesse-traj": ["10"],
            "set-vitesse-rot": ["10"],
            "set-filtre": ["0"],
            "set-filtre-raw": ["1", "2", "3"],
            "set-new-pos": ["1", "2", "3"],
            "set-timeout": ["500"],
            "set-odometrie": ["1", "280", "3"],
            "scale": ["50"],
            "flash": ["fw.bin"],
        }.get(name, [])
        args = ap.parse_args(["--bus", "1", name, *argv])
        assert args.bus_command == name
    assert not is_bus_command(ap.parse_args(["encode", "GOTO"]))


@pytest.mark.parametrize(
    ("argv", "expected"),
    [
        (["goto", "200", "100"], (0, (200, 100, 0))),
        (["goto", "-1500", "-1000", "--options", "3"], (0, (-1500, -1000, 3))),
        (["goto-reverse", "255"], (1, (255,))),
        (["goto-panier", "45"], (2, (22,))),
        (["goto-panier", "-180"], (2, (-90,))),
        (["stop"], (12, ())),
        (["set-vitesse-traj", "100"], (6, (100,))),
        (["set-vitesse-traj", "100", "40"], (6, (100, 40))),
        (["set-vitesse-rot", "50", "0x28"], (7, (50, 40))),
        (["set-filtre", "souple"], (8, (1,))),
        (["set-filtre", "FILTRE_RAIDE"], (8, (2,))),
        (["set-filtre", "0"], (8, (0,))),
        (["set-filtre-raw", "4660", "0", "65535"], (9, (4660, 0, 65535))),
        (["set-new-pos", "-5", "3", "-2"], (10, (-5, 3, -2))),
        (["set-timeout", "500"], (15, (500,))),
        (["set-timeout", "0"], (15, (0,))),
        (["set-odometrie", "-113", "279.384", "871"], (16, (-113, 27938, 871))),
    ],
)
def test_orders_and_settings_reach_the_board(
    argv: list[str], expected: tuple[int, tuple[int, ...]], capsys: pytest.CaptureFixture[str]
) -> None:
    rig = Rig()
    assert rig.run("--bus", "1", *argv) == 0
    assert rig.taken() == [expected]
    assert rig.opened == [1]
    assert capsys.readouterr().out.strip().endswith(": accepted")


def test_options_after_the_subcommand_and_pec(capsys: pytest.CaptureFixture[str]) -> None:
    rig = Rig()
    assert rig.run("goto", "200", "100", "--bus", "3", "--pec", "--address", "0x02") == 0
    assert rig.opened == [3]
    assert rig.rec.events[0] == ("w", codec.encode("GOTO", 200, 100, 0, pec=True), False)
    assert rig.taken() == [(0, (200, 100, 0))]


def test_queries_print_what_the_board_says(capsys: pytest.CaptureFixture[str]) -> None:
    rig = Rig()
    rig.dev.layer.set_snapshot(
        x_mm=-1500,
        y_mm=1000,
        angle_2deg=-45,
        radius_mm=255,
        status=int(Status.CHOC_PANIER),
        sensors=0x81,
        debug={"tick": 7, "heading_cdeg": -9000, "order_state": 4, "end_reason": 5},
    )
    rig.dev.layer.tick()
    out: dict[str, str] = {}
    for cmd in ("position", "status", "info-choc", "version", "last-reject", "debug"):
        assert rig.run("--bus", "1", "--pec", cmd) == 0, cmd
        out[cmd] = capsys.readouterr().out
    assert out["position"] == "x -1500 mm, y 1000 mm, angle -90 deg, error radius 255 mm\n"
    assert out["status"] == "status 0x08: CHOC_PANIER\n"
    assert out["info-choc"] == "sensors 0x81: CAPTEUR_0 CAPTEUR_7\n"
    assert out["version"] == (
        "protocol 1.0, capabilities 0x4fdf: PEC STOP LAST_REJECT DEBUG TIMEOUT"
        " PAUSE SPEED_SCALE QUEUE CORNERS HEARTBEAT FIX QUIET_SERVO\n"
    )
    assert out["last-reject"] == "no write rejected since reset\n"
    lines = out["debug"].splitlines()
    assert lines[0] == "tick 7"
    assert "heading_cdeg -9000" in lines
    assert lines[-2:] == ["order_state PUSH", "end_reason BASKET"]


def test_a_rejected_order_exits_1_with_the_reason(capsys: pytest.CaptureFixture[str]) -> None:
    rig = Rig()
    rig.dev.layer.set_snapshot(status=int(Status.PB_GRAVE))
    rig.dev.layer.tick()
    assert rig.run("--bus", "1", "goto", "200", "100") == 1
    err = capsys.readouterr().err
    assert err.startswith("asserv goto: GOTO rejected by the board: REFUSED_PB_GRAVE")
    assert err.count("\n") == 1
    assert rig.run("--bus", "1", "last-reject") == 0
    assert capsys.readouterr().out == (
        "REFUSED_PB_GRAVE on GOTO (designation 0x00); 1 writes rejected since reset\n"
    )


def test_no_board_exits_1(capsys: pytest.CaptureFixture[str]) -> None:
    rig = Rig()
    assert rig.run("--bus", "1", "--address", "9", "status") == 1
    err = capsys.readouterr().err
    assert "asserv status: CHECK_BUSY: no acknowledge from address 0x09" in err
    assert rig.rec.events == []


def test_a_bus_that_cannot_be_opened_exits_1(capsys: pytest.CaptureFixture[str]) -> None:
    def missing(n: int) -> VirtualBus:
        raise FileNotFoundError(errno.ENOENT, "No such file or directory")

    args = parser().parse_args(["--bus", "7", "status"])
    assert run_bus_command(args, missing) == 1
    err = capsys.readouterr().err
    assert err.startswith("asserv status: cannot open /dev/i2c-7: No such file or directory")
    assert "is I2C enabled?" in err


@pytest.mark.parametrize(
    ("argv", "message"),
    [
        (["goto", "40000", "0"], "OUT_OF_RANGE: GOTO.x_mm=40000 is outside -32000..32000"),
        (["goto", "x", "0"], "X ('x') is not an integer"),
        (["goto", "1", "2", "--options", "16"], "RESERVED_BIT"),
        (["goto-reverse", "256"], "OUT_OF_RANGE"),
        (["goto-panier", "200"], "OUT_OF_RANGE"),
        (["goto-panier", "nan"], "is not a finite number"),
        (["set-vitesse-traj", "0"], "OUT_OF_RANGE"),
        (["set-filtre", "dur"], "PRESET ('dur') is not a filter preset"),
        (["set-new-pos", "0", "0", "181"], "OUT_OF_RANGE"),
        (["wait", "--timeout", "-1"], "--timeout ('-1') must be >= 0"),
        (["wait", "--poll", "0"], "--poll ('0') must be > 0"),
        (["--pec", "set-vitesse-rot", "10"], "full form"),
        (["--address", "0x80", "status"], "is not a 7-bit address"),
        (["--bus", "one", "status"], "--bus ('one') is not an integer"),
    ],
)
def test_bad_arguments_exit_2_with_one_line_and_send_nothing(
    argv: list[str], message: str, capsys: pytest.CaptureFixture[str]
) -> None:
    rig = Rig()
    if "--bus" not in argv:
        argv = ["--bus", "1", *argv]
    assert rig.run(*argv) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1
    assert message in err
    assert rig.rec.events == []
    assert rig.taken() == []


def test_bus_is_required(capsys: pytest.CaptureFixture[str]) -> None:
    rig = Rig()
    assert rig.run("status") == 2
    assert capsys.readouterr().err == (
        "asserv status: --bus N is required (the Linux I2C bus number, 1 on a Raspberry Pi),"
        " or --sim HOST:PORT for the simulator of `asserv sim serve`\n"
    )
    assert rig.opened == []


def test_wait_polls_on_the_bus_clock(capsys: pytest.CaptureFixture[str]) -> None:
    polls = 0

    def tick() -> None:
        nonlocal polls
        polls += 1
        busy = polls < 5
        rig.dev.layer.set_snapshot(status=int(Status.BUSY_TRAJET if busy else Status.PB_MOTEUR))
        rig.dev.layer.tick()

    rig = Rig(FakeClock(on_sleep=tick))
    assert rig.run("--bus", "1", "goto", "10", "20") == 0
    assert rig.run("--bus", "1", "wait", "--timeout", "2", "--poll", "0.05") == 0
    assert capsys.readouterr().out.splitlines()[-1] == "status 0x20: PB_MOTEUR"
    assert rig.clock is not None
    assert rig.clock.sleeps == [0.05] * 5


def test_wait_timeout_exits_1(capsys: pytest.CaptureFixture[str]) -> None:
    rig = Rig(FakeClock())
    rig.dev.layer.set_snapshot(status=int(Status.BUSY_TRAJET))
    rig.dev.layer.tick()
    assert rig.run("--bus", "1", "wait", "--timeout", "0.1") == 1
    assert "still busy after 0.1 s" in capsys.readouterr().err


def test_standalone_parser_without_other_subcommands(capsys: pytest.CaptureFixture[str]) -> None:
    ap = argparse.ArgumentParser(prog="asserv")
    add_bus_arguments(ap)
    args = ap.parse_args(["--bus", "1", "stop"])
    rig = Rig()
    assert run_bus_command(args, rig.factory) == 0
    assert rig.taken() == [(12, ())]
