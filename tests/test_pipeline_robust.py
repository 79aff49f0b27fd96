"""Robust test, surrogates, data-quality guards and the loop-scale Karnopp valve, against
planted truth and independent computations (stick-slip: tests/test_stickslip.py)."""

import numpy as np
import pytest
from scipy import fft, signal

from models.valves import KarnoppLoopSpec, KarnoppLoopValve
from pipeline.diagnosis import DiagnosisConfig, diagnose_window
from pipeline.dnl import imf_dnl
from pipeline.errors import PipelineConfigError
from pipeline.gate import acf_standard_error
from pipeline.quality import compression, frozen_pv, quantisation, saturation
from pipeline.robust import RobustConfig, mean_wave, robust_dnl_test, wave_dnl
from pipeline.surrogates import harmonic_free_amplitudes, phase_randomised

N = 4096
T = np.arange(N, dtype=float)


def test_phase_randomised_keeps_the_amplitude_spectrum():
    amp = np.abs(fft.rfft(np.random.default_rng(0).standard_normal(N)))
    amp[0] = 0.0
    s = phase_randomised(amp, N, np.random.default_rng(1), count=3)
    for row in s:
        np.testing.assert_allclose(np.abs(fft.rfft(row))[1:-1], amp[1:-1], rtol=1e-9, atol=1e-9)


def test_harmonic_free_amplitudes_replace_planted_harmonics_by_the_local_noise():
    f0 = 64 / N  # exactly on a bin
    noise = 0.01 * np.random.default_rng(2).standard_normal(N)
    x = np.sin(2 * np.pi * f0 * T) + 0.3 * np.sin(2 * np.pi * 3 * f0 * T) + noise
    spec = fft.rfft(x)
    f = fft.rfftfreq(N)
    out = harmonic_free_amplitudes(spec, f, f0=f0, n_harmonics=5, rng=np.random.default_rng(0), count=4)
    k1, k3 = 64, 192
    assert np.all(out[:, k1] == np.abs(spec[k1]))  # fundamental untouched
    noise_level = np.abs(fft.rfft(noise))[150:170].max()
    assert np.all(out[:, k3] <= noise_level * 1.5)  # the 3rd harmonic line is down to the noise
    assert np.abs(spec[k3]) > 50 * out[:, k3].max()


@pytest.mark.parametrize("shape", ["sine", "triangle", "square", "sawtooth"])
def test_wave_dnl_equals_eq11_on_the_synthesised_wave(shape):
    """The closed form of wave_dnl against imf_dnl (eq. 11 through the Hilbert transform and
    zero crossings) on four periods of the same wave.  The two discretise the IF differently
    (exact derivative vs central phase difference at 64 samples per period): 5 %."""
    th = 2 * np.pi * np.arange(64) / 64
    w = {"sine": np.sin(th), "triangle": signal.sawtooth(th + 0.1, 0.5),
         "square": signal.square(th + 0.1), "sawtooth": signal.sawtooth(th, 0.8)}[shape]
    c = fft.rfft(w)[1:6] / 32
    coef = np.stack([c.real, -c.imag], axis=-1)
    k = np.arange(1, 6)[:, None]
    wave = coef[:, 0] @ np.cos(k * th) + coef[:, 1] @ np.sin(k * th)
    expected = imf_dnl(np.tile(wave, 4), fs=64.0).dnl
    assert wave_dnl(coef) == pytest.approx(expected, abs=0.05 * max(expected, 0.05))


def test_mean_wave_recovers_planted_locked_harmonic_under_frequency_wander():
    rng = np.random.default_rng(5)
    # fundamental with a slowly wandering frequency (period 55-65 samples)
    inst = 1 / 60 * (1 + 0.08 * np.sin(2 * np.pi * T / 1500))
    phi = 2 * np.pi * np.cumsum(inst)
    x = np.cos(phi) + 0.3 * np.cos(3 * phi + 0.5) + 0.1 * rng.standard_normal(N)
    f = fft.rfftfreq(N)
    coef = mean_wave(fft.rfft(x), f, N, f0=1 / 60, n_harmonics=5)[0]
    assert coef[0] == pytest.approx([1.0, 0.0], abs=0.05)
    assert coef[2] == pytest.approx([0.3 * np.cos(0.5), -0.3 * np.sin(0.5)], abs=0.03)
    assert np.hypot(*coef[1]) < 0.03 and np.hypot(*coef[3]) < 0.03


def stick_slip(period: float, noise: float, seed: int) -> np.ndarray:
    """A first-order plant's response to a square stem motion (the classic stiction PV shape)."""
    u = np.sign(np.sin(2 * np.pi * T / period))
    y = np.zeros(N)
    a = np.exp(-1.0 / (period / 8))
    for i in range(1, N):
        y[i] = a * y[i - 1] + (1 - a) * u[i - 1]
    return y + noise * np.random.default_rng(seed).standard_normal(N)


@pytest.mark.parametrize("noise", [0.0, 0.05, 0.2])
def test_robust_test_flags_stick_slip_and_passes_sine(noise):
    r = robust_dnl_test(stick_slip(60.0, noise, 1), fs=1.0, period_s=60.0)
    assert r.p_value <= 0.01 and r.dnl >= 0.05, r
    sine = np.sin(2 * np.pi * T / 60.0) + noise * np.random.default_rng(3).standard_normal(N)
    r = robust_dnl_test(sine, fs=1.0, period_s=60.0)
    assert r.p_value > 0.01, r


