"""Identification of the Karnopp valve parameters from bench or positioner data.

Implements section 3–4 of Romano & Garcia (the spec paper,
``/work/shared/papers/romano-garcia-karnopp-valve-identification.md``):

* Savitzky–Golay derivatives ``ẋ``, ``ẍ`` (Appendix A, eq. 20; ``d = 31``, ``n = 3``);
* the stem-position bias ``x̄`` from the breakaway points of the valve signature (eq. 10–14), with
  the spring constant of eq. (15) evaluated over the sliding instants (eq. 16);
* **model 1**: least squares of the sliding force balance (eq. 4–7) for every threshold
  ``δv(s) = s·|ẋ|max/Z`` (eq. 8), the threshold chosen by the minimum of ``σ_s`` (eq. 17) and the
  maximum of ``R²_s`` (eq. 18); ``F_s`` from the force balance at the breakaway instants (eq. 9);
* **model 2**: ``k`` of eq. (15), ``F_c = F_s`` from the breakaway force balances (eq. 11–12) and
  ``F_v`` as the mean of eq. (19) over the sliding instants of the signature; mass nominal.

Departures from the paper, each reported in the result:

* The mass is **held at its nominal value** by default (``m·ẍ`` is subtracted from ``F_ext`` and
  ``θ = [F_c, F_v, k]``): at 1 ms sampling with a 31-sample derivative window the inertial term
  lives in sub-window transients and is not identifiable (the paper's conclusions say as much).
  ``estimate_mass=True`` restores the paper's ``θ = [m, F_v, F_c, k]`` and adds a warning.
* Besides the literal ``σ_s``-minimum selection, a *robust* selection is reported: the smallest
  ``δv`` whose ``σ_s`` is within ``robust_rtol`` of the minimum.  Taken literally, the minimum can
  sit on a few hundred fast samples; the robust choice keeps the bulk of the sliding data.
  Model 1 uses the robust selection; the literal one is reported beside it.
* The breakaway instant of eq. (9) is located by fitting the sliding response after breakaway
  (first-order slip dynamics with the regressed ``k`` and ``F_v``) instead of reading it off a
  plot; model 2 keeps the "graphical" instant (first visible stem motion), as in the paper.

Pure functions over arrays: no I/O, no clock.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
from scipy.signal import lfilter, savgol_coeffs, savgol_filter

from .errors import IdentificationError, ModelConfigError
from .karnopp import M_KG, KarnoppParams, ValveState, simulate

__all__ = [
    "ValveData",
    "Derivatives",
    "DvSweep",
    "Breakaway",
    "ParameterSet",
    "Validation",
    "Identification",
    "check_record",
    "sg_derivatives",
    "dv_sweep",
    "dv_sweep_reference",
    "select_literal",
    "select_robust",
    "find_breakaways",
    "refine_breakaway",
    "spring_constant_eq15",
    "bias_eq14",
    "fs_eq9",
    "fv_eq19",
    "identify",
    "validate",
]


# --------------------------------------------------------------------------- data


@dataclass(frozen=True)
class ValveData:
    """A bench or positioner record: time ``t`` (s), actuator pressure ``p`` (Pa, the pressure
    that drives the actuator) and measured stem position ``x`` (m, ``x_meas`` of eq. 10)."""

    t: np.ndarray
    p: np.ndarray
    x: np.ndarray
    name: str = "data"


def check_record(
    data: ValveData,
    *,
    window: int = 31,
    min_samples: int | None = None,
) -> float:
    """Check that a record can support identification; return its sampling period.

    Raises
    ------
    IdentificationError
        naming what is missing: too few samples, non-finite values, non-uniform or decreasing
        time, no stem motion, or a stem pinned at a travel stop while the force keeps rising.
    """
    name = data.name
    arrays = {"t": np.asarray(data.t, float), "p": np.asarray(data.p, float), "x": np.asarray(data.x, float)}
    n = arrays["t"].size
    if any(a.ndim != 1 or a.size != n for a in arrays.values()):
        raise IdentificationError(f"{name}: t, p and x must be 1-D arrays of one length")
    need = min_samples if min_samples is not None else 10 * window
    if n < need:
        raise IdentificationError(
            f"{name}: too short: {n} samples, need at least {need} (10 derivative windows of {window} samples)"
        )
    for key, a in arrays.items():
        bad = ~np.isfinite(a)
        if bad.any():
            first = int(np.argmax(bad))
            raise IdentificationError(
                f"{name}: column {key} has {int(bad.sum())} missing or non-finite value(s), first at sample {first}; "
                "the derivative filter needs a gap-free record"
            )
    dts = np.diff(arrays["t"])
    if np.any(dts <= 0):
        i = int(np.argmax(dts <= 0))
        raise IdentificationError(f"{name}: time is not strictly increasing at sample {i + 1} (t = {arrays['t'][i + 1]!r})")
    dt = float(np.median(dts))
    if np.max(np.abs(dts - dt)) > 0.01 * dt:
        raise IdentificationError(
            f"{name}: sampling is not uniform (steps from {dts.min():.3g} to {dts.max():.3g} s); "
            "the Savitzky-Golay derivatives (Appendix A) need a constant period"
        )
    x = arrays["x"]
    sx = noise_std(x)
    span = float(np.ptp(x))
    if span < max(20 * sx, 1e-9):
        raise IdentificationError(
            f"{name}: no stem motion: x spans {span * 1e3:.4g} mm, about the measurement noise "
            f"({sx * 1e3:.3g} mm); the record needs the stem to slide"
        )
    if float(np.ptp(arrays["p"])) <= 0:
        raise IdentificationError(f"{name}: the pressure p is constant; the record needs a varying actuator force")
    _check_saturation(name, arrays["p"], x, sx, dt)
    return dt


def noise_std(x: np.ndarray) -> float:
    """Robust estimate of white measurement noise: MAD of second differences / √6."""
    d2 = np.diff(np.asarray(x, float), 2)
    if d2.size == 0:
        return 0.0
    return float(1.4826 * np.median(np.abs(d2 - np.median(d2))) / math.sqrt(6.0))


def _check_saturation(name: str, p: np.ndarray, x: np.ndarray, sx: float, dt: float) -> None:
    # A travel stop against friction, by the force balance Sa·p − k·x (eq. 4) at constant x: while
    # the stem is held still at one position, friction can only hold the pressure within the band
    # (k·x ± F_s)/Sa, so the pressure range over a still run is at most 2·F_s/Sa, whatever Sa and k.
    # The record shows that band itself: the widest pressure range over which the stem is held
    # still at positions away from the candidate stop (a lower bound of 2·F_s/Sa).  A stem held
    # still at its extreme position while the pressure ranges over more than twice that band,
    # pushing into the extreme, is on a stop: friction could not hold it there.  A stem stuck by
    # friction at its lowest position (a sticky valve with small pressure steps) stays inside it.
    tol = max(4 * sx, 1e-4 * float(np.ptp(x)))
    vl, sv = slow_velocity(x, dt)
    still = np.abs(vl) <= 5 * sv
    trim = max(1, int(round(0.05 / dt)))  # half the 0.1 s velocity window: keep slide samples out
    runs = [(a + trim, b - trim) for a, b, s in _runs(still.astype(int)) if s == 1 and b - a > 4 * trim]
    p_span = float(np.ptp(p))
    med = [float(np.median(x[a:b])) for a, b in runs]
    for side, push in (("upper", 1.0), ("lower", -1.0)):
        x_end = float(x.max() if push > 0 else x.min())
        idx = np.flatnonzero(push * (x - x_end) >= -tol)   # within tol of this end
        if idx.size < 100:
            continue
        # still runs at the end of travel: their median within the extreme sample's noise reach
        near = [push * (x_end - m) <= tol + 6 * sx for m in med]
        held = [float(np.ptp(p[a:b])) for (a, b), n in zip(runs, near) if n]
        # how far the pressure pushes on into the end after the stem arrived there (it arrived
        # sliding, at the edge of its friction band: friction alone lets a further push move it)
        def pushed_on(a: int, b: int) -> float:  # on 0.05 s medians: the pressure noise stays out
            m = np.median(p[a : a + ((b - a) // trim) * trim].reshape(-1, trim), axis=1)
            return float(np.max(push * (m - m[0])))

        push_on = [pushed_on(a, b) for (a, b), n in zip(runs, near) if n]
        elsewhere = [float(np.ptp(p[a:b])) for (a, b), n in zip(runs, near) if not n]
        if elsewhere and held:
            band = max(elsewhere)
            hold = max(held)
            # the band seen elsewhere only bounds 2·F_s/S_a from below (a square wave's holds see
            # little pressure change), so a stop also needs the held range to be a large part of
            # the record's whole pressure span, as in the fallback below, and the pressure to push
            # on into the end after the stem arrived by more than half that band (a slip jump's
            # stem stops at F_c and holds a further push up to F_s − F_c): a stem held at the top
            # of a PRBS while the pressure falls to the low level and comes back is held by
            # friction (unseen draw 53 record 4, Stribeck friction: the pressure never rose above
            # its arrival level there)
            if hold > 2.0 * band and hold > 0.25 * p_span and max(push_on) > 0.5 * band:
                raise IdentificationError(
                    f"{name}: travel saturated: the stem is held at its {side} stop "
                    f"({np.median([m for m, n in zip(med, near) if n]):.6g} m) while the "
                    f"pressure ranges over {hold:.4g} Pa, more than twice the widest range friction holds it "
                    f"still elsewhere in the record ({band:.4g} Pa); the identification needs sliding data away "
                    "from the stops"
                )
            continue
        # no still run away from this end to measure friction by: the stem is pinned at the end
        # while the pressure keeps pushing into it by a large part of its whole range
        excess = push * (p[idx] - p[idx[0]])
        if np.percentile(excess, 95) > 0.25 * p_span and idx.size > 0.05 * x.size:
            raise IdentificationError(
                f"{name}: travel saturated: the stem is pinned at its {side} stop "
                f"({x_end:.6g} m) for {idx.size / x.size:.0%} of the record while the "
                "pressure keeps rising into it; the identification needs sliding data away from the stops"
            )


@dataclass(frozen=True)
class Derivatives:
    """Savitzky–Golay smoothed position and its derivatives (Appendix A)."""

    x: np.ndarray
    xd: np.ndarray
    xdd: np.ndarray
    sigma_x: float  # white-noise std of the raw position
    sigma_xd: float  # resulting std of the velocity estimate


def sg_derivatives(x: np.ndarray, dt: float, *, window: int = 31, order: int = 3) -> Derivatives:
    """Stem velocity and acceleration by local polynomial fits (Appendix A, eq. 20).

    Each window of ``d = window`` samples (odd) is fitted by a polynomial of degree
    ``n = order`` (``n ≥ 2`` for the second derivative); the paper uses ``d = 31``, ``n = 3``.
    Ends use the fit of the first/last full window (``mode="interp"``).
    """
    if not (isinstance(window, int) and window % 2 == 1 and window >= 3):
        raise ModelConfigError(f"window = {window!r}: the derivative window must be an odd integer >= 3")
    if not (isinstance(order, int) and 2 <= order < window):
        raise ModelConfigError(f"order = {order!r}: need 2 <= order < window for the second derivative")
    x = np.asarray(x, float)
    if x.size < window:
        raise IdentificationError(f"{x.size} samples: shorter than one derivative window ({window})")
    xs = savgol_filter(x, window, order, mode="interp")
    xd = savgol_filter(x, window, order, deriv=1, delta=dt, mode="interp")
    xdd = savgol_filter(x, window, order, deriv=2, delta=dt, mode="interp")
    sx = noise_std(x)
    gain = float(np.sqrt(np.sum(savgol_coeffs(window, order, deriv=1, delta=dt) ** 2)))
    return Derivatives(xs, xd, xdd, sx, sx * gain)


# --------------------------------------------------------------------------- the δv sweep


@dataclass(frozen=True)
class DvSweep:
    """Least-squares estimates for every threshold ``δv(s)`` (eq. 8).

    ``theta[s]`` holds the parameters named in ``names`` estimated from the samples with
    ``|ẋ| > dv[s]`` (eq. 7); ``sigma`` is eq. (17), ``r2`` eq. (18), ``n`` the samples used.
    Entries with too few samples for the fit are NaN.
    """

    dv: np.ndarray
    n: np.ndarray
    theta: np.ndarray
    sigma: np.ndarray
    r2: np.ndarray
    names: tuple[str, ...]

    def at(self, i: int) -> dict[str, float]:
        return {name: float(v) for name, v in zip(self.names, self.theta[i])}


def _thresholds(speed: np.ndarray, S: int, Z: int) -> np.ndarray:
    if not (isinstance(S, int) and isinstance(Z, int) and 1 <= S < Z):
        raise ModelConfigError(f"S = {S!r}, Z = {Z!r}: eq. (8) needs integers with 1 <= S < Z")
    vmax = float(np.max(speed))
    return np.arange(1, S + 1) * (vmax / Z)


def _min_fit_samples(p: int) -> int:
    # fewer samples than ten per parameter make σ_s (eq. 17) a small-sample accident
    return 10 * p


def _finish_sweep(dv, n, A, b, sF, sF2, sphi, names) -> DvSweep:
    p = A.shape[-1]
    ok = n >= _min_fit_samples(p)
    theta = np.full((dv.size, p), np.nan)
    sigma = np.full(dv.size, np.nan)
    r2 = np.full(dv.size, np.nan)
    if ok.any():
        Ak, bk = A[ok], b[ok]
        # equilibrate the normal equations (columns differ by orders of magnitude)
        d = np.sqrt(np.einsum("sii->si", Ak))
        d[d == 0] = 1.0
        As = Ak / d[:, :, None] / d[:, None, :]
        try:
            th = np.linalg.solve(As, (bk / d)[..., None])[..., 0] / d
        except np.linalg.LinAlgError:
            th = np.stack([np.linalg.lstsq(a, c, rcond=None)[0] for a, c in zip(As, bk / d)]) / d
        nk = n[ok].astype(float)
        quad = np.einsum("si,sij,sj->s", th, Ak, th)
        rss = np.maximum(sF2[ok] - 2 * np.einsum("si,si->s", th, bk) + quad, 0.0)
        mean = sF[ok] / nk
        ss_tot = sF2[ok] - nk * mean**2
        ss_reg = quad - 2 * mean * np.einsum("si,si->s", th, sphi[ok]) + nk * mean**2
        theta[ok] = th
        sigma[ok] = np.sqrt(rss / (nk - p))  # eq. (17)
        with np.errstate(invalid="ignore", divide="ignore"):
            r2[ok] = ss_reg / ss_tot  # eq. (18)
    return DvSweep(dv=dv, n=n, theta=theta, sigma=sigma, r2=r2, names=tuple(names))


def dv_sweep(
    F: np.ndarray,
    phi: np.ndarray,
    speed: np.ndarray,
    *,
    S: int = 330,
    Z: int = 350,
    names: tuple[str, ...] | None = None,
) -> DvSweep:
    """Least squares of eq. (7) for all ``S`` thresholds of eq. (8) in one pass.

    Every sample is binned by how many thresholds ``δv(s)`` its speed exceeds; per-bin sums of
    ``φφᵀ``, ``φF``, ``F`` and ``F²`` accumulated from the top bin down give the normal equations of
    every threshold, so the cost is one pass over the data plus ``S`` tiny ``p×p`` solves.

    Parameters
    ----------
    F : target ``F_ext`` (minus any term held fixed), N, shape (n,).
    phi : regressors ``φ(t)`` (eq. 5), shape (n, p).
    speed : ``|ẋ|``, m/s, shape (n,).
    S, Z : eq. (8); the paper uses S = 330, Z = 350.
    """
    F = np.asarray(F, float)
    phi = np.asarray(phi, float)
    speed = np.asarray(speed, float)
    n, p = phi.shape
    dv = _thresholds(speed, S, Z)
    # bin[i] = number of thresholds strictly below speed[i]: sample i is used for s <= bin[i]
    bins = np.searchsorted(dv, speed, side="left")
    nb = S + 1

    def acc(w: np.ndarray) -> np.ndarray:  # sums over samples used for each s = 1..S
        per_bin = np.bincount(bins, weights=w, minlength=nb)
        return np.cumsum(per_bin[::-1])[::-1][1:]

    counts = np.cumsum(np.bincount(bins, minlength=nb)[::-1])[::-1][1:]
    A = np.empty((S, p, p))
    for i in range(p):
        for j in range(i, p):
            A[:, i, j] = A[:, j, i] = acc(phi[:, i] * phi[:, j])
    b = np.stack([acc(phi[:, i] * F) for i in range(p)], axis=1)
    sphi = np.stack([acc(phi[:, i]) for i in range(p)], axis=1)
    return _finish_sweep(dv, counts, A, b, acc(F), acc(F * F), sphi, names or tuple(f"theta{i}" for i in range(p)))


def dv_sweep_reference(
    F: np.ndarray,
    phi: np.ndarray,
    speed: np.ndarray,
    *,
    S: int = 330,
    Z: int = 350,
    names: tuple[str, ...] | None = None,
) -> DvSweep:
    """The same sweep as :func:`dv_sweep` done the plain way: ``S`` separate least-squares solves
    (eq. 7) on the selected samples.  Slow; kept as the reference for tests and benchmarks."""
    F = np.asarray(F, float)
    phi = np.asarray(phi, float)
    speed = np.asarray(speed, float)
    n, p = phi.shape
    dv = _thresholds(speed, S, Z)
    theta = np.full((S, p), np.nan)
    sigma = np.full(S, np.nan)
    r2 = np.full(S, np.nan)
    counts = np.zeros(S, dtype=np.int64)
    for s in range(S):
        sel = speed > dv[s]
        ns = int(sel.sum())
        counts[s] = ns
        if ns < _min_fit_samples(p):
            continue
        Phi, Fs = phi[sel], F[sel]
        th = np.linalg.lstsq(Phi, Fs, rcond=None)[0]
        fit = Phi @ th
        theta[s] = th
        sigma[s] = math.sqrt(float(np.sum((Fs - fit) ** 2)) / (ns - p))
        r2[s] = float(np.sum((fit - Fs.mean()) ** 2) / np.sum((Fs - Fs.mean()) ** 2))
    return DvSweep(dv=dv, n=counts, theta=theta, sigma=sigma, r2=r2, names=tuple(names or [f"theta{i}" for i in range(p)]))


def select_literal(sweep: DvSweep) -> int:
    """Index of the threshold with the minimum ``σ_s`` (eq. 17), the paper's rule."""
    if not np.isfinite(sweep.sigma).any():
        raise IdentificationError("no threshold δv(s) leaves enough sliding samples for the least squares (eq. 7)")
    return int(np.nanargmin(sweep.sigma))


