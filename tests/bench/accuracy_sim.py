"""Randomised simulated benchmark of the diagnosis (issue 3): robust (default) vs paper method.

Seeded.  Each loop: a random FOPDT plant (gain 0.5–3, time constant 3–60 s, dead time
0.1–1 x the time constant, at least 1 s; 1 s sampling), a PI controller, 4096 s recorded,
one window over the whole record.  Causes (planted truth):

* linear: aggressive tuning (the loop's gain margin set to 1.02–1.10, noise-excited), one or
  two external sinusoidal disturbances (period 20–400 s, amplitude 1–5, on the plant output)
  with a well-tuned PI, or tuning and a disturbance together;
* nonlinear: valve stiction by the two-parameter model (S 2–10 %, J 0.2–1 x S), by the
  LuGre valve (stick band 3–10 %) or by a Karnopp valve (the low- or high-friction valve of
  Romano & Garcia, F_s = 1–1.5 F_c, quasi-static at loop time scales:
  :class:`models.valves.KarnoppLoopValve`), with the well-tuned PI.  A stiction loop counts
  as an oscillation cause only when the valve limit-cycles: its parameters are drawn again
  (up to 30 times) until the simulated stem (with the loop's noise) reverses at least 16
  times (8 cycles) over the last three quarters of the record; a valve that sticks once and
  stays put gives no oscillation to diagnose;
* not oscillating: well-tuned loops with set-point steps and load noise, with or without a
  backlash valve (backlash alone does not limit-cycle with a self-regulating plant and PI; see
  models/loop.py).

Well tuned = SIMC (Skogestad 2003) with tau_c = theta.  Noise: white measurement noise and
white load noise (at the plant input), standard deviations 0, 1, 2.5 or 5 % of the noise-free
PV's and OP's oscillation amplitudes (healthy loops: of their spread).  Every loop is
diagnosed by both methods on the same record, given PV, SP and OP as the monitor gets them.

Run: ``.venv/bin/python -m pytest -q -m bench -s tests/bench/accuracy_sim.py``
(``LOOPWATCH_SIM_LOOPS`` sets the number of loops, default 360; ``LOOPWATCH_SIM_SEEDS`` the
comma-separated seeds, default ``2026,7``: 2026 was used while developing the robust method,
7 was not).
"""

from __future__ import annotations

import os
import time
from collections import Counter, defaultdict
from dataclasses import replace

import numpy as np
import pytest

from models.loop import FOPDT, LoopScenario, PIController, SetpointStep, Sinusoid, gain_margin, simulate_loop
from models.karnopp import preset
from models.valves import (
    BacklashSpec,
    ChoudhuryStictionSpec,
    KarnoppLoopSpec,
    LuGreParams,
    LuGreSpec,
    lugre_force_gain_for_stick_band,
)
from pipeline.diagnosis import DiagnosisConfig, diagnose_window

from .conftest import machine_note

DURATION = 4096.0
CAUSES = {  # cause: truth class
    "tuning": "linear",
    "disturbance": "linear",
    "two disturbances": "linear",
    "tuning+disturbance": "linear",
    "stiction (two-parameter)": "nonlinear",
    "stiction (LuGre)": "nonlinear",
    "stiction (Karnopp)": "nonlinear",
    "healthy": "not_oscillating",
    "backlash": "not_oscillating",
}
NOISE = (0.0, 0.01, 0.025, 0.05)


def simc(plant: FOPDT) -> PIController:
    """SIMC PI tuning (Skogestad 2003) with tau_c = theta: Kc = tau / (K 2 theta), Ti = min(tau, 8 theta)."""
    kc = plant.tau_s / (plant.gain * 2.0 * plant.dead_time_s)
    ti = min(plant.tau_s, 8.0 * plant.dead_time_s)
    return PIController(kc, kc / ti)


def random_scenario(cause: str, rng: np.random.Generator) -> LoopScenario:
    tau = float(np.exp(rng.uniform(np.log(3), np.log(60))))
    theta = max(1.0, tau * float(rng.uniform(0.1, 1.0)))
    plant = FOPDT(float(np.exp(rng.uniform(np.log(0.5), np.log(3)))), tau, theta)
    pi = simc(plant)
    steps = (SetpointStep(1.0, float(rng.uniform(1, 5))),)
    kw: dict = dict(plant=plant, controller=pi, setpoint_steps=steps, duration_s=DURATION)

    def sinusoid() -> Sinusoid:
        period = float(np.exp(rng.uniform(np.log(20), np.log(400))))
        return Sinusoid(float(rng.uniform(1, 5)), 2 * np.pi / period, float(rng.uniform(0, 2 * np.pi)))

    if cause in ("tuning", "tuning+disturbance"):
        factor = gain_margin(plant, pi) / float(rng.uniform(1.02, 1.10))
        kw["controller"] = PIController(pi.kc * factor, pi.ki * factor)
        kw["load_noise_std"] = 0.05
    if cause in ("disturbance", "tuning+disturbance"):
        kw["disturbances"] = (sinusoid(),)
    if cause == "two disturbances":
        kw["disturbances"] = (sinusoid(), sinusoid())
    if cause == "stiction (two-parameter)":
        s = float(rng.uniform(2, 10))
        kw["valve"] = ChoudhuryStictionSpec(S=s, J=s * float(rng.uniform(0.2, 1.0)))
    if cause == "stiction (LuGre)":
        kw["valve"] = LuGreSpec(params=LuGreParams(), force_gain=lugre_force_gain_for_stick_band(float(rng.uniform(3, 10))))
    if cause == "stiction (Karnopp)":
        valve = preset(str(rng.choice(["low", "high"])), fs_ratio=float(rng.uniform(1.0, 1.5)))
        kw["valve"] = KarnoppLoopSpec.from_karnopp(valve)
    if cause in ("healthy", "backlash"):
        kw["setpoint_steps"] = steps + (SetpointStep(1500.0, float(rng.uniform(-5, 5))), SetpointStep(3000.0, float(rng.uniform(-5, 5))))
        kw["load_noise_std"] = float(rng.uniform(0.2, 1.0))
    if cause == "backlash":
        kw["valve"] = BacklashSpec(float(rng.uniform(1, 5)))
    return LoopScenario(**kw)


