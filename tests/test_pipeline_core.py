"""Unit tests of the numerical core, each against an independent expected value."""

import numpy as np
import pytest
from scipy import signal
from scipy.interpolate import CubicSpline
from PyEMD import EMD

from pipeline.dnl import imf_dnl, tdnl
from pipeline.emd import EMDConfig, emd, not_a_knot_spline
from pipeline.errors import PipelineConfigError, SignalError
from pipeline.frequency import instantaneous_frequency, zero_crossing_references, zero_crossings
from pipeline.gate import GateConfig, acf, oscillation_gate
from pipeline.pruning import imf_correlation, significant_imfs

N = 4096
T = np.arange(N, dtype=float)


# ---------------------------------------------------------------- gate (Thornhill et al. 2003)
def test_acf_matches_direct_sum():
    x = np.random.default_rng(0).standard_normal(300)
    x -= x.mean()
    direct = np.array([np.dot(x[: x.size - k], x[k:]) for k in range(50)]) / np.dot(x, x)
    np.testing.assert_allclose(acf(x, max_lag=49), direct, atol=1e-12)


@pytest.mark.parametrize("period", [12.0, 40.0, 137.0, 500.0])
@pytest.mark.parametrize("shape", ["sine", "square", "triangle"])
def test_gate_finds_planted_period(period, shape):
    rng = np.random.default_rng(int(period))
    w = 2 * np.pi * T / period + 0.3
    x = {"sine": np.sin(w), "square": signal.square(w), "triangle": signal.sawtooth(w, 0.5)}[shape]
    x = 2.0 * x + 0.1 * rng.standard_normal(N) + 0.001 * T  # with a ramp, removed by detrending
    g = oscillation_gate(x, fs=2.0)
    assert g.oscillating, g.reason
    assert g.period_s == pytest.approx(period / 2.0, rel=0.02)
    assert g.regularity > 1
    # robust half peak-to-peak (5-95 % range / 2): 0.988 A for a sine, 0.9 A for a triangle, and
    # for a square wave A + 1.28 sigma (the 90th percentile of the noise on each plateau)
    expected = {"sine": 2.0 * np.sin(0.45 * np.pi), "square": 2.0 + 1.2816 * 0.1, "triangle": 1.8}[shape]
    assert g.amplitude == pytest.approx(expected, rel=0.06)


@pytest.mark.parametrize("seed", range(5))
def test_gate_rejects_white_and_damped_noise(seed):
    rng = np.random.default_rng(seed)
    assert not oscillation_gate(rng.standard_normal(N), fs=1.0).oscillating
    # noise through a well-damped second-order loop (zeta = 0.5): resonant, not oscillating
    r, w = np.exp(-0.5 * 0.2), 0.2 * np.sqrt(1 - 0.25)
    y = signal.lfilter([1], [1, -2 * r * np.cos(w), r * r], rng.standard_normal(N))
    assert not oscillation_gate(y, fs=1.0).oscillating


def test_gate_two_oscillations_reports_one_of_them():
    x = np.sin(2 * np.pi * T / 17) + 1.2 * np.sin(2 * np.pi * T / 63 + 1)
    g = oscillation_gate(x, fs=1.0)
    assert g.oscillating
    assert min(abs(g.period_s - 17), abs(g.period_s - 63)) / g.period_s < 0.03


def test_gate_needs_several_periods():
    g = oscillation_gate(np.sin(2 * np.pi * T[:1000] / 400), fs=1.0)
    assert not g.oscillating


def test_gate_constant_and_bad_input():
    assert not oscillation_gate(np.full(500, 3.0), fs=1.0).oscillating
    with pytest.raises(SignalError):
        oscillation_gate(np.r_[1.0, np.nan, 2.0] * np.ones(3), fs=1.0)
    with pytest.raises(PipelineConfigError, match="min_regularity"):
        GateConfig(min_regularity=0)


# ---------------------------------------------------------------- EMD
@pytest.mark.parametrize("n_knots", [4, 5, 17, 300])
def test_not_a_knot_spline_equals_scipy_cubicspline(n_knots):
    rng = np.random.default_rng(n_knots)
    xk = np.sort(rng.choice(2000, n_knots, replace=False)).astype(float) / 1999.0
    yk = rng.standard_normal(n_knots)
    t = np.arange(2000) / 1999.0
    t = t[(t >= xk[0]) & (t <= xk[-1])]
    np.testing.assert_allclose(not_a_knot_spline(xk, yk, t), CubicSpline(xk, yk)(t), atol=1e-10)


def test_bounded_emd_equals_pyemd_fixed_sifting_and_reconstructs():
    x = np.sin(T / 5) + 0.5 * signal.square(T / 50) + 0.2 * np.random.default_rng(1).standard_normal(N)
    imfs, residue = emd(x, config=EMDConfig(sifts=6, max_imfs=3))
    assert imfs.shape == (3, N)
    np.testing.assert_allclose(imfs.sum(0) + residue, x, atol=1e-10)
    reference = EMD(FIXE=6).emd(x, max_imf=3)[:3]
    np.testing.assert_allclose(imfs, reference, atol=1e-9)


def test_emd_separates_two_tones():
    x = np.sin(2 * np.pi * T[:2000] / 10) + np.sin(2 * np.pi * T[:2000] / 80)
    imfs, _ = emd(x, config=EMDConfig(sifts=10, max_imfs=2))
    np.testing.assert_allclose(imfs[0][200:-200], np.sin(2 * np.pi * T[200:1800] / 10), atol=0.1)


