"""The lean fixed-sifting loop of pipeline.emd against stock PyEMD configured identically.

Reference: PyEMD's own ``EMD(FIXE=sifts).emd(x, max_imf=max_imfs)`` (default cubic spline,
simple extrema, nbsym=2), an independent implementation of the same algorithm.  The signals
cover the rules PyEMD applies at the edges of its algorithm: flat steps (plateau extrema),
envelopes with few knots, windows with too few extrema to mirror, trends that end the
decomposition early, and the end condition.
"""

import numpy as np
import pytest
from PyEMD import EMD
from scipy import signal

from pipeline.emd import EMDConfig, emd, not_a_knot_spline
from pipeline.gate import detrend_linear

T = np.arange(4096, dtype=float)
RNG = np.random.default_rng(42)
NOISE = RNG.standard_normal(4096)

SIGNALS = {
    "two tones + square + noise": np.sin(T / 5) + 0.5 * signal.square(T / 50) + 0.2 * NOISE,
    "clean square": signal.square(2 * np.pi * T / 60),
    "clean square detrended": detrend_linear(signal.square(2 * np.pi * T / 25)),
    "square + 1% noise": signal.square(2 * np.pi * T / 150) + 0.01 * NOISE,
    "clean triangle": signal.sawtooth(2 * np.pi * T / 60, 0.5),
    "triangle + 1% noise": signal.sawtooth(2 * np.pi * T / 25, 0.5) + 0.01 * NOISE,
    "white noise": NOISE,
    "random walk": np.cumsum(NOISE) * 0.1,
    "quantised sine (flat steps)": np.round(4 * np.sin(2 * np.pi * T / 97)),
    "x + x^2 (paper eq. 9)": (lambda x: x + x**2)(np.sin(2 * np.pi * 0.05 * T) + np.sin(2 * np.pi * 0.1 * T)),
    "1.5 periods on a ramp (a trend after one IMF)": (np.sin(2 * np.pi * T / 2731) + T / 4096)[:3000],
    "1.3 periods on a ramp (envelopes of 3 knots)": np.sin(2 * np.pi * T[:1300] / 1000) + T[:1300] / 2000,
    "short noisy window": NOISE[:64] + np.sin(T[:64]),
}
CONFIGS = [EMDConfig(), EMDConfig(sifts=1, max_imfs=-1), EMDConfig(sifts=10, max_imfs=5)]


def stock(x, config):
    e = EMD(FIXE=config.sifts)
    e.emd(x, max_imf=config.max_imfs)
    return e.get_imfs_and_residue()


@pytest.mark.parametrize("config", CONFIGS, ids=str)
@pytest.mark.parametrize("name", SIGNALS)
def test_lean_sifting_equals_stock_pyemd(name, config):
    x = SIGNALS[name]
    imfs, residue = emd(x, config=config)
    ref_imfs, ref_residue = stock(x, config)
    assert imfs.shape == ref_imfs.shape
    np.testing.assert_allclose(imfs, ref_imfs, rtol=0, atol=1e-9)
    np.testing.assert_allclose(residue, ref_residue, rtol=0, atol=1e-9)
    np.testing.assert_allclose(imfs.sum(0) + residue, x, atol=1e-9)


@pytest.mark.parametrize("seed", range(20))
def test_lean_sifting_equals_stock_pyemd_random_windows(seed):
    rng = np.random.default_rng(seed)
    n = int(rng.integers(40, 3000))
    t = np.arange(n, dtype=float)
    w = 2 * np.pi * t / rng.uniform(4, 200) + rng.uniform(0, 2 * np.pi)
    shape = [np.sin(w), signal.square(w), signal.sawtooth(w, rng.uniform(0, 1)), np.round(3 * np.sin(w))][seed % 4]
    x = rng.uniform(0.1, 10) * shape + rng.choice([0.0, 1e-3, 0.1]) * rng.standard_normal(n) + rng.uniform(-1, 1) * t / n
    config = EMDConfig(sifts=int(rng.integers(1, 12)), max_imfs=int(rng.choice([-1, 2, 3, 4])))
    imfs, _ = emd(x, config=config)
    ref_imfs, _ = stock(x, config)
    assert imfs.shape == ref_imfs.shape
    np.testing.assert_allclose(imfs, ref_imfs, rtol=0, atol=1e-9)


def test_monotonic_window_has_no_imf():
    imfs, residue = emd(T[:100] ** 1.5, config=EMDConfig())
    assert imfs.shape == (0, 100)
    np.testing.assert_allclose(residue, T[:100] ** 1.5)


def test_not_a_knot_spline_matches_scipy_bit_for_bit_or_close():
    from scipy.interpolate import CubicSpline

    xk = np.array([-7.0, -2.0, 3.0, 10.0, 11.0, 40.0, 41.0, 100.0])
    yk = np.sin(xk)
    t = np.arange(0.0, 100.0)
    np.testing.assert_allclose(not_a_knot_spline(xk, yk, t), CubicSpline(xk, yk)(t), rtol=0, atol=1e-12)


@pytest.mark.parametrize("dtype", [np.float64, np.float32])
def test_emd_method_returns_what_pyemd_returns(dtype):
    """PyEMD's calling convention (IMFs and residue stacked) and its precision (float32 input is
    sifted in float32 by PyEMD, so the lean float64 loop must not take it)."""
    from pipeline.emd import _BoundedEMD

    x = SIGNALS["two tones + square + noise"].astype(dtype)
    ours = _BoundedEMD(FIXE=4).emd(x, max_imf=3)
    ref = EMD(FIXE=4).emd(x, max_imf=3)
    assert ours.dtype == ref.dtype and ours.shape == ref.shape
    np.testing.assert_allclose(ours, ref, rtol=0, atol=1e-9 if dtype == np.float64 else 0)
