"""The ``asserv`` command line: demonstrations and protocol tools."""

from __future__ import annotations

import argparse
import sys

from . import codec


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


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="asserv", description=__doc__)
    sub = ap.add_subparsers(dest="command", required=True)
    sub.add_parser("demo", help="the specification's annex session through the board's C layer")
    enc = sub.add_parser("encode", help="print the bytes of a write, e.g. encode GOTO 200 100 0")
    enc.add_argument("message")
    enc.add_argument("params", nargs="*")
    enc.add_argument("--pec", action="store_true", help="append the SMBus PEC")
    dec = sub.add_parser(
        "decode", help="explain the bytes of a write, e.g. decode 00 00 c8 00 64 00"
    )
    dec.add_argument("bytes", nargs="+")
    args = ap.parse_args(argv)

    if args.command == "demo":
        from . import protodemo

        return protodemo.run()
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
