"""``loopwatch simulate loop --case CASE --out FILE.csv``: simulate one closed loop of the paper.

Writes the columns ``t, sp, pv, op, mv, mode`` (``mode = 1``: the loop is in automatic) with
:func:`adapters.csv_table.write_table`, and prints the case and the cause (``truth``).
"""

from __future__ import annotations

import argparse
import math
from pathlib import Path

import numpy as np

from adapters.csv_table import write_table
from models.loop import CASES, scenario_for_case, simulate_loop

from ..errors import UsageError


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--case", required=True, choices=list(CASES),
                   help="which loop to simulate (Aftab et al. 2016 §4 cases plus healthy and deadband)")
    p.add_argument("--noise", type=float, default=0.0, metavar="STD",
                   help="PV measurement noise standard deviation, PV units per sample (default 0)")
    p.add_argument("--duration", type=float, default=None, metavar="S",
                   help="record length in seconds (default 4000, at 1 s sampling)")
    p.add_argument("--seed", type=int, default=0, metavar="N", help="noise seed (default 0)")
    p.add_argument("--out", type=Path, required=True, metavar="FILE.csv", help="output CSV file")


def run(args: argparse.Namespace) -> int:
    if not (math.isfinite(args.noise) and args.noise >= 0.0):
        raise UsageError(f"--noise {args.noise}: must be a finite number >= 0")
    if args.duration is not None and not (math.isfinite(args.duration) and args.duration >= 1.0):
        raise UsageError(f"--duration {args.duration}: must be a finite number of seconds >= 1")
    duration = None if args.duration is None else float(args.duration)
    scenario = scenario_for_case(args.case, noise_std=args.noise, duration_s=duration)
    result = simulate_loop(scenario, seed=args.seed)
    write_table(
        args.out,
        {
            "t": result.t,
            "sp": result.sp,
            "pv": result.pv,
            "op": result.op,
            "mv": result.mv,
            "mode": np.ones_like(result.t),
        },
    )
    print(f"case {args.case}: truth {result.truth}; {len(result.t)} samples at "
          f"{scenario.sample_time_s:g} s, noise {args.noise:g}, seed {args.seed} -> {args.out}")
    return 0
