"""Does the valve follow the OP?  A Hammerstein (stiction + linear) fit of OP → PV against a linear one.

A linear valve passes the controller output to the process: the PV follows the OP through
the process dynamics, across set-point steps as well (the controller's kick is in the OP).  A
sticking valve holds the stem while the OP ramps and lets it jump when the force beats static
friction: the PV stays flat where a linear model of the loop predicts movement, then catches
up with no OP step.  So fit two models of PV from OP on the window itself and compare them:

* **linear**: ``pv(k) = K G(q) op(k - d) + c``, ``G`` a first-order lag ``(1 - a) / (1 - a q^-1)``
  (static when ``a = 0``, near-integrating for ``a → 1``), dead time ``d >= 1`` samples (a PV
  sample cannot answer the OP computed from it; at ``d = 0`` the OP's reaction to the PV's
  measurement noise would read as a response);
* **Hammerstein**: the same, fed by the stem ``x = f_{fs,fd}(op)`` of a two-parameter
  stiction model: the force-balance form (static and dynamic friction, He et al. 2007;
  :func:`stiction_stem`) or the reversal rule of Choudhury, Thornhill & Shah (2005;
  :func:`reversal_stem`), whose stuck count restarts at every OP reversal.

This is the Hammerstein identification of Srinivasan, Rengaswamy, Narasimhan & Miller (2005,
"Control loop performance assessment. 2. Hammerstein model approach for stiction diagnosis",
Ind. Eng. Chem. Res. 44:6719–6728) and Jelali (2008, "Estimation of valve stiction in control
loops using separable least-squares and global search algorithms", J. Process Control
18:632–642): the stiction parameters by a global grid search, refined by a finer grid around
its best point and once more by a narrower one; the linear part by separable least squares
(for each pole and dead time the gain and offset are linear; the
cross-correlations of every candidate stem with the PV at every dead time come from one
matrix product per pole).  The linear model is the ``fs = fd = 0`` member of the family.

Decision (:func:`stiction_test`): PV and stems are first high-passed alike (less an
``n/8``-sample moving average; a linear filter on both sides keeps the linear relation and
drops slow unmeasured loads).  The stiction model must then explain the PV better than the
linear model by a likelihood ratio that is significant after accounting for the residuals'
autocorrelation (effective sample size ``n (1 - r1) / (1 + r1)``, Bartlett 1946, with ``r1``
the lag-1 autocorrelation of the Hammerstein residual), penalised as BIC (``2 ln n_eff``,
Schwarz 1978), plus ``ln n_eff`` for the choice between the two stem models (one more
parameter); the static
friction searched is at least a tenth of the window's OP travel (``min_share``) and ``z`` OP
noise deviations (a "deadband" within the OP's noise, or a small
share of the control action, is a model mismatch more often than a valve fault).  Defaults
chosen on planted loops (``tests/bench/accuracy_sim.py``), not on plant data.

What it cannot tell apart: a deadband (backlash, ``fd = fs``) is the same family; the finding
is "the valve does not follow the OP (stiction or deadband)".  In closed loop the OP is
correlated with the disturbances it cancels: while the stem is held, "the stem did not move"
and "it moved and a disturbance cancelled it" predict the same PV, so a compensated load can
read as stiction (:mod:`pipeline.stickslip` adds a guard); a PV that does not depend on the OP
within the window (valve stuck throughout) gives no evidence either way.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from scipy.ndimage import uniform_filter1d
from scipy.signal import lfilter

from .jit import compile_cached

__all__ = ["HammersteinFit", "StictionTest", "stiction_stem", "reversal_stem", "hammerstein_fit", "stiction_test"]


def stiction_stem(op: np.ndarray, fs: np.ndarray, fd: np.ndarray, force0: np.ndarray | float = 0.0) -> np.ndarray:
    """Stem positions of the two-parameter force-balance stiction model for several (fs, fd).

    The semi-physical model of He, Wang, Pottmann & Qin (2007, "A curve fitting method for
    detecting valve stiction in oscillating control loops", Ind. Eng. Chem. Res. 46:4549–4560,
    Fig. 3): the net force on a stuck stem is the OP travelled since it stuck plus the
    dynamic friction it stuck with, ``u_r(k) = u_r(k-1) + op(k) - op(k-1)``; while
    ``|u_r| <= fs`` (static friction) the stem holds, beyond it the stem moves by
    ``u_r - sign(u_r) fd`` (dynamic friction) and ``u_r = sign(u_r) fd``.  A slowly ramping OP
    gives stick-slip with jumps ``fs - fd``; ``fs = fd`` is a deadband of ``2 fd``; ``fd = 0``
    a stem that jumps to the OP.  Unlike the reversal-point rule of Choudhury, Thornhill & Shah
    (2005), noise on the OP does not restart the count, so a noisy OP still breaks a stem away
    after it has travelled ``fs`` net (as a real actuator's force would).  At the start the
    stem is at rest with the net force ``force0`` (``|force0| <= fs``): ``u_r = op - x`` is the
    OP's distance from the stem, so ``x(0) = op(0) - force0``.  The window starts at an unknown
    point of a stuck phase, hence the free ``force0``.

    Parameters
    ----------
    op : 1-D controller output.
    fs, fd : 1-D arrays of equal length ``m``, ``fs >= fd >= 0`` (OP units).
    force0 : net force at the first sample, scalar or length ``m``.

    Returns
    -------
    (m, n) array of stem positions.
    """
    return _stems(*_kernel_args(op, fs, fd, force0))


def _kernel_args(op, a, b, force0) -> tuple[np.ndarray, ...]:
    """The stem kernels' arguments: contiguous float arrays, ``force0`` one per candidate."""
    a = np.ascontiguousarray(a, dtype=np.float64)
    f0 = np.broadcast_to(np.asarray(force0, dtype=np.float64), a.shape).copy()
    return np.ascontiguousarray(op, dtype=np.float64), a, np.ascontiguousarray(b, dtype=np.float64), f0


@compile_cached
def _stems(op, fs, fd, ur):
    """Kernel of :func:`stiction_stem` (compiled): one candidate at a time, sample by sample."""
    m, n = fs.size, op.size
    out = np.empty((m, n))
    for j in range(m):
        u = ur[j]
        x = op[0] - u
        out[j, 0] = x
        for k in range(1, n):
            u += op[k] - op[k - 1]
            if abs(u) > fs[j]:
                s = 1.0 if u > 0 else -1.0
                x = x + u - s * fd[j]
                u = s * fd[j]
            out[j, k] = x
    return out


def reversal_stem(op: np.ndarray, S: np.ndarray, J: np.ndarray, force0: np.ndarray | float = 0.0) -> np.ndarray:
    """Stem positions of the two-parameter stiction model with the reversal rule, for several (S, J).

    Choudhury, Thornhill & Shah (2005, "Modelling valve stiction", Control Eng. Practice
    13:641–658, §4 and the flow chart of Fig. 7), step by step on the sampled OP ``x``: the OP's
    direction is ``d = sign(x(k) - x(k-1))``; on a *reversal* (``d = -d_old``, both non-zero) the
    valve sticks at ``x_ss = x(k-1)`` and needs ``|x - x_ss| > S`` (deadband + stickband) to move
    again; when the OP *stops* (``d = 0``) a moving valve sticks there and, if the OP resumes the
    same way, needs only ``|x - x_ss| > J`` (resuming the other way is a reversal); while stuck the
    stem holds; while moving (and on breakaway) ``y = x - d (S - J) / 2``, so a breakaway after a
    reversal jumps by ``J``.  Unlike :func:`stiction_stem` (He et al. 2007, the force-balance
    form) the stuck count restarts at every OP reversal, so with a noisy OP the stem holds while
    the OP travels many ``S``, and the stuck travel varies from one episode to the next.  The
    force-balance ``(fs, fd)`` has the same deadband, jump and sliding lag as ``S = fs + fd``,
    ``J = fs - fd``.  (The same rule as :class:`models.valves.ChoudhuryStiction`, which the
    loop simulator uses; the pipeline keeps its own compiled kernel, as it must not import
    the models.)

    At the start the valve is at rest as :class:`models.valves.ChoudhuryStiction` after
    ``reset`` (threshold ``S`` whichever way the OP moves first), with the stem ``force0`` below
    the OP, ``y(0) = x(0) - force0`` (``force0 = 0``: the simulator's reset).  Held by the
    reversal rule, a stem can sit many ``S`` away from the OP when the window starts (the OP
    has travelled on in steps shorter than ``S``), so ``force0`` may be as large as the OP's
    travel; it sets the size of the first slip (after it ``y = x - d (S - J) / 2`` whatever
    ``y(0)`` was).

    Parameters
    ----------
    op : 1-D controller output (the OP the valve receives, once per sample).
    S, J : 1-D arrays of equal length ``m``, ``S >= 0``, ``J >= 0`` (OP units).
    force0 : the OP's distance above the stem at the first sample, scalar or length ``m``.

    Returns
    -------
    (m, n) array of stem positions.
    """
    return _reversal_stems(*_kernel_args(op, S, J, force0))


@compile_cached
def _reversal_stems(op, S, J, f0):
    """Kernel of :func:`reversal_stem` (compiled): one candidate at a time, sample by sample."""
    m, n = S.size, op.size
    out = np.empty((m, n))
    for j in range(m):
        half = 0.5 * (S[j] - J[j])
        d_old = 0
        x_ss = op[0]
        y = op[0] - f0[j]
        stuck = True
        thr = S[j]
        resume = 0
        out[j, 0] = y
        for k in range(1, n):
            x = op[k]
            dx = x - op[k - 1]
            d = 1 if dx > 0 else (-1 if dx < 0 else 0)
            if d != d_old:
                if d == 0:  # the OP stops: a moving valve sticks; the same way on needs only J
                    if not stuck:
                        stuck = True
                        x_ss = op[k - 1]
                        thr = J[j]
                    resume = d_old
                elif d_old == 0:  # the OP moves again: the other way is a reversal
                    if d != resume:
                        x_ss = op[k - 1]
                        thr = S[j]
                else:  # reversal: deadband + stickband from the reversal point
                    stuck = True
                    x_ss = op[k - 1]
                    thr = S[j]
            if stuck:
                if d != 0 and abs(x - x_ss) > thr:
                    stuck = False
                    y = x - d * half
            else:
                y = x - d * half
            d_old = d
            out[j, k] = y
    return out


@dataclass(frozen=True)
class HammersteinFit:
    """Least-squares fit of ``pv`` from each candidate stem: error sum of squares and the
    best first-order pole ``a`` and dead time ``d`` (samples) per candidate."""

    sse: np.ndarray
    pole: np.ndarray
    dead_time: np.ndarray
    gain: np.ndarray
    n: int


def _time_constants(n: int) -> np.ndarray:
    """Poles of the first-order lag searched: static, then time constants 1 … 4n samples."""
    tau = np.geomspace(1.0, 4.0 * n, 14)
    return np.r_[0.0, np.exp(-1.0 / tau)]


def _lagged(v: np.ndarray, n: int, D: int) -> np.ndarray:
    """(n, D+1) view ``H[s, d] = v[s + d - D]`` where that index is in ``v`` (the ``N = n - D``
    fitted samples), else 0: ``f @ H`` correlates ``f`` delayed by ``d`` with ``v``."""
    pad = np.zeros(D)
    return np.lib.stride_tricks.sliding_window_view(np.r_[pad, v, pad], D + 1)[:n]


def _cumsum0(f: np.ndarray) -> np.ndarray:
    """Cumulative sums along rows with a leading 0: ``c[:, j] = f[:, :j].sum(1)``."""
    c = np.zeros((f.shape[0], f.shape[1] + 1))
    np.cumsum(f, axis=1, out=c[:, 1:])
    return c


def hammerstein_fit(pv: np.ndarray, stems: np.ndarray, *, max_dead_time: int, min_dead_time: int = 0,
                    poles: np.ndarray | None = None) -> HammersteinFit:
    """Fit ``pv(k) = K G_a(q) x(k - d) + c + c' a^k`` for every stem ``x`` (rows of
    ``stems``), best over the pole grid and ``d = min_dead_time … max_dead_time`` (separable least squares,
    see the module docstring).  ``c' a^k`` is the free response of the lag from its unknown
    state at the window's start (for a pole near 1 it is the drift of an integrating PV); the
    input enters as ``x - x(0)``.  All fits use the same samples ``max_dead_time … n-1``.
    ``min_dead_time``: the shortest dead time searched; ``poles``: the poles searched (default
    :func:`_time_constants`)."""
    pv = np.asarray(pv, dtype=np.float64)
    stems = np.atleast_2d(np.asarray(stems, dtype=np.float64))
    m, n = stems.shape
    D = int(max_dead_time)
    N = n - D
    y = pv[D:]
    x0 = stems - stems[:, :1]
    lo = D - np.arange(D + 1)  # first input sample of the fitted span at each lag
    rows = np.arange(m)
    best = np.full(m, np.inf)
    best_a = np.zeros(m)
    best_d = np.zeros(m, dtype=int)
    best_k = np.zeros(m)
    t = np.arange(N, dtype=np.float64)
    for a in (_time_constants(n) if poles is None else poles):
        # nuisance regressors over the span: offset and free response a^t, orthonormalised
        # (q1 = 1/sqrt N, q2 = (a^t - mean) / norm)
        g = a ** t if a > 0 else (t == 0).astype(np.float64)
        gc = g - g.mean()
        gn = float(np.sqrt(gc @ gc))
        yp = y - y.mean()
        if gn > 0:
            yp = yp - gc * (gc @ yp) / gn**2
        syy = float(yp @ yp)
        H = np.ascontiguousarray(_lagged(yp, n, D))
        f = lfilter([1.0 - a], [1.0, -a], x0, axis=1) if a > 0 else x0
        # in blocks of a few rows, small enough that a threaded BLAS stays on one thread (a
        # threaded product of this size ran 100 x slower on a busy host)
        sfy = np.concatenate([f[r:r + 4] @ H for r in range(0, m, 4)])
        c1 = _cumsum0(f)
        c2 = _cumsum0(f * f)
        s1 = c1[:, lo + N] - c1[:, lo]
        sff = c2[:, lo + N] - c2[:, lo] - s1 * s1 / N
        if gn > 0:
            # f . g over each lag's span from one backward recursion R[s] = f[s] + a R[s+1]
            R = lfilter([1.0], [1.0, -a], f[:, ::-1], axis=1)[:, ::-1] if a > 0 else f
            R = np.concatenate([R, np.zeros((m, 1))], axis=1)
            fg = R[:, lo] - (a ** N) * R[:, lo + N]
            fgc = fg - s1 * g.mean()
            sff = sff - (fgc / gn) ** 2
        with np.errstate(divide="ignore", invalid="ignore"):
            ok = sff > 1e-9 * np.maximum(c2[:, lo + N] - c2[:, lo], 1e-300)
            sse = np.where(ok, syy - sfy * sfy / np.where(ok, sff, 1.0), syy)
        sse[:, :min_dead_time] = np.inf
        j = np.argmin(sse, axis=1)
        v = sse[rows, j]
        better = v < best
        best = np.where(better, v, best)
        best_a = np.where(better, a, best_a)
        best_d = np.where(better, j, best_d)
        with np.errstate(divide="ignore", invalid="ignore"):
            best_k = np.where(better, sfy[rows, j] / sff[rows, j], best_k)
    return HammersteinFit(np.maximum(best, 0.0), best_a, best_d, best_k, N)


def _residual(pv: np.ndarray, stem: np.ndarray, a: float, d: int, D: int) -> np.ndarray:
    """Residual of one fit of :func:`hammerstein_fit` (same regressors, plain least squares)."""
    n = pv.size
    f = stem - stem[0]
    if a > 0:
        f = lfilter([1.0 - a], [1.0, -a], f)
    k = np.arange(D, n, dtype=np.float64)
    cols = [f[D - d:n - d], np.ones(n - D)] + ([a ** (k - D)] if a > 0 else [])
    A = np.column_stack(cols)
    y = pv[D:]
    coef, *_ = np.linalg.lstsq(A, y, rcond=None)
    return y - A @ coef


@dataclass(frozen=True)
class StictionTest:
    """Outcome of :func:`stiction_test`.

    ``sticking``: the stiction model wins; ``fs``, ``fd`` its static and dynamic friction (OP
    units); ``sse_ratio`` Hammerstein / linear error; ``statistic`` the autocorrelation-corrected
    likelihood ratio and ``penalty`` what it had to exceed; ``slips`` the fitted stem's moves
    after a stuck phase, ``stuck_fraction`` of the window the fitted stem held while the OP
    moved; ``pole`` and ``dead_time`` (samples) the fitted lag of the stiction model; ``stem``
    the fitted stem (OP units); ``rule`` its stem model, ``"force balance"`` (:func:`stiction_stem`)
    or ``"reversal rule"`` (:func:`reversal_stem`).
    """

    sticking: bool
    fs: float
    fd: float
    sse_ratio: float
    statistic: float
    penalty: float
    slips: int
    stuck_fraction: float
    reason: str
    pole: float = 0.0
    dead_time: int = 0
    stem: np.ndarray = field(default=None, repr=False, compare=False)
    rule: str = "force balance"


def _noise_std(x: np.ndarray) -> float:
    d = np.diff(x)
    return float(np.median(np.abs(d - np.median(d))) / 0.6745 / np.sqrt(2.0))


def stiction_test(pv: np.ndarray, op: np.ndarray, *, z: float = 4.0, min_share: float = 0.1,
                  max_dead_time: int | None = None, min_dead_time: int = 1,
                  highpass: int | None = None, refine_rounds: int = 1,
                  reversal_rule: bool = True) -> StictionTest | None:
    """Is the PV explained better by a sticking valve than by a linear one?  (Module docstring.)

    Parameters
    ----------
    pv, op : finite 1-D arrays of one window.
    z : the static friction ``fs`` must exceed ``z`` OP noise deviations (first differences, MAD).
    min_share : and at least this share of the OP's travel in the window (1–99 % range): a
        friction that holds the stem for a small part of the control action is no fault
        worth reporting (and a small model mismatch reads as one).
    max_dead_time : longest dead time searched, samples (default a tenth of the window).
    min_dead_time : shortest dead time searched, samples: 1, because a PV sample cannot answer
        the OP computed from it (at lag 0 the OP carries the controller's reaction to the PV's
        measurement noise, which a linear model of PV from OP would fit and a held stem cannot).
    highpass : length in samples of the moving average removed from PV and stems before the
        fit (default an eighth of the window; 0: none).
    refine_rounds : narrowed refinement passes after the first fine one (fs x 0.92-1.08,
        fd/fs +- 0.125, initial force +- 0.15 fs around the best).
    reversal_rule : also search stems of the reversal-rule model (:func:`reversal_stem`,
        Choudhury et al. 2005) on the same grid (``S = fs + fd``, ``J = fs - fd``; the stem's
        start ``force0`` below the OP over -0.8 … 0.8 of the OP's travel, since a stem held by
        the reversal rule can sit many ``S`` from the OP), each candidate with its own
        likelihood.  The rule reads the raw sampled OP: it is a sampled-data model of the OP
        the positioner receives once per scan, and smoothing would invent a filter that is in
        neither the model nor the loop.  Each family's best coarse candidate is refined and the
        better refined model kept; the choice between the two families is counted in the
        penalty as one more parameter, ``+ ln n_eff`` (BIC; on the planted windows the
        alternative, ``+ 2 ln 2``, a prior of 1/2 on each family or a Bonferroni doubling of the
        look, found more but raised more false alarms than main: ACCURACY.md, issue 3, session 7).

    Returns
    -------
    StictionTest, or None when the OP or PV does not move (nothing to judge).
    """
    pv = np.asarray(pv, dtype=np.float64)
    op = np.asarray(op, dtype=np.float64)
    n = pv.size
    D = n // 10 if max_dead_time is None else int(max_dead_time)
    L = n // 8 if highpass is None else int(highpass)
    lo, hi = np.percentile(op, [1, 99])
    travel = hi - lo
    s_op = _noise_std(op)
    if n < 50 or not travel > 0 or not np.ptp(pv) > 0:
        return None
    fs = travel * np.geomspace(min_share, 1.0, 8)
    fs = fs[fs > z * s_op]
    if fs.size == 0:
        return None
    # static friction x dynamic share fd/fs x initial net force / fs (force balance: |force0| <= fs)
    # or initial distance of the stem from the OP / OP travel (reversal rule: the stem may have
    # been held while the OP travelled many S)
    families = (0, 1) if reversal_rule else (0,)
    f0_grid = ([-0.75, 0.0, 0.75], [-0.8, -0.4, 0.0, 0.4, 0.8])

    def f0_unit(fam, fs):
        """Unit of the initial force: the static friction (force balance) or the OP's travel (reversal rule)."""
        return np.where(fam == 0, fs, travel)

    g = np.concatenate([np.array(np.meshgrid(fs, [0.0, 0.5, 1.0], f0_grid[f], [f], indexing="ij")).reshape(4, -1)
                        for f in families], axis=1)
    FS, FD, FAM = np.r_[0.0, g[0]], np.r_[0.0, g[0] * g[1]], np.r_[0, g[3]].astype(int)
    F0 = np.r_[0.0, g[2] * f0_unit(g[3], g[0])]
    h = L // 2 if L > 1 else 0

    def fit_grid(FS, FD, F0, FAM, poles=None):
        stems = np.empty((FS.size, n))
        he = FAM == 0
        stems[he] = stiction_stem(op, FS[he], FD[he], F0[he])
        if not he.all():
            stems[~he] = reversal_stem(op, FS[~he] + FD[~he], FS[~he] - FD[~he], F0[~he])
        moves = np.ptp(stems, axis=1) > 0  # a stem that never moves predicts nothing
        moves[0] |= FS[0] == 0
        if not he.all():  # reversal-rule stems can coincide (e.g. the same single slip): one each
            rev = np.flatnonzero(moves & ~he)
            keep = np.zeros(FS.size, dtype=bool)
            if rev.size:
                keep[rev[np.unique(stems[rev], axis=0, return_index=True)[1]]] = True
            moves &= he | keep
        FS, FD, F0, FAM, stems = FS[moves], FD[moves], F0[moves], FAM[moves], stems[moves]
        # unmeasured slow disturbances: the same high-pass (less an L-sample moving average) on
        # the PV and on every stem keeps the linear relation and drops what the OP did not cause
        # (L/2 samples at each end, where the average is one-sided, are left out)
        if L > 1:
            stems_w = (stems - uniform_filter1d(stems, L, axis=1, mode="nearest"))[:, h:n - h]
        else:
            stems_w = stems
        fit = hammerstein_fit(pv_w, stems_w, max_dead_time=D, min_dead_time=min_dead_time, poles=poles)
        return FS, FD, F0, FAM, stems, stems_w, fit

    pv_w = (pv - uniform_filter1d(pv, L, mode="nearest"))[h:n - h] if L > 1 else pv
    FS, FD, F0, FAM, stems, stems_w, fit = fit_grid(FS, FD, F0, FAM)  # row 0: fs = fd = 0, the linear valve
    if stems.shape[0] < 2:
        return None
    sse_lin = float(fit.sse[0])
    if not sse_lin > 0:
        return None
    # finer passes around the best stiction candidate (the slip times hinge on fs and the
    # initial force together: the coarse grid can miss a slip by tens of samples), over the
    # best fit's pole and its two neighbours; same family, same parameters.  The first spans
    # fd/fs and the initial force whole, each further one (``refine_rounds``) narrows all three
    # around the best so far.  Each family's best coarse candidate is refined, and the family
    # is chosen after refinement (a coarse grid can favour the family whose grid happens to
    # lie nearer, not the better model)
    poles = _time_constants(n)
    spans = [(np.array([0.8, 0.9, 1.0, 1.12, 1.25]), None, None)] + [
        (np.array([0.92, 0.96, 1.0, 1.04, 1.08]), np.array([-0.125, 0.0, 0.125]), np.linspace(-0.15, 0.15, 7))
    ] * refine_rounds

    def refine(state, i):
        FS, FD, F0, FAM, stems, stems_w, fit = state
        sse_st = float(fit.sse[i])
        for fs_mul, fd_off, f0_off in spans:
            j = int(np.argmin(np.abs(poles - fit.pole[i])))
            r_d, r_0 = FD[i] / FS[i], F0[i] / f0_unit(FAM[i], FS[i])
            fd_sh = np.array([0.0, 0.25, 0.5, 0.75, 1.0]) if fd_off is None else np.unique(np.clip(r_d + fd_off, 0, 1))
            f0_sh = np.linspace(-0.9, 0.9, 7) if f0_off is None else np.clip(r_0 + f0_off, -1, 1)
            g = np.array(np.meshgrid(FS[i] * fs_mul, fd_sh, f0_sh, indexing="ij")).reshape(3, -1)
            g = g[:, (g[0] > z * s_op) & (g[0] >= min_share * travel)]
            if not g.shape[1]:
                break
            fine = fit_grid(g[0], g[0] * g[1], g[2] * f0_unit(FAM[i], g[0]), np.full(g.shape[1], FAM[i]),
                            poles=poles[max(j - 1, 0):j + 2])
            if not fine[-1].sse.size:
                break
            k = int(np.argmin(fine[-1].sse))
            if not fine[-1].sse[k] < sse_st:
                break
            state, i, sse_st = fine, k, float(fine[-1].sse[k])
            FS, FD, F0, FAM, stems, stems_w, fit = state
        return state, i, sse_st

    best = None
    for f in families:
        rows = 1 + np.flatnonzero(FAM[1:] == f)
        if rows.size:
            cand = refine((FS, FD, F0, FAM, stems, stems_w, fit), int(rows[np.argmin(fit.sse[rows])]))
            if best is None or cand[2] < best[2]:
                best = cand
    (FS, FD, F0, FAM, stems, stems_w, fit), i, sse_st = best
    r = _residual(pv_w, stems_w[i], float(fit.pole[i]), int(fit.dead_time[i]), D)
    r1 = float(np.clip((r[1:] @ r[:-1]) / max(r @ r, 1e-300), 0.0, 0.99))
    n_eff = fit.n * (1.0 - r1) / (1.0 + r1)
    ratio = max(sse_st, 1e-300) / sse_lin
    stat = float(n_eff * np.log(1.0 / ratio))
    penalty = float((1 + len(families)) * np.log(max(n_eff, 2.0)))  # BIC: fs, fd and the family choice
    sticking = stat > penalty
    held = np.diff(stems[i]) == 0
    slips = int(np.count_nonzero(held[:-1] & ~held[1:]))
    frac = float(np.mean(held & (np.diff(op) != 0)))
    rule = "reversal rule" if FAM[i] else "force balance"
    if sticking:
        reason = (f"valve does not follow the OP (stiction or deadband): a stiction model ({rule}, static friction "
                  f"{FS[i]:.3g}, dynamic {FD[i]:.3g} OP units) explains the PV with {ratio:.0%} of a linear "
                  f"model's error")
    else:
        reason = f"the PV follows the OP (a stiction model leaves {ratio:.0%} of a linear model's error)"
    return StictionTest(bool(sticking), float(FS[i]), float(FD[i]), ratio, stat, penalty, slips, frac, reason,
                        float(fit.pole[i]), int(fit.dead_time[i]), stems[i], rule)
