"""``loopwatch analyze FILE.csv``: diagnose the oscillations of one loop record."""

from __future__ import annotations

import argparse
import json
from pathlib import Path

from rich.console import Console
from rich.table import Table

from adapters.loop_csv import read_loop_csv
from pipeline.diagnosis import DiagnosisConfig

from ..analysis import LoopReport, analyze_loop
from ..errors import UsageError


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("file", type=Path, help="CSV with columns t (s), pv, op and optional sp, mv, mode")
    p.add_argument("--signal", choices=["auto", "pv", "op", "error"], default="auto",
                   help="series to analyse (auto: pv, or op when the file has no pv; error = sp - pv)")
    p.add_argument("--window", type=int, default=None, help="window length in samples (default 4096 or the record)")
    p.add_argument("--hop", type=int, default=None, help="hop between windows in samples (default window/2)")
    p.add_argument("--method", choices=["robust", "paper"], default="robust",
                   help="robust: DNL of the phase-locked mean wave with a surrogate significance test, "
                        "set-point changes analysed as control error, OP as second witness (default); "
                        "paper: Aftab et al. 2016 as published (EMD, lambda pruning, TDNL > threshold)")
    p.add_argument("--threshold", type=float, default=None,
                   help="paper method: TDNL above which the cause is non-linear (default 0.1); robust method: "
                        "smallest DNL of the mean wave reported as non-linear (default 0.05)")
    p.add_argument("--json", type=Path, default=None, metavar="OUT", help="write the report as JSON")


def run(args: argparse.Namespace) -> int:
    for name in ("window", "hop"):
        v = getattr(args, name)
        if v is not None and v < 1:
            raise UsageError(f"--{name} {v}: must be at least 1 sample")
    if args.threshold is not None and not args.threshold > 0:
        raise UsageError(f"--threshold {args.threshold}: must be > 0")
    config = DiagnosisConfig(method=args.method)
    if args.threshold is not None:
        config = config.with_decision_threshold(args.threshold)
    data = read_loop_csv(args.file)
    report = analyze_loop(data, signal=args.signal, window=args.window, hop=args.hop, config=config)
    print_report(report)
    if args.json:
        args.json.parent.mkdir(parents=True, exist_ok=True)
        args.json.write_text(json.dumps(report.to_json(), indent=2) + "\n")
    return 0


def print_report(report: LoopReport, console: Console | None = None) -> None:
    console = console or Console()
    table = Table(title=f"{report.source}  ({report.signal}, {report.n_samples} samples at {report.sample_time_s:g} s)")
    for col in ("start s", "end s", "period s", "r", "IMFs", "DNL", "TDNL", "p", "verdict"):
        table.add_column(col, justify="right" if col not in ("IMFs", "verdict") else "left")
    for w in report.windows:
        j = w.to_json()
        fmt = lambda v, f="{:.3g}": "-" if v is None else f.format(v)  # noqa: E731
        table.add_row(
            f"{j['start_s']:g}", f"{j['end_s']:g}", fmt(j["period_s"]), fmt(j["regularity"], "{:.2f}"),
            ",".join(map(str, j["imfs_kept"])) or "-",
            " ".join(fmt(v, "{:.3f}") for v in j["dnl"]) or "-", fmt(j["tdnl"], "{:.3f}"),
            fmt(j["p_value"], "{:.3f}"), j["verdict"],
        )
    console.print(table)
    tdnl = "-" if report.tdnl != report.tdnl else f"{report.tdnl:.3f}"
    console.print(f"[bold]verdict: {report.verdict}[/bold]  (TDNL {tdnl}) — {report.reason}")
    if report.n_duplicates:
        console.print(f"note: {report.n_duplicates} row(s) with a repeated time stamp dropped (first kept)")
