"""The extended Karnopp valve (models/valve_effects.py): each effect checked against an independent
computation or the planted truth, never against a run of the code under test."""

from __future__ import annotations

import math

import numpy as np
import pytest

from models.errors import ModelConfigError
from models.karnopp import PRESETS, simulate
from models.valve_effects import (
    EffectValve,
    actuator_pressure,
    hidden_record,
    hide_effects,
    jump_windows,
    parse_hide,
    residual_effects,
    simulate_effects,
    transmitter,
)
from models.valve_tests import sine


def test_no_effect_agrees_with_the_paper_simulator():
    # models.karnopp.simulate (issue 7, a separate implementation of eq. 1-2): same valve, same
    # smooth pressure; the sub-step event placement may move the stem by at most a few µm
    p = PRESETS["low"].replace(tau_p=0.0)
    pc = actuator_pressure(sine().p_cmd, 1e-3, 1.0)
    ref = simulate(p, pc, 1e-3)
    got = simulate_effects(EffectValve.from_karnopp(p), pc, 1e-3)
    assert np.max(np.abs(got.x - ref.x)) < 5e-6
    assert np.ptp(ref.x) > 0.01  # the test moves the stem


def test_dead_time_and_lag_are_exact_linear_operations():
    dt = 1e-3
    p = np.r_[np.zeros(100), np.ones(400)]
    d = actuator_pressure(p, dt, theta=0.0305)  # 30.5 samples: linear interpolation between samples
    assert d[129] == 0.0 and d[130] == pytest.approx(0.5) and d[131] == 1.0
    lag = actuator_pressure(p, dt, tau=0.05)
    t = dt * (np.arange(500) - 99)  # the step is applied at sample 100, held over each step
    np.testing.assert_allclose(lag[100:], 1 - np.exp(-t[100:] / 0.05), rtol=1e-12)


def test_the_compiled_dead_time_and_lag_compute_what_numpy_and_lfilter_compute_bit_for_bit():
    # actuator_pressure is one compiled pass (a fit computes it at every simulation); the array
    # expressions and scipy's lfilter it replaced are the independent reference, to the bit
    from scipy.signal import lfilter

    def reference(p, dt, tau, theta):
        if theta > 0:
            n = min(int(theta / dt), p.size)
            f = theta / dt - n
            padded = np.concatenate((np.full(n + 1, p[0]), p))
            p = (1.0 - f) * padded[1 : p.size + 1] + f * padded[: p.size]
        if tau > 0:
            a = math.exp(-dt / tau)
            p = lfilter([1.0 - a], [1.0, -a], p, zi=[a * p[0]])[0]
        return p

    rng = np.random.default_rng(5)
    for _ in range(300):
        n = int(rng.integers(1, 2000))
        p = rng.normal(6e4, 2e4, n)
        dt = float(rng.choice([1e-3, 2.5e-4]))
        tau = float(rng.choice([0.0, rng.uniform(0.0, 1.0), 1e-6]))
        theta = float(rng.choice([0.0, rng.uniform(0.0, 0.5), 3.0 * n * dt]))  # also longer than the record
        assert np.array_equal(actuator_pressure(p, dt, tau, theta), reference(p, dt, tau, theta))


def test_the_fit_residual_is_the_simulated_record_bit_for_bit():
    # residual_effects (the fits' entry, no input checks) against simulate_effects, every effect on
    valve = EffectValve(k=2e5, fc=150.0, fv=5000.0, sa=0.0445, dv=1e-4, fs=200.0, vs=2e-3, tau=0.05, theta=0.02,
                        deadband=2e-4, bias=1e-3)
    rng = np.random.default_rng(2)
    p = np.repeat(rng.uniform(3e4, 9e4, 40), 100)
    x = rng.normal(0.0, 1e-3, p.size)
    rest = np.where(rng.random(p.size) < 0.05, x, np.nan)
    band = rng.uniform(0.0, 20.0, p.size)
    sim = simulate_effects(valve, p, 1e-3, x0_meas=0.0, rest_meas=rest, band=band)
    assert np.ptp(sim.x) > 1e-3  # the stem moves
    assert np.array_equal(residual_effects(valve, p, 1e-3, x, x0_meas=0.0, rest_meas=rest, band=band), x - sim.x_meas)
    fine = jump_windows(p, 1e-3, 0.0, window_s=0.05).astype(float)  # the 50 ms after each step
    assert 0.3 < fine.mean() < 0.9
    sub = simulate_effects(valve, p, 1e-3, x0_meas=0.0, rest_meas=rest, band=band, substeps=4, fine=fine)
    assert not np.array_equal(sub.x_meas, sim.x_meas)
    assert np.array_equal(residual_effects(valve, p, 1e-3, x, x0_meas=0.0, rest_meas=rest, band=band, substeps=4,
                                           fine=fine), x - sub.x_meas)


