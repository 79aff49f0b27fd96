"""Oscillation gate: is a window oscillating, at what period, how regularly?

Method: Thornhill, Huang & Zhang (2003), "Detection of multiple oscillations in control loops",
J. Process Control 13:91–100.  The autocovariance function (ACF) of an oscillating signal
oscillates with the same period; the intervals between its zero crossings are then regular.
With zero-crossing lags ``z_1 < z_2 < ...`` of the ACF, every full period is estimated as
``T_k = z_{k+2} - z_k`` and the regularity factor is (Thornhill et al. 2003, eq. 2)::

    r = mean(T) / (3 * std(T))          oscillation is regular if r > 1

Several oscillations at once (a tuning mode and a disturbance, say) make the raw ACF irregular;
Thornhill et al. (2003, §3) then band-pass filter around each spectral peak and apply the test
to every band.  We do the same, with a band of two octaves, ``[f0/2, 2 f0]``, around each of the
strongest peaks of the smoothed periodogram; the raw signal is tried first.

Choices the method leaves open, documented here:

* detrending: a straight line is removed from the window before anything else;
* the ACF is the biased estimate (divided by N) from an FFT, up to lag ``2N/3``; at least
  ``min_periods`` full-period estimates (``min_periods + 2`` zero crossings) are needed, so the
  window must hold about four periods or more (default 3 estimates; periods down to 3 samples);
* sustained, not resonant: band-limited noise (a well-damped loop excited by noise, or noise
  band-passed by the filter above) also has an ACF with a few regular zero crossings near lag
  zero, but its ACF peaks are small and die out.  We require every ACF peak near ``T``, ``2T``
  and ``3T`` (corrected for the ``1 - lag/N`` taper of the biased estimator) to reach
  ``max(min_persistence, z * se)``, where ``se`` is the standard error of the ACF of white
  noise through the same filter (Bartlett's formula, ``se^2 = sum_k rho_h(k)^2 / N`` with
  ``rho_h`` the filter's own autocorrelation; ``1/sqrt(N)`` for the unfiltered window) and
  ``z = 3``: the peaks must be significant for this window length and band, not a fixed number.
  For a band-passed candidate the null is not white but a power law ``f^b`` fitted to the
  periodogram outside the band (Vaughan 2005; :func:`power_law_background`), so that drifting,
  coloured noise does not pass for an oscillation; and ``se`` is inflated by
  ``sqrt(N / (N - kT))`` for the furthest peak ``kT`` checked (the taper-corrected ACF there
  averages only ``N - kT`` products), which lets short records (3 period estimates) be judged
  without loosening the test.
  ``min_persistence`` (default 0.1) asks that the periodic part carry at least a tenth of the
  analysed variance.  This check is ours, not Thornhill's;
* amplitude: half the 5 %–95 % percentile range of the detrended window (robust half
  peak-to-peak: ``A`` for a square wave of amplitude ``A``, ``0.99 A`` for a sine).

Second detector, for band-passed candidates whose ACF test fails (ours; added because an
oscillation whose period and amplitude wander keeps regular zero crossings but an ACF that
dies out within three periods, like a resonance's): **a steady envelope**.  The envelope of the
analytic band-passed signal follows the oscillation whatever its period does, so wander costs
it nothing.  Gaussian noise of *any* spectrum (white, red, a random walk, a damped resonance)
has, in any band, a Rayleigh envelope: the squared envelope ``u = |z|^2`` of the analytic
band-passed signal ``z`` is exponential (Rice 1944-45, "Mathematical analysis of random noise",
Bell Syst. Tech. J. 23:282-332, 24:46-156: the envelope of Gaussian noise, and of a sine plus
noise); what sets it apart is its deep fades, ``u`` near 0 once every few cycles.  The test
statistic is Moran's (Moran 1951, "The random division of an interval, Part II", J. R. Stat.
Soc. B 13:147-150; the locally most powerful test of an exponential against gamma
distributions), ``m = log(mean u) - mean(log u)``: Euler's ``gamma = 0.5772`` for exponential
``u`` at any scale, 0 for a constant amplitude, ``ln(1 + 1/K) - E1(K)`` for a sine in noise
(Rician ``u``, ``K`` the in-band power ratio; ``E[ln u]`` from Lapidoth & Moser 2003, IEEE
Trans. Inf. Theory 49:2426-2467), and ``2 s^2`` for an amplitude that wanders log-normally with
log-sd ``s`` (0.32 at ``s = 0.4``, whose ``var(u)/mean(u)^2`` of 0.9 is hard to tell from
noise's 1: the logarithm weighs the fades, not the bursts that level steps add).  Under the
Gaussian null, two samples of ``u`` at lag ``k`` are bivariate exponential with correlation
``kappa_k = |rho_k|^2`` (``rho`` the complex autocorrelation of the band-passed null: the same
power-law background as the ACF test), whose Laguerre expansion, with
``E[u L_j(u)] = -[j = 1]`` and ``E[log(u) L_j(u)] = -1/j``, gives by the delta method
``var(m) = (1/n) sum_k (Li2(kappa_k) - kappa_k)`` (``(pi^2/6 - 1)/n`` for independent samples)
and the bias ``E[m] = gamma - sum_k kappa_k / (2 n)`` (:func:`envelope_test`; checked by
simulation in ``tests/test_gate.py``).  A band passes when ``m`` is below its null mean by
``z`` standard errors, ``z`` the one-sided level of ``acf_z`` (``P = 0.00135`` for 3)
Bonferroni-corrected over the ``max_bands`` candidates (3.32 for 3 bands), *and* the zero
crossings of the band-passed signal itself are regular by Thornhill's criterion
(``r > min_regularity`` over at least ``min_periods`` period estimates
``T_k = z_{k+2} - z_k``) within the period limits.  Non-Gaussian non-oscillations (spikes,
steps) have bursts, ``m`` above the null's, and fail.  (Sessions 4-7 used
``q = var(u) / mean(u)^2``, 1 under the null; Moran's ``m`` replaced it in session 8: planted
wandering oscillations 0.84 -> 0.97 found, no planted negative changed, ACCURACY.md.)

Third stage, for windows in which only part oscillates (ours): **half windows**.  An
oscillation present on a stretch of the window, or riding on level shifts and excursions in the
other part, fails both detectors on the whole window: the quiet or stepping part dilutes the
ACF peaks, and band-passed steps add envelope bursts.  When the whole window fails, its first,
middle and last halves are tested with the band-passed candidates (not the raw signal, whose
white null is the gate's known weak point), at ``acf_z`` Bonferroni-corrected over the three
halves (3.32 for ``acf_z = 3``; the envelope detector then at 3.6 over three bands); a half's
ACF pass must also have an envelope steadier than Gaussian noise's at the one-sided 5 % level
(z >= 1.645).  Under Gaussian nulls the ACF peak's and the envelope's z are uncorrelated
(measured: r = -0.01 for ``q``, session 5; r = 0.005 for Moran's ``m``, whose z had mean
-0.03, sd 1.02, 3.8 % at or above 1.645 and none above 3.32, over 1800 band candidates of
white, red, random-walk and resonant noise, 300-4096 samples, session 8),
so the two together reject a Gaussian null at about ``P(ACF) x 0.05``: the guard that the
power-law null's approximation (a resonance's ACF over half the samples) does not become a
false alarm.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from functools import lru_cache

import numpy as np
from scipy import fft, signal, special

from .errors import PipelineConfigError, SignalError
from .filters import band_weights
from .frequency import zero_crossings

__all__ = ["GateConfig", "GateResult", "oscillation_gate", "acf", "regularity", "envelope_test"]


@dataclass(frozen=True)
class GateConfig:
    """Thresholds of the oscillation gate (Thornhill et al. 2003).

    Parameters
    ----------
    min_regularity : r above which the ACF zero crossings count as regular (paper value 1).
    min_persistence : lowest ACF peak over the first three periods (share of the variance that
        is periodic).
    acf_z : the ACF peaks must also exceed ``acf_z`` standard errors of the null's ACF; and a
        band-passed candidate's envelope must be ``acf_z`` standard errors steadier than
        Gaussian noise's for the second detector (:func:`envelope_test`).
    min_periods : fewest full-period estimates from ACF zero crossings.
    min_period_samples : shortest period considered an oscillation, in samples.
    max_bands : spectral peaks tried with band-pass filtering when the raw ACF is irregular.
    half_windows : when the whole window fails, also test its first, middle and last halves
        (module docstring, third stage).
    """

    min_regularity: float = 1.0
    min_persistence: float = 0.1
    acf_z: float = 3.0
    min_periods: int = 3
    min_period_samples: float = 3.0
    max_bands: int = 3
    half_windows: bool = True

    def __post_init__(self) -> None:
        if not self.min_regularity > 0:
            raise PipelineConfigError(
                f"min_regularity={self.min_regularity!r} must be > 0, or every noise would pass the gate"
            )
        if not 0 <= self.min_persistence < 1:
            raise PipelineConfigError(
                f"min_persistence={self.min_persistence!r} must be in [0, 1): it is an autocorrelation"
            )
        if not self.acf_z >= 0:
            raise PipelineConfigError(f"acf_z={self.acf_z!r} must be >= 0 (standard errors)")
        if self.min_periods < 2:
            raise PipelineConfigError(
                f"min_periods={self.min_periods!r} must be >= 2: regularity needs a standard deviation"
            )
        if not self.min_period_samples >= 2:
            raise PipelineConfigError(
                f"min_period_samples={self.min_period_samples!r} must be >= 2 (Nyquist)"
            )
        if self.max_bands < 0:
            raise PipelineConfigError(f"max_bands={self.max_bands!r} must be >= 0")


@dataclass(frozen=True)
class GateResult:
    """Outcome of the oscillation gate for one window.

    ``period_s``, ``regularity`` and ``persistence`` describe the best candidate found even when
    the window is judged not oscillating (NaN when no candidate had enough zero crossings).
    ``band_hz`` is the pass band used, or ``None`` when the raw signal passed.
    """

    oscillating: bool
    period_s: float
    amplitude: float
    regularity: float
    persistence: float
    n_periods: int
    band_hz: tuple[float, float] | None
    reason: str


def acf(x: np.ndarray, *, max_lag: int | None = None) -> np.ndarray:
    """Biased autocorrelation of a zero-mean 1-D signal, normalised to 1 at lag 0, via FFT."""
    x = np.asarray(x, dtype=np.float64)
    n = x.size
    nfft = fft.next_fast_len(2 * n - 1, real=True)
    spec = fft.rfft(x, nfft)
    r = fft.irfft(spec.real**2 + spec.imag**2, nfft)[: n if max_lag is None else max_lag + 1]
    return r / r[0] if r[0] > 0 else np.zeros_like(r)


@lru_cache(maxsize=16)
def _centred_time(n: int) -> tuple[np.ndarray, float]:
    """Sample times centred on the window's middle and their sum of squares (read-only, cached)."""
    t = np.arange(n, dtype=np.float64) - (n - 1) / 2.0
    t.flags.writeable = False
    return t, float(np.dot(t, t))


