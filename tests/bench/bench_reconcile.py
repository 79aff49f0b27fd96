"""Cost of ``reconcile`` (issue 8) on a 60 s record at 1 ms (60 000 samples).

Acceptance (issue 8): one reconcile run on a 60 s record at 1 ms finishes in under 60 s; asserted
on the wall time with the default two fitting workers (``ReconcileConfig.threads``: worker
processes since session 9, threads in session 8; before, one thread, and the process CPU time was
asserted).  The CPU time of the process and its workers is printed beside it; on the shared
2-core machine other engineers' jobs inflate the wall time, so the assertion holds only on a
quiet machine.  Also printed, not asserted: a 60 s version of the slowest unseen record known
(independent draw 23, record 12 of ``accuracy_reconcile.py``: PRBS, hidden dead time 115 ms;
the 40 s original took 65–90 s in session 8), of unseen draw 127, record 26 (ramps, Stribeck +
lag: the slowest since the Stribeck search of session 24) and of unseen draw 159, record 4 (PRBS,
Stribeck: the slowest known since session 35).  Also
prints :func:`core_probe` (the simulator alone and beside a copy of itself on the other core: how
fast the machine is today, as the 60 s line sees it).  Also
times, in the same run, the compiled simulator against the pure-Python one of issue 7
(:func:`models.karnopp.simulate`) on the same record: the fits run the simulator hundreds of times.

Run: ``.venv/bin/python -m pytest -q -m bench -s tests/bench/bench_reconcile.py``; the 60 s
version of any unseen record, one at a time: ``.venv/bin/python -m tests.bench.bench_reconcile
DRAW:I ...`` (``I`` from 0; ``DRAW:all`` and ``DRAW:pairs`` too, as in ``accuracy_reconcile.select``;
:func:`main`).
"""

import multiprocessing
import os
import time

import numpy as np
import pytest

from models.identification import ValveData
from models.karnopp import PRESETS, simulate
from models.reconcile import ReconcileConfig, reconcile
from models.valve_effects import EffectValve, hidden_record, simulate_effects
from models.valve_tests import isa_steps, square

from .accuracy_reconcile import indep_cases, make_record, select
from .conftest import machine_note


def _probe_loop(valve: EffectValve, pc: np.ndarray, reps: int, barrier, out) -> None:
    barrier.wait()  # both copies start together
    t0 = time.perf_counter()
    for _ in range(reps):
        simulate_effects(valve, pc, 1e-3)
    out.put((time.perf_counter() - t0) / reps)


def core_probe(reps: int = 1000, rounds: int = 3) -> tuple[float, float]:
    """Seconds per compiled 60 000-step simulation (the low preset with a Stribeck curve on the
    square test), (run alone, run with a copy of itself on the other core at the same time): the
    medians of ``rounds`` alternations of the two (one core alone may run at a higher clock, or
    share its host with other work at that moment: single figures of either vary by a third).

    The search spends most of its time in this simulator on both cores at once, so the second
    figure is what its run time scales with.  On the shared 2-core machine the two differ from day
    to day: 159 #4 at 60 s made the same 1018 fits in 53.5-57 s (94 s CPU) in session 37 and in
    62-71 s (108-122 s CPU) in sessions 39-40 (BENCHMARKS.md, issue 8, session 40).  Printed beside
    the 60 s runs with the number of fits, it tells a slow machine from a search that does more work."""
    valve = EffectValve.from_karnopp(PRESETS["low"]).replace(fs=1.4 * PRESETS["low"].fc, vs=3e-3)
    pc = square(periods=60.0 / 10.4).p_cmd
    simulate_effects(valve, pc, 1e-3)  # compile (or load the cache) before forking
    ctx = multiprocessing.get_context("fork")
    times: dict[int, list[float]] = {1: [], 2: []}
    for _ in range(rounds):
        for copies in (1, 2):
            barrier, out = ctx.Barrier(copies), ctx.Queue()
            procs = [ctx.Process(target=_probe_loop, args=(valve, pc, reps, barrier, out)) for _ in range(copies)]
            for p in procs:
                p.start()
            got = [out.get() for _ in procs]
            for p in procs:
                p.join()
            times[copies].append(max(got))
    return float(np.median(times[1])), float(np.median(times[2]))


