"""Closed-loop simulator against control theory (Aftab et al. 2016 §4 loop).

Expected values are computed here from the continuous-time loop (analytic step responses, the
characteristic equation ``1 + C(s) G(s) = 0``, the sensitivity function), never by running the
simulator.
"""

from __future__ import annotations

import cmath
import math
import time
from dataclasses import replace

import numpy as np
import pytest
from scipy.optimize import brentq, fsolve

from models.errors import ModelConfigError
from models.loop import (
    CASES,
    FOPDT,
    LoopScenario,
    LoopSimResult,
    PIController,
    SetpointStep,
    Sinusoid,
    fopdt_response,
    gain_margin,
    scenario_for_case,
    simulate_loop,
)
from models.valves import BacklashSpec, ChoudhuryStictionSpec

K, TAU, THETA = 2.25, 4.5, 3.0  # paper eq. (13)
KC = 0.1


def _L(s: complex, ki: float) -> complex:
    return (KC + ki / s) * K * cmath.exp(-THETA * s) / (TAU * s + 1.0)


def _phase_crossover(ki: float) -> float:
    ph = lambda w: -w * THETA - math.atan(w * TAU) - math.atan2(ki, KC * w) + math.pi  # noqa: E731
    return brentq(ph, 0.05, 1.0)


def _dominant_pole(ki: float) -> complex:
    w0 = _phase_crossover(ki)

    def f(v):
        r = 1.0 + _L(complex(v[0], v[1]), ki)
        return [r.real, r.imag]

    re, im = fsolve(f, [-0.01, w0], xtol=1e-13)
    return complex(re, im)


def _peaks(x: np.ndarray) -> np.ndarray:
    return np.nonzero((x[1:-1] > x[:-2]) & (x[1:-1] >= x[2:]))[0] + 1


# ------------------------------------------------------------------------------- plant alone


def test_fopdt_step_response_is_analytic_and_dead_time_exact():
    p = FOPDT(K, TAU, THETA)
    h = 0.1
    t = np.arange(600) * h
    y = fopdt_response(p, np.ones_like(t), h, hold="zoh")
    expected = np.where(t >= THETA, K * (1.0 - np.exp(-(t - THETA) / TAU)), 0.0)
    np.testing.assert_allclose(y, expected, atol=1e-12)
    assert np.all(y[t <= THETA + 1e-9] == 0.0)  # nothing before the dead time


def test_fopdt_foh_is_exact_for_ramps():
    p = FOPDT(K, TAU, THETA)
    h = 0.1
    t = np.arange(600) * h
    y = fopdt_response(p, t.copy(), h)  # input u(t) = t, linear between samples
    tt = np.clip(t - THETA, 0.0, None)
    expected = K * (tt - TAU * (1.0 - np.exp(-tt / TAU)))
    np.testing.assert_allclose(y, expected, atol=1e-11)


def test_dead_time_shifts_response_exactly():
    h = 0.1
    rng = np.random.default_rng(3)
    u = rng.standard_normal(500)
    y0 = fopdt_response(FOPDT(K, TAU, 0.1), u, h)
    y3 = fopdt_response(FOPDT(K, TAU, 3.1), u, h)
    np.testing.assert_allclose(y3[30:], y0[:-30], atol=1e-12)
    assert np.all(y3[:31] == 0.0)


# ------------------------------------------------------------------------- closed-loop theory


def test_gain_margin_of_fast_integral_is_barely_above_one():
    w180 = _phase_crossover(0.19)
    gm_theory = 1.0 / abs(_L(1j * w180, 0.19))
    assert gm_theory == pytest.approx(1.0107, abs=2e-4)  # the brief's "about 1.01"
    assert gain_margin(FOPDT(K, TAU, THETA), PIController(KC, 0.19)) == pytest.approx(gm_theory, rel=1e-9)
    w180n = _phase_crossover(0.05)
    assert gain_margin(FOPDT(K, TAU, THETA), PIController(KC, 0.05)) == pytest.approx(
        1.0 / abs(_L(1j * w180n, 0.05)), rel=1e-9
    )


