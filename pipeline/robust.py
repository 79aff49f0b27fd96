"""Noise-robust test for intra-wave frequency modulation, with a significance level.

The paper method (Aftab et al. 2016) fails on real data in two ways: EMD puts measurement
noise and the stick-slip harmonics into IMFs that λ-pruning (eq. 7–8) throws away, so a sticking
valve reads linear; and noise itself modulates the IF, so a linear loop can exceed the fixed
0.1 threshold.  This method keeps the DNL idea (eq. 10–11: the spread of the instantaneous
frequency within each wave, weighted by the wave's amplitude) and changes what it is computed on
and what it is compared with.

A non-linearity driven at the oscillation's fundamental ``f0`` distorts every wave the same way:
its harmonics ``k f0`` are *phase-locked* to the fundamental (quadratic phase coupling, the
property the bicoherence test of Choudhury, Shah & Thornhill 2004, "Diagnosis of poor
control-loop performance using higher-order statistics", Automatica 40:1719–1728, detects).
Noise and a second, unrelated oscillation are not locked.  So:

1. **The fundamental's phase.**  ``f0`` is refined to the periodogram peak near the gate's
   period; the window is band-passed to ``[f0/1.5, 1.5 f0]`` (zero-phase, in the frequency
   domain) and its analytic signal (eq. 3–4) gives the phase ``phi(t)`` and the envelope
   ``a(t)`` of the fundamental, cycle by cycle, whatever the frequency wander.
2. **The phase-locked mean wave.**  The oscillation band ``[f0/2, (H + 1/2) f0]`` of the window
   is fitted by weighted least squares (a Hann taper against spectral leakage) with
   ``a(t) sum_k (alpha_k cos k phi + beta_k sin k phi)``, ``k = 1 .. H``: the average shape of one
   cycle, ``P(theta) = sum_k alpha_k cos k theta + beta_k sin k theta``.  Averaging over all the
   cycles of the window removes the noise and everything not locked to ``phi``; a
   phase-locked average ("synchronous average") is the time-domain form of the coupling that
   the bispectrum measures.
3. **DNL of the mean wave** by eq. 11 (:func:`pipeline.dnl.imf_dnl` on a few periods of
   ``P`` sampled uniformly in phase): zero for a sinusoid, large for a stick-slip square or
   triangle.  This is the reported ``dnl``.
4. **Significance from surrogates** (:mod:`pipeline.surrogates`, Theiler et al. 1992): the same
   statistic on ``n_surrogates`` harmonic-free phase-randomised surrogates of the window, i.e.
   linear oscillations with the same fundamental (its amplitude and frequency wander), the same
   noise, and nothing locked at the harmonics.  ``p = (1 + #{DNL_s >= DNL}) / (1 + S)``; the
   reported threshold is the surrogates' 95th percentile.

What the test cannot tell apart: a second, *linear* oscillation at a frequency within about
two frequency bins (``2 fs / N``) of a harmonic ``k f0`` is locked over the window, like a
distortion; an exactly periodic disturbance with harmonics of its own (e.g. from a sticking
valve upstream) is a distortion that did not arise in this loop.

The random generator is seeded from the configuration, so a window always gets the same
surrogates: replays are bit-for-bit.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy import fft

from .dnl import imf_dnl
from .errors import PipelineConfigError
from .filters import band_weights
from .surrogates import harmonic_free_amplitudes, random_phase_spectra

__all__ = ["RobustConfig", "RobustResult", "band_weights", "robust_dnl_test", "refine_f0", "mean_wave", "wave_dnl"]

#: phases per period at which the mean wave's DNL is evaluated, periods synthesised for the fallback
_WAVE_SAMPLES, _WAVE_PERIODS = 64, 4


@dataclass(frozen=True)
class RobustConfig:
    """Settings of the robust test.

    Parameters
    ----------
    n_harmonics : harmonics of the mean wave, ``k = 1 .. n_harmonics``.
    n_surrogates : surrogates per window; the smallest p-value is ``1 / (n_surrogates + 1)``.
    alpha : significance level of the test.
    min_dnl : smallest DNL of the mean wave that counts as a non-linearity worth reporting
        (effect size).  Default 0.05: the DNL of a sine with a phase-locked harmonic of about
        3 % of its amplitude (a linear loop's waves are sinusoidal to within the noise; a
        stick-slip triangle reads about 0.1, a square wave 0.3 or more).
    seed : seed of the surrogate generator (same window, same surrogates).
    """

    n_harmonics: int = 5
    n_surrogates: int = 99
    alpha: float = 0.01
    min_dnl: float = 0.05
    seed: int = 20160707

    def __post_init__(self) -> None:
        if self.n_harmonics < 2:
            raise PipelineConfigError(
                f"n_harmonics={self.n_harmonics!r} must be >= 2: without harmonics a stick-slip wave looks linear"
            )
        if not 0 < self.alpha < 1:
            raise PipelineConfigError(f"alpha={self.alpha!r} must be in (0, 1)")
        if self.n_surrogates < int(np.ceil(1 / self.alpha)) - 1:
            raise PipelineConfigError(
                f"n_surrogates={self.n_surrogates!r} is too few for alpha={self.alpha}: the smallest "
                f"p-value would be {1 / (self.n_surrogates + 1):.3f} and nothing could be significant"
            )
        if not self.min_dnl >= 0:
            raise PipelineConfigError(f"min_dnl={self.min_dnl!r} must be >= 0")


@dataclass(frozen=True)
class RobustResult:
    """DNL of the phase-locked mean wave, the surrogates' 95th percentile and the p-value.

    ``harmonic_ratio`` is the rms of the locked harmonics ``k >= 2`` over the fundamental's
    amplitude; ``f0_hz`` the refined fundamental; ``band_hz`` the analysed band; ``signal`` which
    of the tested signals the figures come from (``primary`` or ``other``, see
    :func:`robust_dnl_test`).
    """

    dnl: float
    threshold: float
    p_value: float
    n_surrogates: int
    band_hz: tuple[float, float]
    harmonic_ratio: float = float("nan")
    f0_hz: float = float("nan")
    signal: str = "primary"


def refine_f0(spec: np.ndarray, f: np.ndarray, f0: float) -> float:
    """Frequency of the largest periodogram bin within ``[f0/1.5, 1.5 f0]`` (parabolic interpolation)."""
    sel = np.flatnonzero((f > f0 / 1.5) & (f < 1.5 * f0))
    if sel.size < 3:
        return f0
    p = np.abs(spec[sel]) ** 2
    i = int(np.argmax(p))
    if 0 < i < p.size - 1:
        den = p[i - 1] - 2 * p[i] + p[i + 1]
        shift = 0.5 * (p[i - 1] - p[i + 1]) / den if den != 0 else 0.0
    else:
        shift = 0.0
    return float(f[sel[i]] + shift * (f[1] - f[0]))


def _band_bins(f: np.ndarray, *, f0: float, n_harmonics: int) -> int:
    """Number of leading spectral bins that hold the analysed band (up to ``1.25 (H + 1/2) f0``,
    where the fourth-order low-pass edge of :func:`mean_wave` is down to 0.03)."""
    return min(f.size, int(np.ceil(1.25 * (n_harmonics + 0.5) * f0 / (f[1] - f[0]))) + 1)


def mean_wave(spectra: np.ndarray, f: np.ndarray, n: int, *, f0: float, n_harmonics: int) -> np.ndarray:
    """Fourier coefficients ``(alpha_k, beta_k)`` of the phase-locked mean wave, ``k = 1 .. H``.

    Parameters
    ----------
    spectra : one-sided spectra (``rfft``) of windows of ``n`` samples, shape ``(S, m)`` or
        ``(m,)``; only the first :func:`_band_bins` bins are used (``m`` may stop there).
    f : their frequencies; ``f0`` in the same unit.
    n_harmonics : ``H``.

    Returns
    -------
    array of shape ``(S, H, 2)``: ``[:, k-1, 0] = alpha_k``, ``[:, k-1, 1] = beta_k``.

    Notes
    -----
    Everything above ``1.25 (H + 1/2) f0`` is negligible after the band-pass, so the time
    series are synthesised from the spectra on a coarser grid of ``n'`` samples over the same
    span (spectral truncation, an exact resampling of band-limited series); the least-squares
    sums are then taken over ``n'`` samples instead of ``n`` (their products reach at most
    ``2 (H + 1/2) f0``, below the coarse grid's sampling rate, so no product aliases to zero
    frequency).  The basis and the sums are single precision (ten unknowns, well conditioned).
    """
    spectra = np.atleast_2d(spectra)
    h = n_harmonics
    m = _band_bins(f, f0=f0, n_harmonics=h)
    n2 = min(n, fft.next_fast_len(2 * m, real=True))
    m = min(m, n2 // 2 + 1)
    scale = n2 / n
    sp, fk = spectra[:, :m], f[:m]
    # analytic signal of the fundamental: one-sided spectrum doubled, inverse complex FFT
    wf = band_weights(fk, f_lo=f0 / 1.5, f_hi=1.5 * f0, order=4)
    wf /= band_weights(np.array([f0]), f_lo=f0 / 1.5, f_hi=1.5 * f0, order=4)[0]  # unit gain at f0
    full = np.zeros((sp.shape[0], n2), dtype=complex)
    full[:, :m] = (2.0 * scale) * sp * wf
    z = fft.ifft(full, n2, axis=-1)
    amp = np.abs(z)
    unit = np.divide(z, amp, out=np.zeros_like(z), where=amp > 0)
    # the oscillation band, real
    wb = band_weights(fk, f_lo=f0 / 2.0, f_hi=(h + 0.5) * f0, order=4)
    c = fft.irfft(scale * sp * wb, n2, axis=-1).astype(np.float32)
    # basis a(t) e^{i k phi}, k = 1..H, as real cos/sin columns
    powers = np.empty((sp.shape[0], h, n2), dtype=np.complex64)
    powers[:, 0] = z
    unit = unit.astype(np.complex64)
    for k in range(1, h):
        np.multiply(powers[:, k - 1], unit, out=powers[:, k])
    basis = np.concatenate([powers.real, powers.imag], axis=1)  # (S, 2H, n2)
    bw = basis * np.hanning(n2).astype(np.float32)
    gram = np.matmul(bw, basis.transpose(0, 2, 1)).astype(np.float64)
    rhs = np.matmul(bw, c[:, :, None])[:, :, 0].astype(np.float64)
    gram += 1e-9 * np.trace(gram, axis1=-2, axis2=-1)[:, None, None] * np.eye(2 * h)
    coef = np.linalg.solve(gram, rhs[..., None])[..., 0]
    return np.stack([coef[:, :h], coef[:, h:]], axis=-1)


def wave_dnl(coef: np.ndarray) -> np.ndarray:
    """DNL (eq. 11) of mean waves with coefficients ``coef`` (shape ``(S, H, 2)`` or ``(H, 2)``).

    For a periodic wave ``P(theta) = sum_k alpha_k cos k theta + beta_k sin k theta`` every term
    of eq. 11 is exact: the analytic signal (eq. 4) is ``Z = sum_k (alpha_k - i beta_k)
    e^{i k theta}``, the instantaneous frequency (eq. 5) relative to the wave's ``IF_z = f0`` is
    ``Im(Z' conj Z) / |Z|^2`` with ``Z' = dZ/dtheta``, and ``a_z`` is the largest ``|P|`` of the
    half wave.  Evaluated at 64 phases per period.  A wave with more than two zero crossings
    per period (a harmonic stronger than the fundamental) goes through
    :func:`pipeline.dnl.imf_dnl` on four synthesised periods instead, where ``IF_z`` comes
    from the zero crossings.
    """
    coef = np.asarray(coef, dtype=np.float64)
    single = coef.ndim == 2
    coef = np.atleast_3d(coef) if not single else coef[None]
    h = coef.shape[1]
    k = np.arange(1, h + 1)
    theta = 2 * np.pi * np.arange(_WAVE_SAMPLES) / _WAVE_SAMPLES
    e = np.exp(1j * np.outer(k, theta))  # (H, M)
    cz = coef[:, :, 0] - 1j * coef[:, :, 1]  # (S, H)
    z = cz @ e
    dz = (cz * (1j * k)) @ e
    p = z.real
    mag2 = np.abs(z) ** 2
    ratio = np.divide((dz * np.conj(z)).imag, mag2, out=np.zeros_like(mag2), where=mag2 > 0)
    pos = p > 0
    crossings = np.count_nonzero(pos != np.roll(pos, 1, axis=1), axis=1)
    hi = np.where(pos, p, 0.0).max(axis=1)
    lo = np.where(pos, 0.0, -p).max(axis=1)
    az = np.where(pos, hi[:, None], lo[:, None])
    mean_az = az.mean(axis=1, keepdims=True)
    dev = (ratio - 1.0) * np.divide(az, mean_az, out=np.zeros_like(az), where=mean_az > 0)
    out = dev.std(axis=1)
    out[~(mean_az[:, 0] > 0)] = np.nan
    for i in np.flatnonzero(crossings != 2):
        wave = np.tile(p[i], _WAVE_PERIODS)
        out[i] = imf_dnl(wave, fs=float(_WAVE_SAMPLES)).dnl
    return out[0] if single else out


def _harmonic_ratio(coef: np.ndarray) -> float:
    fund = float(np.hypot(*coef[0]))
    return float(np.sqrt(np.sum(coef[1:] ** 2)) / fund) if fund > 0 else float("nan")


def _signal_dnls(y: np.ndarray, *, fs: float, f0_hint: float, config: RobustConfig, rng: np.random.Generator):
    """DNL of the mean wave of ``y`` and of its surrogates; the refined f0 and harmonic ratio."""
    n = y.size
    h = config.n_harmonics
    f = fft.rfftfreq(n, d=1.0 / fs)
    spec = fft.rfft(y)
    f0 = refine_f0(spec, f, f0_hint)
    m = _band_bins(f, f0=f0, n_harmonics=h)
    amplitudes = harmonic_free_amplitudes(spec[:m], f[:m], f0=f0, n_harmonics=h, rng=rng, count=config.n_surrogates)
    spectra = np.concatenate([spec[None, :m], random_phase_spectra(amplitudes, n, rng, count=config.n_surrogates)])
    coefs = mean_wave(spectra, f, n, f0=f0, n_harmonics=h)
    dnls = wave_dnl(coefs)
    return float(dnls[0]), dnls[1:], f0, _harmonic_ratio(coefs[0])


def robust_dnl_test(y: np.ndarray, *, fs: float, period_s: float, config: RobustConfig = RobustConfig(),
                    other: np.ndarray | None = None) -> RobustResult:
    """DNL of the phase-locked mean wave of a detrended window, with its surrogate significance.

    Parameters
    ----------
    y : detrended 1-D window, finite.
    fs : sampling frequency in Hz.
    period_s : oscillation period from the gate, in seconds.
    config : see :class:`RobustConfig`.
    other : optionally a second detrended window of the same loop over the same time (the OP
        when ``y`` is the PV or the control error).  A process that filters the valve's
        stick-slip square wave into a near-sine leaves the distortion in the OP (a sawtooth),
        and a fast process leaves it in the PV; the test then uses the larger of the two
        DNLs, each divided by the median of its own surrogates, and compares it with the same
        maximum over pairs of surrogates (one of each signal): one test, one p-value, and
        conservative (the pairs are independent, the two real statistics are not).  The
        reported ``dnl`` and ``threshold`` are those of the signal with the larger ratio,
        named in ``signal``.
    """
    n = y.size
    h = config.n_harmonics
    rng = np.random.default_rng(config.seed)
    dnl, ds, f0, ratio = _signal_dnls(y, fs=fs, f0_hint=1.0 / period_s, config=config, rng=rng)
    band = (f0 / 2.0, min((h + 0.5) * f0, 0.5 * fs))
    nan = float("nan")
    if not np.isfinite(dnl) or not np.all(np.isfinite(ds)):
        return RobustResult(dnl, nan, nan, int(np.isfinite(ds).sum()), band, ratio, f0)
    name = "primary"
    if other is not None and other.size == n:
        dnl2, ds2, _, ratio2 = _signal_dnls(other, fs=fs, f0_hint=f0, config=config, rng=rng)
        med1, med2 = float(np.median(ds)), float(np.median(ds2))
        if np.isfinite(dnl2) and np.all(np.isfinite(ds2)) and med1 > 0 and med2 > 0:
            stat = max(dnl / med1, dnl2 / med2)
            null = np.maximum(ds / med1, ds2 / med2)
            p = (1.0 + np.sum(null >= stat)) / (1.0 + null.size)
            if dnl2 / med2 > dnl / med1:
                dnl, ds, ratio, name = dnl2, ds2, ratio2, "other"
            return RobustResult(dnl, float(np.quantile(ds, 0.95)), float(p), int(ds.size), band, ratio, f0, name)
    p = (1.0 + np.sum(ds >= dnl)) / (1.0 + ds.size)
    return RobustResult(dnl, float(np.quantile(ds, 0.95)), float(p), int(ds.size), band, ratio, f0, name)