def limit_cycles(mv: np.ndarray) -> float:
    """Cycles of the stem over the last three quarters of a noise-free record: reversals by
    more than a tenth of its 5–95 % range, halved."""
    x = mv[mv.size // 4:]
    lo, hi = np.percentile(x, [5, 95])
    thr = 0.1 * (hi - lo)
    if not thr > 0:
        return 0.0
    reversals, ext, direction = 0, x[0], 0
    for v in x[1:]:
        if direction >= 0 and v > ext or direction < 0 and v < ext:
            ext = v
        elif abs(v - ext) > thr:
            reversals += direction != 0
            direction = 1 if v > ext else -1
            ext = v
    return reversals / 2.0


def make_loop(i: int, seed: int, rng: np.random.Generator):
    """Loop ``i`` of the benchmark: (cause, noise level, scenario, noisy simulation) or None."""
    names = list(CAUSES)
    cause = names[i % len(names)]
    noise = NOISE[(i // len(names)) % len(NOISE)]
    for _ in range(30):
        sc = random_scenario(cause, rng)
        sim = simulate_loop(sc, seed=seed + i)
        if not np.all(np.isfinite(sim.pv)) or np.abs(sim.pv).max() > 1e6:
            return None  # unstable after discretisation: not a usable planted case
        if noise:
            tail = slice(len(sim.pv) // 4, None)
            pv_scale, op_scale = (np.sqrt(2) * np.std(v[tail]) for v in (sim.pv, sim.op))
            sc = replace(sc, measurement_noise_std=float(noise * pv_scale),
                         load_noise_std=float(np.hypot(sc.load_noise_std, noise * op_scale)))
            sim = simulate_loop(sc, seed=seed + i)
        if CAUSES[cause] != "nonlinear" or limit_cycles(sim.mv) >= 8:
            return cause, noise, sc, sim
    return None


def run_benchmark(n_loops: int, seed: int = 2026):
    rng = np.random.default_rng(seed)
    rows = []
    skipped: list[str] = []
    configs = {"robust": DiagnosisConfig(), "paper": DiagnosisConfig(method="paper")}
    for i in range(n_loops):
        loop = make_loop(i, seed, rng)
        if loop is None:
            skipped.append(list(CAUSES)[i % len(CAUSES)])
            continue
        cause, noise, sc, sim = loop
        verdicts = {}
        for m, cfg in configs.items():
            t0 = time.perf_counter()
            d = diagnose_window(sim.pv, fs=1.0, config=cfg, sp=sim.sp, op=sim.op)
            verdicts[m] = (d.verdict, time.perf_counter() - t0)
        rows.append((cause, CAUSES[cause], noise, verdicts))
    if skipped:
        print(f"\n{len(skipped)} loops skipped (unstable, or no stiction limit cycle in 30 draws): {skipped}")
    return rows


def summarise(rows, method: str) -> dict:
    """Confusion matrix and the acceptance figures for one method."""
    conf = Counter((truth, v[method][0]) for _, truth, _, v in rows)
    osc_truth = [r for r in rows if r[1] != "not_oscillating"]

    def recall(truth: str, ok: set[str], subset=rows) -> float:
        sel = [r for r in subset if r[1] == truth]
        return sum(r[3][method][0] in ok for r in sel) / max(1, len(sel))

    rec_nl = recall("nonlinear", {"nonlinear"})
    rec_l = recall("linear", {"linear"})
    osc = {"nonlinear", "linear", "uncertain"}
    rec_osc = sum(r[3][method][0] in osc for r in osc_truth) / max(1, len(osc_truth))
    rec_not = recall("not_oscillating", {"not_oscillating"})
    return {
        "confusion": conf,
        "ba_nl_vs_l": (rec_nl + rec_l) / 2,
        "recall_nonlinear": rec_nl,
        "recall_linear": rec_l,
        "ba_osc": (rec_osc + rec_not) / 2,
        "recall_oscillating": rec_osc,
        "recall_not_oscillating": rec_not,
        "uncertain": sum(r[3][method][0] == "uncertain" for r in rows) / len(rows),
        "p95_ms": 1e3 * float(np.percentile([r[3][method][1] for r in rows], 95)),
    }


def print_report(rows) -> None:
    verdicts = ("nonlinear", "linear", "uncertain", "not_oscillating", "invalid")
    print(f"\n[accuracy_sim] {len(rows)} loops; {machine_note()}")
    for method in ("robust", "paper"):
        s = summarise(rows, method)
        print(f"\n### method: {method}")
        print("| truth \\ verdict | " + " | ".join(verdicts) + " |")
        print("|---" * (len(verdicts) + 1) + "|")
        for truth in ("nonlinear", "linear", "not_oscillating"):
            print(f"| {truth} | " + " | ".join(str(s["confusion"][(truth, v)]) for v in verdicts) + " |")
        print(f"balanced accuracy nonlinear vs linear (truly oscillating loops; uncertain or missed counts as wrong): "
              f"{s['ba_nl_vs_l']:.3f} (recall nonlinear {s['recall_nonlinear']:.3f}, linear {s['recall_linear']:.3f})")
        print(f"balanced accuracy oscillating vs not: {s['ba_osc']:.3f} (recall oscillating {s['recall_oscillating']:.3f}, "
              f"not oscillating {s['recall_not_oscillating']:.3f})")
        print(f"uncertain: {s['uncertain']:.1%} of loops; p95 wall time per 4096-sample window {s['p95_ms']:.0f} ms "
              "(shared machine; see bench_robust.py for the cost)")
        by_cause = defaultdict(Counter)
        by_noise = defaultdict(Counter)
        for cause, truth, noise, v in rows:
            ok = v[method][0] == truth
            by_cause[cause][ok] += 1
            by_noise[noise][ok] += 1
        print("per cause (share with the right verdict): " + ", ".join(
            f"{c} {by_cause[c][True] / sum(by_cause[c].values()):.2f}" for c in CAUSES))
        print("per noise level (share right): " + ", ".join(
            f"{n:.1%} {by_noise[n][True] / sum(by_noise[n].values()):.2f}" for n in NOISE))
        per_noise = {n: summarise([r for r in rows if r[2] == n], method) for n in NOISE}
        print("per noise level (BA nonlinear vs linear / BA oscillating vs not): " + ", ".join(
            f"{n:.1%} {per_noise[n]['ba_nl_vs_l']:.3f} / {per_noise[n]['ba_osc']:.3f}" for n in NOISE))


@pytest.mark.bench
@pytest.mark.timeout(7200)  # long on a shared machine
def test_accuracy_simulated():
    n = int(os.environ.get("LOOPWATCH_SIM_LOOPS", "360"))
    seeds = [int(v) for v in os.environ.get("LOOPWATCH_SIM_SEEDS", "2026,7").split(",")]
    for seed in seeds:
        rows = run_benchmark(n, seed=seed)
        print(f"\n## seed {seed}")
        print_report(rows)
        s = summarise(rows, "robust")
        assert s["ba_nl_vs_l"] > 0.5  # sanity only: the figures are reported in ACCURACY.md


# ------------------------------------------------------------------ hard cases for the gate alone
GATE_CASES = {  # case: truth (oscillating?)
    "short record (2.5-5 periods)": True,
    "irregular (period jitter 5-20 %)": True,
    "fast (period 3-4 samples)": True,
    "regular, coloured noise": True,
    "drifting coloured noise": False,
    "random walk + AR(1)": False,
    "damped resonance (zeta 0.4-1)": False,
    # session 4: the failure modes seen in the ISDB misses, truth from the generator
    "wandering period and amplitude": True,
    "intermittent (on 60-90 % of the record)": True,
    "very short (2-3 periods)": True,
    "spectral bump (zeta 0.2-0.4) in drifting noise": False,
    # session 5: level shifts, bursts, few noisy cycles (the ISDB misses of session 4), truth from the generator
    "on level shifts and excursions": True,
    "burst on 30-60 % of the record": True,
    "few noisy cycles (6-10 periods)": True,
    "level shifts + red noise": False,
    "resonance bursts + level shifts": False,
}


def _ar1(rng: np.random.Generator, n: int, phi: float) -> np.ndarray:
    from scipy.signal import lfilter
    return lfilter([1.0], [1.0, -phi], rng.standard_normal(n + 200))[200:]


def _resonance(rng: np.random.Generator, n: int, zeta: float, burn: int = 0) -> np.ndarray:
    """White noise through a second-order resonance of damping ``zeta`` and period 8 to n/8
    samples (log-uniform); the first ``burn`` samples of the output are dropped."""
    from scipy.signal import lfilter
    w = 2 * np.pi / float(np.exp(rng.uniform(np.log(8), np.log(n / 8))))
    a1, a2 = -2 * np.exp(-zeta * w) * np.cos(w * np.sqrt(max(1 - zeta**2, 0.0))), np.exp(-2 * zeta * w)
    return lfilter([1.0], [1.0, a1, a2], rng.standard_normal(n + burn))[burn:]


def gate_case(case: str, rng: np.random.Generator) -> np.ndarray:
    """One planted window for :data:`GATE_CASES` (record length 200-4096 samples).

    Oscillations: a sine, a triangle (stick-slip OP) or a square wave, amplitude 1, in
    coloured noise (AR(1), phi 0-0.95, standard deviation 0.1-0.5) plus a random slow drift;
    the phase advances by ``2 pi / T`` per sample with the period jittered per cycle.
    Non-oscillating: AR(1) with phi 0.9-0.999 plus a random walk and white noise (a drifting
    process variable), or a second-order resonance driven by white noise with damping 0.4-1.
    """
    n = int(np.exp(rng.uniform(np.log(200), np.log(4096))))
    for table in (_SESSION4_CASES, _SESSION5_CASES):
        if case in table:
            return table[case](rng, n)
    if GATE_CASES[case]:
        jitter = 0.0
        if case.startswith("short"):
            n = int(rng.integers(200, 1000))
            period = n / rng.uniform(2.5, 5.0)
        elif case.startswith("fast"):
            period = rng.uniform(3.0, 4.0)
        else:
            period = float(np.exp(rng.uniform(np.log(5), np.log(n / 8))))
        if case.startswith("irregular"):
            jitter = rng.uniform(0.05, 0.2)
        n_cyc = int(n / period) + 3
        lengths = period * np.clip(1.0 + jitter * rng.standard_normal(n_cyc), 0.5, 1.5)
        s = _cycles(rng, n, lengths, np.ones(n_cyc), start=period)
        noise = rng.uniform(0.1, 0.5) * _ar1(rng, n, rng.uniform(0.0, 0.95))
        noise = noise / max(np.std(noise), 1e-12) * rng.uniform(0.1, 0.5)
        drift = np.cumsum(rng.standard_normal(n)) * rng.uniform(0, 0.02)
        return s + noise + drift
    if case.startswith("damped"):
        return _resonance(rng, n, rng.uniform(0.4, 1.0))
    x = _ar1(rng, n, rng.uniform(0.9, 0.999))
    if case.startswith("random walk"):
        x = x + np.cumsum(rng.standard_normal(n)) * rng.uniform(0.05, 0.5)
    return x + rng.uniform(0, 0.5) * np.std(x) * rng.standard_normal(n)


def _cycles(rng: np.random.Generator, n: int, lengths: np.ndarray, amps: np.ndarray,
            start: float | None = None) -> np.ndarray:
    """A sine, triangle or square wave whose cycle ``k`` lasts ``lengths[k]`` samples and has
    amplitude ``amps[k]`` (amplitude interpolated between cycle centres), random start phase
    (the record starts up to ``start`` samples, default ``lengths[0]``, into the first cycle)."""
    knots = np.r_[0.0, np.cumsum(lengths)]
    t = np.arange(n) + rng.uniform(0, lengths[0] if start is None else start)
    phase = np.interp(t, knots, 2 * np.pi * np.arange(knots.size))
    amp = np.interp(t, knots[:-1] + lengths / 2, amps)
    shape = rng.choice(["sine", "triangle", "square"])
    s = {"sine": np.sin, "triangle": lambda p: 2 / np.pi * np.arcsin(np.sin(p)),
         "square": lambda p: np.sign(np.sin(p))}[str(shape)](phase)
    return amp * s


def _coloured(rng: np.random.Generator, n: int, sd: float) -> np.ndarray:
    """AR(1) noise (phi 0-0.95) of standard deviation ``sd`` plus a random-walk drift."""
    noise = _ar1(rng, n, rng.uniform(0.0, 0.95))
    noise = noise / max(np.std(noise), 1e-12) * sd
    return noise + np.cumsum(rng.standard_normal(n)) * rng.uniform(0, 0.02)


def _wandering(rng: np.random.Generator, n: int) -> np.ndarray:
    """Oscillation whose period wanders slowly (log-period AR(1) over cycles, phi 0.7, sd
    10-25 %, plus 5-10 % independent jitter per cycle) and whose amplitude varies per cycle
    (log-normal, sd 0.2-0.4), with 0-3 level steps of up to 1.5 amplitudes and coloured noise
    (sd 0.1-0.5); mean period 8 samples to n/10 (at least 10 cycles), n 500-4096."""
    n = int(np.exp(rng.uniform(np.log(500), np.log(4096))))
    period = float(np.exp(rng.uniform(np.log(8), np.log(n / 10))))
    m = int(2 * n / period) + 3
    sd, e = rng.uniform(0.1, 0.25), np.zeros(m)
    for k in range(1, m):
        e[k] = 0.7 * e[k - 1] + np.sqrt(1 - 0.49) * sd * rng.standard_normal()
    lengths = period * np.exp(e + rng.uniform(0.05, 0.1) * rng.standard_normal(m))
    amps = np.exp(rng.uniform(0.2, 0.4) * rng.standard_normal(m))
    x = _cycles(rng, n, lengths, amps)
    for _ in range(int(rng.integers(0, 4))):
        x[int(rng.integers(0, n)):] += rng.uniform(-1.5, 1.5)
    return x + _coloured(rng, n, rng.uniform(0.1, 0.5))


def _intermittent(rng: np.random.Generator, n: int) -> np.ndarray:
    """A regular oscillation (5 % jitter) present on 60-90 % of the record, in 1-3 bursts, the
    rest coloured noise only; at least 8 periods in the record."""
    period = float(np.exp(rng.uniform(np.log(5), np.log(n / 12))))
    m = int(n / period) + 3
    x = _cycles(rng, n, period * (1 + 0.05 * rng.standard_normal(m)), np.ones(m))
    off = int((1 - rng.uniform(0.6, 0.9)) * n)
    cuts = np.sort(rng.integers(0, n - off, int(rng.integers(1, 4))))
    pieces = np.diff(np.r_[0, np.sort(rng.uniform(0, 1, cuts.size - 1)), 1] * off).astype(int)
    for c, ln in zip(cuts, pieces):
        x[c:c + ln] = 0.0
    return x + _coloured(rng, n, rng.uniform(0.1, 0.5))


def _very_short(rng: np.random.Generator, n: int) -> np.ndarray:
    """2-3 periods of a regular oscillation in 200-1000 samples, coloured noise sd 0.1-0.3."""
    n = int(rng.integers(200, 1000))
    period = n / rng.uniform(2.0, 3.0)
    return _cycles(rng, n, np.full(5, period), np.ones(5)) + _coloured(rng, n, rng.uniform(0.1, 0.3))


def _bump(rng: np.random.Generator, n: int) -> np.ndarray:
    """Noise through a second-order resonance (zeta 0.2-0.4, period 8 to n/8 samples) on a
    drifting AR(1) (phi 0.9-0.999) with a random walk: a spectral bump, not an oscillation."""
    res = _resonance(rng, n, rng.uniform(0.2, 0.4), burn=500)
    drift = _ar1(rng, n, rng.uniform(0.9, 0.999)) + np.cumsum(rng.standard_normal(n)) * rng.uniform(0.0, 0.2)
    return res / np.std(res) + rng.uniform(0.3, 1.0) * drift / max(np.std(drift), 1e-12)


_SESSION4_CASES = {
    "wandering period and amplitude": _wandering,
    "intermittent (on 60-90 % of the record)": _intermittent,
    "very short (2-3 periods)": _very_short,
    "spectral bump (zeta 0.2-0.4) in drifting noise": _bump,
}


def _shifts(rng: np.random.Generator, n: int, k: int, size: float, unit: float) -> np.ndarray:
    """``k`` level shifts of ``unit`` x U(1, ``size``) (random sign) at random times; about half
    of them excursions that return after n/40 to n/8 samples."""
    x = np.zeros(n)
    for _ in range(k):
        at, h = int(rng.integers(0, n)), rng.choice([-1, 1]) * rng.uniform(1, size) * unit
        end = n if rng.uniform() < 0.5 else min(n, at + int(rng.uniform(n / 40, n / 8)))
        x[at:end] += h
    return x


def _wandering_lengths(rng: np.random.Generator, m: int, period: float) -> np.ndarray:
    """``m`` cycle lengths around ``period``: log-period AR(1) over cycles (phi 0.7, sd 5-15 %)
    plus 3-8 % independent jitter per cycle."""
    sd, e = rng.uniform(0.05, 0.15), np.zeros(m)
    for k in range(1, m):
        e[k] = 0.7 * e[k - 1] + np.sqrt(1 - 0.49) * sd * rng.standard_normal()
    return period * np.exp(e + rng.uniform(0.03, 0.08) * rng.standard_normal(m))


def _on_level_shifts(rng: np.random.Generator, n: int) -> np.ndarray:
    """An oscillation with a wandering period (:func:`_wandering_lengths`, mean period 8 to
    n/10, n 500-4096) riding on 2-6 level shifts or excursions of 1-4 amplitudes, in coloured
    noise (sd 0.1-0.5)."""
    n = int(np.exp(rng.uniform(np.log(500), np.log(4096))))
    period = float(np.exp(rng.uniform(np.log(8), np.log(n / 10))))
    m = int(2 * n / period) + 3
    x = _cycles(rng, n, _wandering_lengths(rng, m, period), np.ones(m))
    return x + _shifts(rng, n, int(rng.integers(2, 7)), 4.0, 1.0) + _coloured(rng, n, rng.uniform(0.1, 0.5))


def _burst(rng: np.random.Generator, n: int) -> np.ndarray:
    """An oscillation with a wandering period (:func:`_wandering_lengths`) in one stretch
    covering 30-60 % of the record (at least 8 cycles in it, n 500-4096), coloured noise
    (sd 0.1-0.5) throughout."""
    n = int(np.exp(rng.uniform(np.log(500), np.log(4096))))
    on = int(rng.uniform(0.3, 0.6) * n)
    period = float(np.exp(rng.uniform(np.log(5), np.log(on / 8))))
    m = int(2 * n / period) + 3
    x = _cycles(rng, n, _wandering_lengths(rng, m, period), np.ones(m))
    start = int(rng.integers(0, n - on + 1))
    x[:start] = 0.0
    x[start + on:] = 0.0
    return x + _coloured(rng, n, rng.uniform(0.1, 0.5))


def _few_noisy(rng: np.random.Generator, n: int) -> np.ndarray:
    """6-10 periods (:func:`_wandering_lengths`) in 200-4096 samples, coloured noise sd 0.3-0.6."""
    period = n / rng.uniform(6.0, 10.0)
    m = int(2 * n / period) + 3
    x = _cycles(rng, n, _wandering_lengths(rng, m, period), np.ones(m))
    return x + _coloured(rng, n, rng.uniform(0.3, 0.6))


def _shifted_red_noise(rng: np.random.Generator, n: int) -> np.ndarray:
    """AR(1) noise (phi 0.5-0.99, sd 1) with 2-8 level shifts or excursions of 1-4 sd, plus white
    noise: a drifting, stepping process variable without an oscillation."""
    x = _ar1(rng, n, rng.uniform(0.5, 0.99))
    x = x / max(np.std(x), 1e-12) + _shifts(rng, n, int(rng.integers(2, 9)), 4.0, 1.0)
    return x + rng.uniform(0, 0.5) * rng.standard_normal(n)


def _resonance_bursts(rng: np.random.Generator, n: int) -> np.ndarray:
    """A damped resonance (zeta 0.2-0.4) whose standard deviation switches between 0.2 and 1 in
    2-4 stretches, on 1-4 level shifts of 1-3 sd and drifting AR(1) noise: non-stationary noise."""
    res = _resonance(rng, n, rng.uniform(0.2, 0.4), burn=500)
    edges = np.sort(rng.integers(0, n, int(rng.integers(1, 4))))
    scale = np.ones(n)
    for k, (a, b) in enumerate(zip(np.r_[0, edges], np.r_[edges, n])):
        scale[a:b] = 1.0 if k % 2 == 0 else 0.2
    x = res / max(np.std(res), 1e-12) * scale
    drift = _ar1(rng, n, rng.uniform(0.9, 0.99))
    return x + _shifts(rng, n, int(rng.integers(1, 5)), 3.0, 1.0) + 0.3 * drift / max(np.std(drift), 1e-12)


_SESSION5_CASES = {
    "on level shifts and excursions": _on_level_shifts,
    "burst on 30-60 % of the record": _burst,
    "few noisy cycles (6-10 periods)": _few_noisy,
    "level shifts + red noise": _shifted_red_noise,
    "resonance bursts + level shifts": _resonance_bursts,
}


def gate_benchmark(n_per_case: int, seed: int, config=None):
    """Share of planted gate cases judged right, per case; and the balanced accuracy."""
    from pipeline.gate import GateConfig, oscillation_gate
    rng = np.random.default_rng(seed)
    right: dict[str, list[bool]] = {}
    for case, truth in GATE_CASES.items():
        right[case] = [oscillation_gate(gate_case(case, rng), fs=1.0, config=config or GateConfig()).oscillating == truth
                       for _ in range(n_per_case)]
    pos = [v for c, t in GATE_CASES.items() if t for v in right[c]]
    neg = [v for c, t in GATE_CASES.items() if not t for v in right[c]]
    return {c: float(np.mean(v)) for c, v in right.items()}, (np.mean(pos) + np.mean(neg)) / 2


def _planted_report(title: str, benchmark, *, env: str, default: int, figure: str) -> None:
    """Run a planted-case benchmark per seed, print the per-case figure and the balanced accuracy."""
    n = int(os.environ.get(env, str(default)))
    for seed in [int(v) for v in os.environ.get("LOOPWATCH_SIM_SEEDS", "2026,7").split(",")]:
        per_case, ba = benchmark(n, seed)
        print(f"\n[{title}] seed {seed}, {n} per case: balanced accuracy {ba:.3f}")
        for c, v in per_case.items():
            print(f"  {c}: {figure} {v:.2f}")
        assert ba > 0.5


@pytest.mark.bench
def test_gate_hard_cases():
    _planted_report("gate hard cases", gate_benchmark, env="LOOPWATCH_GATE_CASES", default=100, figure="right")


# ------------------------------------------------------------------ stick-slip episodes (no limit cycle)
STICK_CASES = {  # case: truth (the valve sticks?)
    "stiction, slow PI, SP steps": True,
    "stiction (Karnopp), slow PI, SP steps": True,
    "healthy, slow PI, SP steps": False,
    "healthy, near-integrating plant": False,
    "healthy, SIMC PI, SP steps": False,
    "healthy, slow PI, SP steps, slow load swing": False,
    "healthy, SIMC PI, SP steps, disturbances compensated": False,
    "stiction (Karnopp), slow PI, SP moves in bursts of clicks": True,
    "healthy, SIMC PI, cascade set point, disturbances compensated": False,
    # session 5: the shapes the plant misses and their healthy twins
    "stiction (Karnopp), flow loop, slow integral ramps, small slips": True,
    "stiction (two-parameter), slow PI, SP reversals": True,
    "healthy, flow loop, slow integral ramps, slow load drift": False,
    "healthy, slow PI, SP reversals": False,
}


def stick_case(case: str, rng: np.random.Generator, seed: int, n: int = 751):
    """One planted window (``n`` samples at 1 s, 751 unless told; the set-point steps fall in
    800 s .. n + 599 s) for :data:`STICK_CASES`: (pv, op, sp, stem) or None.

    A FOPDT plant (gain 0.5-3, tau 5-40 s, dead time 0.1-0.5 tau; near-integrating: tau
    2000-20000 s), a 751 s warm-up at the set point 50, then 2-4 set-point steps of 2-10 % at random times, measurement noise 0.5-5 %
    and load noise 0-2 % (standard deviations, PV / OP units).  Slow PI: the SIMC gains
    times 0.2-0.6 (proportional) and 0.1-0.5 (integral), so that the OP ramps for a long
    time before a sticking valve breaks away.  Stiction: the two-parameter model with
    S 2-8 %, J 0-0.5 S (with a noisy OP its reversal rule can hold the stem while the OP
    travels many S), or a Karnopp valve (force balance: F_s 1-6 %, F_c 0.2-0.8 F_s).  Slow
    load swing: a sinusoidal disturbance of period 300-1500 s, amplitude 1-5, on the PV;
    disturbances compensated: three sinusoids of period 50-750 s, amplitude 0.3-2, that the
    SIMC loop largely cancels (the OP wanders, the PV stays near the set point).  SP moves in
    bursts: each move made of 2-3 clicks 1-5 s apart (as operators move set points).  Cascade
    set point: a master's output, two sinusoids of period 200-1000 s and amplitude 1-3 on the
    set point, quantised to 0.01 (it changes at nearly every sample).  Windows whose stem limit-cycles (>= 4 cycles) are drawn again: the
    detector is for sticking valves *without* a limit cycle.

    Session 5 cases (the shapes of the plant misses, each with a healthy twin).  Flow loop: a
    fast plant (tau 1-4 s, dead time 1 s), a PI with the SIMC gain times 0.1-0.3 and the
    integral gain times 0.005-0.03 (the OP ramps for hundreds of samples), SP moves of 0.5-3;
    small slips: a Karnopp valve with F_s 1-4, F_c 0.7-0.95 F_s (a slip jump of a few
    measurement-noise deviations or less); its healthy twin: a linear valve and a slow load
    drift (a sinusoid of period 3000-12000 s, amplitude 3-10, on the PV: locally a ramp that
    the slow integral follows with a constant error, as a stuck valve's OP does).  SP
    reversals: the SP moves alternate in sign, so the OP reverses while a two-parameter valve
    (S 3-8, J 0.2-0.8 S) is stuck (stuck across an OP reversal); its healthy twin the same with
    a linear valve."""
    for _ in range(20):
        tau = float(np.exp(rng.uniform(np.log(5), np.log(40))))
        if case == "healthy, near-integrating plant":
            tau = float(np.exp(rng.uniform(np.log(2000), np.log(20000))))
        theta = max(1.0, float(rng.uniform(0.1, 0.5)) * min(tau, 40.0))
        plant = FOPDT(float(np.exp(rng.uniform(np.log(0.5), np.log(3)))), tau, theta)
        pi = simc(plant)
        flow = "flow loop" in case
        if flow:  # a fast flow loop, a very slow integral
            plant = FOPDT(plant.gain, float(rng.uniform(1, 4)), 1.0)
            pi = simc(plant)
            pi = PIController(pi.kc * float(rng.uniform(0.1, 0.3)), pi.ki * float(rng.uniform(0.005, 0.03)))
        elif "slow PI" in case or "stiction" in case:
            pi = PIController(pi.kc * float(rng.uniform(0.2, 0.6)), pi.ki * float(rng.uniform(0.1, 0.5)))
        times = np.sort(rng.uniform(800, 599 + n, int(rng.integers(2, 5))))
        level = 50.0
        steps = [SetpointStep(0.0, level)]
        sign = float(rng.choice([-1, 1])) if "reversals" in case else 0.0
        for t in times:
            if flow:
                move = float(rng.choice([-1, 1]) * rng.uniform(0.5, 3))
            elif sign:  # alternating moves: the OP reverses
                sign = -sign
                move = sign * float(rng.uniform(2, 10))
            else:
                move = float(rng.choice([-1, 1]) * rng.uniform(2, 10))
            if "bursts" in case:  # the move in 2-3 clicks a few seconds apart
                clicks = int(rng.integers(2, 4))
                for j, dt in enumerate(np.cumsum(np.r_[0.0, rng.uniform(1, 5, clicks - 1)])):
                    steps.append(SetpointStep(float(t + dt), level + move * (j + 1) / clicks))
                level += move
                continue
            level += move
            steps.append(SetpointStep(float(t), level))
        if "cascade" in case:  # a master's wandering output, changing at nearly every sample
            tt = np.arange(0.0, 751.0 + n)
            w = sum(float(rng.uniform(1, 3)) * np.sin(2 * np.pi * tt / float(rng.uniform(200, 1000)) + float(rng.uniform(0, 2 * np.pi)))
                    for _ in range(2))
            steps = [SetpointStep(float(ti), float(np.round(50.0 + wi, 2))) for ti, wi in zip(tt, w)]
        steps.sort(key=lambda st: st.time_s)  # clicks of one move may pass the next move's time
        kw = dict(plant=plant, controller=pi, setpoint_steps=tuple(steps), duration_s=751.0 + n,
                  measurement_noise_std=float(rng.uniform(0.005, 0.05)) * 10,
                  load_noise_std=float(rng.uniform(0.0, 0.02)) * 10)
        if case.startswith("stiction,"):
            s = float(rng.uniform(2, 8))
            kw["valve"] = ChoudhuryStictionSpec(S=s, J=s * float(rng.uniform(0.0, 0.5)))
        if case.startswith("stiction (two-parameter)"):
            s = float(rng.uniform(3, 8))
            kw["valve"] = ChoudhuryStictionSpec(S=s, J=s * float(rng.uniform(0.2, 0.8)))
        if case.startswith("stiction (Karnopp), flow loop"):
            f_s = float(rng.uniform(1, 4))
            kw["valve"] = KarnoppLoopSpec(fc=f_s * float(rng.uniform(0.7, 0.95)), fs=f_s)
        elif case.startswith("stiction (Karnopp)"):  # also the bursts case
            f_s = float(rng.uniform(1, 6))
            kw["valve"] = KarnoppLoopSpec(fc=f_s * float(rng.uniform(0.2, 0.8)), fs=f_s)
        if "compensated" in case:  # a wandering load the OP cancels (PV near the SP)
            kw["disturbances"] = tuple(
                Sinusoid(float(rng.uniform(0.3, 2)), 2 * np.pi / float(np.exp(rng.uniform(np.log(50), np.log(750)))),
                         float(rng.uniform(0, 2 * np.pi))) for _ in range(3))
        if "load drift" in case:  # locally a ramp over the window
            period = float(rng.uniform(3000, 12000))
            kw["disturbances"] = (Sinusoid(float(rng.uniform(3, 10)), 2 * np.pi / period, float(rng.uniform(0, 2 * np.pi))),)
        if "load swing" in case:
            period = float(rng.uniform(300, 1500))
            kw["disturbances"] = (Sinusoid(float(rng.uniform(1, 5)), 2 * np.pi / period, float(rng.uniform(0, 2 * np.pi))),)
        sim = simulate_loop(LoopScenario(**kw), seed=seed)
        if not np.all(np.isfinite(sim.pv)):
            continue
        if case.startswith("stiction") and limit_cycles(sim.mv[-n:]) >= 4:
            continue
        return sim.pv[-n:], sim.op[-n:], sim.sp[-n:], sim.mv[-n:]
    return None


def stick_benchmark(n_per_case: int, seed: int, window: int = 751):
    """Share of planted windows with stick-slip episodes found (per case); for the sticking
    cases also among the windows whose planted stem moved at all (a stem held throughout the
    window leaves the PV nothing to show)."""
    from pipeline.stickslip import stick_slip_episodes
    rng = np.random.default_rng(seed)
    found: dict[str, list[bool]] = {}
    moved: dict[str, list[bool]] = {}
    for case in STICK_CASES:
        found[case], moved[case] = [], []
        for i in range(n_per_case):
            w = stick_case(case, rng, seed + i, n=window)
            if w is not None:
                r = stick_slip_episodes(w[0], w[1], w[2])
                found[case].append(bool(r and r.episodes))
                moved[case].append(bool(np.ptp(w[3]) > 0))
    tpr = np.mean([v for c, t in STICK_CASES.items() if t for v in found[c]])
    tnr = 1 - np.mean([v for c, t in STICK_CASES.items() if not t for v in found[c]])
    per_case = {c: float(np.mean(v)) for c, v in found.items()}
    for c, t in STICK_CASES.items():
        m = [f for f, mv in zip(found[c], moved[c]) if mv]
        if t and m:
            per_case[f"{c} [stem moved: {len(m)} of {len(found[c])} windows]"] = float(np.mean(m))
    return per_case, (tpr + tnr) / 2


@pytest.mark.bench
@pytest.mark.timeout(1800)  # two stem families: ~2x main's search (over the suite's 300 s)
def test_stick_slip_planted():
    _planted_report("stick-slip planted", stick_benchmark, env="LOOPWATCH_STICK_CASES", default=60,
                    figure="episodes found in")


@pytest.mark.bench
@pytest.mark.timeout(1800)  # two stem families: ~2x main's search (over the suite's 300 s)
def test_stick_slip_planted_long():
    """The planted stick-slip cases on 4096-sample windows (the monitor's default length; the
    same loops, 2-4 set-point moves spread over the window): a window this long is tested in
    segments at its own sampling (pipeline.stickslip)."""
    _planted_report("stick-slip planted, 4096-sample windows", lambda n, seed: stick_benchmark(n, seed, window=4096),
                    env="LOOPWATCH_STICK_LONG_CASES", default=20, figure="episodes found in")
