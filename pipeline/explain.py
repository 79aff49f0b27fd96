"""The arrays behind one window's verdict, for drawing: kept IMFs, IF against IF_z, a_z.

:func:`pipeline.diagnosis.diagnose_window` returns figures only (it runs for every window of every
loop and must stay cheap).  A dashboard that shows *why* a window was called non-linear needs the
decomposition itself; :func:`explain_window` recomputes it for the few windows that are drawn,
from the same public functions and the same configuration, so the arrays agree with the verdict:

* the window is gap-filled and linearly detrended as in the diagnosis;
* EMD with the configured budget (Aftab et al. 2016, eq. 1–2) and the IMFs kept by the
  ``lambda > threshold`` rule (eq. 7–8);
* the *components* whose DNL makes the verdict: for the ``paper`` method the kept IMFs, for the
  ``robust`` method the band-passed oscillation ``[f0/2, (H + 1/2) f0]`` of :mod:`pipeline.robust`
  (its DNL is that of the phase-locked mean wave fitted to the band, the verdict's figure);
* for every component its instantaneous frequency ``IF`` (eq. 3–5), the full-wave zero-crossing
  frequency ``IF_z`` and amplitude ``a_z`` (eq. 10–11) and its DNL (eq. 11).  Intra-wave frequency
  modulation -- ``IF`` swinging around ``IF_z`` within each wave -- is what a sticking valve shows.

Pure: arrays in, a small dataclass out; no I/O, no clock.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy import fft

from .diagnosis import DiagnosisConfig, fill_gaps
from .dnl import imf_dnl
from .emd import emd
from .errors import SignalError
from .frequency import instantaneous_frequency, zero_crossing_references, zero_crossings
from .gate import detrend_linear, oscillation_gate
from .pruning import significant_imfs
from .filters import band_weights
from .robust import refine_f0, mean_wave, wave_dnl

__all__ = ["WindowDetails", "explain_window"]


@dataclass(frozen=True)
class WindowDetails:
    """The decomposition of one window (``N`` samples).

    Attributes
    ----------
    method : ``robust`` or ``paper`` (from the configuration).
    imfs : ``(k, N)`` the IMFs kept by eq. 8 (``k`` may be 0).
    imf_numbers : 1-based numbers of the kept IMFs (IMF 1 = highest frequency).
    component_names : one name per component: ``"band"`` (robust) or ``"imf1"``, ``"imf2"``, ...
    components : ``(m, N)`` the components whose DNL makes the verdict.
    inst_freq, if_z, a_z : ``(m, N)`` IF (Hz, eq. 5), IF_z (Hz) and a_z of every component;
        NaN for a component with fewer than three zero crossings (``a_z`` also outside the
        first and last crossing).
    dnl : DNL of every component (eq. 11); robust method: the DNL of the phase-locked mean wave
        (:func:`pipeline.robust.wave_dnl`), as in the verdict.
    band_hz : the robust band ``(f_lo, f_hi)``; ``None`` for the paper method.
    period_s : the oscillation period used (from the gate or given).
    n_filled : missing samples filled by interpolation.
    """

    method: str
    imfs: np.ndarray
    imf_numbers: tuple[int, ...]
    component_names: tuple[str, ...]
    components: np.ndarray
    inst_freq: np.ndarray
    if_z: np.ndarray
    a_z: np.ndarray
    dnl: tuple[float, ...]
    band_hz: tuple[float, float] | None
    period_s: float
    n_filled: int


def explain_window(x: np.ndarray, *, fs: float, config: DiagnosisConfig = DiagnosisConfig(),
                   period_s: float | None = None) -> WindowDetails:
    """Recompute the decomposition behind the diagnosis of one window (see the module docstring).

    Parameters
    ----------
    x : the analysed 1-D window (NaN = missing), as given to ``diagnose_window``.
    fs : sampling frequency in Hz.
    config : the diagnosis configuration the window was diagnosed with.
    period_s : the oscillation period from the gate, when known (saves running the gate again);
        needed by the robust method.

    Raises
    ------
    SignalError
        the window cannot be explained: too many or too long gaps, or (robust method) no
        oscillation period.
    """
    x = np.asarray(x, dtype=np.float64)
    if x.ndim != 1 or x.size < 8:
        raise SignalError(f"explain_window expects a 1-D window of >= 8 samples, got shape {x.shape}")
    x, n_filled, problem = fill_gaps(x, max_fraction=config.max_missing_fraction, max_gap=config.max_gap_samples)
    if problem:
        raise SignalError(f"window cannot be explained: {problem}")
    if period_s is None or not np.isfinite(period_s) or period_s <= 0:
        gate = oscillation_gate(x, fs=fs, config=config.gate)
        period_s = gate.period_s if gate.oscillating else float("nan")
    y = detrend_linear(x)
    imfs, _ = emd(y, config=config.emd)
    keep = (significant_imfs(imfs, y, threshold=config.lambda_threshold)[0]
            if imfs.shape[0] else np.empty(0, dtype=int))
    kept = imfs[keep]
    numbers = tuple(int(i) + 1 for i in keep)
    band = None
    if config.method == "robust":
        if not np.isfinite(period_s):
            raise SignalError("window cannot be explained by the robust method: it does not oscillate (no period)")
        # what pipeline.robust.robust_dnl_test fits (steps 1-3 of its docstring): the refined f0,
        # the oscillation band [f0/2, (H + 1/2) f0] (drawn, with its IF and IF_z) and the DNL of
        # the phase-locked mean wave (the verdict's figure for the analysed signal)
        h = config.robust.n_harmonics
        f = fft.rfftfreq(y.size, d=1.0 / fs)
        spec = fft.rfft(y)
        f0 = refine_f0(spec, f, 1.0 / period_s)
        band = (f0 / 2.0, min((h + 0.5) * f0, 0.5 * fs))
        components = fft.irfft(spec * band_weights(f, f_lo=band[0], f_hi=band[1], order=4), y.size)[None, :]
        names: tuple[str, ...] = ("band",)
        trim = 1
        wave = float(wave_dnl(mean_wave(spec, f, y.size, f0=f0, n_harmonics=h)[0]))
    else:
        components, names, trim = kept, tuple(f"imf{n}" for n in numbers), config.end_trim_waves
    m, n = components.shape
    inst = np.full((m, n), np.nan)
    ifz = np.full((m, n), np.nan)
    az = np.full((m, n), np.nan)
    dnl = []
    if m:
        inst, _ = instantaneous_frequency(components, fs=fs)
    for i, c in enumerate(components):
        zc = zero_crossings(c)
        if zc.size >= 3:
            ifz[i], az[i] = zero_crossing_references(c, zc, fs=fs)
        dnl.append(imf_dnl(c, fs=fs, end_trim_waves=trim, freq=inst[i]).dnl)
    if config.method == "robust":
        dnl = [wave]
    return WindowDetails(config.method, kept, numbers, names, components, inst, ifz, az, tuple(dnl), band,
                         float(period_s), n_filled)