def select_robust(sweep: DvSweep, rtol: float = 0.05, min_fraction: float = 0.25) -> int:
    """Index of the smallest ``δv`` whose ``σ_s`` (eq. 17) is within ``rtol`` of a reference minimum.

    The reference is the minimum of ``σ_s`` over the thresholds that keep at least
    ``min_fraction`` of the samples of the smallest threshold, so that it is not a small-sample
    fluctuation among the few fastest samples (where the literal rule tends to land, and where
    selecting on a noisy ``|ẋ|`` biases ``F_v`` low and ``F_c`` high).
    """
    if not (math.isfinite(rtol) and rtol >= 0):
        raise ModelConfigError(f"robust_rtol = {rtol!r}: must be a finite number >= 0")
    if not (math.isfinite(min_fraction) and 0 < min_fraction <= 1):
        raise ModelConfigError(f"min_fraction = {min_fraction!r}: must be in (0, 1]")
    select_literal(sweep)  # raises when nothing is finite
    finite = np.isfinite(sweep.sigma)
    n0 = sweep.n[np.flatnonzero(finite)[0]]
    pool = finite & (sweep.n >= min_fraction * n0)
    best = float(np.min(sweep.sigma[pool])) if pool.any() else float(np.nanmin(sweep.sigma))
    ok = np.flatnonzero(finite & (sweep.sigma <= (1 + rtol) * best))
    return int(ok[0])