def test_deadband_reading_stays_put_until_the_stem_moves_half_the_width_past_it():
    s = np.r_[np.linspace(0, 1, 11), np.linspace(1, 0, 11)[1:]]
    y = transmitter(s, 0.4)
    # going up the reading trails by d/2 = 0.2 once dragged; after the reversal at 1.0 it stays at
    # 0.8 until the stem is below 0.6
    assert y[10] == pytest.approx(0.8)
    down = y[11:]
    stem = s[11:]
    assert np.all(down[stem >= 0.6] == pytest.approx(0.8))
    np.testing.assert_allclose(down[stem < 0.6 - 1e-12], stem[stem < 0.6 - 1e-12] + 0.2)


def test_slip_jump_needs_fs_to_break_away_and_stribeck_falls_to_fc():
    base = EffectValve(k=2e5, fc=150.0, fv=5000.0, sa=0.0445, dv=1e-4)
    dt = 1e-3
    # a slow force ramp from rest: breakaway when S_a·p − k·x0 reaches F_s (eq. 2, third line)
    p = np.linspace(0.0, 20000.0, 2001)
    for fs in (150.0, 200.0):
        sim = simulate_effects(base.replace(fs=fs), p, dt, x0_meas=0.0)
        first = int(np.argmax(sim.x != sim.x[0]))
        f_break = 0.0445 * p[first]
        assert fs <= f_break <= fs + 0.0445 * (p[1] - p[0]) * 1.01
    # Stribeck: at steady sliding speed v the friction is Fc + (Fs − Fc)·exp(−(v/vs)²); a constant
    # force ramp rate R makes the stem slide at v = R/k and lag the static line by F(v)/k + Fv·v/k
    R = 2000.0  # N/s
    t = np.arange(0, 4.0, dt)
    pr = (200.0 + R * t) / 0.0445
    v_ss = R / 2e5
    for vs in (0.02, 0.05):  # slope of the Stribeck curve below F_v: steady sliding (no stick-slip)
        val = base.replace(fs=250.0, vs=vs)
        x = simulate_effects(val, pr, dt, x0_meas=0.0).x
        lagf = 0.0445 * pr[-1] - 2e5 * x[-1]
        expect = 150.0 + 100.0 * math.exp(-((v_ss / vs) ** 2)) + 5000.0 * v_ss
        assert lagf == pytest.approx(expect, rel=0.01)


def test_hide_and_parse():
    base = EffectValve.from_karnopp(PRESETS["low"])
    assert parse_hide("deadband") == ("deadband", (0.5e-3,))
    assert parse_hide("stribeck=1.5") == ("stribeck", (1.5, 3e-3))
    v = hide_effects(base, dict([parse_hide("slip_jump=1.3"), parse_hide("dead_time=0.05")]))
    assert v.fs == pytest.approx(1.3 * base.fc) and v.theta == 0.05
    assert v.effects == ("slip_jump", "dead_time")
    for bad in ("nope", "slip_jump=0.9", "deadband=-1", "dead_time=x", "stribeck=1.2:1:3"):
        with pytest.raises(ModelConfigError):
            parse_hide(bad)
    with pytest.raises(ModelConfigError):
        hide_effects(base, {"slip_jump": (1.2,), "stribeck": (1.2, 1e-3)})
    with pytest.raises(ModelConfigError):
        EffectValve(k=1.0, fc=10.0, fv=0.0, fs=5.0)


def test_hidden_record_noise_and_truth():
    rec = hidden_record(PRESETS["high"], "isa-steps", {"deadband": (1e-3,)}, noise_x=2e-5, noise_p=100.0, seed=4)
    assert np.std(rec.x - rec.x_true) == pytest.approx(2e-5, rel=0.05)
    assert np.std(rec.p - rec.p_true) == pytest.approx(100.0, rel=0.05)
    assert rec.valve.deadband == 1e-3


