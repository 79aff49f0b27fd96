"""Harmonic-free surrogates: what a *linear* oscillation with the same spectrum would look like.

Surrogate-data testing (Theiler et al. 1992, "Testing for nonlinearity in time series: the
method of surrogate data", Physica D 58:77–94) compares a statistic of the data with its
distribution over surrogates that share the data's power spectrum but have random Fourier
phases, i.e. realisations of a linear Gaussian process.  For intra-wave frequency modulation
that null is the wrong one: a stick-slip limit cycle puts lines at 2f0, 3f0, ... into the
spectrum, and ordinary phase-randomised surrogates keep those lines, so their waveforms are
just as distorted (we measured surrogate DNLs as high as the data's on simulated stiction).

A linear loop driven at f0, by tuning or by a sinusoidal disturbance, does not create
harmonics.  The null hypothesis here is therefore "a linear oscillation at f0 in the observed
noise": the surrogate keeps the amplitude spectrum of the window except in narrow bands around
the harmonics ``k f0`` (k = 2 .. n_harmonics + 1, half-width ``f0 / 4``), whose amplitudes are
replaced by amplitudes drawn at random from the neighbouring noise (the bins between ``f0/4``
and ``f0/2`` on either side of the band), and gets uniformly random phases (Theiler's FT
surrogate).  Amplitude and frequency wander of the fundamental, and the noise (coloured as it
is), are kept; phase-locked harmonics are not.
"""

from __future__ import annotations

import numpy as np
from scipy import fft

__all__ = ["harmonic_free_amplitudes", "random_phase_spectra", "phase_randomised"]


def harmonic_free_amplitudes(spectrum: np.ndarray, f: np.ndarray, *, f0: float, n_harmonics: int,
                             rng: np.random.Generator, count: int | None = None) -> np.ndarray:
    """Amplitude spectrum with the harmonic bands of ``f0`` replaced by the local noise.

    Parameters
    ----------
    spectrum : complex or real one-sided spectrum (``rfft``) of the window.
    f : its frequencies (same unit as ``f0``).
    f0 : fundamental frequency of the oscillation.
    n_harmonics : harmonics 2 .. n_harmonics + 1 are replaced.
    rng : draws the replacement amplitudes (a bootstrap of the neighbouring noise bins).
    count : number of independent draws; ``None`` returns one spectrum, else ``(count, len(f))``.

    Returns
    -------
    amplitudes, shape ``spectrum.shape`` or ``(count, len(f))``.
    """
    mag = np.abs(spectrum)
    shape = mag.shape if count is None else (count,) + mag.shape
    out = np.broadcast_to(mag, shape).copy()
    for k in range(2, n_harmonics + 2):
        d = np.abs(f - k * f0)
        band = np.flatnonzero(d < f0 / 4.0)
        if band.size == 0:
            continue
        near = np.flatnonzero((d >= f0 / 4.0) & (d < f0 / 2.0))
        if near.size == 0:
            out[..., band] = 0.0
            continue
        out[..., band] = mag[near][rng.integers(0, near.size, shape[:-1] + (band.size,))]
    return out


def random_phase_spectra(amplitudes: np.ndarray, n: int, rng: np.random.Generator, *, count: int) -> np.ndarray:
    """``count`` one-sided spectra (``rfft`` of real series of length ``n``) with the given
    amplitudes (one vector, or one per spectrum) and independent uniformly random phases.

    The mean (bin 0) and, for even ``n``, the Nyquist bin keep zero phase so that the series
    are real.  ``amplitudes`` may stop short of the Nyquist bin (the leading bins of a
    band-limited spectrum).  Returns shape ``(count, len(amplitudes))``.
    """
    m = amplitudes.shape[-1]
    phases = rng.uniform(0.0, 2.0 * np.pi, size=(count, m))
    phases[:, 0] = 0.0
    if n % 2 == 0 and m == n // 2 + 1:
        phases[:, -1] = 0.0
    return amplitudes * np.exp(1j * phases)


def phase_randomised(amplitudes: np.ndarray, n: int, rng: np.random.Generator, *, count: int) -> np.ndarray:
    """``count`` real series of length ``n`` with the given one-sided amplitudes and random phases
    (the inverse FFT of :func:`random_phase_spectra`); shape ``(count, n)``."""
    return fft.irfft(random_phase_spectra(amplitudes, n, rng, count=count), n, axis=-1)
