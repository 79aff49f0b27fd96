"""``loopwatch demo``: the embedded demonstration.

Until the always-on monitor lands, the demo simulates the paper's loops and diagnoses each one.
"""

from __future__ import annotations

import argparse
import tempfile
from pathlib import Path

from rich.console import Console
from rich.table import Table


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--out", type=Path, default=None, help="folder for the simulated CSV files (default: a temp dir)")
    p.add_argument("--seed", type=int, default=1)


def run(args: argparse.Namespace) -> int:
    from adapters.csv_table import write_table
    from adapters.loop_csv import read_loop_csv
    from models.loop import CASES, simulate_loop

    from ..analysis import analyze_loop

    out = args.out or Path(tempfile.mkdtemp(prefix="loopwatch-demo-"))
    table = Table(title="loopwatch demo: simulated loops (paper §4) and their diagnosis")
    for col in ("case", "truth", "verdict", "TDNL", "reason"):
        table.add_column(col)
    for name, scenario in CASES.items():
        sim = simulate_loop(scenario, seed=args.seed)
        path = out / f"{name}.csv"
        write_table(path, {"t": sim.t, "sp": sim.sp, "pv": sim.pv, "op": sim.op, "mv": sim.mv})
        report = analyze_loop(read_loop_csv(path))
        table.add_row(name, sim.truth, report.verdict, f"{report.tdnl:.3f}", report.reason)
    Console().print(table)
    print(f"CSV files in {out}")
    return 0
