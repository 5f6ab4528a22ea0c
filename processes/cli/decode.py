"""`pingpong decode`: one captured wire message, validated and pretty-printed."""
from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path
from typing import TYPE_CHECKING

from processes.cli.common import FORMATTER

if TYPE_CHECKING:
    from processes.network import wire



def decode_command(args: argparse.Namespace) -> int:
    """`pingpong decode FILE|HEX`: pretty-print one captured message; exit 2 if it is bad."""
    from processes.network import wire

    try:
        data = _read_capture(args.message)
    except (ValueError, OSError) as err:
        print(f"pingpong decode: {err}", file=sys.stderr)
        return 2
    try:
        message = wire.decode(data)
    except wire.WireError as err:
        if args.json:
            print(json.dumps({"ok": False, "reason": err.reason, "detail": str(err), "bytes": len(data)}))
        print(f"pingpong decode: bad message: {err.reason}: {err}", file=sys.stderr)
        return 2
    if args.json:
        print(json.dumps({"ok": True, **message.to_dict()}, ensure_ascii=False))
    else:
        print(_human(message))
    return 0


def _read_capture(source: str) -> bytes:
    try:
        is_file = Path(source).is_file()
    except OSError:  # a long hex string is too long for a file name
        is_file = False
    if is_file:
        return Path(source).read_bytes()
    text = "".join(source.split()).replace(":", "")
    if text[:2].lower() == "0x":
        text = text[2:]
    try:
        return bytes.fromhex(text)
    except ValueError:
        raise ValueError(f"{source!r} is neither a file nor a hex string") from None


def _human(message: wire.Message) -> str:
    from processes.network import wire

    lines = [f"{message.kind.name.lower()}  seq {message.seq}  tick {message.tick}  flags 0x{message.flags:02x}  "
             f"({wire.SIZES[message.kind]} bytes, protocol {wire.PROTOCOL_VERSION})"]
    for name, value in message.to_dict().items():
        if name in ("kind", "seq", "tick", "flags"):
            continue
        if isinstance(value, float) or (isinstance(value, list) and value and isinstance(value[0], float)):
            value = json.dumps(value)
        elif isinstance(value, str) and name in wire.SPECS[message.kind].text:
            value = json.dumps(value, ensure_ascii=False)
        lines.append(f"  {name:<12} {value}")
    return "\n".join(lines)


def add_commands(sub) -> None:
    """`pingpong decode`."""
    decode = sub.add_parser("decode", help="pretty-print one captured wire message (exit 2 if it is bad)",
                            formatter_class=FORMATTER)
    decode.add_argument("message", metavar="FILE|HEX", help="a file of the message's raw bytes, or its bytes in hex")
    decode.add_argument("--json", action="store_true", help="print one JSON object")
    decode.set_defaults(func=decode_command)
