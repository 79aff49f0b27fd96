"""Cost of the rerun dashboard (issue 6).

1. **Logging a window** (1024 samples of OP, PV, SP) to an ``.rrd`` file: one ``send_columns``
   call per signal vs. the per-sample baseline (``set_time`` + ``log(Scalars)`` per sample and
   signal), same run, same windows; the time includes flushing the recording to disk.
2. **The plant view at 10,000 loops**: windows of ``LOOPWATCH_BENCH_RERUN_LOOPS`` loops (default
   10,000; the paper's closed loops in turn, 1/3 sticking, each raising an alert on its 2nd
   window) fed through :class:`~adapters.rerun_dashboard.RerunDashboard` as fast as it takes them,
   with the default throttles (draw 50 windows/s, explain 2 windows/s, overview every 2 s) and
   unthrottled variants.  Figure of merit: windows/s the sink sustains (wall time including the
   final flush) against the monitor's 38.5 windows/s at 10,000 loops (BENCHMARKS.md, issue 4).
   Analysis is not part of the cost: the windows are analysed once, before the clock starts.

Run: ``.venv/bin/python -m pytest -q -m bench -s tests/bench/bench_rerun.py``
"""

from __future__ import annotations

import dataclasses
import os
import time

import numpy as np
import pytest

from adapters.rerun_dashboard import RerunDashboard
from models.loop import scenario_for_case, simulate_loop
from service.monitor import Alert, AnalysisConfig, WindowSamples, analyze_window

from .conftest import machine_note

pytestmark = pytest.mark.bench

W = 1024
HOP = 256
T0 = 1_750_000_000.0
MIX = ("stiction-datadriven", "tuning", "disturbance", "healthy", "stiction-lugre", "deadband")
MONITOR_RATE = 23_125 / 600.0      # windows/s of 10,000 loops in the issue-4 benchmark


def _base_windows():
    """Two consecutive windows per case, analysed once (not timed)."""
    out = {}
    for case in MIX:
        sim = simulate_loop(scenario_for_case(case, duration_s=2000.0), seed=0)
        ws = []
        for seq in range(2):
            s = 500 + seq * HOP
            w = WindowSamples("x", seq, s, T0 + np.arange(s, s + W, dtype=float), 1.0,
                              {k: getattr(sim, k)[s:s + W].copy() for k in ("sp", "op", "pv")}, AnalysisConfig())
            ws.append((w, analyze_window(w)))
        out[case] = ws
    return out


def _rec(path):
    import rerun as rr

    rec = rr.RecordingStream("loopwatch-bench")
    rec.save(path)
    return rec


def _median_time(fn, repeats=3):
    ts = []
    for _ in range(repeats):
        t = time.perf_counter()
        fn()
        ts.append(time.perf_counter() - t)
    return float(np.median(ts))


def test_window_logging_send_columns_vs_per_sample(tmp_path):
    import rerun as rr

    base = _base_windows()["stiction-datadriven"][0][0]
    n_cols, n_rows = 200, 5

    def columns():
        rec = _rec(tmp_path / "cols.rrd")
        for i in range(n_cols):
            t = base.t + i * W
            for sig in ("op", "pv", "sp"):
                rec.send_columns(f"loops/L{i % 50}/signals/{sig}", indexes=[rr.TimeColumn("time", timestamp=t)],
                                 columns=rr.Scalars.columns(scalars=base.signals[sig]))
        rec.flush()
        rec.disconnect()

    def rows():
        rec = _rec(tmp_path / "rows.rrd")
        for i in range(n_rows):
            t = base.t + i * W
            for k in range(W):
                rec.set_time("time", timestamp=t[k])
                for sig in ("op", "pv", "sp"):
                    rec.log(f"loops/L{i}/signals/{sig}", rr.Scalars(base.signals[sig][k]))
        rec.flush()
        rec.disconnect()

    per_col = _median_time(columns) / n_cols
    per_row = _median_time(rows) / n_rows
    print(f"\n[bench_rerun] {machine_note()}")
    print(f"log one window ({W} samples x OP, PV, SP) to an .rrd, incl. flush; median of 3 runs:")
    print(f"  send_columns, one call per signal : {per_col * 1e3:8.3f} ms/window  ({3 * W / per_col / 1e6:.2f} M scalars/s)")
    print(f"  per-sample set_time + log         : {per_row * 1e3:8.3f} ms/window  ({3 * W / per_row / 1e3:.1f} k scalars/s)")
    print(f"  ratio per-sample / send_columns   : {per_row / per_col:.0f}x")
    assert per_row / per_col > 10