def test_tuning_case_oscillates_near_stability_limit():
    pole = _dominant_pole(0.19)
    assert pole.real < 0 and pole.real > -0.002  # continuous loop: barely stable
    r = simulate_loop(CASES["tuning"], seed=0)
    e = (r.pv - r.sp)[300:3900]
    pk = _peaks(e)
    pk = pk[e[pk] > 0.05 * e.max()]
    period = np.mean(np.diff(pk))
    assert period == pytest.approx(2 * math.pi / pole.imag, rel=0.01)
    slope = np.polyfit(pk.astype(float), np.log(e[pk]), 1)[0]
    assert slope == pytest.approx(pole.real, abs=1.5e-4)
    decay_ratio = math.exp(slope * period)  # ratio of successive peaks
    assert 0.95 < decay_ratio < 1.0
    assert e[pk][-1] > 0.02 * e[pk][0]  # still oscillating at the end of 4000 s


def test_nominal_loop_settles_to_setpoint_fast():
    pole = _dominant_pole(0.05)
    assert math.exp(2 * math.pi * pole.real / pole.imag) < 0.01  # decay ratio per period
    sc = replace(CASES["healthy"], load_noise_std=0.0)
    r = simulate_loop(sc, seed=0)
    for step in sc.setpoint_steps:
        i_end = int(step.time_s) + 400
        assert r.pv[i_end] == pytest.approx(step.value, abs=1e-6)  # integral action: no offset
        assert r.op[i_end] == pytest.approx(step.value / K, abs=1e-6)
    np.testing.assert_array_equal(r.mv, r.op)


@pytest.mark.parametrize("case, amp, omega", [("disturbance", 5.0, 0.25), ("tuning+disturbance", 10.0, 0.1)])
def test_output_disturbance_is_attenuated_by_sensitivity(case, amp, omega):
    ki = CASES[case].controller.ki
    expected = amp * abs(1.0 / (1.0 + _L(1j * omega, ki)))  # |S(j w)| A
    r = simulate_loop(CASES[case], seed=0)
    t = r.t[2000:]
    e = (r.pv - r.sp)[2000:]
    basis = [np.sin(omega * t), np.cos(omega * t), np.ones_like(t)]
    if ki > 0.1:  # the slowly decaying tuning oscillation is also present: fit it too
        w = _dominant_pole(ki).imag
        decay = np.exp(_dominant_pole(ki).real * (t - t[0]))
        basis += [decay * np.sin(w * t), decay * np.cos(w * t)]
    coef, *_ = np.linalg.lstsq(np.column_stack(basis), e, rcond=None)
    assert math.hypot(coef[0], coef[1]) == pytest.approx(expected, rel=0.01)


def _amplitude(x: np.ndarray) -> float:
    return 0.5 * (np.percentile(x, 99) - np.percentile(x, 1))


def test_datadriven_stiction_sustains_a_limit_cycle():
    r = simulate_loop(CASES["stiction-datadriven"], seed=0)
    e = r.pv - r.sp
    a1, a2 = _amplitude(e[1000:2000]), _amplitude(e[3000:4000])
    assert a1 > 2.0 and 0.8 < a2 / a1 < 1.25  # does not decay
    # Describing-function theory: stiction adds phase lag, so the limit cycle is slower than
    # the linear loop's ultimate period 2 pi / w180.
    pk = _peaks(e[1000:])
    pk = pk[e[1000:][pk] > 0.5 * a2]
    assert np.mean(np.diff(pk)) > 2 * math.pi / _phase_crossover(0.05)
    # The valve really sticks: MV is constant over long stretches while OP keeps moving.
    assert np.mean(np.diff(r.mv[1000:]) == 0.0) > 0.5
    assert np.mean(np.diff(r.op[1000:]) == 0.0) < 0.01


