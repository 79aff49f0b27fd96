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
PyEMD's IMFs bit for bit at a fraction of its cost: each sift (extrema, boundary mirroring, both
spline envelopes, mean subtraction) is one numba-compiled function, :func:`_sift_step`,
translated operation by operation from the numpy code kept here as its reference.  numba caches
the compiled code on disk (``__pycache__`` next to this file, else the user's cache directory;
without any writable location it compiles in memory): the first sift of a process costs about
0.3 s with the cache and several seconds without (BENCHMARKS.md, issue 2).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from PyEMD import EMD
from scipy.linalg.lapack import dgtsv

from .errors import PipelineConfigError, SignalError
from .jit import compile_cached

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


# --- compiled sift -------------------------------------------------------------------------------
# One sift of the lean loop (extrema, boundary mirroring, both envelopes, mean subtraction) as one
# compiled function.  It performs the same IEEE operations in the same order as the numpy code
# above (itself scipy's CubicSpline / PPoly and LAPACK's dgtsv, operation by operation), so it
# gives the same numbers; numba compiles without fastmath, so nothing is reassociated or fused.


@compile_cached
def _gtsv(dl, d, du, b):  # pragma: no cover - compiled
    """LAPACK ``dgtsv`` (one right-hand side) in place: Gaussian elimination with partial pivoting
    on a tridiagonal system, the reference algorithm step by step.  Returns ``False`` on a zero
    pivot (LAPACK's ``info > 0``)."""
    n = d.size
    for i in range(n - 1):
        if abs(d[i]) >= abs(dl[i]):  # no row interchange
            if d[i] == 0.0:
                return False
            fact = dl[i] / d[i]
            d[i + 1] = d[i + 1] - fact * du[i]
            b[i + 1] = b[i + 1] - fact * b[i]
            dl[i] = 0.0
        else:  # interchange rows i and i + 1
            fact = d[i] / dl[i]
            d[i] = dl[i]
            temp = d[i + 1]
            d[i + 1] = du[i] - fact * temp
            if i < n - 2:
                dl[i] = du[i + 1]
                du[i + 1] = -fact * dl[i]
            du[i] = temp
            temp = b[i]
            b[i] = b[i + 1]
            b[i + 1] = temp - fact * b[i + 1]
    if d[n - 1] == 0.0:
        return False
    b[n - 1] = b[n - 1] / d[n - 1]
    if n > 1:
        b[n - 2] = (b[n - 2] - du[n - 2] * b[n - 1]) / d[n - 2]
    for i in range(n - 3, -1, -1):
        b[i] = (b[i] - du[i] * b[i + 1] - dl[i] * b[i + 2]) / d[i]
    return True


@compile_cached
def _spline_fit(x, y):  # pragma: no cover - compiled
    """:func:`_not_a_knot_coefficients` for one spline (``x.size >= 4``): slopes ``s`` at the
    knots and ``c2``, ``c3`` per segment, after a flag that is ``False`` on a singular system."""
    k = x.size
    dx = np.empty(k - 1)
    slope = np.empty(k - 1)
    for j in range(k - 1):
        dx[j] = x[j + 1] - x[j]
        slope[j] = (y[j + 1] - y[j]) / dx[j]
    dl, d, du, b = np.empty(k - 1), np.empty(k), np.empty(k - 1), np.empty(k)
    for i in range(1, k - 1):
        d[i] = (dx[i - 1] + dx[i]) * 2
        du[i] = dx[i - 1]
        dl[i - 1] = dx[i]
        b[i] = (dx[i] * slope[i - 1] + dx[i - 1] * slope[i]) * 3
    dx0, dx1, w = x[1] - x[0], x[2] - x[1], x[2] - x[0]  # not-a-knot at the first interior knot
    d[0], du[0] = dx1, w
    b[0] = ((dx0 + 2 * w) * dx1 * slope[0] + dx0 * dx0 * slope[1]) / w
    dx0, dx1, w = x[k - 2] - x[k - 3], x[k - 1] - x[k - 2], x[k - 1] - x[k - 3]  # and at the last
    d[k - 1], dl[k - 2] = dx0, w
    b[k - 1] = (dx1 * dx1 * slope[k - 3] + (2 * w + dx1) * dx0 * slope[k - 2]) / w
    c2, c3 = np.empty(k - 1), np.empty(k - 1)
    if not _gtsv(dl, d, du, b):
        return False, b, c2, c3
    for j in range(k - 1):
        t = (b[j] + b[j + 1] - 2 * slope[j]) / dx[j]
        c2[j] = (slope[j] - b[j]) / dx[j] - t
        c3[j] = t / dx[j]
    return True, b, c2, c3