def test_substeps_converge_to_the_step_response_of_eq_1():
    # planted truth: a stem at rest with F_s = F_c under a pressure step held from the sample
    # before it slides by m·z'' + F_v·z' + k·z = ΔF − F_c (eq. 1–2, overdamped, no reversal), whose
    # solution is z∞·(1 + (r2·e^{r1 t} − r1·e^{r2 t}) / (r1 − r2)).  The one-step scheme the
    # workflow fits is first order: its error halves with every doubling of the sub-steps.
    k, m, fv, fc, sa, dt = 2e5, 2.0, 8000.0, 400.0, 0.0445, 1e-3
    valve = EffectValve(k=k, fc=fc, fv=fv, m=m, sa=sa, dv=1e-7)
    p0, df = 50e3, 2000.0
    p = np.r_[np.full(100, p0), np.full(300, p0 + df / sa)]
    x0 = sa * p0 / k
    zinf = (df - fc) / k  # 8 mm
    root = math.sqrt(fv * fv - 4 * m * k)
    r1, r2 = (-fv + root) / (2 * m), (-fv - root) / (2 * m)
    t = dt * (np.arange(p.size) - 99)  # p[100] acts from t[99] on
    z = np.where(t > 0, zinf * (1 + (r2 * np.exp(r1 * t) - r1 * np.exp(r2 * t)) / (r1 - r2)), 0.0)
    err = {n: np.max(np.abs(simulate_effects(valve, p, dt, x0_meas=x0, substeps=n).x - x0 - z)) for n in (1, 4, 16, 64)}
    for n in (1, 4, 16):
        assert 3.0 < err[n] / err[4 * n] < 5.0  # first order: 4 times the sub-steps, a quarter of the error
    assert err[64] < 1e-6
    assert err[1] < 0.01 * zinf  # the one-step scheme: within 1 % of an 8 mm step
    with pytest.raises(ModelConfigError):
        simulate_effects(valve, p, dt, substeps=0)
    # sub-steps only in the 0.2 s after the step (jump_windows): there the full sub-stepped
    # response, before it the one-step one (the stem is at rest: the same)
    fine = np.zeros(p.size, bool)
    fine[100:300] = True
    part = simulate_effects(valve, p, dt, x0_meas=x0, substeps=4, fine=fine).x
    full = simulate_effects(valve, p, dt, x0_meas=x0, substeps=4).x
    assert np.max(np.abs(part[:300] - full[:300])) < 1e-12
    assert np.max(np.abs(part[:300] - x0 - z[:300])) < 0.3 * err[1]
    with pytest.raises(ModelConfigError):
        simulate_effects(valve, p, dt, substeps=4, fine=fine[:-1])


def test_jump_windows_flag_command_steps_only():
    # planted: a raw 30 kPa command step at sample 1000, the same step behind a 50 ms V/P lag, and
    # white noise of 200 Pa; a 100 Pa seam (a smoother's join) is a jump only without a floor
    dt, n, sd = 1e-3, 3000, 200.0
    rng = np.random.default_rng(11)
    raw = np.where(np.arange(n) < 1000, 40e3, 70e3)
    got = jump_windows(raw, dt, 0.0)
    assert np.array_equal(np.flatnonzero(got), np.arange(1000, 1200))
    lagged = actuator_pressure(raw, dt, 0.05, 0.0)
    assert not jump_windows(lagged, dt, 0.0).any()
    noisy = 50e3 + sd * rng.standard_normal(n)
    assert not jump_windows(noisy, dt, sd).any()
    seam = np.where(np.arange(n) < 2000, 50e3, 50.1e3)
    assert jump_windows(seam, dt, 0.0).any()
    assert not jump_windows(seam, dt, 0.0, floor=sd).any()


# --------------------------------------------------------------------------- stick band


def _first_restart(x: np.ndarray, after: int) -> int:
    """Index of the first sample after ``after`` at which a stem at rest moves again."""
    mv = np.diff(x) != 0
    rest = after + int(np.argmax(~mv[after:]))
    return rest + int(np.argmax(mv[rest:])) + 1