def test_emd_config_validation():
    with pytest.raises(PipelineConfigError, match="max_imfs"):
        EMDConfig(max_imfs=0)


# ---------------------------------------------------------------- pruning (eq. 7-8)
def test_lambda_against_numpy_corrcoef():
    rng = np.random.default_rng(2)
    x = rng.standard_normal(500)
    imfs = np.vstack([x + rng.standard_normal(500), 0.1 * rng.standard_normal(500), -x])
    rho = imf_correlation(imfs, x)
    expected = [np.corrcoef(c, x)[0, 1] for c in imfs]
    np.testing.assert_allclose(rho, expected, atol=1e-12)
    keep, lam = significant_imfs(imfs, x)
    assert list(keep) == [0]
    assert lam[0] == 1.0


# ---------------------------------------------------------------- IF (eq. 3-5), IF_z and a_z
def test_if_of_a_tone_is_its_frequency():
    f0 = 0.037
    freq, amp = instantaneous_frequency(3.0 * np.cos(2 * np.pi * f0 * T), fs=1.0)
    np.testing.assert_allclose(freq[300:-300], f0, rtol=2e-3)
    np.testing.assert_allclose(amp[300:-300], 3.0, rtol=2e-3)


def test_zero_crossing_references_of_a_tone():
    period = 50.0
    c = 2.5 * np.sin(2 * np.pi * (T[:1000] + 0.3) / period)
    zc = zero_crossings(c)
    np.testing.assert_allclose(np.diff(zc), period / 2, atol=1e-2)
    ifz, az = zero_crossing_references(c, zc, fs=4.0)
    np.testing.assert_allclose(ifz, 4.0 / period, rtol=1e-3)
    inside = np.isfinite(az)
    np.testing.assert_allclose(az[inside], 2.5, rtol=5e-3)


# ---------------------------------------------------------------- DNL (eq. 11-12)
def test_dnl_of_a_tone_is_near_zero():
    # 102.4 periods in the window: the FFT-based Hilbert transform leaks a little at the ends
    assert imf_dnl(np.sin(2 * np.pi * T / 40), fs=1.0).dnl < 0.01
    assert imf_dnl(np.sin(2 * np.pi * T / 64), fs=1.0).dnl < 1e-6  # whole number of periods


@pytest.mark.parametrize("eps", [0.05, 0.2, 0.4])
def test_dnl_of_intra_wave_fm_is_eps_over_sqrt2(eps):
    """c = cos(wt + eps sin wt): IF = w(1 + eps cos wt)/2pi, IF_z = w/2pi, a_z = 1 (analytic),
    so (IF - IF_z)/IF_z = eps cos wt and DNL = std(eps cos wt) = eps / sqrt(2)."""
    w = 2 * np.pi / 64
    c = np.cos(w * T + eps * np.sin(w * T))
    assert imf_dnl(c, fs=1.0).dnl == pytest.approx(eps / np.sqrt(2), rel=0.05)


def test_dnl_weights_by_zero_crossing_amplitude():
    """Eq. 11 weights by a_z / mean(a_z): FM only in the large waves counts more."""
    w = 2 * np.pi / 64
    big = (T < N / 2).astype(float)  # first half of the window: large, modulated waves
    amp = np.where(big > 0, 2.0, 1.0)
    eps = 0.2 * big
    c = amp * np.cos(w * T + eps * np.sin(w * T))
    analytic_if = w * (1 + eps * np.cos(w * T)) / (2 * np.pi)  # isolates eq. 11 from Hilbert artefacts
    d = imf_dnl(c, fs=1.0, freq=analytic_if).dnl
    # half the waves modulated with eps=0.2 at weight 2/1.5: std = 0.2/sqrt(2) * (4/3) / sqrt(2)
    assert d == pytest.approx(0.2 / np.sqrt(2) * (4 / 3) / np.sqrt(2), rel=0.03)


def test_tdnl_is_energy_weighted():
    imfs = np.vstack([np.ones(10) * 2.0, np.ones(10)])  # energies 40 and 10
    assert tdnl(np.array([0.5, 0.1]), imfs) == pytest.approx((0.5 * 40 + 0.1 * 10) / 50)
    assert tdnl(np.array([np.nan, 0.1]), imfs) == pytest.approx(0.1)
    assert np.isnan(tdnl(np.array([np.nan]), imfs[:1]))


def test_imf_without_full_wave_has_no_dnl():
    assert np.isnan(imf_dnl(np.linspace(-1, 1, 100), fs=1.0).dnl)


def test_gate_passes_short_and_fast_oscillations():
    """Planted: 4.5 periods of a sine in a 450-sample record; a 3.3-sample period."""
    rng = np.random.default_rng(3)
    t = np.arange(450)
    g = oscillation_gate(np.sin(2 * np.pi * t / 100) + 0.1 * rng.standard_normal(t.size), fs=1.0)
    assert g.oscillating and g.period_s == pytest.approx(100, rel=0.1), g
    t = np.arange(1441)
    g = oscillation_gate(np.sin(2 * np.pi * t / 3.3) + 0.2 * rng.standard_normal(t.size), fs=1.0)
    assert g.oscillating and g.period_s == pytest.approx(3.3, rel=0.05), g

