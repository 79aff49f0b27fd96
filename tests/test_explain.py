"""pipeline.explain: the arrays behind a window's verdict.

Planted truth: a sinusoid of known frequency (IF and IF_z at that frequency, DNL near 0), the
same window diagnosed by ``diagnose_window`` (the explained DNL is the DNL of the verdict, for both
methods), and windows that cannot be explained."""

import numpy as np
import pytest

from models.loop import scenario_for_case, simulate_loop
from pipeline.diagnosis import DiagnosisConfig, diagnose_window
from pipeline.errors import SignalError
from pipeline.explain import explain_window

N, FS = 1024, 1.0


def sine(f=1 / 40.0, noise=0.0, seed=0):
    t = np.arange(N) / FS
    return np.sin(2 * np.pi * f * t) + noise * np.random.default_rng(seed).standard_normal(N)


@pytest.mark.parametrize("method", ["robust", "paper"])
def test_sinusoid_if_and_if_z_at_the_planted_frequency(method):
    f = 1 / 40.0
    det = explain_window(sine(f), fs=FS, config=DiagnosisConfig(method=method))
    assert det.components.shape[1] == N and det.inst_freq.shape == det.components.shape
    main = int(np.argmax(np.sum(det.components**2, axis=1)))
    mid = slice(100, N - 100)                          # away from the window's ends
    assert np.median(det.if_z[main, mid]) == pytest.approx(f, rel=0.01)
    assert np.median(det.inst_freq[main, mid]) == pytest.approx(f, rel=0.01)
    assert det.dnl[main] < 0.02                        # no intra-wave modulation in a sinusoid
    assert det.period_s == pytest.approx(1 / f, rel=0.05)


def test_robust_component_is_the_band_and_the_kept_imf_is_the_sinusoid():
    x = sine(1 / 40.0, noise=0.05)
    det = explain_window(x, fs=FS, config=DiagnosisConfig())
    assert det.component_names == ("band",) and det.method == "robust"
    lo, hi = det.band_hz
    # pipeline.robust: [f0/2, (H + 1/2) f0] with H = 5 harmonics
    assert lo == pytest.approx(1 / 80.0, rel=0.05) and hi == pytest.approx(5.5 / 40.0, rel=0.05)
    assert det.imfs.shape == (len(det.imf_numbers), N) and len(det.imf_numbers) >= 1
    planted = np.sin(2 * np.pi * np.arange(N) / 40.0)
    best = max(np.corrcoef(c, planted)[0, 1] for c in det.imfs)
    assert best > 0.95                                 # IMF 1 holds the noise and is pruned (eq. 8)
    # the band component keeps the planted sinusoid (unit amplitude) and drops most of the noise
    resid = det.components[0, 100:-100] - np.sin(2 * np.pi * np.arange(100, N - 100) / 40.0)
    assert np.std(resid) < 0.05


@pytest.mark.parametrize("case", ["stiction-datadriven", "tuning"])
@pytest.mark.parametrize("method", ["robust", "paper"])
def test_explained_dnl_is_the_verdicts_dnl(case, method):
    sim = simulate_loop(scenario_for_case(case, duration_s=2200.0), seed=0)
    x = sim.pv[1000:1000 + N]
    cfg = DiagnosisConfig(method=method)
    d = diagnose_window(x, fs=FS, config=cfg)
    det = explain_window(x, fs=FS, config=cfg, period_s=d.gate.period_s)
    # the verdict fits the window together with its surrogates (batched single-precision sums)
    np.testing.assert_allclose(det.dnl, d.dnl, rtol=1e-9, atol=1e-12)
    if method == "paper":
        assert det.imf_numbers == d.imfs_kept
        assert det.component_names == tuple(f"imf{i}" for i in d.imfs_kept)


def test_windows_that_cannot_be_explained():
    x = sine()
    x[100:120] = np.nan
    with pytest.raises(SignalError, match="gap"):
        explain_window(x, fs=FS)
    noise = np.random.default_rng(1).standard_normal(N)
    with pytest.raises(SignalError, match="does not oscillate"):
        explain_window(noise, fs=FS)                      # robust method needs a period
    with pytest.raises(SignalError):
        explain_window(np.ones((2, N)), fs=FS)


def test_short_gaps_are_filled_as_in_the_diagnosis():
    x = sine()
    x[500:503] = np.nan
    det = explain_window(x, fs=FS)
    assert det.n_filled == 3 and np.all(np.isfinite(det.components))