def test_stick_band_a_sliding_stem_that_stops_within_the_band_moves_on_against_coulomb_friction():
    # planted truth, eq. (2): a stem slides up a slow force ramp (1 mm/s, above DV); a 20 ms dip
    # of 8 N (F_net 3 N below F_c) stops it.  Without a band it sticks and needs F_s = 250 N to
    # break away again (third line of eq. 2); with a 10 N band the net force never reversed it
    # by more than the band, so it moves on once F_net exceeds F_c + b = 160 N (not F_s).
    k, fc, fs, fv, sa, dt = 2e5, 150.0, 250.0, 5000.0, 0.0445, 1e-3
    t = np.arange(0, 3.0, dt)
    F = 200.0 + 200.0 * t - 8.0 * ((t >= 1.5) & (t < 1.52))
    i_dip = int(np.argmax(t >= 1.5))
    step = 200.0 * dt  # force increment per sample of the ramp
    for dv, b, f_lo, f_hi in ((1e-4, 0.0, fs, fs + step), (1e-4, 10.0, fc + 10.0, fc + 10.0 + step)):
        valve = EffectValve(k=k, fc=fc, fv=fv, sa=sa, dv=dv, fs=fs)
        x = simulate_effects(valve, F / sa, dt, x0_meas=0.0, band=b).x
        assert np.all(np.diff(x[1000:i_dip]) > 0)  # sliding before the dip
        j = _first_restart(x, i_dip)
        f_break = F[j] - k * x[j - 1]  # the net force that moved the stem again
        assert f_lo - 1e-6 <= f_break <= f_hi + 1e-6, (b, f_break)
    # the DV test of eq. (2) no longer sticks a moving stem: with DV (2 mm/s) above the sliding
    # speed the band-free model breaks away again at every sample, so the slide runs against
    # F_s + F_v·v = 255 N (third line of eq. 2 with viscous friction, v = R/k = 1 mm/s); with the
    # band it slides against F_c + F_v·v = 155 N (first line)
    slow = EffectValve(k=k, fc=fc, fv=fv, sa=sa, dv=2e-3, fs=fs)
    for b, f_lo, f_hi in ((0.0, 255.0 - 0.5, 255.0 + 0.5), (10.0, 155.0 - 0.5, 155.0 + 0.5)):
        x = simulate_effects(slow, F / sa, dt, x0_meas=0.0, band=b).x
        f_slide = F[1000:i_dip] - k * x[1000:i_dip]
        assert np.all(np.diff(x[1000:i_dip]) > 0)
        assert f_lo - 1e-6 <= f_slide.min() and f_slide.max() <= f_hi + 1e-6, (b, f_slide.min(), f_slide.max())


def test_stick_band_a_stem_at_rest_ignores_pressure_noise_within_the_band_and_keeps_its_slip_jump():
    # planted truth: F_s = F_c = 150 N; the stem slides up after a force step and stops at the edge
    # of its stick band.  Bounded noise (±4 N as a force) on the recorded pressure then keeps
    # breaking the band-free model loose (it creeps on by up to 4 N / k), while with a 12 N band
    # it does not move at all.  Then a reversal of more than the band sticks it: with F_s = 250 N
    # the next breakaway upwards is at F_net = F_s, as in eq. (2) (the stuck stem is more than the
    # band inside its friction band, so the band has nothing left to guard: no delay of b/Ḟ).
    k, fc, fv, sa, dt = 2e5, 150.0, 5000.0, 0.0445, 1e-3
    rng = np.random.default_rng(3)
    n = 3000
    F = np.r_[np.full(100, 0.0), np.full(n - 100, 1000.0)] + rng.uniform(-4.0, 4.0, n) * (np.arange(n) >= 100)
    rest = slice(1000, n)  # the slide (time constant F_v/k = 25 ms) is over
    valve = EffectValve(k=k, fc=fc, fv=fv, sa=sa, dv=1e-4)
    x0 = simulate_effects(valve, F / sa, dt, x0_meas=0.0).x
    x1 = simulate_effects(valve, F / sa, dt, x0_meas=0.0, band=12.0).x
    assert np.ptp(x0[rest]) > 1e-6  # creeps: µm
    assert np.ptp(x1[rest]) == 0.0
    assert abs(x1[-1] - (1000.0 - fc) / k) < 12.0 / k  # it stopped within the band of the force balance
    # a reversal of more than the band, then a ramp back up: breakaway at F_s
    fs, b = 250.0, 12.0
    up = np.linspace(0.0, 600.0, 1200)
    G = np.r_[np.full(100, 0.0), np.full(900, 1000.0), np.full(500, 1000.0 - 200.0), 800.0 + up]
    xs = simulate_effects(valve.replace(fs=fs), G / sa, dt, x0_meas=0.0, band=b).x
    j = _first_restart(xs, 1600)
    f_break = G[j] - k * xs[j - 1]
    assert fs - 1e-6 <= f_break <= fs + 0.5 + 1e-6


