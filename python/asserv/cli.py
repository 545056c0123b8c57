"""The ``asserv`` command line: the annex demonstration, simulated scenarios, protocol tools."""

from __future__ import annotations

import argparse
import sys

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
    enc = sub.add_parser("encode", help="print the bytes of a write, e.g. encode GOTO 200 100 0")
    enc.add_argument("message")
    enc.add_argument("params", nargs="*")
    enc.add_argument("--pec", action="store_true", help="append the SMBus PEC")
    dec = sub.add_parser(
        "decode", help="explain the bytes of a write, e.g. decode 00 00 c8 00 64 00"
    )
    dec.add_argument("bytes", nargs="+")
    cli_bus.add_bus_arguments(ap, sub)
    args = ap.parse_args(argv)
    if cli_bus.is_bus_command(args):
        return cli_bus.run_bus_command(args)

    if args.command == "demo":
        from . import demo

        return demo.run(png=None if args.no_png else args.png)
    if args.command == "sim":
        return _sim_run(args.scenario, args.png, args.zoom)
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
