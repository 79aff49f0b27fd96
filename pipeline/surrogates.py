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
the harmonics ``k f0`` (k = 2 .. n_harmonics + 1, half-width ``f0 / 4``), where the amplitude is
lowered to the median level of the band outside the fundamental and the harmonics (the noise
floor), and gets uniformly random phases (Theiler's FT surrogate).  Amplitude and frequency
wander of the fundamental, and the noise, are kept; phase-locked harmonics are not.
"""

from __future__ import annotations

import numpy as np
from scipy import fft

__all__ = ["harmonic_free_amplitudes", "phase_randomised"]


def harmonic_free_amplitudes(spectrum: np.ndarray, f: np.ndarray, *, f0: float, f_hi: float, n_harmonics: int) -> np.ndarray:
    """Amplitude spectrum with the harmonic bands of ``f0`` lowered to the noise floor.

    Parameters
    ----------
    spectrum : complex or real one-sided spectrum (``rfft``) of the window.
    f : its frequencies (same unit as ``f0``).
    f0 : fundamental frequency of the oscillation.
    f_hi : upper edge of the analysed band; the floor is the median amplitude in
        ``(f0/2, f_hi)`` outside the fundamental and harmonic bands.
    n_harmonics : harmonics 2 .. n_harmonics + 1 are removed.
    """
    mag = np.abs(spectrum)
    half = f0 / 4.0
    fundamental = np.abs(f - f0) < half
    harmonic = np.zeros(f.size, dtype=bool)
    for k in range(2, n_harmonics + 2):
        harmonic |= np.abs(f - k * f0) < half
    floor_band = (f > f0 / 2.0) & (f < f_hi) & ~harmonic & ~fundamental
    floor = float(np.median(mag[floor_band])) if floor_band.any() else 0.0
    out = mag.copy()
    out[harmonic] = np.minimum(out[harmonic], floor)
    return out


def phase_randomised(amplitudes: np.ndarray, n: int, rng: np.random.Generator, *, count: int) -> np.ndarray:
    """``count`` real series of length ``n`` with the given one-sided amplitudes and random phases.

    Returns an array of shape ``(count, n)``.  The mean (bin 0) and, for even ``n``, the Nyquist
    bin keep zero phase so that the series are real.
    """
    phases = rng.uniform(0.0, 2.0 * np.pi, size=(count, amplitudes.size))
    phases[:, 0] = 0.0
    if n % 2 == 0:
        phases[:, -1] = 0.0
    return fft.irfft(amplitudes * np.exp(1j * phases), n, axis=-1)
