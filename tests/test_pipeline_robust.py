"""Robust test, surrogates and data-quality guards, against planted truth."""

import numpy as np
import pytest
from scipy import fft

from pipeline.diagnosis import DiagnosisConfig, diagnose_window
from pipeline.errors import PipelineConfigError
from pipeline.quality import compression, quantisation, saturation
from pipeline.robust import RobustConfig, robust_dnl_test
from pipeline.surrogates import harmonic_free_amplitudes, phase_randomised

N = 4096
T = np.arange(N, dtype=float)


def test_phase_randomised_keeps_the_amplitude_spectrum():
    amp = np.abs(fft.rfft(np.random.default_rng(0).standard_normal(N)))
    amp[0] = 0.0
    s = phase_randomised(amp, N, np.random.default_rng(1), count=3)
    for row in s:
        np.testing.assert_allclose(np.abs(fft.rfft(row))[1:-1], amp[1:-1], rtol=1e-9, atol=1e-9)


def test_harmonic_free_amplitudes_remove_planted_harmonics_only():
    f0 = 64 / N  # exactly on a bin
    x = np.sin(2 * np.pi * f0 * T) + 0.3 * np.sin(2 * np.pi * 3 * f0 * T) + 0.01 * np.random.default_rng(2).standard_normal(N)
    spec = fft.rfft(x)
    f = fft.rfftfreq(N)
    out = harmonic_free_amplitudes(spec, f, f0=f0, f_hi=5 * f0, n_harmonics=5)
    k1, k3 = 64, 192
    assert out[k1] == pytest.approx(np.abs(spec[k1]))  # fundamental untouched
    assert np.abs(spec[k3]) > 100 * out[k3]  # the 3rd harmonic line is down to the floor


def stick_slip(period: float, noise: float, seed: int) -> np.ndarray:
    """A first-order plant's response to a square stem motion (the classic stiction PV shape)."""
    u = np.sign(np.sin(2 * np.pi * T / period))
    y = np.zeros(N)
    a = np.exp(-1.0 / (period / 8))
    for i in range(1, N):
        y[i] = a * y[i - 1] + (1 - a) * u[i - 1]
    return y + noise * np.random.default_rng(seed).standard_normal(N)


@pytest.mark.parametrize("noise", [0.0, 0.02, 0.05])
def test_robust_test_flags_stick_slip_and_passes_sine(noise):
    r = robust_dnl_test(stick_slip(60.0, noise, 1), fs=1.0, period_s=60.0)
    assert r.p_value <= 0.05 and r.dnl >= 0.1, r
    sine = np.sin(2 * np.pi * T / 60.0) + noise * np.random.default_rng(3).standard_normal(N)
    r = robust_dnl_test(sine, fs=1.0, period_s=60.0)
    assert r.p_value > 0.05, r


def test_robust_test_is_deterministic():
    x = stick_slip(45.0, 0.03, 4)
    assert robust_dnl_test(x, fs=1.0, period_s=45.0) == robust_dnl_test(x, fs=1.0, period_s=45.0)


def test_robust_config_refuses_an_impossible_significance():
    with pytest.raises(PipelineConfigError, match="too few"):
        RobustConfig(n_surrogates=9, alpha=0.05)


def test_guards():
    x = np.sin(2 * np.pi * T[:1000] / 50)
    assert quantisation(x) is None and compression(x) is None
    assert "quantised" in quantisation(np.round(3 * x))
    knots = np.arange(0, 1000, 25)
    assert "compression" in compression(np.interp(T[:1000], knots, x[knots]))
    op = np.clip(40 * x, -30, 30)
    assert saturation(op) and saturation(40 * x + 1e-3 * np.random.default_rng(0).standard_normal(1000)) is None


def test_quantised_stick_slip_is_not_called_nonlinear():
    x = np.round(4 * stick_slip(60.0, 0.0, 0))  # 9 levels: a staircase
    d = diagnose_window(x, fs=1.0, config=DiagnosisConfig())
    assert d.verdict != "nonlinear" and "quantised" in d.reason
