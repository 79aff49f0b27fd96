"""Degree of non-linearity of IMFs and of a window (Aftab et al. 2016, §3.2, eq. 10–12).

A non-linearly distorted oscillation shows intra-wave frequency modulation: its instantaneous
frequency ``IF`` swings within each wave around the wave's mean frequency ``IF_z``.  The DNL of
IMF ``i`` (eq. 11, after Huang et al. 2014) is::

    DNL_i = std( (IF_i - IF_z,i) / IF_z,i * a_z,i / mean(a_z,i) )

and the total ``TDNL = sum_j DNL_j |c_j|^2 / sum_k |c_k|^2`` over the kept IMFs (eq. 12).

Choices the paper leaves open, documented here:

* end effects: the Hilbert transform and the spline envelopes are unreliable near the window
  ends, so the statistic is taken only between the zero crossings ``2 * end_trim_waves`` from each
  end (``end_trim_waves`` full waves dropped on each side); with too few waves the trim is
  dropped, and an IMF with fewer than three zero crossings has no DNL (NaN) and no weight in
  the TDNL;
* ``mean(a_z)`` is the mean over the same samples as the standard deviation (population std);
* ``|c_j|^2`` in eq. 12 is the energy ``sum_t c_j(t)^2`` (squared 2-norm) over the whole window.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .frequency import frequency_and_analytic, zero_crossing_references, zero_crossings

__all__ = ["imf_dnl", "tdnl", "DNLFigures"]


@dataclass(frozen=True)
class DNLFigures:
    """DNL of one IMF with what it was computed from."""

    dnl: float
    mean_frequency_hz: float
    n_waves: int


def imf_dnl(c: np.ndarray, *, fs: float, end_trim_waves: int = 1, freq: np.ndarray | None = None) -> DNLFigures:
    """Degree of non-linearity of one IMF (eq. 11).

    Parameters
    ----------
    c : 1-D IMF.
    fs : sampling frequency in Hz.
    end_trim_waves : full waves left out at each end (end effects).
    freq : its instantaneous frequency in Hz if already computed (eq. 5); else computed here.

    Returns
    -------
    DNLFigures with ``dnl`` NaN when the IMF has fewer than three zero crossings.
    """
    c = np.asarray(c, dtype=np.float64)
    zc = zero_crossings(c)
    if zc.size < 3:
        return DNLFigures(float("nan"), float("nan"), 0)
    if freq is None:
        freq = frequency_and_analytic(c, fs=fs)[0]
    ifz, az = zero_crossing_references(c, zc, fs=fs)
    trim = 2 * end_trim_waves
    if zc.size < 2 * trim + 3:
        trim = 0
    lo = int(np.floor(zc[trim])) + 1
    hi = int(np.floor(zc[zc.size - 1 - trim])) + 1
    sl = slice(lo, hi)
    a = az[sl]
    mean_a = a.mean()
    if not (hi > lo and mean_a > 0):
        return DNLFigures(float("nan"), float("nan"), 0)
    dev = (freq[sl] - ifz[sl]) / ifz[sl] * (a / mean_a)
    n_waves = (zc.size - 1 - 2 * trim) // 2
    return DNLFigures(float(dev.std()), float(np.mean(ifz[sl])), int(n_waves))


def tdnl(dnl: np.ndarray, imfs: np.ndarray) -> float:
    """Energy-weighted total degree of non-linearity (eq. 12) over IMFs with a finite DNL."""
    dnl = np.asarray(dnl, dtype=np.float64)
    energy = np.einsum("ij,ij->i", np.atleast_2d(imfs), np.atleast_2d(imfs))
    ok = np.isfinite(dnl) & (energy > 0)
    if not ok.any():
        return float("nan")
    return float(np.sum(dnl[ok] * energy[ok]) / np.sum(energy[ok]))