@compile_cached
def _spline_into(out, x, y, s, c2, c3):  # pragma: no cover - compiled
    """A spline at ``t = 0, 1, ..., out.size - 1`` into ``out``, segment by segment as
    :func:`_evaluate` assigns the points (``x[j] <= t < x[j + 1]``; the last segment up to the end)
    and summed in its order; ``x[0] <= 0``, integer-valued knots."""
    n, last = out.size, x.size - 2
    start = 0
    for j in range(last + 1):
        stop = n if j == last else min(max(int(x[j + 1]), 0), n)
        xj, yj, sj, c2j, c3j = x[j], y[j], s[j], c2[j], c3[j]
        for i in range(start, stop):
            u = i - xj
            u2 = u * u
            out[i] = sj * u + yj + c2j * u2 + c3j * (u2 * u)
        start = max(start, stop)


@compile_cached
def _put_reversed(row, src, lo, hi, first, last):  # pragma: no cover - compiled
    """``row[:count] = [first] + src[lo:hi][::-1] + [last]`` (``-1``: no ``first`` / ``last``);
    returns ``count``."""
    count = 0
    if first >= 0:
        row[0] = first
        count = 1
    for i in range(hi - 1, lo - 1, -1):
        row[count] = src[i]
        count += 1
    if last >= 0:
        row[count] = last
        count += 1
    return count


@compile_cached
def _mirror(s, imax, imin, nbsym, pts, count):  # pragma: no cover - compiled
    """:func:`_mirror_indices` on arrays (``nbsym >= 1``): the mirrored extrema go to the rows
    of ``pts`` (0 left maxima, 1 left minima, 2 right maxima, 3 right minima; ``count`` holds
    their numbers).  Returns ``(ok, lsym, rsym)``, ``ok`` False where that returns None."""
    n, n_hi, n_lo, nb = s.size, imax.size, imin.size, nbsym
    if imax[0] < imin[0]:
        if s[0] > s[imin[0]]:
            count[0] = _put_reversed(pts[0], imax, 1, min(n_hi, nb + 1), -1, -1)
            count[1] = _put_reversed(pts[1], imin, 0, min(n_lo, nb), -1, -1)
            lsym = imax[0]
        else:
            count[0] = _put_reversed(pts[0], imax, 0, min(n_hi, nb), -1, -1)
            count[1] = _put_reversed(pts[1], imin, 0, min(n_lo, nb - 1), -1, 0)
            lsym = 0
    else:
        if s[0] < s[imax[0]]:
            count[0] = _put_reversed(pts[0], imax, 0, min(n_hi, nb), -1, -1)
            count[1] = _put_reversed(pts[1], imin, 1, min(n_lo, nb + 1), -1, -1)
            lsym = imin[0]
        else:
            count[0] = _put_reversed(pts[0], imax, 0, min(n_hi, nb - 1), -1, 0)
            count[1] = _put_reversed(pts[1], imin, 0, min(n_lo, nb), -1, -1)
            lsym = 0
    if imax[n_hi - 1] < imin[n_lo - 1]:
        if s[n - 1] < s[imax[n_hi - 1]]:
            count[2] = _put_reversed(pts[2], imax, max(n_hi - nb, 0), n_hi, -1, -1)
            count[3] = _put_reversed(pts[3], imin, max(n_lo - nb - 1, 0), n_lo - 1, -1, -1)
            rsym = imin[n_lo - 1]
        else:
            count[2] = _put_reversed(pts[2], imax, max(n_hi - nb + 1, 0), n_hi, n - 1, -1)
            count[3] = _put_reversed(pts[3], imin, max(n_lo - nb, 0), n_lo, -1, -1)
            rsym = n - 1
    else:
        if s[n - 1] > s[imin[n_lo - 1]]:
            count[2] = _put_reversed(pts[2], imax, max(n_hi - nb - 1, 0), n_hi - 1, -1, -1)
            count[3] = _put_reversed(pts[3], imin, max(n_lo - nb, 0), n_lo, -1, -1)
            rsym = imax[n_hi - 1]
        else:
            count[2] = _put_reversed(pts[2], imax, max(n_hi - nb, 0), n_hi, -1, -1)
            count[3] = _put_reversed(pts[3], imin, max(n_lo - nb + 1, 0), n_lo, n - 1, -1)
            rsym = n - 1
    if count[0] == 0 or count[1] == 0 or count[2] == 0 or count[3] == 0:
        return False, lsym, rsym
    # mirrored points that fall inside the window: mirror about the window's end instead
    if 2 * lsym - pts[1, 0] > 0 or 2 * lsym - pts[0, 0] > 0:
        if lsym == imax[0]:
            count[0] = _put_reversed(pts[0], imax, 0, min(n_hi, nb), -1, -1)
        else:
            count[1] = _put_reversed(pts[1], imin, 0, min(n_lo, nb), -1, -1)
        if lsym == 0:
            return False, lsym, rsym
        lsym = 0
    if 2 * rsym - pts[3, count[3] - 1] < n - 1 or 2 * rsym - pts[2, count[2] - 1] < n - 1:
        if rsym == imax[n_hi - 1]:
            count[2] = _put_reversed(pts[2], imax, max(n_hi - nb, 0), n_hi, -1, -1)
        else:
            count[3] = _put_reversed(pts[3], imin, max(n_lo - nb, 0), n_lo, -1, -1)
        if rsym == n - 1:
            return False, lsym, rsym
        rsym = n - 1
    return True, lsym, rsym