def _probe_line() -> str:
    alone, both = core_probe()
    return (f"core probe: one compiled 60 000-step Stribeck simulation {alone * 1e3:.2f} ms alone, {both * 1e3:.2f} ms "
            f"with a copy on the other core ({both / alone:.2f} x)")


def _cpu() -> float:
    t = os.times()  # the worker processes count once they have ended (reconcile ends them)
    return t.user + t.system + t.children_user + t.children_system


@pytest.mark.bench
# six 60 s records: about 260 s on the AMD EPYC of sessions 37-44, over 300 s (the suite's
# timeout) on the slower Intel Xeon of session 45, which then reported nothing
@pytest.mark.timeout(1800)
def test_reconcile_60s_record_under_60s():
    cases = {
        "square, V/P lag, hidden actuator_lag 0.2 s": (PRESETS["low"], square(periods=60.0 / 10.4), {"actuator_lag": (0.2,)}),
        "ISA steps, raw command, hidden dead_time 0.03 s + deadband 0.5 mm": (
            PRESETS["high"].replace(tau_p=0.0), isa_steps(hold=60.0 / 19), {"dead_time": (0.03,), "deadband": (0.5e-3,)}),
        "square, V/P lag, clean": (PRESETS["low"], square(periods=60.0 / 10.4), {}),
    }
    print()
    print(f"machine: {machine_note()}")
    print(_probe_line())
    worst = 0.0
    for name, (params, exc, hidden) in cases.items():
        assert abs(exc.t.size - 60000) <= 10
        rec = hidden_record(params, exc, hidden, seed=7)
        t0, c0 = time.perf_counter(), _cpu()
        r = reconcile(ValveData(rec.t, rec.p, rec.x, "bench"))
        dt, cpu = time.perf_counter() - t0, _cpu() - c0
        worst = max(worst, dt)
        print(f"{name}: {exc.t.size} samples, reconcile {dt:.1f} s wall, {cpu:.1f} s CPU, effects {r.effects}, "
              f"RMSE {r.baseline.rmse * 1e6:.1f} -> {r.final.rmse * 1e6:.1f} µm (noise {r.noise_floor * 1e6:.1f})")
    # printed, not asserted (see the module docstring): unseen draw 23 record 12 (PRBS, hidden dead
    # time), unseen draw 127, record 26 (ramps, hidden Stribeck + lag), where a slip jump passes and
    # the search runs in both folds, and the slowest known since session 35: unseen draw 159, record 4
    # (PRBS, hidden Stribeck; 53.5-57.0 s, BENCHMARKS.md issue 8 session 37)
    for draw, idx in ((23, 11), (127, 25), (159, 3)):
        case = indep_cases(draw)[idx]
        t, p, x, sa = make_record(case, 60.0)
        t0, c0 = time.perf_counter(), _cpu()
        r = reconcile(ValveData(t, p, x, "bench"), config=ReconcileConfig(sa=sa))
        dt, cpu = time.perf_counter() - t0, _cpu() - c0
        hidden = ", ".join(f"{e} " + "/".join(f"{v:.3g}" for v in vs) for e, vs in case["hidden"].items())
        print(f"unseen draw {draw} record {idx + 1} at 60 s ({case['exc']}, hidden {hidden}): {t.size} samples, reconcile "
              f"{dt:.1f} s wall ({'under' if dt < 60 else 'OVER'} 60 s, not asserted), {cpu:.1f} s CPU, effects "
              f"{r.effects}, RMSE {r.baseline.rmse * 1e6:.1f} -> {r.final.rmse * 1e6:.1f} µm")
    p = PRESETS["low"].replace(tau_p=0.0)
    pc = square(periods=60.0 / 10.4).p_cmd
    ev = EffectValve.from_karnopp(p)
    simulate_effects(ev, pc, 1e-3)  # compile
    ts = []
    for _ in range(5):
        t0 = time.perf_counter()
        simulate_effects(ev, pc, 1e-3)
        ts.append(time.perf_counter() - t0)
    tp = []
    for _ in range(3):
        t0 = time.perf_counter()
        simulate(p, pc, 1e-3)
        tp.append(time.perf_counter() - t0)
    print(f"simulate 60 000 steps: compiled {np.median(ts) * 1e3:.1f} ms, pure Python (issue 7) "
          f"{np.median(tp) * 1e3:.0f} ms ({np.median(tp) / np.median(ts):.0f}x)")
    assert worst < 60.0


