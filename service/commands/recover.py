"""``loopwatch recover FILE``: turn a recording cut short (crash, kill -9, full disk) into a valid MCAP file.

Every complete record up to the cut is kept (with a flush every ``recording.flush_s``, that is
every window flushed before the crash).  The output defaults to FILE without ``.part`` (for a
``.mcap`` file: ``FILE.recovered.mcap``); the input is left in place unless ``--remove``.
"""

from __future__ import annotations

import argparse
from pathlib import Path

from ..errors import UsageError


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("files", nargs="+", type=Path, metavar="FILE", help="truncated recording(s) (.mcap.part or .mcap)")
    p.add_argument("-o", "--output", type=Path, default=None, metavar="OUT",
                   help="output file (only with a single FILE)")
    p.add_argument("--remove", action="store_true", help="delete each input once it is recovered")


def run(args: argparse.Namespace) -> int:
    from adapters.mcap_recorder import recover_file

    if args.output is not None and len(args.files) != 1:
        raise UsageError("--output needs exactly one FILE")
    for f in args.files:
        res = recover_file(f, args.output)
        state = f"cut short ({res.error})" if res.truncated else "complete"
        print(f"{res.source} -> {res.target}: {res.messages} message(s) kept; input was {state}")
        if args.remove:
            Path(res.source).unlink()
    return 0