def test_datadriven_stiction_limit_cycle_survives_measurement_noise():
    # A sticky valve under a noisy OP still stick-slips: the oscillation neither freezes nor
    # lets the integral wind up.
    r = simulate_loop(scenario_for_case("stiction-datadriven", noise_std=0.3), seed=4)
    e = r.pv - r.sp
    a1, a2 = _amplitude(e[1000:2000]), _amplitude(e[3000:4000])
    assert a1 > 2.0 and 0.8 < a2 / a1 < 1.25
    assert np.max(np.abs(r.op)) < 3 * 7.0


def test_lugre_stiction_sustains_a_limit_cycle():
    sc = scenario_for_case("stiction-lugre", duration_s=2000.0)
    r = simulate_loop(sc, seed=0)
    e = r.pv - r.sp
    a1, a2 = _amplitude(e[800:1400]), _amplitude(e[1400:2000])
    assert a1 > 2.0 and 0.8 < a2 / a1 < 1.25
    pk = _peaks(e[800:])
    pk = pk[e[800:][pk] > 0.5 * a2]
    assert np.mean(np.diff(pk)) > 2 * math.pi / _phase_crossover(0.05)


def test_healthy_case_does_not_oscillate():
    r = simulate_loop(CASES["healthy"], seed=5)
    assert r.truth == "healthy"
    e = (r.pv - r.sp)[1200:2000]  # a set-point-free stretch: load-noise response only
    e = e - e.mean()
    acf = np.correlate(e, e, "full")[e.size - 1:] / (e @ e)
    # Closed-loop dominant time constant 1/0.103 ~ 10 s: no periodic correlation left at lags
    # beyond a few time constants (an oscillation would give ACF peaks of +-0.5 or more).
    assert np.max(np.abs(acf[30:300])) < 0.3


def test_backlash_loop_has_no_sustained_oscillation_but_lags():
    sc = CASES["deadband"]
    w = sc.valve.width
    r = simulate_loop(sc, seed=0)
    assert r.truth == "deadband"
    assert np.all(np.abs(r.op - r.mv) <= w / 2 + 1e-9)  # the stem stays within the gap
    e = r.pv - r.sp
    # Describing-function theory (backlash + PI + self-regulating plant): no limit cycle.  The
    # loop ends each set-point segment close to the set point, with at most a few stem
    # reversals (the integrator creeps across the gap), not a cycle every period.
    bounds = [s.time_s for s in sc.setpoint_steps] + [sc.duration_s]
    prev_sp = 0.0
    for step, end in zip(sc.setpoint_steps, bounds[1:]):
        seg = slice(int(end) - 20, int(end))
        assert np.max(np.abs(e[seg])) < 0.05 * abs(step.value - prev_sp)
        dmv = np.diff(r.mv[int(step.time_s) + 1:int(end)])
        moves = np.sign(dmv[dmv != 0.0])
        assert np.count_nonzero(np.diff(moves)) <= 4
        prev_sp = step.value
    # and the valve is stuck most of the time while the OP keeps moving
    assert np.mean(np.diff(r.mv) == 0.0) > 0.5


# ----------------------------------------------------------------------------- bookkeeping


def test_result_shape_and_truths():
    for name, sc in CASES.items():
        r = simulate_loop(replace(sc, duration_s=50.0), seed=1)
        assert isinstance(r, LoopSimResult)
        for a in (r.t, r.sp, r.pv, r.op, r.mv):
            assert a.shape == (50,)
        np.testing.assert_array_equal(r.t, np.arange(50.0))
        assert r.truth == {"stiction-datadriven": "stiction", "stiction-lugre": "stiction"}.get(name, name)


def test_truth_derived_when_not_given():
    p = FOPDT(K, TAU, THETA)
    assert LoopScenario(p, PIController(KC, 0.19)).cause == "tuning"
    assert LoopScenario(p, PIController(KC, 0.05)).cause == "healthy"
    assert LoopScenario(p, PIController(KC, 0.05), disturbances=(Sinusoid(1, 0.2),)).cause == "disturbance"
    assert LoopScenario(p, PIController(KC, 0.19), disturbances=(Sinusoid(1, 0.2),)).cause == "tuning+disturbance"
    assert LoopScenario(p, PIController(KC, 0.05), ChoudhuryStictionSpec(3, 1)).cause == "stiction"
    assert LoopScenario(p, PIController(KC, 0.05), BacklashSpec(3)).cause == "deadband"


