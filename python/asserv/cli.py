"""The ``asserv`` command line: the annex demonstration, simulated scenarios, protocol tools."""

from __future__ import annotations

import argparse
import os
import sys
from typing import Any

from . import cli_bus, codec


def _parse_bytes(words: list[str]) -> bytes:
    out = bytearray()
    for i, w in enumerate(words, 1):
        try:
            value = int(w, 16)
        except ValueError:
            raise SystemExit(f"asserv decode: byte {i} ({w!r}) is not hexadecimal") from None
        if not 0 <= value <= 255:
            raise SystemExit(f"asserv decode: byte {i} ({w!r}) is not a byte (00..ff)")
        out.append(value)
    return bytes(out)


def _parse_ints(name: str, words: list[str]) -> list[int]:
    out = []
    for i, w in enumerate(words, 1):
        try:
            out.append(int(w, 0))
        except ValueError:
            raise SystemExit(f"asserv encode {name}: param {i} ({w!r}) is not an integer") from None
    return out


def _sim_run(path: str, png: str | None, zoom: list[float] | None = None) -> int:
    from . import plots, scenario

    if zoom is not None and not (zoom[0] < zoom[1] and zoom[2] < zoom[3]):
        print(
            "asserv sim run: --zoom XMIN XMAX YMIN YMAX needs XMIN < XMAX and YMIN < YMAX, "
            f"not {' '.join(f'{v:g}' for v in zoom)}",
            file=sys.stderr,
        )
        return 2
    if zoom is not None and not png:
        print("asserv sim run: --zoom applies to the plot: give --png too", file=sys.stderr)
        return 2

    try:
        scn = scenario.load(path)
    except scenario.ScenarioError as e:
        print(f"asserv sim run: {e}", file=sys.stderr)
        return 2
    res = scenario.play(scn)
    scenario.summary(res)
    if png:
        box = None if zoom is None else (zoom[0], zoom[1], zoom[2], zoom[3])
        out = plots.plot_run(
            res.sim.trace, scn.field, png, title=path, targets=res.targets, zoom=box
        )
        print(f"plot: {out}")
    return 0 if res.ok else 1


