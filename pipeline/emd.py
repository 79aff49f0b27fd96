"""Empirical mode decomposition with bounded cost, through PyEMD.

EMD (Huang et al. 1998; Aftab et al. 2016, eq. 1–2) splits a window into intrinsic mode functions
(IMFs) ``c_i`` and a residue ``r``: ``x = sum_i c_i + r``.  PyEMD's default stop rule (the sign
test plus ``|#extrema - #zero crossings| < 2``, checked over the whole window) can sift up to
``MAX_ITERATION = 1000`` times per IMF on square-ish waves, i.e. seconds per window (see the
project's stack notes).  A monitor needs a bounded cost, so we use the fixed sifting budget
``FIXE`` (exactly ``sifts`` sifting iterations per IMF, Huang & Wu's "fixed sifting") and cap the
number of IMFs: the cost is then at most ``sifts * max_imfs`` sifts.  The first IMFs of a capped
run are identical to those of an uncapped run with the same stop rule.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from PyEMD import EMD
from scipy.linalg.lapack import dgtsv

from .errors import PipelineConfigError, SignalError

__all__ = ["EMDConfig", "emd", "not_a_knot_spline"]


def not_a_knot_spline(xk: np.ndarray, yk: np.ndarray, t: np.ndarray) -> np.ndarray:
    """Cubic spline through ``(xk, yk)`` with not-a-knot ends, evaluated at sorted ``t``.

    The same spline as ``scipy.interpolate.CubicSpline(xk, yk)(t)`` (PyEMD's "cubic" envelope),
    to rounding, at about half the cost: the slopes come from one tridiagonal LAPACK solve and
    the segment of every ``t`` from one ``searchsorted`` of the knots into ``t``.  ``xk`` must be
    strictly increasing with at least 4 knots, ``t`` sorted and inside ``[xk[0], xk[-1]]``.
    """
    n = xk.size
    dx = np.diff(xk)
    slope = np.diff(yk) / dx
    dl, d, du, b = np.empty(n - 1), np.empty(n), np.empty(n - 1), np.empty(n)
    d[1:-1] = 2.0 * (dx[:-1] + dx[1:])
    du[1:] = dx[:-1]
    dl[:-1] = dx[1:]
    b[1:-1] = 3.0 * (dx[1:] * slope[:-1] + dx[:-1] * slope[1:])
    w0 = xk[2] - xk[0]  # not-a-knot at the first interior knot
    d[0], du[0] = dx[1], w0
    b[0] = ((dx[0] + 2.0 * w0) * dx[1] * slope[0] + dx[0] ** 2 * slope[1]) / w0
    w1 = xk[-1] - xk[-3]  # and at the last interior knot
    d[-1], dl[-1] = dx[-2], w1
    b[-1] = (dx[-1] ** 2 * slope[-2] + (2.0 * w1 + dx[-1]) * dx[-2] * slope[-1]) / w1
    s = dgtsv(dl, d, du, b, overwrite_dl=1, overwrite_d=1, overwrite_du=1, overwrite_b=1)[3]
    c2 = (3.0 * slope - 2.0 * s[:-1] - s[1:]) / dx
    c3 = (s[:-1] + s[1:] - 2.0 * slope) / dx**2
    first = np.searchsorted(t, xk[1:-1], side="left")  # first t of segments 1 .. n-2
    seg = np.repeat(np.arange(n - 1), np.diff(np.r_[0, first, t.size]))
    u = t - xk[seg]
    return yk[seg] + u * (s[seg] + u * (c2[seg] + u * c3[seg]))


class _BoundedEMD(EMD):
    """PyEMD's EMD with two shortcuts that leave its numbers unchanged.

    * the cubic envelopes are built by :func:`not_a_knot_spline`;
    * every sifting iteration of ``EMD.emd`` finds the extrema of the same proto-IMF twice (once
      to count them, once in ``extract_max_min_spline``); the second time reuses the first result.
    """

    _last_input: np.ndarray | None = None
    _last_extrema = None

    def find_extrema(self, T, S):
        last = self._last_input
        if last is not None and last.shape == S.shape and np.array_equal(last, S):
            return self._last_extrema
        result = super().find_extrema(T, S)
        self._last_input, self._last_extrema = S.copy(), result
        return result

    def spline_points(self, T, extrema):
        if self.spline_kind != "cubic" or extrema.shape[1] <= 3:
            return super().spline_points(T, extrema)
        t = T[(T >= extrema[0, 0]) & (T <= extrema[0, -1])]
        return t, not_a_knot_spline(extrema[0], extrema[1], t)


@dataclass(frozen=True)
class EMDConfig:
    """Bounded EMD settings.

    Parameters
    ----------
    sifts : sifting iterations per IMF (PyEMD ``FIXE``); ``0`` selects PyEMD's default adaptive
        stop rule, which is unbounded and exists only for comparison.
    max_imfs : the most IMFs extracted; the remainder is the residue.  ``-1`` = no cap.

    The defaults (4 sifts, 3 IMFs: at most 12 sifts, about 10 ms for 4096 samples) were chosen
    by cost: the paper's verdicts on its Tables 2 and 3 are the same with 4, 8 or 10 sifts and
    3 or 4 IMFs (tests/test_paper_reproduction.py; figures in ACCURACY.md), while 8 sifts and 4
    IMFs cost about twice as much (BENCHMARKS.md).
    """

    sifts: int = 4
    max_imfs: int = 3

    def __post_init__(self) -> None:
        if self.sifts < 0:
            raise PipelineConfigError(f"sifts={self.sifts!r} must be >= 0 (0 = PyEMD's unbounded default rule)")
        if self.max_imfs == 0 or self.max_imfs < -1:
            raise PipelineConfigError(f"max_imfs={self.max_imfs!r} must be >= 1, or -1 for no cap")


def emd(x: np.ndarray, *, config: EMDConfig = EMDConfig()) -> tuple[np.ndarray, np.ndarray]:
    """Decompose a 1-D window into IMFs (Aftab et al. 2016, eq. 1–2).

    Parameters
    ----------
    x : 1-D array of finite samples.
    config : sifting budget and IMF cap.

    Returns
    -------
    imfs : array of shape ``(n_imfs, N)``, highest frequency first (``n_imfs`` may be 0 for a
        monotonic window).
    residue : array of shape ``(N,)``; ``imfs.sum(0) + residue == x`` to rounding.
    """
    x = np.asarray(x, dtype=np.float64)
    if x.ndim != 1 or not np.all(np.isfinite(x)):
        raise SignalError("emd expects a 1-D window of finite samples")
    kwargs = {"FIXE": config.sifts} if config.sifts else {}
    # one instance per call: PyEMD keeps state on the instance
    decomposer = _BoundedEMD(**kwargs) if config.sifts else EMD()
    decomposer.emd(x, max_imf=config.max_imfs)
    imfs, residue = decomposer.get_imfs_and_residue()
    imfs = np.asarray(imfs, dtype=np.float64).reshape(-1, x.size)
    return imfs, x - imfs.sum(axis=0)
