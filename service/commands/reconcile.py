"""``loopwatch reconcile DATA.csv [--signature SIG.csv] [--json OUT] [--report OUT.html]``: find
where the Karnopp model (Romano & Garcia, model 1) and the measurement disagree, name the missing
effect(s), add them and show the gap shrink (issue 8; the method is :mod:`models.reconcile`).

Prints the baseline, the residual split by regime, every candidate tried at each step with its
held-out statistics, and the accepted effects; optionally writes the JSON document and a
self-contained HTML report (matplotlib PNGs embedded as base64).
"""

from __future__ import annotations

import argparse
import base64
import html
import io
import json
import math
import time
from pathlib import Path

import numpy as np
from rich.console import Console

from adapters.valve_csv import read_valve_csv
from models.karnopp import M_KG, SA_M2
from models.reconcile import REGIMES, Reconciliation, ReconcileConfig, reconcile

from ..errors import UsageError


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("data", type=Path, metavar="DATA.csv", help="bench or positioner record (t s, p Pa, x m)")
    p.add_argument("--signature", type=Path, default=None, metavar="SIG.csv",
                   help="a second record (e.g. a slow triangular signature) fitted and scored with the first")
    p.add_argument("--area", type=float, default=SA_M2, metavar="M2",
                   help=f"actuator diaphragm area in m^2 (default {SA_M2}, the paper's Fisher ET)")
    p.add_argument("--mass", type=float, default=M_KG, metavar="KG",
                   help=f"mass of the moving parts in kg, held fixed (default {M_KG})")
    p.add_argument("--threads", type=int, default=ReconcileConfig.threads, metavar="N",
                   help="worker processes for the multi-start fits (default %(default)s; the result does not depend on it)")
    p.add_argument("--stick-band", type=float, default=ReconcileConfig.stick_band, metavar="SD",
                   help="stick band of the fitted models in standard deviations of the recorded-pressure noise "
                        "(default %(default)s; 0: the stick/slip rule of eq. 2 as written)")
    p.add_argument("--global-search", action="store_true",
                   help="when the local search stops above the noise, fit every candidate added to the accepted "
                        "effects by a global search (differential evolution) too: finds some pairs the local "
                        "search misses, and can take several times longer (ReconcileConfig.global_search)")
    p.add_argument("--split-check", type=int, default=1, metavar="N",
                   help="run the search on N draws of the training / held-out blocks and report how many name "
                        "each effect (the result is the first draw's; N times the cost; default 1)")
    p.add_argument("--json", type=Path, default=None, metavar="OUT.json", help="write the result as JSON")
    p.add_argument("--report", type=Path, default=None, metavar="OUT.html",
                   help="write a self-contained HTML report with plots")


def _um(v: float) -> str:
    return f"{v * 1e6:.2f} µm"


def _named(r: Reconciliation) -> str:
    """The effects found, each with the candidates the record cannot tell it from."""
    return ", ".join(s.effect + (f" (or {' or '.join(s.indistinguishable_from)}: the record cannot tell them apart)"
                                 if s.indistinguishable_from else "") for s in r.steps) or "none"


def _lines(r: Reconciliation) -> list[str]:
    out = [f"noise floor (white position noise): {_um(r.noise_floor)}"]
    b = r.baseline
    out.append(f"baseline (Karnopp model 1, Fs = Fc): RMSE {_um(b.rmse)}, held-out {_um(b.heldout_rmse)}")
    out.append("  params: " + ", ".join(f"{k} {v:.5g}" for k, v in b.params.items()))
    out.append("where the baseline disagrees (share of squared error / RMSE / samples):")
    for g in REGIMES:
        if g in r.regime_share:
            out.append(f"  {g:13s} {r.regime_share[g]:6.1%}  {_um(b.regime_rmse[g]):>12s}  {r.regime_samples[g]}")
    out.append(f"residual-input-rate cross-correlation: peak {r.xcorr['peak']:+.3f} at lag {r.xcorr['lag_s']:+.3f} s")
    for i, rnd in enumerate(r.rounds, 1):
        out.append(f"step {i}: candidates (held-out)")
        for c in sorted(rnd, key=lambda c: -c.delta_bic):
            verdict = "PASS" if c.passed else "fail: " + "; ".join(c.reasons)
            out.append(f"  {c.effect:13s} RMSE {_um(c.heldout_rmse):>12s}  dBIC {c.delta_bic:9.1f}  p {c.t_stat:8.2g}  "
                       f"gain/noise {c.gain_over_noise:7.3f}  in predicted regimes {c.gain_in_predicted:4.0%}  {verdict}")
    for s in r.steps:
        out.append(f"added {s.effect}: RMSE {_um(s.rmse)} (held-out {_um(s.heldout_rmse)}): {s.evidence}")
        out.append("  params: " + ", ".join(f"{k} {v:.5g}" for k, v in s.params.items()))
    out.append(f"effects: {_named(r)} — {r.message}")
    out.append(f"RMSE: baseline {_um(r.baseline.rmse)} -> final {_um(r.final.rmse)} (noise {_um(r.noise_floor)})")
    out.append(f"pressure-noise floor of the final model (what the recorded pressure's noise alone moves its stem, "
               f"RMS, median of {len(r.pressure_floor_draws)} bootstrap draws): {_um(r.pressure_floor)}, up to "
               f"{_um(max(r.pressure_floor_draws, default=0.0))}")
    return out