def detrend_linear(x: np.ndarray) -> np.ndarray:
    """``x`` minus its least-squares straight line (closed form; same as ``scipy.signal.detrend``)."""
    n = x.size
    if n < 2:
        return x - x.mean() if n else x.copy()
    t, tt = _centred_time(n)
    slope = np.dot(t, x) / tt
    if x.dtype != np.float64:
        return x - x.mean() - slope * t
    y = x - x.mean()
    y -= slope * t
    return y


def robust_amplitude(y: np.ndarray) -> float:
    """Half the 5 %–95 % percentile range (robust half peak-to-peak), nearest-rank percentiles."""
    if y.size == 0:
        return 0.0
    k5, k95 = int(round(0.05 * (y.size - 1))), int(round(0.95 * (y.size - 1)))
    part = np.partition(y, (k5, k95))
    return float(part[k95] - part[k5]) / 2.0


def _full_periods(c: np.ndarray) -> np.ndarray:
    """Full-period estimates ``T_k = z_{k+2} - z_k`` from the zero crossings ``z`` of ``c``."""
    z = zero_crossings(c)
    return z[2:] - z[:-2]


def _mean_and_regularity(periods: np.ndarray) -> tuple[float, float]:
    """Mean period and Thornhill's regularity ``r = mean(T) / (3 std(T))`` (inf for equal periods)."""
    tp = float(periods.mean())
    sd = float(periods.std(ddof=1))
    return tp, (np.inf if sd == 0 else tp / (3.0 * sd))