def _stream(n_loops: int, windows_per_loop: int, base):
    """(loop_id, window, result, alert) for every loop, window by window (round robin), as the
    monitor would hand them over; loops of a sticking case raise an alert on their 2nd window."""
    items = []
    for seq in range(windows_per_loop):
        for i in range(n_loops):
            case = MIX[i % len(MIX)]
            w0, r = base[case][min(seq, 1)]
            loop_id = f"area{i // 100}/L{i:05d}"
            w = dataclasses.replace(w0, loop_id=loop_id, seq=seq, t=w0.t + seq * HOP)
            alert = None
            if case.startswith("stiction") and seq == 1:
                d = r.diagnosis
                alert = Alert(loop_id, "raised", d.verdict, d.tdnl, d.dnl, 0.1, r.period_s, r.amplitude, "pv",
                              w.start_t, w.end_t, seq, 2, "2 consecutive non-linear windows")
            items.append((loop_id, w, r, alert))
    return items


def _run_sink(path, items, **kw):
    rec = _rec(path)
    sink = RerunDashboard(rec, **kw)
    t = time.perf_counter()
    for loop_id, w, r, a in items:
        sink.on_window(loop_id, w, r, a)
    t_feed = time.perf_counter() - t
    sink.close()
    total = time.perf_counter() - t
    return total, t_feed, sink.status(), os.path.getsize(path)


def test_plant_view_keeps_up_with_10000_loops(tmp_path):
    n = int(os.environ.get("LOOPWATCH_BENCH_RERUN_LOOPS", "10000"))
    base = _base_windows()
    items = _stream(n, 2, base)
    variants = [
        ("default throttle (draw 50/s, explain 2/s)", {}, items),
        ("draw every window, explain 2/s", {"draw_per_s": 1e9, "draw_burst": 1e9}, items),
        ("draw nothing (DNL rows + overview only)", {"draw_per_s": 0.0, "draw_burst": 1, "explain_per_s": 0.0,
                                                    "explain_burst": 1}, items),
        ("draw and explain every window (first 300)", {"draw_per_s": 1e9, "draw_burst": 1e9, "explain_per_s": 1e9,
                                                       "explain_burst": 1e9}, items[:300]),
    ]
    print(f"\n[bench_rerun] {machine_note()}")
    print(f"plant view: {n} loops x 2 windows of {W} samples (1/3 sticking: {sum(a is not None for *_, a in items)} "
          f"alerts); monitor rate to keep up with: {MONITOR_RATE:.1f} windows/s")
    print(f"{'variant':48s} {'windows':>8s} {'drawn':>7s} {'explained':>9s} {'s total':>8s} {'windows/s':>10s} "
          f"{'ms/window':>9s} {'x monitor':>9s} {'MB':>7s}")
    rates = {}
    for name, kw, its in variants:
        total, _, st, size = _run_sink(tmp_path / "plant.rrd", its, **kw)
        rate = len(its) / total
        rates[name] = rate
        print(f"{name:48s} {len(its):8d} {st.get('drawn', 0):7d} {st.get('explained', 0):9d} {total:8.2f} "
              f"{rate:10.0f} {1e3 / rate:9.3f} {rate / MONITOR_RATE:9.1f} {size / 1e6:7.1f}")
    assert rates["default throttle (draw 50/s, explain 2/s)"] > MONITOR_RATE