def _bench_accuracy(args: argparse.Namespace) -> int:
    from . import accuracy
    from .calibration import Plan

    if args.robots < 1 or args.jobs < 1:
        print("asserv bench accuracy: --robots and --jobs must be at least 1", file=sys.stderr)
        return 2
    plan = Plan(turns=args.turns, round_trips=args.round_trips)

    def progress(done: int, total: int) -> None:
        if done == total or done % max(1, total // 10) == 0:
            print(f"  {done}/{total} robots", file=sys.stderr, flush=True)

    res = accuracy.bench(
        args.robots,
        args.first_seed,
        plan=plan,
        jobs=args.jobs,
        examples=not args.no_png,
        progress=progress,
    )
    for line in accuracy.report(res):
        print(line)
    if not args.no_png:
        for path in accuracy.plot(res, args.out):
            print(f"plot: {path}")
    return 0


def _calibrate(args: argparse.Namespace) -> int:
    from . import calibration
    from .driver import AsservError, Board

    prog = "asserv calibrate"
    if args.turns < 1 or args.round_trips < 2:
        print(f"{prog}: the procedure needs at least 1 turn and 2 round trips", file=sys.stderr)
        return 2
    geometry = calibration.Geometry(
        table_length_mm=args.table_length,
        robot_length_mm=args.robot_length,
        turn_radius_mm=args.turn_radius,
    )
    plan = calibration.Plan(turns=args.turns, round_trips=args.round_trips)
    current = calibration.OdometrySetting(
        args.ratio_ppm, round(args.track_mm * 100), args.scale_ppm
    )
    if getattr(args, "bus", None) is None:
        from . import accuracy
        from .sim import Simulator

        sim = Simulator(
            {"start": accuracy.CALIBRATION_START}, seed=args.seed, randomize=True, record=False
        )
        print(f"{prog}: simulated robot {args.seed}: {sim.describe_robot()}")
        geometry = calibration.Geometry(
            table_length_mm=sim.field.length_mm,
            robot_length_mm=float(sim.config.outline_length_mm),
            turn_radius_mm=args.turn_radius,
        )
        before = sim.odometry_errors()
        bus: Any = sim.bus
    else:
        import smbus2

        try:
            bus = smbus2.SMBus(int(args.bus, 0))
        except (OSError, ValueError) as e:
            print(f"{prog}: cannot open I2C bus {args.bus!r}: {e}", file=sys.stderr)
            return 1
    try:
        board = Board(bus, int(args.address, 0), pec=args.pec)
        res = calibration.calibrate(board, geometry, plan, current, write=not args.dry_run)
    except (calibration.CalibrationError, AsservError) as e:
        print(f"{prog}: {e}", file=sys.stderr)
        return 1
    except KeyboardInterrupt:
        print(f"{prog}: interrupted (the robot may still be moving: `stop`)", file=sys.stderr)
        return 130
    finally:
        if getattr(args, "bus", None) is not None:
            bus.close()
    print("measured:")
    for line in res.lines():
        print(line)
    if getattr(args, "bus", None) is None:
        sim.advance(0.002)
        after = sim.odometry_errors()
        print("the simulated robot's true errors (configured odometry vs true wheels):")
        for name, errs in (("before", before), ("after", after)):
            print(
                f"  {name}: wheel ratio {errs.ratio * 100:+.4f} %, track {errs.track_mm:+.3f} mm,"
                f" scale {errs.scale * 100:+.4f} %"
            )
        print(f"simulated time {sim.time_s:.1f} s")
    return 0


def _add_calibrate(sub: Any) -> None:
    cal = sub.add_parser(
        "calibrate",
        help="odometry calibration against the borders (simulated robot, or --bus N)",
        description="Measure the wheel ratio, the encoder track and the wheel scale by N turns"
        " and wall-to-wall round trips, and write them with SET_ODOMETRIE (docs/calibration.md)."
        " The robot starts with its rear flat against a border, facing the opposite one.",
    )
    cal.add_argument(
        "--bus",
        metavar="N",
        default=argparse.SUPPRESS,
        help="a real board on /dev/i2c-N (default: a simulated robot)",
    )
    cal.add_argument("--address", default="2", help="7-bit address of the board (default 2)")
    cal.add_argument("--pec", action="store_true", help="PEC on every write and reply")
    cal.add_argument("--seed", type=int, default=0, help="the simulated robot (default 0)")
    cal.add_argument("--turns", type=int, default=10, help="full turns in place (default 10)")
    cal.add_argument(
        "--round-trips", type=int, default=3, help="wall-to-wall round trips (default 3)"
    )
    cal.add_argument(
        "--table-length",
        type=float,
        default=3000.0,
        help="between the two borders driven between, mm (default 3000)",
    )
    cal.add_argument(
        "--robot-length",
        type=float,
        default=250.0,
        help="rear bumper to front bumper, mm (default 250)",
    )
    cal.add_argument(
        "--turn-radius",
        type=float,
        default=200.0,
        help="encoder midpoint to the outline's farthest point, mm (default 200)",
    )
    cal.add_argument(
        "--ratio-ppm",
        type=int,
        default=0,
        help="the board's current SET_ODOMETRIE ratio (default 0, as after reset)",
    )
    cal.add_argument(
        "--track-mm",
        type=float,
        default=280.0,
        help="the board's current encoder track, mm (default 280: the build's)",
    )
    cal.add_argument(
        "--scale-ppm",
        type=int,
        default=0,
        help="the board's current SET_ODOMETRIE scale (default 0)",
    )
    cal.add_argument(
        "--dry-run", action="store_true", help="measure, but leave the board's setting as it was"
    )


def _add_bench(sub: Any) -> None:
    bench = sub.add_parser("bench", help="benchmarks that print figures")
    bsub = bench.add_subparsers(dest="bench_command", required=True)
    acc = bsub.add_parser(
        "accuracy",
        help="the specification's Performances experiment on randomized robots",
        description="A 1.8 m straight at 0.2, 0.5 and 1 m/s on randomized simulated robots:"
        " legacy P-only baseline, this board, this board calibrated (bench/README.md).",
    )
    acc.add_argument("--robots", type=int, default=200, help="how many (default 200)")
    acc.add_argument("--first-seed", type=int, default=0, help="seed of the first robot")
    acc.add_argument(
        "--jobs", type=int, default=os.cpu_count() or 1, help="processes (default: all cores)"
    )
    acc.add_argument("--turns", type=int, default=10, help="calibration: full turns")
    acc.add_argument("--round-trips", type=int, default=3, help="calibration: round trips")
    acc.add_argument(
        "--out", default="bench-out", help="directory of the PNGs (default %(default)s)"
    )
    acc.add_argument("--no-png", action="store_true", help="do not write the plots")


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="asserv", description=__doc__)
    sub = ap.add_subparsers(dest="command", required=True)
    demo_p = sub.add_parser(
        "demo", help="the specification's annex session on the simulated board (frames, poses, PNG)"
    )
    demo_p.add_argument("--png", default="asserv-demo.png", help="plot file (default %(default)s)")
    demo_p.add_argument("--no-png", action="store_true", help="do not write the plot")
    sim = sub.add_parser("sim", help="the simulated board")
    simsub = sim.add_subparsers(dest="sim_command", required=True)
    run_p = simsub.add_parser("run", help="play a scenario file (orders, waits) on the simulator")
    run_p.add_argument("scenario", help="scenario file, e.g. scenarios/annex.txt")
    run_p.add_argument("--png", help="also write a plot of the run to this file")
    run_p.add_argument(
        "--zoom",
        nargs=4,
        type=float,
        metavar=("XMIN", "XMAX", "YMIN", "YMAX"),
        help="field view of the plot [mm]",
    )
    from . import server

    server.register(simsub)  # asserv sim serve (python/asserv/server.py)
    enc = sub.add_parser("encode", help="print the bytes of a write, e.g. encode GOTO 200 100 0")
    enc.add_argument("message")
    enc.add_argument("params", nargs="*")
    enc.add_argument("--pec", action="store_true", help="append the SMBus PEC")
    dec = sub.add_parser(
        "decode", help="explain the bytes of a write, e.g. decode 00 00 c8 00 64 00"
    )
    dec.add_argument("bytes", nargs="+")
    _add_calibrate(sub)
    _add_bench(sub)
    cli_bus.add_bus_arguments(ap, sub)
    args = ap.parse_args(argv)
    if cli_bus.is_bus_command(args):
        return cli_bus.run_bus_command(args)

    if args.command == "demo":
        from . import demo

        return demo.run(png=None if args.no_png else args.png)
    if args.command == "sim" and hasattr(args, "sim_handler"):
        return int(args.sim_handler(args))
    if args.command == "sim":
        return _sim_run(args.scenario, args.png, args.zoom)
    if args.command == "calibrate":
        return _calibrate(args)
    if args.command == "bench":
        return _bench_accuracy(args)
    try:
        if args.command == "encode":
            frame = codec.encode(
                args.message, *_parse_ints(args.message, args.params), pec=args.pec
            )
            print(" ".join(f"{b:02x}" for b in frame))
        else:
            print(codec.decode_write(_parse_bytes(args.bytes)).describe())
    except codec.FrameError as e:
        print(f"asserv {args.command}: the board would reject this: {e}", file=sys.stderr)
        return 2
    return 0
