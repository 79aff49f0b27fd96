"""``loopwatch simulate valve --test TEST --preset PRESET --out FILE.csv``: a simulated bench test.

Runs one excitation of the Karnopp paper (square, triangle, sine, ISA-75.25 steps) through the
paper's valve with a friction set of Table 1 and writes ``t`` (s), ``p`` (Pa, the actuator
pressure after the V/P lag, with noise) and ``x`` (m, measured stem position, with noise).
"""

from __future__ import annotations

import argparse
import math
from pathlib import Path

from adapters.valve_csv import write_valve_csv
from models.karnopp import PRESETS, preset
from models.valve_tests import DT, EXCITATIONS, bench_record

from ..errors import UsageError


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--test", required=True, choices=list(EXCITATIONS),
                   help="bench excitation: square (identification), triangle (signature), sine / isa-steps (validation)")
    p.add_argument("--preset", required=True, choices=list(PRESETS), help="friction set of the paper's Table 1")
    p.add_argument("--fs-ratio", type=float, default=None, metavar="R",
                   help="give the valve a slip jump: Fs = R * Fc (R >= 1; default: Fs = Fc as in Table 1)")
    p.add_argument("--noise-x", type=float, default=1e-5, metavar="M",
                   help="stem-position noise standard deviation in m (default 1e-5)")
    p.add_argument("--noise-p", type=float, default=200.0, metavar="PA",
                   help="pressure noise standard deviation in Pa (default 200)")
    p.add_argument("--no-noise", action="store_true", help="write the noise-free record")
    p.add_argument("--seed", type=int, default=0, metavar="N", help="noise seed (default 0)")
    p.add_argument("--out", type=Path, required=True, metavar="FILE.csv", help="output CSV file")


def run(args: argparse.Namespace) -> int:
    for flag, value in (("--noise-x", args.noise_x), ("--noise-p", args.noise_p)):
        if not (math.isfinite(value) and value >= 0.0):
            raise UsageError(f"{flag} {value}: must be a finite number >= 0")
    nx, npr = (0.0, 0.0) if args.no_noise else (args.noise_x, args.noise_p)
    params = preset(args.preset, fs_ratio=args.fs_ratio)
    rec = bench_record(params, args.test, noise_x=nx, noise_p=npr, seed=args.seed, dt=DT)
    write_valve_csv(args.out, rec.t, rec.p, rec.x)
    print(
        f"valve {args.preset} (Fc {params.fc:g} N, Fs {params.fs:g} N, Fv {params.fv:g} N s/m, k {params.k:g} N/m, "
        f"bias {params.bias * 1e3:g} mm), test {args.test}: {rec.t.size} samples at {DT * 1e3:g} ms, "
        f"noise x {nx:g} m, p {npr:g} Pa, seed {args.seed} -> {args.out}"
    )
    return 0
