"""The ``loopwatch`` command line: a thin parser over one module per command.

Each command module in :mod:`service.commands` exposes ``add_arguments(parser)`` and
``run(args) -> int``.  Errors of the project's own exception roots are printed as one line
(``loopwatch: error: ...``) with exit status 2; nothing reaches the user as a traceback.
"""

from __future__ import annotations

import argparse
import importlib
import logging
import sys
from collections.abc import Sequence

from adapters.errors import AdapterError
from models.errors import ModelError
from pipeline.errors import PipelineError

from .errors import ServiceError

#: (command path, module, one-line help).  Add a command by adding one row.
COMMANDS: list[tuple[tuple[str, ...], str, str]] = [
    (("analyze",), "service.commands.analyze", "diagnose the oscillations of one loop record (CSV)"),
    (("simulate", "loop"), "service.commands.simulate_loop", "simulate a closed loop (FOPDT + PI + valve) to CSV"),
    (("demo",), "service.commands.demo", "run the embedded demo"),
    (("simulate", "valve"), "service.commands.simulate_valve", "simulate a Karnopp valve bench test (t, p, x) to CSV"),
    (("monitor",), "service.commands.monitor", "run the always-on monitor (zenoh in, alerts and status out)"),
    (("simulate", "plant"), "service.commands.simulate_plant", "publish a simulated mixed plant over zenoh"),
    (("identify",), "service.commands.identify", "identify Karnopp valve friction parameters from bench or positioner data"),
    (("replay",), "service.commands.replay", "re-run the pipeline on recorded windows (MCAP), or re-publish them"),
    (("recover",), "service.commands.recover", "make a recording cut short by a crash a valid MCAP file"),
    (("export",), "service.commands.export", "write one loop's recorded samples as the CSV of `analyze`"),
    (("reconcile",), "service.commands.reconcile", "find where the Karnopp model and a valve record disagree and name the missing effect"),
]

_USER_ERRORS = (PipelineError, ModelError, AdapterError, ServiceError)


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="loopwatch",
        description="Monitor control loops; tell valve stiction from tuning and disturbances.",
    )
    parser.add_argument("-v", "--verbose", action="count", default=0, help="more log output (-vv: debug)")
    groups: dict[tuple[str, ...], argparse._SubParsersAction] = {
        (): parser.add_subparsers(dest="command", metavar="COMMAND", required=True)
    }
    for path, module_name, help_text in COMMANDS:
        for depth in range(1, len(path)):
            prefix = path[:depth]
            if prefix not in groups:
                group = groups[prefix[:-1]].add_parser(prefix[-1], help=f"{prefix[-1]} commands")
                groups[prefix] = group.add_subparsers(dest="_".join(prefix), metavar="KIND", required=True)
        module = importlib.import_module(module_name)
        sub = groups[path[:-1]].add_parser(path[-1], help=help_text, description=help_text)
        module.add_arguments(sub)
        sub.set_defaults(_run=module.run)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of the ``loopwatch`` console script."""
    args = build_parser().parse_args(argv)
    logging.basicConfig(
        level=(logging.WARNING, logging.INFO, logging.DEBUG)[min(args.verbose, 2)],
        format="%(asctime)s %(levelname)s %(name)s: %(message)s",
    )
    try:
        return int(args._run(args) or 0)
    except _USER_ERRORS as exc:
        print(f"loopwatch: error: {exc}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        return 130


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
