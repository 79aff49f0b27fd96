"""Empirical mode decomposition with bounded cost, through PyEMD.

EMD (Huang et al. 1998; Aftab et al. 2016, eq. 1–2) splits a window into intrinsic mode functions
(IMFs) ``c_i`` and a residue ``r``: ``x = sum_i c_i + r``.  PyEMD's default stop rule (the sign
test plus ``|#extrema - #zero crossings| < 2``, checked over the whole window) can sift up to
``MAX_ITERATION = 1000`` times per IMF on square-ish waves, i.e. seconds per window (see the
project's stack notes).  A monitor needs a bounded cost, so we use the fixed sifting budget
``FIXE`` (exactly ``sifts`` sifting iterations per IMF, Huang & Wu's "fixed sifting") and cap the
number of IMFs: the cost is then at most ``sifts * max_imfs`` sifts.  The first IMFs of a capped
run are identical to those of an uncapped run with the same stop rule.

The sifting itself is PyEMD's algorithm run by a lean loop (:class:`_BoundedEMD`) that gives
PyEMD's IMFs bit for bit at a fraction of its numpy call overhead per sift.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from PyEMD import EMD
from scipy.linalg.lapack import dgtsv

from .errors import PipelineConfigError, SignalError

__all__ = ["EMDConfig", "emd", "not_a_knot_spline"]


def _not_a_knot_coefficients(xk: np.ndarray, yk: np.ndarray, ends: tuple[int, ...]) -> tuple[np.ndarray, ...]:
    """Coefficients of not-a-knot cubic splines, several at once.

    ``xk``/``yk`` hold the knots of consecutive splines, spline ``b`` ending before ``ends[b]``
    (each with at least 4 strictly increasing knots).  Returns the slopes ``s`` at the knots and
    ``c2``, ``c3`` per segment: on segment ``j``, ``y = yk[j] + s[j] u + c2[j] u^2 + c3[j] u^3``
    with ``u = t - xk[j]`` (the segment joining two splines is meaningless).

    The arithmetic is that of ``scipy.interpolate.CubicSpline`` step by step (the same
    tridiagonal system solved by the same LAPACK ``gtsv``, the coefficients formed as
    ``CubicHermiteSpline`` forms them), so the numbers are the same to the last bit; the splines
    are uncoupled blocks of one tridiagonal system (zero coupling terms, no pivoting across).
    """
    n = xk.size
    dx = xk[1:] - xk[:-1]
    slope = yk[1:] - yk[:-1]
    slope /= dx
    dl, d, du, b = np.empty(n - 1), np.empty(n), np.empty(n - 1), np.empty(n)
    np.add(dx[:-1], dx[1:], out=d[1:-1])
    d[1:-1] *= 2
    du[1:] = dx[:-1]
    dl[:-1] = dx[1:]
    np.multiply(dx[1:], slope[:-1], out=b[1:-1])
    b[1:-1] += dx[:-1] * slope[1:]
    b[1:-1] *= 3
    start = 0
    for end in ends:  # the end rows of each spline, in Python floats (same IEEE arithmetic)
        x0, x1, x2 = xk[start:start + 3].tolist()
        dx0, dx1, w = x1 - x0, x2 - x1, x2 - x0  # not-a-knot at the first interior knot
        s0, s1 = slope[start:start + 2].tolist()
        d[start], du[start] = dx1, w
        b[start] = ((dx0 + 2 * w) * dx1 * s0 + dx0 * dx0 * s1) / w
        x0, x1, x2 = xk[end - 3:end].tolist()
        dx0, dx1, w = x1 - x0, x2 - x1, x2 - x0  # and at the last interior knot
        s0, s1 = slope[end - 3:end - 1].tolist()
        d[end - 1], dl[end - 2] = dx0, w
        b[end - 1] = (dx1 * dx1 * s0 + (2 * w + dx1) * dx0 * s1) / w
        if end < n:  # no coupling between splines
            du[end - 1] = dl[end - 1] = 0.0
        start = end
    s = dgtsv(dl, d, du, b, overwrite_dl=1, overwrite_d=1, overwrite_du=1, overwrite_b=1)[3]
    # t = (s[:-1] + s[1:] - 2 slope) / dx, c2 = (slope - s[:-1]) / dx - t, c3 = t / dx
    t = s[:-1] + s[1:]
    t -= 2 * slope
    t /= dx
    c2 = slope
    c2 -= s[:-1]
    c2 /= dx
    c2 -= t
    t /= dx
    return s, c2, t


def _evaluate(xk, yk, coefficients, counts, t):
    """Evaluate spline segments at ``t``: ``counts[j]`` consecutive points in segment ``j``."""
    s, c2, c3 = coefficients
    # the segment's knot and coefficients at every point: one repeat of the five rows
    rows = np.empty((5, c2.size))
    rows[0], rows[1], rows[2], rows[3], rows[4] = xk[:-1], s[:-1], yk[:-1], c2, c3
    u, y, y0, term2, term3 = np.repeat(rows, counts, axis=1)
    np.subtract(t, u, out=u)
    # y + s u + c2 u^2 + c3 u^3 summed in the order of scipy's PPoly evaluation (same rounding)
    y *= u
    y += y0
    u2 = u * u
    term2 *= u2
    y += term2
    u2 *= u
    term3 *= u2
    y += term3
    return y


def not_a_knot_spline(xk: np.ndarray, yk: np.ndarray, t: np.ndarray) -> np.ndarray:
    """Cubic spline through ``(xk, yk)`` with not-a-knot ends, evaluated at sorted ``t``.

    The same spline as ``scipy.interpolate.CubicSpline(xk, yk)(t)`` (PyEMD's "cubic" envelope),
    to rounding, at a fraction of the cost: the slopes come from one tridiagonal LAPACK solve and
    the segment of every ``t`` from one ``searchsorted`` of the knots into ``t``.  ``xk`` must be
    strictly increasing with at least 4 knots, ``t`` sorted and inside ``[xk[0], xk[-1]]``.
    """
    first = np.searchsorted(t, xk[1:-1], side="left")  # first t of segments 1 .. n-2
    counts = np.diff(np.concatenate(([0], first, [t.size])))
    return _evaluate(xk, yk, _not_a_knot_coefficients(xk, yk, (xk.size,)), counts, t)


def _simple_extrema(s: np.ndarray) -> tuple[np.ndarray, np.ndarray] | None:
    """Indices of the local maxima and minima of ``s`` as PyEMD's ``_find_extrema_simple``
    defines them (a sample above/below both neighbours: ``d1 * d2 < 0`` on the differences),
    or ``None`` when ``s`` has a flat step (``d == 0``: PyEMD's plateau rules apply) or a
    difference so small that a product ``d1 * d2`` could underflow (PyEMD's test would then
    miss that extremum): those cases are left to PyEMD."""
    d = s[1:] - s[:-1]
    # |d| >= 1e-160 everywhere: no flat step, and no product d1 * d2 underflows to zero, so PyEMD's
    # sign test is a change of the sign of d
    if not np.abs(d).min() >= 1e-160:
        return None
    up = d > 0
    turn = np.flatnonzero(up[1:] != up[:-1])  # d changes sign between turn and turn + 1
    turn += 1
    # without flat steps maxima and minima alternate; the first turn after a rise is a maximum
    first_is_max = bool(turn.size) and bool(up[turn[0] - 1])
    return (turn[0::2], turn[1::2]) if first_is_max else (turn[1::2], turn[0::2])


def _mirror_indices(s: np.ndarray, imax: np.ndarray, imin: np.ndarray, nbsym: int):
    """PyEMD's ``prepare_points_simple`` boundary mirroring, on sample indices.

    Returns ``(left_max, left_min, lsym, right_max, right_min, rsym)``: the extrema mirrored about
    sample ``lsym`` (``rsym``) to extend the envelopes past the left (right) end, as Python lists
    in the order PyEMD places them; ``None`` in the rare cases where PyEMD falls back to mirroring
    whole extrema arrays (too few extrema of one kind), left to PyEMD itself.
    """
    n = s.size
    end_max, end_min = imax.size, imin.size
    head_max, head_min = imax[: nbsym + 1].tolist(), imin[: nbsym + 1].tolist()
    tail_max, tail_min = imax[-nbsym - 1 :].tolist(), imin[-nbsym - 1 :].tolist()
    # left end
    if head_max[0] < head_min[0]:
        if s[0] > s[head_min[0]]:
            lmax, lmin, lsym = head_max[1 : min(end_max, nbsym + 1)][::-1], head_min[: min(end_min, nbsym)][::-1], head_max[0]
        else:
            lmax, lmin, lsym = head_max[: min(end_max, nbsym)][::-1], head_min[: min(end_min, nbsym - 1)][::-1] + [0], 0
    else:
        if s[0] < s[head_max[0]]:
            lmax, lmin, lsym = head_max[: min(end_max, nbsym)][::-1], head_min[1 : min(end_min, nbsym + 1)][::-1], head_min[0]
        else:
            lmax, lmin, lsym = head_max[: min(end_max, nbsym - 1)][::-1] + [0], head_min[: min(end_min, nbsym)][::-1], 0
    # right end (PyEMD slices the last nbsym (+1) extrema; the tails hold nbsym + 1 of them)
    def last(tail, size, k):  # ind[max(size - k, 0):]
        return tail[len(tail) - min(k, size):] if k > 0 else []
    if tail_max[-1] < tail_min[-1]:
        if s[-1] < s[tail_max[-1]]:
            rmax, rmin, rsym = last(tail_max, end_max, nbsym)[::-1], last(tail_min, end_min, nbsym + 1)[:-1][::-1], tail_min[-1]
        else:
            rmax, rmin, rsym = (last(tail_max, end_max, nbsym - 1) + [n - 1])[::-1], last(tail_min, end_min, nbsym)[::-1], n - 1
    else:
        if s[-1] > s[tail_min[-1]]:
            rmax, rmin, rsym = last(tail_max, end_max, nbsym + 1)[:-1][::-1], last(tail_min, end_min, nbsym)[::-1], tail_max[-1]
        else:
            rmax, rmin, rsym = last(tail_max, end_max, nbsym)[::-1], (last(tail_min, end_min, nbsym - 1) + [n - 1])[::-1], n - 1
    if not (lmin and rmin and lmax and rmax):
        return None
    # mirrored points that fall inside the window: mirror about the window's end instead
    if 2 * lsym - lmin[0] > 0 or 2 * lsym - lmax[0] > 0:
        if lsym == head_max[0]:
            lmax = head_max[: min(end_max, nbsym)][::-1]
        else:
            lmin = head_min[: min(end_min, nbsym)][::-1]
        if lsym == 0:
            return None  # PyEMD raises "Left edge BUG"; let it
        lsym = 0
    if 2 * rsym - rmin[-1] < n - 1 or 2 * rsym - rmax[-1] < n - 1:
        if rsym == tail_max[-1]:
            rmax = last(tail_max, end_max, nbsym)[::-1]
        else:
            rmin = last(tail_min, end_min, nbsym)[::-1]
        if rsym == n - 1:
            return None  # PyEMD raises "Right edge BUG"
        rsym = n - 1
    return lmax, lmin, lsym, rmax, rmin, rsym


class _BoundedEMD(EMD):
    """PyEMD's EMD with its fixed-sifting (``FIXE``) loop rewritten lean, same numbers.

    ``EMD.emd`` spends most of a sift in numpy call overhead: it finds the extrema of every
    proto-IMF twice, builds the mirrored boundary points with ~50 small-array calls, and fits
    the envelopes with ``scipy.interpolate.CubicSpline``.  :meth:`emd` runs the same algorithm
    for ``FIXE > 0`` with PyEMD's settings ``extrema_detection="simple"``, ``spline_kind="cubic"``
    (the only ones :func:`emd` uses): PyEMD's extrema definition, its boundary mirroring
    (``prepare_points_simple``, ``nbsym`` points), the same not-a-knot cubic envelopes (one
    tridiagonal solve each), ``FIXE`` sifts per IMF, ``MAX_ITERATION``, PyEMD's end condition
    and IMF cap.  Where a proto-IMF needs one of PyEMD's rare special rules (flat steps, fewer
    than 4 knots in an envelope, too few extrema to mirror) that sift is done by PyEMD's own
    methods.  The arithmetic follows PyEMD and scipy operation by operation, so the IMFs come
    out bit for bit; tests/test_pipeline_emd.py checks them against stock PyEMD (to 1e-9).
    """

    def _envelope_mean(self, T: np.ndarray, TT: np.ndarray, imf: np.ndarray, extrema) -> np.ndarray:
        """Mean of the upper and lower envelopes of ``imf`` (PyEMD's ``extract_max_min_spline``):
        the two splines solved and evaluated together; ``TT`` is ``T`` twice."""
        n = imf.size
        mirrored = _mirror_indices(imf, extrema[0], extrema[1], self.nbsym) if extrema is not None else None
        if mirrored is not None:
            lmax, lmin, lsym, rmax, rmin, rsym = mirrored
            imax, imin = extrema
            n_max = len(lmax) + imax.size + len(rmax)
            idx = np.concatenate((lmax, imax, rmax, lmin, imin, rmin))
            # knot positions: the mirrored extrema about lsym / rsym, in increasing order by
            # construction; the envelopes must cover [0, n - 1] and join the extrema increasingly
            lpos = [[2 * lsym - i for i in lmax], [2 * lsym - i for i in lmin]]
            rpos = [[2 * rsym - i for i in rmax], [2 * rsym - i for i in rmin]]
            ok = n_max > 3 and idx.size - n_max > 3
            for left, inner, right in zip(lpos, extrema, rpos):
                ok = ok and left[0] <= 0 and right[-1] >= n - 1 and left[-1] < inner[0] and inner[-1] < right[0]
            if ok:
                k = idx.size
                pos, edges = idx.astype(np.float64), idx.copy()
                for lo, hi, mpos in ((0, len(lmax), lpos[0]), (n_max - len(rmax), n_max, rpos[0]),
                                     (n_max, n_max + len(lmin), lpos[1]), (k - len(rmin), k, rpos[1])):
                    pos[lo:hi] = mpos
                    edges[lo:hi] = [min(max(p, 0), n) for p in mpos]
                # segment j holds the samples xk[j] <= t < xk[j+1] (the last one also t = xk[-1]),
                # the two splines one after the other on TT
                edges[n_max - 1] = edges[k - 1] = n
                counts = edges[1:] - edges[:-1]
                counts[n_max - 1] = 0
                val = imf[idx]
                coefficients = _not_a_knot_coefficients(pos, val, (n_max, idx.size))
                both = _evaluate(pos, val, coefficients, counts, TT)
                both[:n] += both[n:]
                both[:n] *= 0.5
                return both[:n]
        max_env, min_env, _, _ = EMD.extract_max_min_spline(self, T, imf)
        return 0.5 * (max_env + min_env)

    def _lean(self, S) -> bool:
        """Whether :meth:`sift` applies: fixed sifting, PyEMD's simple extrema and cubic
        envelopes, float64 samples (PyEMD computes in the input's precision)."""
        return (self.FIXE > 0 and self.extrema_detection == "simple" and self.spline_kind == "cubic"
                and np.asarray(S).dtype == np.float64)

    def emd(self, S, T=None, max_imf=-1):
        if T is not None or not self._lean(S):
            return super().emd(S, T=T, max_imf=max_imf)
        self.sift(S, max_imf)
        return np.vstack((self.imfs, self.residue)) if not np.allclose(self.residue, 0) else self.imfs

    def sift(self, S: np.ndarray, max_imf: int = -1) -> None:
        """``EMD.emd(S, max_imf=max_imf)`` for fixed sifting (see the class docstring), without
        its return value; sets ``imfs`` and ``residue``."""
        if not self._lean(S):
            raise PipelineConfigError("the lean sifting loop needs FIXE > 0, simple extrema, cubic "
                                      "envelopes and float64 samples; use EMD.emd otherwise")
        S = np.asarray(S)
        n = S.size
        T = np.arange(n, dtype=np.float64)  # PyEMD's normalised timeline for T=None
        TT = np.concatenate((T, T))
        imfs = []
        total = None  # sum of the IMFs, row by row as np.sum(IMF, axis=0) adds them
        residue = S.copy()
        ext_no = -1
        finished = False
        while not finished:
            imf = residue.copy()
            it = 0
            while True:
                it += 1
                if it >= self.MAX_ITERATION:
                    break
                extrema = _simple_extrema(imf)
                if extrema is None:
                    found = EMD._find_extrema_simple(T, imf)
                    ext_no = len(found[0]) + len(found[2])
                else:
                    ext_no = extrema[0].size + extrema[1].size
                if ext_no <= 2:  # a trend: the decomposition is over
                    finished = True
                    break
                imf -= self._envelope_mean(T, TT, imf, extrema)
                if it >= self.FIXE:
                    break
            imfs.append(imf)
            if total is None:
                total = imf.copy()
            else:
                total += imf
            residue = S - total
            # PyEMD's end_condition: the residue's range or its L1 norm below the thresholds
            if len(imfs) == max_imf or (
                residue.max() - residue.min() < self.range_thr or np.sum(np.abs(residue)) < self.total_power_thr
            ):
                finished = True
        if ext_no <= 2:  # the last proto-IMF was a trend: it stays in the residue
            imfs.pop()
        self.imfs = np.array(imfs).reshape(len(imfs), n)
        self.residue = S - np.sum(self.imfs, axis=0)


@dataclass(frozen=True)
class EMDConfig:
    """Bounded EMD settings.

    Parameters
    ----------
    sifts : sifting iterations per IMF (PyEMD ``FIXE``); ``0`` selects PyEMD's default adaptive
        stop rule, which is unbounded and exists only for comparison.
    max_imfs : the most IMFs extracted; the remainder is the residue.  ``-1`` = no cap.

    The defaults (4 sifts, 3 IMFs: at most 12 sifts, a few ms for 4096 samples, BENCHMARKS.md)
    were chosen by cost: the paper's verdicts on its Tables 2 and 3 are the same with 4, 8 or 10
    sifts and 3 or 4 IMFs (tests/test_paper_reproduction.py; figures in ACCURACY.md), while 8
    sifts and 4 IMFs cost about twice as much.
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
    if config.sifts:
        decomposer.sift(x, config.max_imfs)
    else:
        decomposer.emd(x, max_imf=config.max_imfs)
    imfs, residue = decomposer.get_imfs_and_residue()
    imfs = np.asarray(imfs, dtype=np.float64).reshape(-1, x.size)
    return imfs, x - imfs.sum(axis=0)