@pytest.mark.bench
def test_split_check_cost():
    """``--split-check 3`` against the default single draw on the same 60 s record, same run: the
    check runs the whole search once per draw, so about three times the wall time is expected."""
    rec = hidden_record(PRESETS["low"], square(periods=60.0 / 10.4), {"actuator_lag": (0.2,)}, seed=7)
    data = ValveData(rec.t, rec.p, rec.x, "bench")
    print()
    print(f"machine: {machine_note()}")
    walls = {}
    for n in (1, 3):
        t0 = time.perf_counter()
        r = reconcile(data, config=ReconcileConfig(split_check=n))
        walls[n] = time.perf_counter() - t0
        print(f"split_check {n}: {walls[n]:.1f} s wall, effects {r.effects}, named {r.split_named or '-'}")
    print(f"ratio 3 draws / 1 draw: {walls[3] / walls[1]:.2f}")
    assert r.split_draws == 3


def main(argv: list[str] | None = None) -> None:
    """``python -m tests.bench.bench_reconcile DRAW:I ...``: the 60 s version of each unseen record
    (same valve, hidden effects, noise and seed; a 60 s excitation) reconciled alone, one after
    the other: wall and CPU time, the fits made (:func:`models.reconcile._fit_once`, in the calling
    process and the workers: the search's work, whatever the machine's speed), the calls to the Stribeck search (:func:`models.reconcile._stribeck_search`;
    a second search's repeats of the first's are taken from its memo) and the time in them, whether the second search ran (``ReconcileConfig.retry_pairs``), the effects named."""
    import sys

    from models import reconcile as rc

    search, calls = rc._stribeck_search, []

    def counted(*a, **kw):
        t0 = time.perf_counter()
        try:
            return search(*a, **kw)
        finally:
            calls.append(time.perf_counter() - t0)

    rc._stribeck_search = counted
    fits, fit_once = multiprocessing.get_context("fork").Value("l", 0), rc._fit_once

    def fit_counted(*a, **kw):  # the workers are forked after this: they count in the shared value
        with fits.get_lock():
            fits.value += 1
        return fit_once(*a, **kw)

    rc._fit_once = fit_counted
    print(f"machine: {machine_note()}")
    print(_probe_line(), flush=True)
    for tag, case in (tc for spec in (sys.argv[1:] if argv is None else argv) for tc in select(spec)):
        draw, _, idx = tag.partition(":")
        t, p, x, sa = make_record(case, 60.0)
        calls.clear()
        fits.value = 0
        t0, c0 = time.perf_counter(), _cpu()
        r = reconcile(ValveData(t, p, x, "bench"), config=ReconcileConfig(sa=sa))
        dt, cpu = time.perf_counter() - t0, _cpu() - c0
        print(f"{tag} ({draw} #{int(idx) + 1}, {case['exc']}, hidden {'+'.join(case['hidden']) or 'none'}): {t.size} "
              f"samples, {dt:.1f} s wall ({'under' if dt < 60 else 'OVER'} 60 s), {cpu:.1f} s CPU, {fits.value} fits, {len(calls)} Stribeck "
              f"searches ({sum(calls):.1f} s), second search {r.second_search or 'not run'}, swapped search {r.swap_search or 'not run'}, effects {r.effects}", flush=True)


if __name__ == "__main__":
    main()
