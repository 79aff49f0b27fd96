"""Instantaneous frequency of IMFs and the zero-crossing references of the DNL index.

* Analytic signal ``Z = X + jY`` with ``Y`` the Hilbert transform of ``X`` (Aftab et al. 2016,
  eq. 3–4), computed by FFT (``scipy.signal.hilbert``) over the whole window.
* Instantaneous frequency ``omega = d theta / dt`` (eq. 5).  Estimator (a choice the paper leaves
  open): the central phase difference ``omega[n] = arg(Z[n+1] conj(Z[n-1])) / (2 dt)``, which is
  eq. 5 (``(X dY - Y dX)/A^2``) with central differences, immune to phase wrapping; one-sided at
  the two end samples.
* Full-wave zero-crossing frequency ``IF_z`` (Huang et al. 2009, "On instantaneous frequency";
  used in eq. 10–11): zero crossings are located by linear interpolation; each full wave from
  crossing ``k`` to crossing ``k + 2`` gives ``1 / (z_{k+2} - z_k)`` at the wave's centre, and
  ``IF_z`` at every sample is the linear interpolation between wave centres (held constant past
  the first and last centres).
* Zero-crossing amplitude ``a_z`` (eq. 11): the absolute value of the extremum between two
  successive zero crossings, held constant over that half wave.
"""

from __future__ import annotations

import numpy as np
from scipy import fft

__all__ = ["instantaneous_frequency", "zero_crossings", "zero_crossing_references"]


def instantaneous_frequency(imfs: np.ndarray, *, fs: float, axis: int = -1) -> tuple[np.ndarray, np.ndarray]:
    """Instantaneous frequency (Hz) and amplitude of each IMF from its analytic signal (eq. 3–5).

    Parameters
    ----------
    imfs : array, one IMF per slice along ``axis`` (at least 3 samples).
    fs : sampling frequency in Hz.

    Returns
    -------
    freq : same shape as ``imfs``, Hz.
    amplitude : ``a(t) = |Z(t)|`` (eq. 4), same shape.
    """
    x = np.asarray(imfs, dtype=np.float64)
    last = axis in (-1, x.ndim - 1)
    freq, z = frequency_and_analytic(x if last else np.moveaxis(x, axis, -1), fs=fs)
    if last:
        return freq, np.abs(z)
    return np.moveaxis(freq, -1, axis), np.moveaxis(np.abs(z), -1, axis)


def frequency_and_analytic(x: np.ndarray, *, fs: float) -> tuple[np.ndarray, np.ndarray]:
    """Instantaneous frequency (Hz) along the last axis of float array ``x`` and its analytic
    signal ``Z`` (:func:`instantaneous_frequency` without the amplitude)."""
    z = _analytic(x)
    w = np.empty(x.shape)
    np.divide(np.angle(z[..., 2:] * np.conj(z[..., :-2])), 2.0, out=w[..., 1:-1])
    w[..., 0] = np.angle(z[..., 1] * np.conj(z[..., 0]))
    w[..., -1] = np.angle(z[..., -1] * np.conj(z[..., -2]))
    w *= fs / (2.0 * np.pi)
    return w, z


def _analytic(x: np.ndarray) -> np.ndarray:
    """``scipy.signal.hilbert(x, axis=-1)`` without its array-API dispatch (the same FFTs and
    operations, so the same numbers): keep the mean and Nyquist bins, double the positive
    frequencies, zero the negative ones."""
    n = x.shape[-1]
    spec = fft.fft(x, axis=-1)
    spec[..., 1:(n + 1) // 2] *= 2.0
    spec[..., n // 2 + 1:] = 0.0
    return fft.ifft(spec, axis=-1, overwrite_x=True)


def zero_crossings(c: np.ndarray) -> np.ndarray:
    """Fractional sample indices where a 1-D signal changes sign (linear interpolation)."""
    c = np.asarray(c, dtype=np.float64)
    neg = np.signbit(c)
    i = np.flatnonzero(neg[1:] != neg[:-1])
    return i + c[i] / (c[i] - c[i + 1])


def zero_crossing_references(c: np.ndarray, zc: np.ndarray, *, fs: float) -> tuple[np.ndarray, np.ndarray]:
    """Full-wave zero-crossing frequency ``IF_z`` (Hz) and zero-crossing amplitude ``a_z`` per sample.

    Parameters
    ----------
    c : 1-D IMF.
    zc : its zero crossings (from :func:`zero_crossings`); at least 3 are needed.
    fs : sampling frequency in Hz.

    Returns
    -------
    ifz : ``IF_z`` at every sample (Hz).
    az : ``a_z`` at every sample inside ``[zc[0], zc[-1]]``; NaN outside.
    """
    n = c.size
    idx = np.arange(n, dtype=np.float64)
    if zc.size < 3:
        raise ValueError("zero_crossing_references needs at least 3 zero crossings (one full wave)")
    centres = 0.5 * (zc[2:] + zc[:-2])
    ifz = np.interp(idx, centres, fs / (zc[2:] - zc[:-2]))
    # half wave k spans the samples strictly after zc[k] up to zc[k+1]
    starts = np.floor(zc).astype(np.intp) + 1
    starts = np.minimum(starts, n - 1)
    peaks = np.maximum.reduceat(np.abs(c), starts)[:-1]  # one value per half wave
    az = np.full(n, np.nan)
    lengths = np.diff(starts)
    az[starts[0]:starts[-1]] = np.repeat(peaks, lengths)
    return ifz, az