def test_stick_band_zero_is_the_band_free_model_and_bad_bands_are_refused():
    p = np.r_[np.full(100, 20e3), np.full(400, 60e3)] + np.random.default_rng(1).normal(0, 300.0, 500)
    valve = EffectValve(k=2e5, fc=150.0, fv=5000.0, sa=0.0445, dv=1e-4, fs=200.0)
    ref = simulate_effects(valve, p, 1e-3)
    for b in (0.0, np.zeros(p.size)):
        got = simulate_effects(valve, p, 1e-3, band=b)
        assert np.array_equal(got.x, ref.x) and np.array_equal(got.v, ref.v)
    for bad in (-1.0, np.full(3, 1.0), math.nan):
        with pytest.raises(ModelConfigError):
            simulate_effects(valve, p, 1e-3, band=bad)


def test_steep_stribeck_slide_follows_a_pressure_ramp_without_sticking():
    # planted truth: under a pressure ramp a sliding stem settles at the speed that keeps the
    # spring force following the ramp, u* = (S_a·dp/dt)/k, where Stribeck friction has fallen to
    # F_c (u* = 3·v_s: F'(u*) + F_v > 0, a stable slide).  The friction falls from F_s to F_c faster
    # than (m/h + F_v) rises, so the step equation is not monotone and at rest the step could not
    # break the stem loose (F_s − F_c > u*·(m/h + F_v)): a scheme that stops a slide whenever
    # that holds makes a stick-slip staircase instead
    k, m, fv, fc, fs, vs, sa, dt = 2e5, 2.0, 5000.0, 300.0, 500.0, 5e-3, 0.0445, 1e-3
    assert fs - fc > 3 * vs * (m / dt + fv)
    valve = EffectValve(k=k, fc=fc, fv=fv, m=m, sa=sa, dv=1e-4, fs=fs, vs=vs)
    u_star = 3 * vs
    rate = k * u_star / sa  # Pa/s
    p = 50e3 + rate * dt * np.arange(3000)
    sim = simulate_effects(valve, p, dt)
    late = slice(2000, 3000)
    assert np.all(sim.v[late] > 0)  # slides on, never stuck
    assert np.mean(sim.v[late]) == pytest.approx(u_star, rel=0.02)


def test_stick_band_a_stem_stopped_free_is_not_stuck_by_noise_over_a_long_rest():
    # planted truth: F_s = 350 N > F_c = 150 N; a force step slides the stem up and it comes to
    # rest at the edge of its sliding friction (F_net = F_c), stopped free: the force never turned
    # against its motion.  Over the 5 s rest the recorded force carries Gaussian noise of
    # σ = b/3 (the band is 3 σ); over 5000 samples its lowest dip is below F_c − b (about 3.7 σ),
    # but a dip of noise is not a reversal of the force.  A slow rise of 150 N then moves the stem
    # on against sliding friction (F_c + b + the noise), long before F_net could reach F_s.
    k, fc, fs, fv, sa, dt, b = 2e5, 150.0, 350.0, 5000.0, 0.0445, 1e-3, 12.0
    rng = np.random.default_rng(5)
    n_rest, n_up = 5000, 1000
    noise = rng.normal(0.0, b / 3.0, n_rest)
    assert noise[500:].min() < -b  # the dip that the rest must survive
    F = np.r_[np.full(100, 0.0), np.full(500, 1000.0), 1000.0 + noise[500:], 1000.0 + np.linspace(0.0, 150.0, n_up)]
    valve = EffectValve(k=k, fc=fc, fv=fv, sa=sa, dv=1e-4, fs=fs)
    x = simulate_effects(valve, F / sa, dt, x0_meas=0.0, band=b).x
    i_up = 100 + n_rest
    assert abs(x[i_up - 1] - (1000.0 - fc) / k) < 2.0 * b / k  # at rest at the edge of sliding friction
    j = _first_restart(x, i_up - 200)
    assert j < i_up + n_up
    f_move = F[j] - k * x[j - 1]
    assert f_move <= fc + b + 1e-6 + 150.0 / n_up, f_move  # moved on at F_c + b, not at F_s
    assert x[-1] - x[i_up - 1] > (150.0 - 2.0 * b) / k  # and followed the rise
