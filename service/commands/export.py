"""``loopwatch export FILE --loop ID --csv OUT``: the recorded samples of one loop as the CSV of
``loopwatch analyze`` (columns ``t, pv, op`` and ``sp, mv, mode`` when recorded).

``t`` is the monitor's grid time; every grid point covered by a recorded window is one row
(windows overlap: each point once); missing samples are empty cells.  Values are written with
17 significant digits, so they read back bit for bit.
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

from ..errors import UsageError
from .replay import add_selection


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("paths", nargs="+", type=Path, metavar="FILE_OR_DIR", help="recording files or directories")
    add_selection(p)
    p.add_argument("--csv", type=Path, required=True, metavar="OUT", help="CSV file to write")


def run(args: argparse.Namespace) -> int:
    from adapters.csv_table import write_table

    from ..replay import recorded_windows

    if not args.loop or len(args.loop) != 1:
        raise UsageError("give exactly one --loop ID to export")
    cols: dict[str, dict[int, float]] = {}
    times: dict[int, float] = {}
    n = 0
    for rec in recorded_windows(args.paths, loops=args.loop, t_from=args.t_from, t_to=args.t_to):
        w = rec.window
        n += 1
        idx = range(w.index0, w.index0 + w.t.size)
        times.update(zip(idx, w.t.tolist()))
        for name, v in w.signals.items():
            cols.setdefault(name, {}).update(zip(idx, v.tolist()))
    if n == 0:
        raise UsageError(f"no recorded windows of loop {args.loop[0]!r} in {', '.join(map(str, args.paths))} "
                         "(within the time range)")
    k = np.array(sorted(times))
    out = {"t": np.array([times[i] for i in k])}
    for name in ("pv", "op", "sp", "mv", "mode"):
        if name in cols or name in ("pv", "op"):
            c = cols.get(name, {})
            out[name] = np.array([c.get(i, np.nan) for i in k])
    write_table(args.csv, out, fmt="%.17g")
    print(f"wrote {k.size} rows ({', '.join(out)}) from {n} window(s) of {args.loop[0]} to {args.csv}")
    return 0
