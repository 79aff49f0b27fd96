"""``loopwatch simulate valve --test TEST --preset PRESET --out FILE.csv``: a simulated bench test.

Runs one excitation of the Karnopp paper (square, triangle, sine, ISA-75.25 steps) through the
paper's valve with a friction set of Table 1 and writes ``t`` (s), ``p`` (Pa, the actuator
pressure after the V/P lag, with noise) and ``x`` (m, measured stem position, with noise).

``--hide EFFECT[=value]`` (repeatable) adds an effect the paper's Karnopp structure leaves out
(issue 8; :mod:`models.valve_effects`): ``slip_jump=R`` (Fs = R·Fc), ``stribeck=R:VS``,
``actuator_lag=TAU`` (s), ``dead_time=THETA`` (s), ``deadband=D`` (m).  The recorded ``p`` is
then the pressure *before* the hidden lag / dead time, and ``x`` is read through the hidden
deadband.  ``--vp-lag 0`` records the command itself (no V/P converter).
"""

from __future__ import annotations

import argparse
import math
from pathlib import Path

from adapters.valve_csv import write_valve_csv
from models.karnopp import PRESETS, preset
from models.valve_effects import EFFECTS, hidden_record, parse_hide
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
    p.add_argument("--hide", action="append", default=[], metavar="EFFECT[=VALUE]",
                   help=f"hide an effect in the data, repeatable: {', '.join(EFFECTS)} "
                        "(slip_jump=R, stribeck=R:VS, actuator_lag=TAU, dead_time=THETA, deadband=D; SI units)")
    p.add_argument("--vp-lag", type=float, default=None, metavar="S",
                   help="V/P converter time constant in s (default: the preset's, 1 s); 0 records the command")
    p.add_argument("--out", type=Path, required=True, metavar="FILE.csv", help="output CSV file")


def run(args: argparse.Namespace) -> int:
    for flag, value in (("--noise-x", args.noise_x), ("--noise-p", args.noise_p)):
        if not (math.isfinite(value) and value >= 0.0):
            raise UsageError(f"{flag} {value}: must be a finite number >= 0")
    nx, npr = (0.0, 0.0) if args.no_noise else (args.noise_x, args.noise_p)
    params = preset(args.preset, fs_ratio=args.fs_ratio)
    if args.vp_lag is not None:
        if not (math.isfinite(args.vp_lag) and args.vp_lag >= 0.0):
            raise UsageError(f"--vp-lag {args.vp_lag}: must be a finite number of seconds >= 0")
        params = params.replace(tau_p=args.vp_lag)
    if args.hide or args.vp_lag is not None:
        hidden = dict(parse_hide(h) for h in args.hide)
        if len(hidden) < len(args.hide):
            raise UsageError("--hide: each effect may be given once")
        rec = hidden_record(params, args.test, hidden, noise_x=nx, noise_p=npr, seed=args.seed, dt=DT)
        extra = ", hidden: " + (", ".join(f"{k}={':'.join(f'{v:g}' for v in vals)}" for k, vals in hidden.items()) or "none")
    else:
        rec = bench_record(params, args.test, noise_x=nx, noise_p=npr, seed=args.seed, dt=DT)
        extra = ""
    write_valve_csv(args.out, rec.t, rec.p, rec.x)
    print(
        f"valve {args.preset} (Fc {params.fc:g} N, Fs {params.fs:g} N, Fv {params.fv:g} N s/m, k {params.k:g} N/m, "
        f"bias {params.bias * 1e3:g} mm), test {args.test}: {rec.t.size} samples at {DT * 1e3:g} ms, "
        f"noise x {nx:g} m, p {npr:g} Pa, seed {args.seed}{extra} -> {args.out}"
    )
    return 0
