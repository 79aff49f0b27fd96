"""Cost of the whole chain (gate → EMD → pruning → IF → DNL/TDNL) per 4096-sample window.

Compares, in the same run and on the same windows, the bounded chain (PyEMD's algorithm with a
fixed sifting budget and an IMF cap, its sifts compiled with numba: pipeline/emd.py) with the same chain on PyEMD's default settings (adaptive stop
rule, no IMF cap).  The set holds sine, square and triangular waves at several periods, with
and without noise, the paper's closed-loop cases, and real OP windows from the ISDB (loops flagged oscillating
that have 4096 samples or more).  Acceptance (issue 2): median <= 10 ms,
max <= 50 ms, and >= 10x faster than the PyEMD-defaults chain.  Wall and CPU time are both
reported (see :func:`time_chain`).  Run it alone: it measures the machine as much as the code.
"""

import dataclasses
import os
import time

import numpy as np
import pytest
from scipy import signal

from models.loop import CASES, SetpointStep, simulate_loop
from pipeline.diagnosis import DiagnosisConfig, diagnose_window
from pipeline.emd import EMDConfig

from adapters.loop_csv import read_loop_csv
from tests.conftest import SHARED_DATA

from .conftest import machine_note

N = 4096
REPEATS = 5


def waves(n: int = N):
    """``(name, x)`` of unit sines, squares and triangles of periods 25, 60 and 150 samples."""
    t = np.arange(n, dtype=float)
    for period in (25.0, 60.0, 150.0):
        w = 2 * np.pi * t / period
        for shape, x in (("sine", np.sin(w)), ("square", signal.square(w)), ("triangle", signal.sawtooth(w, 0.5))):
            yield f"{shape} P={period:g}", x


def window_set() -> dict[str, np.ndarray]:
    rng = np.random.default_rng(0)
    out = {}
    for name, x in waves():
        out[name] = x
        out[f"{name} +1% noise"] = x + 0.01 * rng.standard_normal(N)
    for name in ("tuning", "disturbance", "stiction-datadriven", "stiction-lugre"):
        sc = dataclasses.replace(CASES[name], setpoint_steps=(SetpointStep(1.0, 5.0),), duration_s=float(N))
        out[f"loop {name}"] = simulate_loop(sc, seed=0).pv
    out.update(real_windows())
    return out


def real_windows() -> dict[str, np.ndarray]:
    """The first 4096 OP samples of every ISDB loop flagged oscillating that is long enough."""
    labels = SHARED_DATA / "isdb" / "labels.csv"
    if not labels.exists():
        return {}
    flagged = {line.split(",")[0] for line in labels.read_text().splitlines() if ",oscillating," in line}
    out = {}
    for loop in sorted(flagged):
        data = read_loop_csv(SHARED_DATA / "isdb" / f"{loop}.csv")
        op = data.op[:N]
        if op.size == N and np.isfinite(op).all():
            out[f"ISDB {loop} op"] = op
    return out


MEASURES = ("wall median", "CPU median", "CPU best")


def time_chain(x: np.ndarray, config: DiagnosisConfig) -> tuple[dict[str, float], str]:
    """Wall time (median) and CPU time of the process (``time.process_time``; median and best)
    over REPEATS runs of the chain on one window.

    On a shared machine the wall time includes waiting for a core; the CPU time does not, but it
    still includes slow-downs from sharing caches and hyper-threads with other processes, which
    the best of the runs is least affected by."""
    wall, cpu = [], []
    for _ in range(REPEATS):
        t0, c0 = time.perf_counter(), time.process_time()
        d = diagnose_window(x, fs=1.0, config=config)
        wall.append(time.perf_counter() - t0)
        cpu.append(time.process_time() - c0)
    return dict(zip(MEASURES, (float(np.median(wall)), float(np.median(cpu)), float(np.min(cpu))))), d.verdict


@pytest.mark.bench
def test_chain_cost_per_4096_window():
    bounded = DiagnosisConfig(method="paper")
    defaults = DiagnosisConfig(method="paper", emd=EMDConfig(sifts=0, max_imfs=-1))
    windows = window_set()
    # the first analysis of a process loads (or compiles) the numba sift kernel: timed apart
    t0 = time.perf_counter()
    diagnose_window(next(iter(windows.values())), fs=1.0, config=bounded)
    first_call = time.perf_counter() - t0
    rows = []
    for name, x in windows.items():
        tb, vb = time_chain(x, bounded)
        td, vd = time_chain(x, defaults)
        rows.append((name, tb, td, vb, vd))
    # the acceptance is on oscillating windows: the gate keeps the others away from EMD
    osc = [r for r in rows if r[3] != "not_oscillating"]
    print(f"\n[bench_pipeline] {machine_note()}, load average {' '.join(f'{v:.1f}' for v in os.getloadavg())}")
    print(f"first bounded analysis of the process (numba kernel loaded from cache or compiled): {1e3 * first_call:.0f} ms")
    print("ms per window, bounded / PyEMD defaults (ratio):")
    print(f"{'window (4096 samples)':30s}" + "".join(f" {m:>24s}" for m in MEASURES) + "  verdicts")
    for name, tb, td, vb, vd in rows:
        cells = "".join(f" {1e3 * tb[m]:7.2f} / {1e3 * td[m]:7.1f} ({td[m] / tb[m]:4.1f})" for m in MEASURES)
        print(f"{name:30s}{cells}  {vb} / {vd}")
    print(f"statistics over the {len(osc)} windows the gate passes ({len(rows) - len(osc)} rejected, not counted)")
    for m in MEASURES:
        tb = np.array([r[1][m] for r in osc])
        td = np.array([r[2][m] for r in osc])
        print(f"{m:11s}: bounded median {1e3 * np.median(tb):.2f} ms, max {1e3 * tb.max():.2f} ms;"
              f" defaults median {1e3 * np.median(td):.1f} ms, max {1e3 * td.max():.1f} ms;"
              f" ratio of medians {np.median(td) / np.median(tb):.1f}x, median of ratios {np.median(td / tb):.1f}x")
    assert max(r[1]["CPU median"] for r in osc) < 0.5  # sanity; the acceptance figures are reported, see BENCHMARKS.md
