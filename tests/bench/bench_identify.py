"""Cost of the Karnopp valve identification (issue 7) on a 60 s record at 1 ms (60 000 samples).

Compares, in the same run and on the same data, the one-pass δv sweep (all S = 330 thresholds of
eq. 8 from one binning of |ẋ|) with the plain sweep (330 separate least-squares solves), checks
that both give the same estimates, and times the whole identification and the simulator.
Acceptance (issue 7): the identification of the 60 000-sample record with S = 330 takes < 1 s.

Run: ``.venv/bin/python -m pytest -q -m bench -s tests/bench/bench_identify.py``
"""

import time

import numpy as np
import pytest

from models.identification import ValveData, dv_sweep, dv_sweep_reference, identify, sg_derivatives
from models.karnopp import PRESETS, simulate
from models.valve_tests import bench_record, square

from .conftest import machine_note

REPEATS = 5


def _best(fn, repeats=REPEATS):
    times = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        out = fn()
        times.append(time.perf_counter() - t0)
    return out, float(np.median(times)), float(np.min(times))


@pytest.mark.bench
def test_identification_of_60000_samples_under_1s():
    p = PRESETS["low"]
    exc = square(periods=60.0 / 10.4)
    assert exc.t.size == 60000
    rec = bench_record(p, exc, seed=11)
    sig = bench_record(p, "triangle", seed=12)
    data = ValveData(rec.t, rec.p, rec.x, "square60")
    signature = ValveData(sig.t, sig.p, sig.x, "triangle")

    d = sg_derivatives(rec.x, 1e-3)
    phi = np.column_stack([np.sign(d.xd), d.xd, rec.x + p.bias])
    target = p.sa * rec.p - p.m * d.xdd
    speed = np.abs(d.xd)
    fast, t_fast, _ = _best(lambda: dv_sweep(target, phi, speed, S=330, Z=350))
    ref, t_ref, _ = _best(lambda: dv_sweep_reference(target, phi, speed, S=330, Z=350), repeats=2)
    ok = np.isfinite(ref.sigma)
    np.testing.assert_allclose(fast.theta[ok], ref.theta[ok], rtol=1e-6)
    np.testing.assert_allclose(fast.sigma[ok], ref.sigma[ok], rtol=1e-6)

    ident, t_id, t_id_min = _best(lambda: identify(data, None, sa=p.sa))
    ident_sig, t_id_sig, _ = _best(lambda: identify(data, signature, sa=p.sa))
    _, t_sim, _ = _best(lambda: simulate(p, exc.p_cmd, exc.dt), repeats=3)

    print()
    print(f"machine: {machine_note()}")
    print(f"δv sweep, 60 000 samples, S = 330: one pass {t_fast * 1e3:.1f} ms, "
          f"330 separate solves {t_ref * 1e3:.0f} ms ({t_ref / t_fast:.0f}x)")
    print(f"identify(60 000-sample square record): median {t_id * 1e3:.0f} ms (min {t_id_min * 1e3:.0f} ms)")
    print(f"identify(same + 90 000-sample signature): median {t_id_sig * 1e3:.0f} ms")
    print(f"simulate 60 000 steps: {t_sim * 1e3:.0f} ms")
    m1 = ident_sig.model1
    print(f"model 1 errors: k {m1.k / p.k - 1:+.4%}, Fc {m1.fc / p.fc - 1:+.2%}, Fs {m1.fs / p.fs - 1:+.2%}, "
          f"Fv {m1.fv / p.fv - 1:+.1%}, bias {(m1.bias - p.bias) * 1e3:+.4f} mm")
    assert t_id < 1.0 and t_id_sig < 1.0
    assert t_fast < t_ref
    assert m1.k == pytest.approx(p.k, rel=0.01)


@pytest.mark.bench
def test_accuracy_table_over_seeds():
    """The accuracy table of ACCURACY.md (issue 7): 5 seeds per valve, default noise
    (10 µm, 200 Pa); errors of each parameter set against the planted valve and the validation
    RMSE ratio against the true valve driven by the same noisy pressure."""
    from models.identification import ParameterSet, validate

    cases = {
        "low": PRESETS["low"],
        "high": PRESETS["high"],
        "low, Fs=1.3Fc": PRESETS["low"].replace(fs=1.3 * PRESETS["low"].fc),
        "high, Fs=1.3Fc": PRESETS["high"].replace(fs=1.3 * PRESETS["high"].fc),
    }
    print()
    print(f"machine: {machine_note()}")
    print("| valve | set | k err | Fc err | Fs err | Fv err | bias err (mm) | RMSE ratio sine | RMSE ratio ISA |")
    print("|---|---|---|---|---|---|---|---|---|")
    worst = 0.0
    for name, p in cases.items():
        acc: dict[str, list] = {}
        truth = ParameterSet("truth", p.m, p.k, p.fc, p.fs, p.fv, p.bias, p.dv)
        for seed in range(5):
            rec = bench_record(p, "square", seed=seed)
            sig = bench_record(p, "triangle", seed=seed + 1000)
            r = identify(ValveData(rec.t, rec.p, rec.x), ValveData(sig.t, sig.p, sig.x), sa=p.sa)
            vals = {}
            for t in ("sine", "isa-steps"):
                v = bench_record(p, t, seed=seed + 2000)
                vals[t] = ValveData(v.t, v.p, v.x, t)
            ref = {t: validate(truth, v, p.sa).rmse for t, v in vals.items()}
            for ps in (r.model1, r.model1_literal, r.model2):
                row = [ps.k / p.k - 1, ps.fc / p.fc - 1, ps.fs / p.fs - 1, ps.fv / p.fv - 1, (ps.bias - p.bias) * 1e3]
                row += [validate(ps, vals[t], p.sa).rmse / ref[t] for t in ("sine", "isa-steps")]
                acc.setdefault(ps.name, []).append(row)
        for set_name, rows in acc.items():
            a = np.array(rows)
            lo, hi = a.min(0), a.max(0)
            pc = [f"{lo[i]:+.2%} … {hi[i]:+.2%}" for i in range(4)]
            print(f"| {name} | {set_name} | {' | '.join(pc)} | {lo[4]:+.3f} … {hi[4]:+.3f} | "
                  f"{lo[5]:.2f} … {hi[5]:.2f} | {lo[6]:.2f} … {hi[6]:.2f} |")
        worst = max(worst, float(np.max(np.array(acc["model 1 (robust)"])[:, 5:])))
    assert worst <= 1.5