@compile_cached
def _knots(s, left, a, inner, right, c, lsym, rsym):  # pragma: no cover - compiled
    """Knot positions and values of one envelope: the extrema ``inner`` with the mirrored ones
    (``left[:a]`` about ``lsym``, ``right[:c]`` about ``rsym``), after a flag that is ``False``
    unless they are at least 4, cover ``[0, n - 1]`` and increase (the checks of
    :meth:`_BoundedEMD._envelope_mean`)."""
    n, b = s.size, inner.size
    k = a + b + c
    x, y = np.empty(k), np.empty(k)
    if k <= 3 or 2 * lsym - left[0] > 0 or 2 * rsym - right[c - 1] < n - 1:
        return False, x, y
    if 2 * lsym - left[a - 1] >= inner[0] or inner[b - 1] >= 2 * rsym - right[0]:
        return False, x, y
    for j in range(k):
        if j < a:
            i = left[j]
            x[j] = 2 * lsym - i
        elif j < a + b:
            i = inner[j - a]
            x[j] = i
        else:
            i = right[j - a - b]
            x[j] = 2 * rsym - i
        y[j] = s[i]
    return True, x, y


@compile_cached
def _sift_step(imf, nbsym):  # pragma: no cover - compiled
    """One sift of ``imf`` in place.  Returns ``(ext_no, done)``: ``ext_no`` the number of
    extrema (``-1`` when the simple extrema do not apply: flat step, underflowing difference,
    fewer than 3 samples); ``done`` whether ``imf`` was sifted (``False`` when ``ext_no <= 2``
    or one of PyEMD's special rules applies: then ``imf`` is untouched)."""
    n = imf.size
    if n < 3:
        return -1, False
    imax, imin = np.empty(n, np.int64), np.empty(n, np.int64)
    n_hi = n_lo = 0
    prev = imf[1] - imf[0]
    small = not abs(prev) >= 1e-160
    for i in range(1, n - 1):  # branch-free: noisy windows turn at random
        nxt = imf[i + 1] - imf[i]
        small |= not abs(nxt) >= 1e-160
        rise, rise_next = prev > 0, nxt > 0
        imax[n_hi] = i
        n_hi += rise and not rise_next
        imin[n_lo] = i
        n_lo += rise_next and not rise
        prev = nxt
    if small:  # a flat step (or NaN): PyEMD's plateau rules
        return -1, False
    if n_hi + n_lo <= 2:
        return n_hi + n_lo, False
    imax, imin = imax[:n_hi], imin[:n_lo]
    pts, count = np.empty((4, nbsym + 1), np.int64), np.empty(4, np.int64)
    ok, lsym, rsym = _mirror(imf, imax, imin, nbsym, pts, count)
    if not ok:
        return n_hi + n_lo, False
    ok_u, xu, yu = _knots(imf, pts[0], count[0], imax, pts[2], count[2], lsym, rsym)
    ok_l, xl, yl = _knots(imf, pts[1], count[1], imin, pts[3], count[3], lsym, rsym)
    if not (ok_u and ok_l):
        return n_hi + n_lo, False
    ok_u, su, c2u, c3u = _spline_fit(xu, yu)
    ok_l, sl, c2l, c3l = _spline_fit(xl, yl)
    if not (ok_u and ok_l):
        return n_hi + n_lo, False
    upper_env, lower_env = np.empty(n), np.empty(n)
    _spline_into(upper_env, xu, yu, su, c2u, c3u)
    _spline_into(lower_env, xl, yl, sl, c2l, c3l)
    for i in range(n):
        imf[i] -= (upper_env[i] + lower_env[i]) * 0.5
    return n_hi + n_lo, True


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

    Attributes
    ----------
    compiled : sift with the compiled kernel (:func:`_sift_step`, the default) or with the numpy
        code it was translated from (the reference; same numbers, several times slower).
    """

    compiled = True

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

    def _sift_once(self, T: np.ndarray, TT: np.ndarray, imf: np.ndarray) -> int:
        """One sift of ``imf`` in place, unless it has 2 extrema or fewer (a trend: untouched);
        returns its number of extrema.  The compiled :func:`_sift_step` when :attr:`compiled`,
        the numpy code otherwise and wherever one of PyEMD's special rules applies."""
        if self.compiled and self.nbsym >= 1:
            ext_no, done = _sift_step(imf, self.nbsym)
            if done or 0 <= ext_no <= 2:
                return ext_no
        extrema = _simple_extrema(imf)
        if extrema is None:
            found = EMD._find_extrema_simple(T, imf)
            ext_no = len(found[0]) + len(found[2])
        else:
            ext_no = extrema[0].size + extrema[1].size
        if ext_no > 2:
            imf -= self._envelope_mean(T, TT, imf, extrema)
        return ext_no

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
                ext_no = self._sift_once(T, TT, imf)
                if ext_no <= 2:  # a trend: the decomposition is over
                    finished = True
                    break
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