def test_deterministic_per_seed():
    sc = scenario_for_case("stiction-datadriven", noise_std=0.2, duration_s=600.0)
    a = simulate_loop(sc, seed=11)
    b = simulate_loop(sc, seed=11)
    c = simulate_loop(sc, seed=12)
    for f in ("pv", "op", "mv", "sp"):
        np.testing.assert_array_equal(getattr(a, f), getattr(b, f))
    assert not np.array_equal(a.pv, c.pv)


def test_measurement_noise_is_per_sample_white_with_given_std():
    sc = LoopScenario(FOPDT(K, TAU, THETA), PIController(0.0, 0.0), measurement_noise_std=0.3)
    r = simulate_loop(sc, seed=2)  # open loop at rest: PV is the noise alone
    assert r.pv.std() == pytest.approx(0.3, rel=0.05)
    x = r.pv - r.pv.mean()
    assert abs(x[1:] @ x[:-1]) / (x @ x) < 0.05  # independent from sample to sample


def test_anti_windup_releases_the_limit_at_once():
    pi = PIController(KC, 0.05, op_min=-1.0, op_max=1.5)
    steps = (SetpointStep(10.0, 5.0), SetpointStep(1000.0, 0.0))  # 5 needs OP 2.22 > 1.5
    r = simulate_loop(LoopScenario(FOPDT(K, TAU, THETA), pi, None, steps, duration_s=1200.0), seed=0)
    assert r.op.max() <= 1.5 + 1e-12 and r.op.min() >= -1.0 - 1e-12
    assert r.pv[990] == pytest.approx(K * 1.5, abs=1e-6)  # saturated steady state
    # Clamped integrator: as soon as the error changes sign the OP leaves the limit.
    assert r.op[1001] < 1.5


def test_non_lugre_run_is_fast():
    best = math.inf
    for _ in range(2):
        t0 = time.perf_counter()
        simulate_loop(CASES["stiction-datadriven"], seed=0)
        best = min(best, time.perf_counter() - t0)
    assert best < 0.5


@pytest.mark.slow
def test_lugre_full_run_within_budget():
    t0 = time.perf_counter()
    simulate_loop(CASES["stiction-lugre"], seed=0)
    assert time.perf_counter() - t0 < 3.0


@pytest.mark.parametrize(
    "build, word",
    [
        (lambda: FOPDT(K, 0.0, THETA), "tau_s"),
        (lambda: FOPDT(0.0, TAU, THETA), "gain"),
        (lambda: FOPDT(K, TAU, -1.0), "dead_time_s"),
        (lambda: PIController(KC, -0.1), "ki"),
        (lambda: PIController(KC, 0.1, op_min=2.0, op_max=1.0), "op_min"),
        (lambda: Sinusoid(5.0, 0.0), "omega_rad_s"),
        (lambda: SetpointStep(float("inf"), 1.0), "time_s"),
        (lambda: LoopScenario(FOPDT(K, TAU, THETA), PIController(KC, 0.05), duration_s=10.5), "duration_s"),
        (lambda: LoopScenario(FOPDT(K, TAU, THETA), PIController(KC, 0.05), measurement_noise_std=-1), "measurement_noise_std"),
        (lambda: LoopScenario(FOPDT(K, TAU, THETA), PIController(KC, 0.05), substeps=0), "substeps"),
        (lambda: LoopScenario(FOPDT(K, TAU, THETA), PIController(KC, 0.05), truth="gremlins"), "truth"),
        (lambda: LoopScenario(FOPDT(K, TAU, THETA), PIController(KC, 0.05),
                              setpoint_steps=(SetpointStep(5, 1), SetpointStep(1, 2))), "setpoint_steps"),
        (lambda: scenario_for_case("sticky"), "sticky"),
        (lambda: scenario_for_case("tuning", noise_std=-0.1), "measurement_noise_std"),
    ],
)
def test_bad_parameters_are_named(build, word):
    with pytest.raises(ModelConfigError, match=word):
        build()