def regularity(r: np.ndarray, *, n_total: int, min_periods: int = 5) -> tuple[float, float, int, float]:
    """Thornhill et al. (2003) regularity of the zero crossings of an ACF ``r``.

    Returns
    -------
    (period, regularity, n_periods, persistence): the mean full period in lags, ``r`` factor,
    the number of full-period estimates and the weakest ACF peak near ``T``, ``2T``, ``3T``
    (each the largest taper-corrected value within a quarter period of ``k T``).
    NaNs when fewer than ``min_periods`` full periods are available.
    """
    periods = _full_periods(r)
    if periods.size < min_periods:
        return np.nan, np.nan, int(periods.size), np.nan
    # at most ten periods: later lags of a finite record carry little information
    periods = periods[: 2 * 10]
    tp, reg = _mean_and_regularity(periods)
    peaks = []
    top = min(int(np.ceil(3 * tp + tp / 4)) + 1, r.size)
    corrected = r[:top] / (1.0 - np.arange(top) / n_total)  # the biased estimator's taper undone
    for k in (1, 2, 3):
        lo, hi = max(int(np.floor(k * tp - tp / 4)), 1), min(int(np.ceil(k * tp + tp / 4)) + 1, r.size)
        if hi > lo:
            peaks.append(float(corrected[lo:hi].max()))
    persistence = min(peaks) if peaks else np.nan
    return tp, reg, int(periods.size), persistence