def test_second_oscillation_off_the_harmonics_is_not_a_nonlinearity():
    """Two linear oscillations (the second at 2.37 f0, strong) are not phase-locked: linear."""
    rng = np.random.default_rng(4)
    x = np.sin(2 * np.pi * T / 80) + 0.8 * np.sin(2 * np.pi * 2.37 * T / 80 + 1) + 0.1 * rng.standard_normal(N)
    r = robust_dnl_test(x, fs=1.0, period_s=80.0)
    assert r.p_value > 0.01, r


def test_op_witness_finds_distortion_the_process_filtered_out():
    """PV nearly sinusoidal (a slow process smooths the stick-slip), OP a sawtooth."""
    rng = np.random.default_rng(6)
    pv = np.sin(2 * np.pi * T / 90) + 0.05 * rng.standard_normal(N)
    op = signal.sawtooth(2 * np.pi * T / 90 + 0.3, 0.85) + 0.05 * rng.standard_normal(N)
    assert robust_dnl_test(pv, fs=1.0, period_s=90.0).p_value > 0.01
    r = robust_dnl_test(pv, fs=1.0, period_s=90.0, other=op)
    assert r.p_value <= 0.01 and r.signal == "other", r


def test_robust_test_is_deterministic():
    x = stick_slip(45.0, 0.03, 4)
    assert robust_dnl_test(x, fs=1.0, period_s=45.0) == robust_dnl_test(x, fs=1.0, period_s=45.0)


def test_robust_config_refuses_an_impossible_significance():
    with pytest.raises(PipelineConfigError, match="too few"):
        RobustConfig(n_surrogates=9, alpha=0.05)


def test_acf_standard_error_matches_monte_carlo():
    """Bartlett's standard error of the ACF of filtered white noise, against simulation."""
    from pipeline.gate import _bandpass, acf

    n, band = 1024, (0.02, 0.08)
    rng = np.random.default_rng(7)
    lag = 40
    vals = [acf(_bandpass(rng.standard_normal(n), *band), max_lag=lag)[lag] for _ in range(400)]
    assert acf_standard_error(n, band) == pytest.approx(np.std(vals), rel=0.2)
    assert acf_standard_error(n, None) == pytest.approx(1 / np.sqrt(n))


def test_guards():
    x = np.sin(2 * np.pi * T[:1000] / 50)
    assert quantisation(x) is None and compression(x) is None
    assert "quantised" in quantisation(np.round(3 * x))
    knots = np.arange(0, 1000, 25)
    assert "compression" in compression(np.interp(T[:1000], knots, x[knots]))
    op = np.clip(40 * x, -30, 30)
    assert saturation(op) and saturation(40 * x + 1e-3 * np.random.default_rng(0).standard_normal(1000)) is None


def test_a_pv_frozen_while_the_op_moves_is_noted_without_changing_the_verdict():
    rng = np.random.default_rng(3)
    op = 40 + np.cumsum(0.05 * rng.standard_normal(751))  # a PI still acting on its error
    dead = np.full(751, 3.5e-44)  # a dead tag (as in a real plant record) or a valve that does not move
    d = diagnose_window(dead, fs=1.0, op=op, sp=np.full(751, 50.0))
    assert d.verdict == "not_oscillating" and "holds 3.5e-44 to the bit" in d.reason
    # a noise-free steady state (OP still as well) is nothing to note; one changed bit is no freeze
    assert frozen_pv(dead, np.full(751, 40.0)) is None
    assert frozen_pv(np.r_[dead[:-1], 3.6e-44], op) is None
    noisy = diagnose_window(50 + 0.01 * rng.standard_normal(751), fs=1.0, op=op, sp=np.full(751, 50.0))
    assert "to the bit" not in noisy.reason


def test_quantised_stick_slip_is_not_called_nonlinear():
    x = np.round(4 * stick_slip(60.0, 0.0, 0))  # 9 levels: a staircase
    d = diagnose_window(x, fs=1.0, config=DiagnosisConfig())
    assert d.verdict != "nonlinear" and "quantised" in d.reason


def test_setpoint_change_switches_to_control_error():
    rng = np.random.default_rng(8)
    sp = np.where(T < 2000, 0.0, 5.0)
    pv = sp + np.sin(2 * np.pi * T / 70) + 0.05 * rng.standard_normal(N)  # a step plus a linear oscillation
    d = diagnose_window(pv, fs=1.0, sp=sp)
    assert "control error" in d.reason and d.verdict == "linear", d.reason
    d = diagnose_window(pv - sp, fs=1.0, sp=np.zeros(N))  # constant set point: PV analysed as it is
    assert "control error" not in d.reason


def test_karnopp_loop_valve_sticks_breaks_away_at_fs_and_jumps_by_fs_minus_fc():
    v = KarnoppLoopValve(fc=2.0, fs=3.0, tau_s=0.02, dv=0.5)
    assert v.update(0.0, 0.1) == 0.0
    for op in np.arange(0.1, 3.0, 0.1):  # net force below F_s: the stem holds
        assert v.update(op, 0.1) == 0.0
    y = v.update(3.05, 0.1)  # breakaway: tau dy/dt = op - y - F_c from y = 0, solved over the step
    assert y == pytest.approx((3.05 - 2.0) * (1 - np.exp(-0.1 / 0.02)), rel=1e-9)
    # slower than DV afterwards: stuck again until the net force exceeds F_s
    assert v.update(3.1, 0.1) == y
    with pytest.raises(Exception):
        KarnoppLoopSpec(fc=3.0, fs=2.0)


def test_karnopp_loop_spec_from_the_paper_valve():
    from models.karnopp import SA_M2, preset

    spec = KarnoppLoopSpec.from_karnopp(preset("low"))
    per_pct = SA_M2 * (206.84e3 - 41.74e3) / 100  # newton per % of the pressure span
    assert spec.fc == pytest.approx(152.7 / per_pct)
    assert spec.tau_s == pytest.approx(4865.0 / 2.05e5)