# --------------------------------------------------------------------------- breakaways


@dataclass(frozen=True)
class Breakaway:
    """A stick → slip transition (a point P1/P2 of the paper's Fig. 2).

    ``direction`` is +1 for an upward breakaway (eq. 11), −1 for a downward one (eq. 12);
    ``x_stuck`` the measured position while stuck (m); ``i_visible``/``f_visible`` the first
    visibly moving sample and the force there (the "graphical" point); ``t_break``/``f_break``
    the breakaway instant located by :func:`refine_breakaway` (NaN until refined).
    """

    direction: int
    x_stuck: float
    i_stick: int
    i_visible: int
    f_visible: float
    t_break: float = math.nan
    f_break: float = math.nan


def _runs(state: np.ndarray) -> list[tuple[int, int, int]]:
    edges = np.flatnonzero(np.diff(state)) + 1
    starts = np.concatenate(([0], edges))
    ends = np.concatenate((edges, [state.size]))
    return [(int(a), int(b), int(state[a])) for a, b in zip(starts, ends)]


def slow_velocity(x: np.ndarray, dt: float, *, span_s: float = 0.1) -> tuple[np.ndarray, float]:
    """Stem velocity from straight-line fits over ``span_s`` (default 0.1 s) and its noise level.

    Far less noisy than the 31-sample cubic fit of Appendix A; used to tell sliding from
    sticking in slow records (the signature), never inside the regression of eq. (7).
    """
    x = np.asarray(x, float)
    wl = max(5, int(round(span_s / dt)) | 1)
    wl = min(wl, (x.size - 1) | 1 if x.size % 2 == 0 else x.size)
    vl = savgol_filter(x, wl, 1, deriv=1, delta=dt, mode="interp")
    sv = max(noise_std(x), 1e-12) * float(np.sqrt(np.sum(savgol_coeffs(wl, 1, deriv=1, delta=dt) ** 2)))
    return vl, sv


