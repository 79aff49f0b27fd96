"""The lean fixed-sifting loop of pipeline.emd against stock PyEMD configured identically.

Reference: PyEMD's own ``EMD(FIXE=sifts).emd(x, max_imf=max_imfs)`` (default cubic spline,
simple extrema, nbsym=2), an independent implementation of the same algorithm.  The signals
cover the rules PyEMD applies at the edges of its algorithm: flat steps (plateau extrema),
envelopes with few knots, windows with too few extrema to mirror, trends that end the
decomposition early, and the end condition.
"""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
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


# --- the compiled sift (pipeline.emd._sift_step) on generated windows --------------------------------
# Reference: stock PyEMD configured identically.  Tolerance 1e-9 of the window's range: the kernel
# performs the operations of scipy's CubicSpline / LAPACK dgtsv / PPoly in their order and has given
# identical bits on every window tried, but that equality rests on numpy, scipy and LAPACK keeping
# their operation order (e.g. a LAPACK build that fuses multiply-adds would change the last bits);
# the IMFs of a fixed-sifting EMD are continuous in the samples, so such rounding stays at ~1e-15 of
# the range.  Against the numpy path it was translated from the kernel must be bit-identical: same
# operations, no fastmath.


@st.composite
def windows(draw):
    n = draw(st.integers(16, 2048))
    t = np.arange(n, dtype=float)
    x = np.zeros(n)
    for _ in range(draw(st.integers(1, 3))):
        w = 2 * np.pi * t / draw(st.floats(3.0, 600.0)) + draw(st.floats(0.0, 2 * np.pi))
        shape = draw(st.sampled_from(["sine", "square", "triangle", "sawtooth"]))
        wave = {"sine": np.sin, "square": signal.square, "triangle": lambda w: signal.sawtooth(w, 0.5),
                "sawtooth": signal.sawtooth}[shape](w)
        x += draw(st.floats(1e-3, 1e3)) * wave
    scale = max(float(np.ptp(x)), 1e-3)
    x += draw(st.sampled_from([0.0, 1e-6, 1e-3, 0.1])) * scale * np.random.default_rng(draw(st.integers(0, 2**32 - 1))).standard_normal(n)
    x += draw(st.floats(-2.0, 2.0)) * scale * t / n
    if draw(st.booleans()) and draw(st.booleans()):  # quantised: flat steps, PyEMD's plateau rules
        x = np.round(x / scale * 8) * scale / 8
    return x


@settings(max_examples=60, deadline=None, derandomize=True, database=None)
@given(x=windows(), sifts=st.integers(1, 10), max_imfs=st.sampled_from([-1, 1, 2, 3, 5]), nbsym=st.integers(1, 3))
def test_compiled_sift_equals_stock_pyemd_on_generated_windows(x, sifts, max_imfs, nbsym):
    from pipeline.emd import _BoundedEMD

    compiled = _BoundedEMD(FIXE=sifts, nbsym=nbsym)
    compiled.sift(x, max_imfs)
    ref = EMD(FIXE=sifts, nbsym=nbsym)
    ref.emd(x, max_imf=max_imfs)
    ref_imfs, ref_residue = ref.get_imfs_and_residue()
    assert compiled.imfs.shape == ref_imfs.shape
    tol = 1e-9 * max(float(np.ptp(x)), 1e-300)
    np.testing.assert_allclose(compiled.imfs, ref_imfs, rtol=0, atol=tol)
    np.testing.assert_allclose(compiled.residue, ref_residue, rtol=0, atol=tol)
    numpy_path = _BoundedEMD(FIXE=sifts, nbsym=nbsym)
    numpy_path.compiled = False
    numpy_path.sift(x, max_imfs)
    assert np.array_equal(compiled.imfs, numpy_path.imfs)


def test_compiled_sift_is_used_and_hands_special_rules_back():
    """The kernel sifts ordinary windows itself and leaves PyEMD's special rules untouched."""
    from pipeline.emd import _sift_step

    x = SIGNALS["two tones + square + noise"].copy()
    ext_no, done = _sift_step(x, 2)
    assert done and ext_no > 100 and not np.array_equal(x, SIGNALS["two tones + square + noise"])
    flat = SIGNALS["quantised sine (flat steps)"].copy()
    assert _sift_step(flat, 2) == (-1, False) and np.array_equal(flat, SIGNALS["quantised sine (flat steps)"])
    trend = T[:50] ** 1.5
    assert _sift_step(trend.copy(), 2) == (0, False)


@pytest.mark.slow
def test_kernels_compile_without_a_writable_cache_location():
    """numba refuses ``cache=True`` when no cache location is writable (read-only installation
    and home); the kernel must then compile in memory.  ``IPythonCacheLocator`` as the only
    locator applies nowhere outside IPython: no location at all."""
    import os
    import subprocess
    import sys
    from pathlib import Path

    script = ("import numpy as np\nfrom pipeline.emd import _sift_step, emd\n"
              "from models.valve_effects import _backlash\n"
              "imfs, _ = emd(np.sin(np.arange(1000) / 7.0) + np.sin(np.arange(1000) / 41.0))\n"
              "print(type(_sift_step._cache).__name__, imfs.shape[0])\n"
              "print(type(_backlash._cache).__name__, *_backlash(np.array([0.0, 1.0, 0.5]), 0.25, 0.0))\n")
    env = dict(os.environ, NUMBA_CACHE_LOCATOR_CLASSES="IPythonCacheLocator")
    p = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, timeout=600,
                       env=env, cwd=Path(__file__).resolve().parents[1])
    assert p.returncode == 0, p.stderr
    # the valve kernels too: a backlash of half-width 0.25 driven 0 -> 1 -> 0.5 (planted by hand)
    assert p.stdout.split() == ["NullCache", "3", "NullCache", "0.0", "0.75", "0.75"]
