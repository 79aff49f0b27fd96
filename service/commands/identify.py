"""``loopwatch identify DATA.csv [--signature SIG.csv] [--validate FILE.csv ...]``: Karnopp valve
parameters from bench or positioner data (Romano & Garcia, models 1 and 2).

Prints both parameter sets with their figures of merit, the validation RMSE of the stem
position when each set is re-simulated from the measured pressure (section 5), and optionally
writes them as JSON and plots measured vs. simulated position and ``σ_s`` / ``R²`` over ``δv``
(the paper's Fig. 3–4, 6–9).
"""

from __future__ import annotations

import argparse
import json
import math
from pathlib import Path

from adapters.valve_csv import read_valve_csv
from models.identification import Identification, ParameterSet, Validation, identify, validate
from models.karnopp import M_KG, SA_M2

from ..errors import UsageError

MASS_NOTE = (
    "the mass is not identifiable from 1 ms data with a 31-sample derivative window "
    "(the inertial term lives in millisecond transients)"
)


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("data", type=Path, metavar="DATA.csv", help="identification record (t, p, x), e.g. a square-wave test")
    p.add_argument("--signature", type=Path, default=None, metavar="SIG.csv",
                   help="valve signature (slow triangular test) for the bias, eq. (15) and model 2")
    p.add_argument("--validate", type=Path, action="append", default=[], metavar="FILE.csv",
                   help="validation record (e.g. sine, ISA steps); repeatable (default: the identification data)")
    p.add_argument("--area", type=float, default=SA_M2, metavar="M2",
                   help=f"actuator diaphragm area in m^2 (default {SA_M2}, the paper's Fisher ET)")
    p.add_argument("--mass", type=float, default=M_KG, metavar="KG",
                   help=f"nominal mass of the moving parts in kg, held fixed (default {M_KG})")
    p.add_argument("--estimate-mass", action="store_true",
                   help="regress the mass as well (the paper's theta of eq. 3); unreliable, a warning is printed")
    p.add_argument("--json", type=Path, default=None, metavar="OUT.json", help="write the parameter sets as JSON")
    p.add_argument("--plot", type=Path, default=None, metavar="OUT.png", help="write the validation / sweep plot")


def _pset_json(ps: ParameterSet) -> dict:
    return {k: (None if isinstance(v, float) and not math.isfinite(v) else v) for k, v in ps.as_dict().items()}


def _print(ident: Identification, vals: list[Validation]) -> None:
    sets = (ident.model1, ident.model1_literal, ident.model2)
    rows = [
        ("m (kg)", "m", "{:.4g}"), ("k (N/m)", "k", "{:.5g}"), ("Fc (N)", "fc", "{:.5g}"), ("Fs (N)", "fs", "{:.5g}"),
        ("Fv (N s/m)", "fv", "{:.4g}"), ("bias (mm)", "bias", "{:.4f}"), ("DV (m/s)", "dv", "{:.3g}"),
        ("delta v (m/s)", "delta_v", "{:.3g}"), ("sigma_s (N)", "sigma", "{:.4g}"), ("R2_s", "r2", "{:.6f}"),
        ("samples", "n_samples", "{}"),
    ]
    width = 22
    print(f"{'':16s}" + "".join(f"{ps.name:>{width}s}" for ps in sets))
    for label, attr, fmt in rows:
        cells = []
        for ps in sets:
            v = getattr(ps, attr)
            if attr == "bias":
                v = v * 1e3
            cells.append("-" if isinstance(v, float) and not math.isfinite(v) else fmt.format(v))
        print(f"{label:16s}" + "".join(f"{c:>{width}s}" for c in cells))
    print(f"m: held at the nominal value; {MASS_NOTE}" if "held" in ident.model1.notes[-1] else
          f"m: estimated by regression; {MASS_NOTE}")
    print(f"k of eq. (15) from the signature: {ident.k_signature:.5g} N/m; {len(ident.breakaways)} breakaway(s)")
    for v in vals:
        print(f"validation {v.name}: {v.model} position RMSE {v.rmse * 1e3:.4f} mm")
    for w in ident.warnings:
        print(f"warning: {w}")


def _plot(path: Path, ident: Identification, vals: list[Validation]) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    names = list(dict.fromkeys(v.name for v in vals))
    nrow = len(names) + 1
    fig, axes = plt.subplots(nrow, 1, figsize=(10, 3.0 * nrow), squeeze=False)
    for ax, name in zip(axes[:-1, 0], names):
        vs = [v for v in vals if v.name == name]
        ax.plot(vs[0].t, vs[0].x_meas * 1e3, color="k", lw=0.8, label="measured")
        for v in vs:
            ax.plot(v.t, v.x_sim * 1e3, lw=1.0, label=f"{v.model} (RMSE {v.rmse * 1e3:.3f} mm)")
        ax.set_ylabel("stem position (mm)")
        ax.set_title(f"validation: {name}")
        ax.legend(fontsize=8)
    ax = axes[-1, 0]
    sw = ident.sweep
    ax.plot(sw.dv, sw.sigma, color="C0")
    ax.set_xlabel("delta v (m/s)")
    ax.set_ylabel("sigma_s (N), eq. 17", color="C0")
    for i, lab, c in ((ident.i_robust, "robust", "C2"), (ident.i_literal, "literal", "C3")):
        ax.axvline(sw.dv[i], color=c, ls="--", lw=0.8, label=f"{lab} selection")
    ax.legend(fontsize=8, loc="upper center")
    ax2 = ax.twinx()
    ax2.plot(sw.dv, sw.r2, color="C1")
    ax2.set_ylabel("R2_s, eq. 18", color="C1")
    fig.tight_layout()
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=100)
    plt.close(fig)


def run(args: argparse.Namespace) -> int:
    if not (math.isfinite(args.area) and args.area > 0):
        raise UsageError(f"--area {args.area}: the actuator area must be a finite number of m^2 > 0")
    if not (math.isfinite(args.mass) and args.mass > 0):
        raise UsageError(f"--mass {args.mass}: must be a finite number of kg > 0")
    data = read_valve_csv(args.data)
    sig = read_valve_csv(args.signature) if args.signature is not None else None
    ident = identify(data, sig, sa=args.area, m_nominal=args.mass, estimate_mass=args.estimate_mass)
    records = [read_valve_csv(p) for p in args.validate] or [data]
    vals = [validate(ps, rec, args.area) for rec in records for ps in (ident.model1, ident.model2)]
    _print(ident, vals)
    if not args.validate:
        print("note: no --validate record given; the RMSE above is on the identification data (not independent)")
    if args.json is not None:
        doc = {
            "model1": _pset_json(ident.model1),
            "model1_literal": _pset_json(ident.model1_literal),
            "model2": _pset_json(ident.model2),
            "k_signature": ident.k_signature,
            "area_m2": args.area,
            "mass": ("estimated (unreliable)" if args.estimate_mass else "held at nominal") + "; " + MASS_NOTE,
            "validation": [{"file": v.name, "model": v.model, "rmse_m": v.rmse} for v in vals],
            "warnings": list(ident.warnings),
        }
        args.json.parent.mkdir(parents=True, exist_ok=True)
        args.json.write_text(json.dumps(doc, indent=2, allow_nan=False) + "\n", encoding="utf-8")
    if args.plot is not None:
        _plot(args.plot, ident, vals)
    return 0