@lru_cache(maxsize=16)
def _frequencies(n: int) -> np.ndarray:
    """``rfftfreq(n)`` (read-only, cached)."""
    f = fft.rfftfreq(n)
    f.flags.writeable = False
    return f


@lru_cache(maxsize=16)
def _hann(n: int) -> np.ndarray:
    """``np.hanning(n)`` (read-only, cached)."""
    w = np.hanning(n)
    w.flags.writeable = False
    return w


def acf_standard_error(n: int, band: tuple[float, float] | None, *, weights: np.ndarray | None = None,
                       background: np.ndarray | None = None) -> float:
    """Standard error of the ACF of noise after the gate's band-pass (Bartlett's formula).

    ``weights``: the band's gain :func:`pipeline.filters.band_weights` at ``rfftfreq(n)`` if
    already computed.  ``background``: the null's power spectrum at ``rfftfreq(n)`` (any
    scale; ``None`` = white noise), see :func:`power_law_background`."""
    if band is None and background is None:
        return 1.0 / np.sqrt(n)
    if weights is None:
        weights = (np.ones(n // 2 + 1) if band is None
                   else band_weights(_frequencies(n), f_lo=band[0], f_hi=band[1]))
    g = weights**2  # power response
    if background is not None:
        g = g * background
    rho = fft.irfft(g, n)
    if rho[0] <= 0:
        return 1.0
    rho = rho / rho[0]
    return float(np.sqrt(np.sum(rho**2) / n))


def taper_inflation(n: int, period: float, max_lag: int) -> float:
    """Factor on the ACF's standard error at the furthest peak checked: the taper-corrected
    (unbiased) ACF at lag ``k`` averages ``N - k`` products, not ``N``, and the furthest peak
    ``k T`` (``k <= 3``, within the ``max_lag`` lags computed) sets it: ``sqrt(N / (N - k T))``."""
    k_last = min(3, int((max_lag + 1) / period - 0.25)) if period > 0 else 1
    return np.sqrt(n / max(n - k_last * period, 1.0))


def power_law_background(spec: np.ndarray, band: tuple[float, float]) -> np.ndarray:
    """Null spectrum for a band: a power law ``f^b`` fitted outside the band (Vaughan 2005).

    Vaughan (2005, "A simple test for periodic signals in red noise", A&A 431:391–403, §3)
    models the background of a periodogram as a power law and fits it by least squares of
    ``log I`` against ``log f``; a drifting process variable (integrated or strongly
    autocorrelated disturbances) has ``b`` near -2.  We fit the Hann-windowed periodogram
    ``spec`` outside ``[f_lo, f_hi]`` (so that an oscillation inside the band does not raise
    its own null) and clip ``b`` to ``[-4, 0]``: the null is never whiter than white noise,
    so the test is never less strict than with a white null.  Only the shape matters (the
    ACF is normalised), so the constant of the fit and Vaughan's bias term drop out."""
    f = _frequencies(2 * (spec.size - 1)) if spec.size > 1 else np.zeros(1)
    out = (f > 0) & ((f < band[0]) | (f > band[1])) & (spec > 0)
    bg = np.zeros_like(f)
    if np.count_nonzero(out) < 8:
        bg[1:] = 1.0
        return bg
    slope = np.polyfit(np.log(f[out]), np.log(spec[out]), 1)[0]
    bg[1:] = f[1:] ** float(np.clip(slope, -4.0, 0.0))
    return bg


def _band_candidates(x: np.ndarray, *, max_bands: int, min_period: float, max_period: float,
                     spec: np.ndarray | None = None):
    """Pass bands ``[f0/2, 2 f0]`` (cycles/sample) around the strongest spectral peaks.

    ``spec``: the Hann-windowed periodogram of ``x`` if already computed."""
    n = x.size
    if spec is None:
        spec = hann_periodogram(x)
    f = _frequencies(n)
    smooth = signal.savgol_filter(spec, 5, 2) if spec.size > 7 else spec
    peaks, props = signal.find_peaks(smooth, prominence=0)
    ok = (f[peaks] > 1.0 / max_period) & (f[peaks] < 1.0 / min_period)
    peaks = peaks[ok]
    order = np.argsort(props["prominences"][ok])[::-1][:max_bands]
    return [(f[p] / 2.0, min(2.0 * f[p], 0.5)) for p in peaks[order]]


def hann_periodogram(x: np.ndarray) -> np.ndarray:
    """``|rfft(x * hann)|^2``."""
    return np.abs(fft.rfft(x * _hann(x.size))) ** 2


def _bandpass(x: np.ndarray, lo: float, hi: float, *, spectrum: np.ndarray | None = None,
              weights: np.ndarray | None = None) -> np.ndarray:
    """Zero-phase band-pass in the frequency domain (Thornhill et al. 2003, §3): squared
    second-order Butterworth edges, not a brick wall, whose ACF tails (decaying only as
    ``1/lag``) would make band-passed noise look like a sustained oscillation.

    ``spectrum`` (``rfft(x)``) and ``weights`` (the band's gain at ``rfftfreq(x.size)``) may be
    passed when already computed: several bands of one window share the spectrum."""
    if spectrum is None:
        spectrum = fft.rfft(x)
    if weights is None:
        weights = band_weights(_frequencies(x.size), f_lo=lo, f_hi=hi)
    return fft.irfft(spectrum * weights, x.size)


def _analytic(half: np.ndarray, n: int) -> np.ndarray:
    """Analytic signal of length ``n`` from a one-sided spectrum ``half`` (``rfft`` layout)."""
    h = np.zeros(n, dtype=np.complex128)
    h[: half.size] = half
    h[1:(n + 1) // 2] *= 2.0
    return fft.ifft(h)


def envelope_test(band_spectrum: np.ndarray, null_power: np.ndarray, n: int, *, trim: int) -> tuple[float, float]:
    """Steadiness of a band-passed signal's envelope against Gaussian noise: Moran's statistic
    (module docstring).

    Parameters
    ----------
    band_spectrum : ``rfft`` of the window times the band's gain.
    null_power : power spectrum of the band-passed null at ``rfftfreq(n)`` (gain squared times
        the background), any scale.
    n : window length.
    trim : samples dropped at each end (the circular filter's edge effects; about a period).

    Returns
    -------
    (m, z): ``m = log(mean(u)) - mean(log u)`` of the squared envelope ``u`` over the kept
    samples (Moran 1951: Euler's ``gamma = 0.577`` for exponential ``u``, i.e. Gaussian noise;
    0 for a constant amplitude) and ``z = (E0[m] - m) / se`` with, for ``kappa_k = |rho_k|^2``
    (``rho`` the complex autocorrelation of the null), ``E0[m] = gamma - sum_k kappa_k / (2 n)``
    and ``se^2 = sum_k (Li2(kappa_k) - kappa_k) / n`` (``n`` the kept samples; Laguerre
    expansion of the bivariate exponential, module docstring).
    """
    u = np.abs(_analytic(band_spectrum, n)[trim:n - trim]) ** 2
    m = u.mean() if u.size else 0.0
    if u.size < 2 or not m > 0:
        return float("nan"), float("nan")
    stat = float(np.log(m) - np.mean(np.log(np.maximum(u, m * 1e-300))))
    rc = np.abs(_analytic(null_power, n))
    if not rc[0] > 0:
        return stat, float("nan")
    kappa = np.minimum((rc / rc[0]) ** 2, 1.0)
    kappa = kappa[kappa > 1e-12]  # Li2(k) - k = k^2/4 + ...: smaller lags add nothing
    se = float(np.sqrt(np.sum(special.spence(1.0 - kappa) - kappa) / u.size))
    return stat, (np.euler_gamma - kappa.sum() / (2.0 * u.size) - stat) / se


@lru_cache(maxsize=8)
def _bonferroni_z(z: float, n_tests: int) -> float:
    """One-sided threshold at the level of ``z`` (``P(Z > z)``) Bonferroni-corrected over
    ``n_tests`` tests (the band candidates a window may try; the three half windows)."""
    return float(-special.ndtri(special.ndtr(-z) / max(n_tests, 1)))


def _steady_envelope(yy: np.ndarray, band_spectrum: np.ndarray, null_power: np.ndarray, *, config: GateConfig,
                     max_period: float) -> tuple[float, float, int, float, float] | None:
    """The second detector (module docstring) on one band-passed candidate ``yy``: its own zero
    crossings regular (Thornhill's ``r``) and its envelope steadier than Gaussian noise's
    (:func:`_bonferroni_z` standard errors).  ``(period, r, n_periods, m, z)`` when it passes, else ``None``."""
    periods = _full_periods(yy)
    if periods.size < max(config.min_periods, 2):
        return None
    tp, reg = _mean_and_regularity(periods)
    if not (reg > config.min_regularity and config.min_period_samples <= tp <= max_period):
        return None
    m, zm = envelope_test(band_spectrum, null_power, yy.size, trim=int(np.ceil(tp)))
    if not zm >= _bonferroni_z(config.acf_z, config.max_bands):
        return None
    return tp, float(reg), int(periods.size), m, zm


#: one-sided 5 % level: a half window's ACF pass must also have an envelope this many standard
#: errors steadier than Gaussian noise's (module docstring, third stage)
_CONFIRM_Z = 1.6449


def oscillation_gate(x: np.ndarray, *, fs: float, config: GateConfig = GateConfig()) -> GateResult:
    """Decide whether a window oscillates (Thornhill, Huang & Zhang 2003).

    Parameters
    ----------
    x : 1-D array of finite samples on a regular grid.
    fs : sampling frequency in Hz.
    config : thresholds, see :class:`GateConfig`.

    Returns
    -------
    GateResult; when only a half window passes (``config.half_windows``), its period, amplitude
    and regularity, and the reason names the half.
    """
    whole = _gate(x, fs=fs, config=config)
    x = np.asarray(x, dtype=np.float64)
    n = x.size
    if whole.oscillating or not config.half_windows or n < 8 * config.min_period_samples:
        return whole
    half = n // 2
    part = replace(config, acf_z=_bonferroni_z(config.acf_z, 3))
    for start, name in ((0, "first"), ((n - half) // 2, "middle"), (n - half, "last")):
        r = _gate(x[start:start + half], fs=fs, config=part, part=True)
        if r.oscillating:
            return replace(r, reason=f"{r.reason} (in the {name} half of the window, samples {start}–{start + half - 1}; "
                                     f"the whole window: {whole.reason})")
    return whole


def _gate(x: np.ndarray, *, fs: float, config: GateConfig, part: bool = False) -> GateResult:
    """The gate on one window: the raw signal (unless ``part``), then the band candidates, by the
    ACF test and the envelope detector.  ``part``: a half window (module docstring, third stage):
    band candidates only, and an ACF pass needs a steady envelope at :data:`_CONFIRM_Z`."""
    x = np.asarray(x, dtype=np.float64)
    if x.ndim != 1:
        raise SignalError(f"oscillation_gate expects a 1-D window, got shape {x.shape}")
    if not np.all(np.isfinite(x)):
        raise SignalError("oscillation_gate got NaN or inf samples; fill or reject the window first")
    if not fs > 0:
        raise SignalError(f"fs={fs!r} must be > 0")
    n = x.size
    nan = float("nan")
    y = detrend_linear(x)
    amplitude = robust_amplitude(y)
    # max |y| > tol is any(|y| > tol); max |x| is max(x.max(), -x.min())
    if n < 4 * config.min_period_samples or not np.abs(y).max() > 1e-12 * max(1.0, x.max(), -x.min()):
        why = "window too short" if n < 4 * config.min_period_samples else "signal is constant after detrending"
        return GateResult(False, nan, amplitude, nan, nan, 0, None, why)

    max_lag = (2 * n) // 3
    max_period = max_lag / (config.min_periods / 2.0 + 1.0)
    best: tuple | None = None
    periodogram = hann_periodogram(y)

    def candidates():
        if not part:
            yield None  # the raw signal first, then band-pass filtered around spectral peaks
        yield from _band_candidates(
            y, max_bands=config.max_bands, min_period=config.min_period_samples, max_period=max_period / 2,
            spec=periodogram,
        )

    spectrum = None  # rfft(y), shared by the band-passed candidates
    for band in candidates():
        if band is None:
            yy = weights = None
        else:
            spectrum = fft.rfft(y) if spectrum is None else spectrum
            weights = band_weights(_frequencies(n), f_lo=band[0], f_hi=band[1])
            yy = _bandpass(y, *band, spectrum=spectrum, weights=weights)
        tp, reg, nper, pers = regularity(acf(y if yy is None else yy, max_lag=max_lag), n_total=n,
                                         min_periods=config.min_periods)
        if not np.isfinite(tp):
            continue
        background = None if band is None else power_law_background(periodogram, band)
        inflation = taper_inflation(n, tp, max_lag)
        need = max(config.min_persistence,
                   config.acf_z * inflation * acf_standard_error(n, band, weights=weights, background=background))
        passed = (
            reg > config.min_regularity
            and pers >= need
            and config.min_period_samples <= tp <= max_period
        )
        if passed and part:  # a half window's ACF pass is confirmed by its envelope (module docstring)
            passed = envelope_test(spectrum * weights, weights**2 * background, n,
                                   trim=int(np.ceil(tp)))[1] >= _CONFIRM_Z
        steady = None
        if not passed and band is not None:
            steady = _steady_envelope(yy, spectrum * weights, weights**2 * background, config=config,
                                      max_period=max_period)
            passed = steady is not None
        score = (passed, min(reg, 1e6) * max(pers, 0.0))
        if best is None or score > best[0]:
            best = (score, band, tp, reg, nper, pers, need, steady)
        if passed:
            break
    if best is None:
        return GateResult(False, nan, amplitude, nan, nan, 0, None,
                          "no regular oscillation: too few ACF zero crossings for the window length")
    (passed, _), band, tp, reg, nper, pers, need, steady = best
    if steady is not None:  # the envelope test passed: period and regularity from the signal's zero crossings
        tp, reg, nper, m, zm = steady
    band_hz = None if band is None else (band[0] * fs, band[1] * fs)
    period_s = tp / fs
    where = "" if band is None else f" in band {band_hz[0]:.4g}–{band_hz[1]:.4g} Hz"
    if steady is not None:
        reason = (f"oscillating{where}: period {period_s:.4g} s, zero-crossing regularity r={reg:.2f}, "
                  f"steady envelope (Moran m={m:.2f}, {zm:.1f} se below Gaussian noise's 0.58; ACF peaks down to {pers:.2f})")
    elif passed:
        reason = f"oscillating{where}: period {period_s:.4g} s, regularity r={reg:.2f}, ACF peaks >= {pers:.2f}"
    elif reg <= config.min_regularity:
        reason = f"no regular oscillation: regularity r={reg:.2f} <= {config.min_regularity:g}"
    elif pers < need:
        reason = f"no sustained oscillation: ACF peaks over three periods down to {pers:.2f} < {need:.2f} (decaying or noise)"
    elif tp > max_period:
        reason = f"period {period_s:.4g} s too long: the window holds fewer than {n / max_period:.3g} periods"
    else:
        reason = f"period {tp:.3g} samples shorter than {config.min_period_samples:g}"
    return GateResult(bool(passed), period_s, amplitude, float(reg), float(pers), nper, band_hz, reason)