def _png(fig) -> str:
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=90)
    return base64.b64encode(buf.getvalue()).decode("ascii")


def _report(path: Path, r: Reconciliation, lines: list[str]) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    imgs = []
    models = [("baseline", r.baseline)] + [(f"+ {s.effect}", s) for s in r.steps]
    for j, rec in enumerate(r.records):
        t = np.asarray(rec.data.t, float)
        fig, ax = plt.subplots(2, 1, figsize=(11, 6.5), sharex=True)
        ax[0].plot(t, rec.x * 1e3, color="k", lw=0.6, label="measured")
        for name, s in models:
            ax[0].plot(t, s.x_sim[j] * 1e3, lw=0.9, label=f"{name} (RMSE {s.rmse * 1e6:.1f} µm)")
        ax[0].set_ylabel("stem position (mm)")
        ax[0].set_title(f"{rec.data.name}: measured vs. models")
        ax[0].legend(fontsize=8)
        for name, s in models:
            ax[1].plot(t, (rec.x - s.x_sim[j]) * 1e6, lw=0.6, label=name)
        ax[1].axhline(0, color="k", lw=0.5)
        ax[1].set_ylabel("residual (µm)")
        ax[1].set_xlabel("t (s)")
        ax[1].legend(fontsize=8)
        fig.tight_layout()
        imgs.append(_png(fig))
        plt.close(fig)
    fig, ax = plt.subplots(figsize=(9, 3.5))
    regs = [g for g in REGIMES if g in r.baseline.regime_rmse]
    w = 0.8 / len(models)
    for i, (name, s) in enumerate(models):
        ax.bar(np.arange(len(regs)) + i * w, [s.regime_rmse[g] * 1e6 for g in regs], w, label=name)
    ax.axhline(r.noise_floor * 1e6, color="k", ls="--", lw=0.8, label="noise")
    ax.set_xticks(np.arange(len(regs)) + 0.4 - w / 2, regs)
    ax.set_ylabel("RMSE (µm)")
    ax.set_title("RMSE per regime, before and after each step")
    ax.legend(fontsize=8)
    fig.tight_layout()
    imgs.append(_png(fig))
    plt.close(fig)
    body = "".join(f'<p><img alt="plot" src="data:image/png;base64,{b}"></p>' for b in imgs)
    doc = (
        "<!doctype html><html><head><meta charset='utf-8'><title>loopwatch reconcile</title></head><body>"
        f"<h1>loopwatch reconcile: {html.escape(', '.join(rec.data.name for rec in r.records))}</h1>"
        f"<p><b>Effects found:</b> {html.escape(_named(r))} — {html.escape(r.message)}</p>"
        f"<pre>{html.escape(chr(10).join(lines))}</pre>{body}</body></html>"
    )
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(doc, encoding="utf-8")


def _clean(obj):
    if isinstance(obj, float):
        return obj if math.isfinite(obj) else None
    if isinstance(obj, dict):
        return {k: _clean(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [_clean(v) for v in obj]
    return obj


def run(args: argparse.Namespace) -> int:
    for flag, v in (("--area", args.area), ("--mass", args.mass)):
        if not (math.isfinite(v) and v > 0):
            raise UsageError(f"{flag} {v}: must be a finite number > 0")
    if args.threads < 1:
        raise UsageError(f"--threads {args.threads}: at least one fitting worker is needed")
    if args.split_check < 1:
        raise UsageError(f"--split-check {args.split_check}: at least one draw of the held-out blocks is needed")
    if not (math.isfinite(args.stick_band) and args.stick_band >= 0):
        raise UsageError(f"--stick-band {args.stick_band}: must be a finite number >= 0 (noise standard deviations)")
    data = read_valve_csv(args.data)
    sig = read_valve_csv(args.signature) if args.signature is not None else None
    cfg = ReconcileConfig(sa=args.area, m=args.mass, threads=args.threads, stick_band=args.stick_band,
                          global_search=args.global_search, split_check=args.split_check)
    n = data.t.size + (sig.t.size if sig is not None else 0)
    # a spinner on a terminal (nothing when piped): a 60 s record at 1 ms takes a minute or two on 2
    # cores; it says which stage the search is in and how long it has run
    head = f"reconciling {args.data.name}: {n} samples (a minute or two per 60 000)"
    t0 = time.monotonic()
    with Console(stderr=True).status(head) as status:
        r = reconcile(data, sig, cfg, progress=lambda stage: status.update(
            f"{args.data.name}, {time.monotonic() - t0:.0f} s: {stage}"))
    lines = _lines(r)
    print("\n".join(lines))
    if args.json is not None:
        args.json.parent.mkdir(parents=True, exist_ok=True)
        args.json.write_text(json.dumps(_clean(r.as_dict()), indent=2, allow_nan=False) + "\n", encoding="utf-8")
    if args.report is not None:
        _report(args.report, r, lines)
    return 0
