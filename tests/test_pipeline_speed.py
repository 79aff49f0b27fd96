"""Speed-ups keep the numbers: the restructured code against straightforward reference
computations kept here (the code as it was before the speed-up, written plainly).

Equality is bit for bit (``np.array_equal`` / ``==``), not to a tolerance: the speed-ups reorder
no arithmetic, they only share or cache intermediate results.
"""

import numpy as np
import pytest
from scipy import fft, signal

from pipeline.filters import band_weights
from pipeline.frequency import zero_crossings
from pipeline.gate import _bandpass, acf, acf_standard_error, detrend_linear, oscillation_gate, regularity

RNG = np.random.default_rng(7)
T = np.arange(4096, dtype=float)


def windows():
    """Oscillating and non-oscillating windows, some of them needing the band-passed candidates."""
    noise = RNG.standard_normal(4096)
    return {
        "sine": np.sin(2 * np.pi * T / 60) + 0.01 * noise,
        "square + ramp": signal.square(2 * np.pi * T / 25) + T / 1000,
        "two tones + noise": np.sin(2 * np.pi * T / 37) + 0.8 * np.sin(2 * np.pi * T / 300) + noise,
        "slow tone in noise": 0.3 * np.sin(2 * np.pi * T / 200) + noise,
        "white noise": noise,
        "random walk": np.cumsum(noise),
        "odd length": np.sin(2 * np.pi * T[:3001] / 45) + 0.5 * noise[:3001],
        "short": np.sin(T[:40]),
    }


def reference_detrend(x):
    t = np.arange(x.size, dtype=np.float64) - (x.size - 1) / 2.0
    return x - x.mean() - np.dot(t, x) / np.dot(t, t) * t


def reference_peaks(r, tp, n_total):
    peaks = []
    for k in (1, 2, 3):
        lo, hi = max(int(np.floor(k * tp - tp / 4)), 1), min(int(np.ceil(k * tp + tp / 4)) + 1, r.size)
        if hi > lo:
            lags = np.arange(lo, hi)
            peaks.append(float(np.max(r[lo:hi] / (1.0 - lags / n_total))))
    return min(peaks) if peaks else np.nan


def reference_standard_error(n, band):
    g = band_weights(fft.rfftfreq(n), f_lo=band[0], f_hi=band[1]) ** 2
    rho = fft.irfft(g, n)
    rho = rho / rho[0]
    return float(np.sqrt(np.sum(rho**2) / n))


@pytest.mark.parametrize("name", list(windows()))
def test_gate_pieces_equal_the_plain_computation(name):
    x = windows()[name]
    y = detrend_linear(x)
    assert np.array_equal(y, reference_detrend(x))
    n = x.size
    r = acf(y, max_lag=(2 * n) // 3)
    tp, _, nper, pers = regularity(r, n_total=n, min_periods=2)
    if np.isfinite(tp):
        assert pers == reference_peaks(r, tp, n)
        z = zero_crossings(r)
        periods = (z[2:] - z[:-2])[:20]
        assert tp == float(periods.mean()) and nper == periods.size
    for band in ((0.01, 0.04), (0.1, 0.4), (0.2, 0.5)):
        w = band_weights(fft.rfftfreq(n), f_lo=band[0], f_hi=band[1])
        plain = fft.irfft(fft.rfft(y) * w, n)
        assert np.array_equal(_bandpass(y, *band), plain)
        assert np.array_equal(_bandpass(y, *band, spectrum=fft.rfft(y), weights=w), plain)
        assert acf_standard_error(n, band) == reference_standard_error(n, band)
        assert acf_standard_error(n, band, weights=w) == reference_standard_error(n, band)


def test_detrend_of_float32_keeps_its_old_precision_rules():
    x = np.sin(T[:100] / 7).astype(np.float32)
    assert np.array_equal(detrend_linear(x), reference_detrend(x))


def test_gate_decides_on_band_candidates_for_irregular_windows():
    """The shared spectrum path is exercised: a window whose raw ACF is irregular passes in a band."""
    results = [oscillation_gate(x, fs=1.0) for x in windows().values()]
    assert any(g.band_hz is not None for g in results)
    assert any(g.band_hz is None and g.oscillating for g in results)


def reference_evaluate(xk, yk, coefficients, counts, t):
    """The spline evaluation one repeat per coefficient (before the five rows were repeated at once)."""
    s, c2, c3 = coefficients
    u = t - np.repeat(xk[:-1], counts)
    y = np.repeat(s[:-1], counts) * u + np.repeat(yk[:-1], counts)
    y += np.repeat(c2, counts) * (u * u)
    y += np.repeat(c3, counts) * (u * u * u)
    return y


@pytest.mark.parametrize("name", ["sine", "square + ramp", "two tones + noise", "white noise"])
def test_emd_still_equals_stock_pyemd_bit_for_bit(name):
    from PyEMD import EMD

    from pipeline.emd import EMDConfig, emd

    x = detrend_linear(windows()[name])
    imfs, _ = emd(x, config=EMDConfig())
    stock = EMD(FIXE=4)
    stock.emd(x, max_imf=3)
    ref, _ = stock.get_imfs_and_residue()
    assert np.array_equal(imfs, ref)


def test_spline_evaluation_equals_one_repeat_per_coefficient():
    from pipeline.emd import _evaluate, _not_a_knot_coefficients

    xk = np.cumsum(RNG.integers(1, 30, 200)).astype(float) - 5.0
    yk = RNG.standard_normal(200)
    t = np.arange(0.0, xk[-1] + 1)
    coefficients = _not_a_knot_coefficients(xk, yk, (xk.size,))
    counts = np.diff(np.concatenate(([0], np.searchsorted(t, xk[1:-1]), [t.size])))
    assert np.array_equal(_evaluate(xk, yk, coefficients, counts, t), reference_evaluate(xk, yk, coefficients, counts, t))