def _clean_runs(state: np.ndarray, min_stick: int, min_slide: int) -> np.ndarray:
    """Drop moving runs shorter than ``min_slide`` (noise) and still runs shorter than
    ``min_stick`` inside a slide in one direction (a hesitation, not a stick)."""
    state = state.copy()
    for a, b, s in _runs(state):
        if s != 0 and b - a < min_slide:
            state[a:b] = 0
    runs = _runs(state)
    for (_, _, s0), (a, b, s), (_, _, s1) in zip(runs, runs[1:], runs[2:]):
        if s == 0 and s0 == s1 != 0 and b - a < min_stick:
            state[a:b] = s0
    return state


def find_breakaways(
    F: np.ndarray,
    x: np.ndarray,
    dt: float,
    *,
    min_stick_s: float = 0.03,
    min_slide_s: float = 0.03,
) -> list[Breakaway]:
    """Locate the stick → slip transitions of a record.

    The stem counts as moving where a 0.1 s linear-fit velocity exceeds five times its noise
    level; a still run of at least ``min_stick_s`` followed by a moving run of at least
    ``min_slide_s`` is a breakaway.  The stuck position is the median of the raw position over
    the end of the still run, and the visible breakaway is the first sample at which the smoothed
    position leaves it by more than four noise levels.
    """
    F = np.asarray(F, float)
    x = np.asarray(x, float)
    sx = max(noise_std(x), 1e-12)
    vl, sv = slow_velocity(x, dt)
    wl = max(5, int(round(0.1 / dt)) | 1)
    state = np.where(np.abs(vl) > 5 * sv, np.sign(vl), 0).astype(int)
    min_stick, min_slide = int(min_stick_s / dt), int(min_slide_s / dt)
    state = _clean_runs(state, min_stick, min_slide)
    xs = savgol_filter(x, 31 if x.size >= 31 else (x.size | 1) - 2, 3, mode="interp")
    sxs = sx * float(np.sqrt(np.sum(savgol_coeffs(31, 3) ** 2)))
    Fs = savgol_filter(F, 31, 1, mode="interp")
    half = wl // 2
    min_travel = max(20 * sx, 0.01 * float(np.ptp(xs)))
    out: list[Breakaway] = []
    runs = _runs(state)
    for (a0, a1, sa), (b0, b1, sb) in zip(runs, runs[1:]):
        if sa != 0 or sb == 0 or a1 - a0 < min_stick or b1 - b0 < min_slide:
            continue
        lo = max(a0, a1 - int(0.3 / dt))
        hi = a1 - half
        if hi - lo < max(10, min_stick // 2):
            lo, hi = a0, a1
        x_stuck = float(np.median(x[lo:hi]))
        third = max(1, (hi - lo) // 3)
        drift = abs(float(np.median(x[hi - third : hi]) - np.median(x[lo : lo + third])))
        if drift > 5 * sx * math.sqrt(2.0 / third) + 4 * sxs:
            continue  # the stem creeps through this "still" run: not a stick
        seg = sb * (xs[lo:b1] - x_stuck)
        if seg[-1] < min_travel:
            continue  # a hesitation: the "slide" does not get anywhere
        above = np.flatnonzero(seg > 4 * sxs)
        if above.size == 0:
            continue
        # first sample after the last return below the threshold before the slide is under way
        below = np.flatnonzero(seg[: above[-1]] <= 4 * sxs)
        iv = lo + (int(below[-1]) + 1 if below.size else int(above[0]))
        out.append(Breakaway(direction=sb, x_stuck=x_stuck, i_stick=lo, i_visible=iv, f_visible=float(Fs[iv])))
    return out


def refine_breakaway(
    bp: Breakaway,
    t: np.ndarray,
    F: np.ndarray,
    x: np.ndarray,
    k: float,
    fv: float,
    *,
    before_s: float = 0.3,
    after_s: float | None = None,
) -> Breakaway:
    """Locate the breakaway instant of eq. (9) by fitting the slide that follows it.

    For a candidate instant ``t_b`` the stem is held at ``x_stuck`` before it and afterwards
    follows the sliding force balance without inertia, ``F_v·ẋ = F_ext − k·x − dir·F_c``
    (eq. 4 with the regressed ``k``, ``F_v``), integrated exactly for the measured force; ``F_c``
    enters linearly and is fitted for each candidate, so a slip jump (``F_s > F_c``) is allowed.
    The candidate with the least squared position error wins (1-sample grid, parabolic
    refinement).  ``f_break`` is the force at ``t_b`` from a straight-line fit of the force over
    the stuck interval before it.
    """
    dt = float(t[1] - t[0])
    tau = fv / k if k > 0 else 0.0
    if after_s is None:
        after_s = min(max(6 * tau, 0.1), 1.0)
    iv = bp.i_visible
    lo = max(bp.i_stick, iv - int(before_s / dt))
    hi = min(x.size, iv + int(after_s / dt))
    if iv - lo < 5 or hi - iv < 10:
        return bp
    Fw = savgol_filter(F[lo:hi], min(31, ((hi - lo) // 2) * 2 - 1), 1, mode="interp") if hi - lo > 31 else F[lo:hi]
    xw = x[lo:hi] - bp.x_stuck
    a = math.exp(-dt / tau) if tau > 0 else 0.0
    # For a candidate t_b = sample c: deviation from x_stuck = r1 + J·r2, with r1 the response of
    # the first-order slide (time constant F_v/k, from rest) to (F(t) − F(t_b))/k, r2 its step
    # response and J = (F(t_b) − k·x_stuck − dir·F_c)/k the jump, fitted linearly (J·dir ≥ 0).
    cands = np.arange(max(1, (iv - lo) - int(0.8 * (iv - lo))), iv - lo + 1)
    sse = np.full(cands.size, np.inf)
    for j, c in enumerate(cands):
        u = (Fw[c:] - Fw[c]) / k
        r1 = lfilter([1 - a], [1, -a], u)
        r2 = lfilter([1 - a], [1, -a], np.ones_like(u))
        y = xw[c:]
        den = float(r2 @ r2)
        J = float((y - r1) @ r2) / den if den > 0 else 0.0
        if bp.direction * J < 0:
            J = 0.0
        res = y - r1 - J * r2
        sse[j] = float(res @ res) + float(xw[:c] @ xw[:c])
    jbest = int(np.argmin(sse))
    c = float(cands[jbest])
    if 0 < jbest < cands.size - 1:
        y0, y1, y2 = sse[jbest - 1], sse[jbest], sse[jbest + 1]
        den = y0 - 2 * y1 + y2
        if den > 0:
            c += 0.5 * (y0 - y2) / den
    tb = float(t[lo]) + c * dt
    # force at t_b: straight line through the stuck interval's force, evaluated at t_b
    i_end = lo + int(round(c))
    i_beg = max(bp.i_stick, i_end - int(0.3 / dt))
    if i_end - i_beg >= 5:
        coef = np.polyfit(t[i_beg:i_end] - tb, F[i_beg:i_end], 1)
        fb = float(coef[1])
    else:
        fb = float(np.interp(tb, t[lo:hi], Fw))
    return Breakaway(bp.direction, bp.x_stuck, bp.i_stick, bp.i_visible, bp.f_visible, t_break=tb, f_break=fb)


def spring_constant_eq15(
    F: np.ndarray, x: np.ndarray, xd: np.ndarray, sliding: np.ndarray
) -> tuple[float, float]:
    """Spring constant ``k = dF_ext/dx`` (eq. 15) over the sliding instants of a signature.

    Evaluated in its least-squares form: ``F_ext`` regressed on ``x`` over the sliding samples with
    one intercept per sliding direction (they carry ``±F_c`` and the spring preload) and the
    velocity term ``F_v·ẋ`` (zero when the slide is at constant speed, as eq. 15 assumes).
    Returns ``(k, F_v)``.
    """
    sel = np.asarray(sliding, bool)
    up = sel & (xd > 0)
    down = sel & (xd < 0)
    if up.sum() < 20 or down.sum() < 20:
        raise IdentificationError(
            f"the signature slides {int(up.sum())} samples up and {int(down.sum())} down; eq. (15) needs both directions"
        )
    idx = up | down
    Phi = np.column_stack([x[idx], up[idx].astype(float), down[idx].astype(float), xd[idx]])
    theta = np.linalg.lstsq(Phi, F[idx], rcond=None)[0]
    return float(theta[0]), float(theta[3])


def bias_eq14(breakaways: list[Breakaway], k: float, *, refined: bool = False) -> float:
    """Stem-position bias ``x̄`` (eq. 14) from upward (P1, eq. 11) and downward (P2, eq. 12)
    breakaways; with several of each, their mean forces and positions are used."""
    up = [b for b in breakaways if b.direction > 0]
    down = [b for b in breakaways if b.direction < 0]
    if not up or not down:
        raise IdentificationError(
            f"found {len(up)} upward and {len(down)} downward breakaway(s); the bias of eq. (14) needs both "
            "(a signature that reverses the stem in both directions)"
        )
    f = (lambda b: b.f_break) if refined else (lambda b: b.f_visible)
    f1 = float(np.mean([f(b) for b in up]))
    f2 = float(np.mean([f(b) for b in down]))
    x1 = float(np.mean([b.x_stuck for b in up]))
    x2 = float(np.mean([b.x_stuck for b in down]))
    return 0.5 * ((f1 + f2) / k - (x1 + x2))


def fs_eq9(breakaways: list[Breakaway], k: float, bias: float, *, refined: bool = True) -> tuple[float, np.ndarray]:
    """Static friction from the force balance at the breakaway instants (eq. 9; eq. 11–12 for
    ``refined=False``): ``F_s = dir·(F_ext − k·(x_meas + x̄))``.  Returns the mean and the
    per-breakaway values."""
    vals = []
    for b in breakaways:
        f = b.f_break if refined else b.f_visible
        if math.isfinite(f):
            vals.append(b.direction * (f - k * (b.x_stuck + bias)))
    if not vals:
        raise IdentificationError("no breakaway instant found; F_s (eq. 9) needs the stem to break away from rest")
    arr = np.asarray(vals)
    return float(np.mean(arr)), arr


def fv_eq19(
    F: np.ndarray, x: np.ndarray, xd: np.ndarray, sliding: np.ndarray, k: float, fc: float, bias: float
) -> float:
    """Viscous friction as the mean of eq. (19) over the sliding instants."""
    sel = np.asarray(sliding, bool) & (xd != 0)
    if sel.sum() < 20:
        raise IdentificationError("fewer than 20 sliding samples; eq. (19) cannot give F_v")
    v = xd[sel]
    return float(np.mean((F[sel] - np.sign(v) * fc - k * (x[sel] + bias)) / v))


# --------------------------------------------------------------------------- results


@dataclass(frozen=True)
class ParameterSet:
    """One identified parameter set with its figures of merit.

    ``dv`` is the limit velocity DV used to simulate (1 % of ``|ẋ|max``, section 3);
    ``delta_v`` the selected threshold ``δv(s)`` of eq. (8); ``sigma``/``r2`` eq. (17)/(18) at it
    (NaN for model 2, which has no regression); ``notes`` say how each value was obtained.
    """

    name: str
    m: float
    k: float
    fc: float
    fs: float
    fv: float
    bias: float
    dv: float
    delta_v: float = math.nan
    sigma: float = math.nan
    r2: float = math.nan
    n_samples: int = 0
    notes: tuple[str, ...] = ()

    def to_params(self, sa: float, **overrides: float) -> KarnoppParams:
        """The valve for simulation (no V/P lag, no stops: driven by measured actuator pressure)."""
        fields = dict(m=self.m, k=self.k, fc=max(self.fc, 0.0), fs=max(self.fs, self.fc, 0.0), fv=max(self.fv, 0.0),
                      sa=sa, dv=self.dv, bias=self.bias)
        fields.update(overrides)
        return KarnoppParams(**fields)

    def as_dict(self) -> dict[str, float | int | str | list[str]]:
        return {
            "m": self.m, "k": self.k, "Fc": self.fc, "Fs": self.fs, "Fv": self.fv, "bias_m": self.bias,
            "dv": self.dv, "delta_v": self.delta_v, "sigma": self.sigma, "r2": self.r2,
            "n_samples": self.n_samples, "notes": list(self.notes),
        }


@dataclass(frozen=True)
class Validation:
    """Re-simulation of a record with identified parameters (section 5)."""

    name: str
    model: str
    t: np.ndarray
    x_meas: np.ndarray
    x_sim: np.ndarray
    rmse: float


@dataclass(frozen=True)
class Identification:
    """Everything :func:`identify` found.

    ``model1`` uses the robust ``δv`` selection, ``model1_literal`` the paper's minimum-``σ_s``
    rule; ``model2`` is the force-balance set; ``k_signature`` is eq. (15)."""

    model1: ParameterSet
    model1_literal: ParameterSet
    model2: ParameterSet
    sweep: DvSweep
    i_robust: int
    i_literal: int
    i_r2max: int
    breakaways: tuple[Breakaway, ...]
    k_signature: float
    sa: float
    warnings: tuple[str, ...] = field(default=())


# --------------------------------------------------------------------------- the procedure


def _sliding(x: np.ndarray, dt: float, breakaways: list[Breakaway]) -> tuple[np.ndarray, np.ndarray]:
    """Slow velocity and the clearly sliding samples of a slow record: speed above five noise
    levels, away from the first 0.15 s after each breakaway (transients, slip jumps)."""
    vl, sv = slow_velocity(x, dt)
    mask = np.abs(vl) > 5 * sv
    for b in breakaways:
        mask[max(0, b.i_visible - int(0.05 / dt)) : b.i_visible + int(0.15 / dt)] = False
    return vl, mask


def identify(
    data: ValveData,
    signature: ValveData | None = None,
    *,
    sa: float,
    m_nominal: float = M_KG,
    estimate_mass: bool = False,
    window: int = 31,
    order: int = 3,
    S: int = 330,
    Z: int = 350,
    robust_rtol: float = 0.05,
    robust_min_fraction: float = 0.25,
    dv_fraction: float = 0.01,
) -> Identification:
    """Identify model 1 and model 2 of the paper from an identification record and, ideally, a
    valve signature (triangular excitation).

    Parameters
    ----------
    data : identification record (the paper's square-wave test, or any record with sliding).
    signature : slow triangular record for eq. (10)–(16) and model 2; without it the breakaway
        points of ``data`` are used (less precise, a warning says so).
    sa : actuator area ``S_a``, m² (``F_ext = S_a·P``, eq. 1).
    m_nominal : mass held fixed (or reported beside the estimate), kg.
    estimate_mass : regress the mass too (``θ`` of eq. 3); not identifiable at 1 ms with d = 31.
    window, order : Savitzky–Golay ``d`` and ``n`` (Appendix A).
    S, Z : eq. (8).
    robust_rtol, robust_min_fraction : the robust ``δv`` selection (:func:`select_robust`).
    dv_fraction : DV as a fraction of ``|ẋ|max`` (the paper: 1 %).
    """
    for name, val in (("sa", sa), ("m_nominal", m_nominal)):
        if not (isinstance(val, (int, float)) and math.isfinite(val) and val > 0):
            raise ModelConfigError(f"{name} = {val!r}: must be a finite number > 0")
    warnings: list[str] = []
    dt = check_record(data, window=window)
    d = sg_derivatives(data.x, dt, window=window, order=order)
    F = sa * np.asarray(data.p, float)
    x = np.asarray(data.x, float)

    if signature is not None:
        dts = check_record(signature, window=window)
        Fsig, xsig, tsig = sa * np.asarray(signature.p, float), np.asarray(signature.x, float), np.asarray(signature.t, float)
    else:
        warnings.append(
            "no signature given: the bias (eq. 14), k of eq. (15) and the breakaway points come from the "
            "identification record itself, where the force changes fast at breakaway (less precise)"
        )
        dts, Fsig, xsig, tsig = dt, F, x, np.asarray(data.t, float)

    # --- signature: k (eq. 15), breakaways (P1, P2), bias (eq. 14)
    bps = find_breakaways(Fsig, xsig, dts)
    vsig, sliding_sig = _sliding(xsig, dts, bps)
    try:
        k15, _ = spring_constant_eq15(Fsig, xsig, vsig, sliding_sig)
        bias = bias_eq14(bps, k15)
    except IdentificationError as exc:
        where = "the signature" if signature is not None else "the identification record (no signature given)"
        raise IdentificationError(
            f"{where}: {exc}; a slow triangular test that moves the stem up and down is needed "
            "for the bias (eq. 14) and the breakaway force (eq. 9)"
        ) from None

    # --- model 1: δv sweep of eq. (4)–(8) on the identification record
    speed = np.abs(d.xd)
    if estimate_mass:
        phi = np.column_stack([d.xdd, np.sign(d.xd), d.xd, x + bias])
        target = F
        names = ("m", "fc", "fv", "k")
        warnings.append(
            "mass estimated by regression: at 1 ms sampling with a 31-sample derivative window the inertial "
            "term is far below the noise of the force balance; do not trust m"
        )
    else:
        phi = np.column_stack([np.sign(d.xd), d.xd, x + bias])
        target = F - m_nominal * d.xdd
        names = ("fc", "fv", "k")
    sweep = dv_sweep(target, phi, speed, S=S, Z=Z, names=names)
    i_lit = select_literal(sweep)
    i_rob = select_robust(sweep, robust_rtol, robust_min_fraction)
    i_r2 = int(np.nanargmax(sweep.r2))
    dv_model = dv_fraction * float(speed.max())

    refined = []

    def model1_from(i: int, label: str) -> ParameterSet:
        th = sweep.at(i)
        k1, fc1, fv1 = th["k"], th["fc"], th["fv"]
        m1 = th.get("m", m_nominal)
        refined_bps = [refine_breakaway(b, tsig, Fsig, xsig, k1, max(fv1, 0.0)) for b in bps]
        fs1, _ = fs_eq9(refined_bps, k1, bias)
        refined.append(refined_bps)
        notes = [
            f"k, Fc, Fv: least squares of eq. (7) on {int(sweep.n[i])} samples with |xdot| > {sweep.dv[i]:.4g} m/s "
            f"({label} selection)",
            f"Fs: force balance at {len(refined_bps)} breakaway instant(s) (eq. 9)",
            f"bias: eq. (14) with k of eq. (15) = {k15:.6g} N/m",
            "m: estimated (unreliable)" if estimate_mass else f"m: held at nominal {m_nominal} kg (not identifiable)",
        ]
        return ParameterSet(
            name=f"model 1 ({label})", m=float(m1), k=k1, fc=fc1, fs=max(fs1, fc1), fv=fv1, bias=bias, dv=dv_model,
            delta_v=float(sweep.dv[i]), sigma=float(sweep.sigma[i]), r2=float(sweep.r2[i]),
            n_samples=int(sweep.n[i]), notes=tuple(notes),
        )

    model1 = model1_from(i_rob, "robust")
    model1_lit = model1_from(i_lit, "literal")

    # --- model 2: force balances on the signature
    fc2, _ = fs_eq9(bps, k15, bias, refined=False)
    fv2 = fv_eq19(Fsig, xsig, vsig, sliding_sig, k15, fc2, bias)
    model2 = ParameterSet(
        name="model 2", m=m_nominal, k=k15, fc=fc2, fs=fc2, fv=fv2, bias=bias, dv=dv_model,
        n_samples=int(sliding_sig.sum()),
        notes=(
            "k: eq. (15) over the sliding instants of the signature",
            "Fc = Fs: force balance at the visible breakaway points (eq. 11-12)",
            "Fv: mean of eq. (19) over the sliding instants",
            f"m: nominal {m_nominal} kg",
        ),
    )
    return Identification(
        model1=model1, model1_literal=model1_lit, model2=model2, sweep=sweep, i_robust=i_rob, i_literal=i_lit,
        i_r2max=i_r2, breakaways=tuple(refined[0]), k_signature=k15, sa=sa, warnings=tuple(warnings),
    )


def validate(pset: ParameterSet, data: ValveData, sa: float) -> Validation:
    """Re-simulate a record with identified parameters (section 5): the valve is driven by the
    measured actuator pressure (no V/P lag), starts at rest at the measured initial position, and
    the RMSE of the measured position is reported."""
    dt = check_record(data, min_samples=2)
    params = pset.to_params(sa)
    x = np.asarray(data.x, float)
    x0 = float(np.median(x[: min(31, x.size)])) + pset.bias
    p = np.asarray(data.p, float)
    res = simulate(params, p, dt, t0=float(data.t[0]), initial=ValveState(x0, 0.0, float(p[0])))
    rmse = float(np.sqrt(np.mean((res.x_meas - x) ** 2)))
    return Validation(name=data.name, model=pset.name, t=np.asarray(data.t, float), x_meas=x, x_sim=res.x_meas, rmse=rmse)
