"""Karnopp valve with the effects its paper structure leaves out (issue 8).

The baseline is model 1 of Romano & Garcia (the spec paper,
``/work/shared/papers/romano-garcia-karnopp-valve-identification.md``): the force balance of
eq. (1) ``m·ẍ = S_a·P − k·x + F_friction`` with Karnopp friction, eq. (2), ``F_s = F_c``, and the
measured position ``x_meas = x − x̄`` (eq. 10), driven by the *recorded* pressure.  The five
effects of issue 8, each a physical extension with one or two parameters:

``slip_jump``
    static friction above Coulomb friction, ``F_s > F_c`` (third line of eq. 2 with ``F_s``).
``stribeck``
    sliding friction falling from ``F_s`` to ``F_c`` with speed,
    ``(F_c + (F_s − F_c)·exp(−(v/v_s)²))·sgn(v)`` in place of ``F_c·sgn(v)`` in the first line of
    eq. (2).
``actuator_lag``
    the actuator pressure follows the recorded ``p`` through a first-order lag ``τ``.
``dead_time``
    the actuator pressure is the recorded ``p`` delayed by ``θ``.
``deadband``
    backlash of total width ``d`` between the stem and the position transmitter: the recorded
    position stays put until the stem has moved ``d/2`` past it after a reversal.

The mechanics are :func:`models.karnopp.karnopp_step` (same semi-implicit step, same
stick/breakaway/slip logic), compiled with numba because a fit simulates the 60 000-step record
hundreds of times; with ``v_s = 0``, ``τ = θ = d = 0`` :func:`simulate_effects` reproduces
:func:`models.karnopp.simulate` to rounding.  Pure functions: no I/O, no clock.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass, field, fields, replace

import numpy as np
from pipeline.jit import compile_cached

from .errors import ModelConfigError
from .karnopp import M_KG, SA_M2, KarnoppParams

__all__ = [
    "EFFECTS",
    "EFFECT_PARAMS",
    "EffectValve",
    "EffectSim",
    "actuator_pressure",
    "transmitter",
    "simulate_effects",
    "residual_effects",
    "hide_effects",
    "parse_hide",
    "HIDE_DEFAULTS",
    "HiddenRecord",
    "hidden_record",
]

#: The effect names of issue 8, in a fixed order.
EFFECTS = ("slip_jump", "stribeck", "actuator_lag", "dead_time", "deadband")
#: The parameters each effect adds to the baseline (field names of :class:`EffectValve`).
EFFECT_PARAMS: dict[str, tuple[str, ...]] = {
    "slip_jump": ("fs",),
    "stribeck": ("fs", "vs"),
    "actuator_lag": ("tau",),
    "dead_time": ("theta",),
    "deadband": ("deadband",),
}


@dataclass(frozen=True)
class EffectValve:
    """The Karnopp valve of eq. (1)–(2) and (10) plus the five effects.

    Attributes
    ----------
    k, fc, fv, bias : spring constant (N/m), Coulomb friction (N), viscous friction (N·s/m) and
        measurement bias ``x̄`` (m) of the baseline.
    m : moving mass, kg (held at its nominal value: not identifiable at 1 ms, see
        :mod:`models.identification`).
    sa : diaphragm area ``S_a``, m².
    dv : limit velocity DV of eq. (2), m/s.
    fs : static friction ``F_s`` (N); ``nan`` means ``F_s = F_c`` (the paper's model 1).
    vs : Stribeck speed ``v_s`` (m/s); 0: sliding friction is ``F_c`` at every speed.
    tau : actuator lag ``τ`` (s); 0: none.
    theta : dead time ``θ`` (s); 0: none.
    deadband : total backlash width ``d`` between stem and transmitter (m); 0: none.
    x_min, x_max : travel stops in the spring coordinate (m), ±inf: none.
    """

    k: float
    fc: float
    fv: float
    bias: float = 0.0
    m: float = M_KG
    sa: float = SA_M2
    dv: float = 2e-4
    fs: float = math.nan
    vs: float = 0.0
    tau: float = 0.0
    theta: float = 0.0
    deadband: float = 0.0
    x_min: float = -math.inf
    x_max: float = math.inf

    def __post_init__(self) -> None:
        def bad(name: str, why: str) -> ModelConfigError:
            return ModelConfigError(f"EffectValve.{name} = {getattr(self, name)!r}: {why}")

        for f in fields(self):
            v = getattr(self, f.name)
            if not isinstance(v, (int, float)) or (math.isnan(v) and f.name != "fs"):
                raise bad(f.name, "must be a number")
        for name in ("k", "fc", "fv", "bias", "m", "sa", "dv", "vs", "tau", "theta", "deadband"):
            if not math.isfinite(getattr(self, name)):
                raise bad(name, "must be finite; the force balance (eq. 1) is undefined otherwise")
        for name in ("m", "k", "sa"):
            if getattr(self, name) <= 0:
                raise bad(name, "must be > 0 (eq. 1 needs a mass, a spring and an actuator)")
        for name in ("fc", "fv", "dv", "vs", "tau", "theta", "deadband"):
            if getattr(self, name) < 0:
                raise bad(name, "must be >= 0; a negative value has no physical meaning here")
        if not math.isnan(self.fs) and not self.fs >= self.fc:
            raise bad("fs", f"must be >= fc ({self.fc!r}): static friction below Coulomb friction re-sticks at once")
        if not self.x_min < self.x_max:
            raise ModelConfigError(f"EffectValve x_min = {self.x_min!r}, x_max = {self.x_max!r}: need x_min < x_max")

    @property
    def fs_eff(self) -> float:
        """Static friction used by the simulation (``F_c`` when ``fs`` is nan)."""
        return self.fc if math.isnan(self.fs) else self.fs

    @property
    def effects(self) -> tuple[str, ...]:
        """Names of the effects present (in :data:`EFFECTS` order)."""
        out = []
        if self.fs_eff > self.fc and self.vs == 0.0:
            out.append("slip_jump")
        if self.fs_eff > self.fc and self.vs > 0.0:
            out.append("stribeck")
        if self.tau > 0:
            out.append("actuator_lag")
        if self.theta > 0:
            out.append("dead_time")
        if self.deadband > 0:
            out.append("deadband")
        return tuple(out)

    def replace(self, **changes: float) -> EffectValve:
        unknown = set(changes) - {f.name for f in fields(self)}
        if unknown:
            raise ModelConfigError(f"EffectValve has no field(s) {', '.join(sorted(unknown))}")
        return replace(self, **changes)

    def as_dict(self) -> dict[str, float]:
        d = asdict(self)
        d["fs"] = self.fs_eff
        return {k: v for k, v in d.items() if math.isfinite(v)}

    @classmethod
    def from_karnopp(cls, p: KarnoppParams, **changes: float) -> EffectValve:
        """The valve of a :class:`KarnoppParams` (its V/P lag ``tau_p`` is *not* carried over: it
        acts before the recorded pressure)."""
        base = cls(k=p.k, fc=p.fc, fv=p.fv, bias=p.bias, m=p.m, sa=p.sa, dv=p.dv, fs=p.fs,
                   x_min=p.x_min, x_max=p.x_max)
        return base.replace(**changes) if changes else base


# --------------------------------------------------------------------------- pure pieces


def actuator_pressure(p: np.ndarray, dt: float, tau: float = 0.0, theta: float = 0.0) -> np.ndarray:
    """Actuator pressure from the recorded pressure: dead time ``θ`` (linear interpolation between
    samples, ``p[0]`` before the record) then a first-order lag ``τ`` (exact for a pressure held
    over each step, as :func:`models.karnopp.karnopp_step` does for the V/P lag), starting at
    rest at ``p[0]``.  Compiled (:func:`_delay_lag`): a fit computes it at every simulation."""
    p = np.asarray(p, float)
    if not (theta > 0 or tau > 0):
        return p
    n = min(int(theta / dt), p.size) if theta > 0 else 0  # θ/dt = n + f samples
    return _delay_lag(np.ascontiguousarray(p), theta > 0, n, theta / dt - n if theta > 0 else 0.0,
                      tau > 0, math.exp(-dt / tau) if tau > 0 else 0.0)


@compile_cached
def _delay_lag(p, delay, n, f, lag, a):  # pragma: no cover - compiled
    """:func:`actuator_pressure` in one pass, with the arithmetic of the array expressions it
    replaced (bit for bit): the delayed sample ``(1 − f)·p[i − n] + f·p[i − n − 1]`` and the
    lag as ``scipy.signal.lfilter([1 − a], [1, −a], ·, zi=[a·p[0]])`` computes it (its
    transposed direct form: ``y = z + b0·x``, ``z = x·b1 − y·a1`` with ``b1 = 0``, ``a1 = −a``)."""
    out = np.empty_like(p)
    g = 1.0 - f
    b0 = 1.0 - a
    a1 = -a
    z = a * (g * p[0] + f * p[0] if delay else p[0])  # the lag starts at rest at the delayed p[0]
    for i in range(p.size):
        x = p[i]
        if delay:
            x = g * (p[i - n] if i >= n else p[0]) + f * (p[i - n - 1] if i >= n + 1 else p[0])
        if lag:
            y = z + b0 * x
            z = x * 0.0 - y * a1
            x = y
        out[i] = x
    return out


@compile_cached
def _backlash(s, half, y0):  # pragma: no cover - compiled
    y = np.empty_like(s)
    yi = y0
    for i in range(s.size):
        si = s[i]
        if si - yi > half:
            yi = si - half
        elif yi - si > half:
            yi = si + half
        y[i] = yi
    return y


def transmitter(x_stem: np.ndarray, deadband: float, y0: float | None = None) -> np.ndarray:
    """Position seen through a backlash of total width ``d = deadband``: the reading stays put
    until the stem is ``d/2`` away from it, then is dragged along at ``d/2`` behind.  ``y0`` is
    the initial reading (default: the first stem position)."""
    x_stem = np.asarray(x_stem, float)
    if deadband <= 0:
        return x_stem.copy()
    return _backlash(x_stem, 0.5 * deadband, float(x_stem[0] if y0 is None else y0))


@compile_cached
def _fold_speeds(A, h, fc, fs, vs):  # pragma: no cover - compiled
    """(u1, u2): φ(u) = A·u + h·F(u) − gs falls on [u1, u2] and is monotone elsewhere, where the
    Stribeck friction F falls with speed faster than ``A/h``; (−1, −1) where φ is monotone.
    Constant over a simulation (φ' does not depend on gs)."""
    if vs <= 0.0 or fs <= fc:
        return -1.0, -1.0
    c = 2.0 * h * (fs - fc) / (vs * vs)  # φ'(u) = A − c·u·exp(−(u/vs)²)
    w = vs / math.sqrt(2.0)  # where u·exp(−(u/vs)²) peaks
    if c * w * math.exp(-0.5) <= A:
        return -1.0, -1.0
    q = A / c  # u1, u2 solve u·exp(−(u/vs)²) = q
    a1, b1, a2, b2 = 0.0, w, w, 2.0 * w
    while b2 * math.exp(-((b2 / vs) ** 2)) > q:
        b2 *= 2.0
    for _ in range(60):  # bisection for both crossings
        m1 = 0.5 * (a1 + b1)
        if m1 * math.exp(-((m1 / vs) ** 2)) > q:
            b1 = m1
        else:
            a1 = m1
        m2 = 0.5 * (a2 + b2)
        if m2 * math.exp(-((m2 / vs) ** 2)) > q:
            a2 = m2
        else:
            b2 = m2
    return a1, b2  # φ is monotone on [0, u1] and on [u2, ∞)


@compile_cached
def _slide_speed(A, h, gs, fc, fs, vs, u0, u1, u2, uc, ec):  # pragma: no cover - compiled
    """Speed u > 0 of a stem that slides on through a step from speed ``u0`` >= 0, or −1 if it
    stops: the root of φ(u) = A·u + h·F(u) − gs = 0 that the stem reaches, with the sliding
    friction F(u) = fc + (fs − fc)·exp(−(u/vs)²) (first line of eq. 2 with Stribeck).

    φ(u0) < 0: the stem speeds up, to the first root above ``u0``; φ(u0) >= 0: it slows down, to
    the first root below ``u0``, and stops if there is none.  Where friction falls with speed
    faster than ``A/h`` φ is not monotone: it rises, falls on [u1, u2] and rises again
    (``u1``, ``u2`` from :func:`_fold_speeds`, −1 where φ is monotone), so a stem sliding at a
    speed where friction is well below F_s slides on even where φ(0) > 0 (the net force and
    momentum would not break a stem at rest loose, ``gs < h·fs``).  A stop test on φ(0) alone
    stopped such slides at every step: the stem stuck and waited for F_s, a staircase the valve
    does not make (used-draw records with a steep Stribeck curve: 17–659 µm RMS from 64
    sub-steps, ACCURACY.md issue 8 session 9).  The root is bracketed on a segment where φ is
    monotone and found by safeguarded Newton from the previous speed; on a monotone φ the
    iterates are those of the earlier solve, bit for bit.  Coulomb friction (``vs <= 0`` or
    ``fs <= fc``): F = fc, the one root (gs − h·fc)/A if positive.

    ``uc``, ``ec``: a speed where ``exp(−(u/vs)²)`` was last evaluated and its value (the caller
    keeps them from the previous call: a slide's next step starts from the speed the last one
    converged at); returns (u, uc, ec) updated."""
    if vs <= 0.0 or fs <= fc:
        return ((gs - h * fc) / A if gs > h * fc else -1.0), uc, ec
    hi = (gs - h * fc) / A  # φ(hi) = h·(F(hi) − fc) >= 0
    phi0 = h * fs - gs
    if u1 < 0.0 and phi0 >= 0.0:  # φ monotone: a root iff φ(0) < 0
        return -1.0, uc, ec
    if hi <= 0.0:
        return -1.0, uc, ec
    lo = 0.0
    u = min(max(u0, 0.0), hi)
    if u1 >= 0.0:  # φ falls on [u1, u2]: the bracket of the root on the stem's path
        if u != uc:
            uc = u
            ec = math.exp(-((u / vs) ** 2))
        pu = A * u + h * (fc + (fs - fc) * ec) - gs
        if pu < 0.0:  # speeds up: the first root above u0
            if u < u1 and A * u1 + h * (fc + (fs - fc) * math.exp(-((u1 / vs) ** 2))) - gs >= 0.0:
                lo, hi = u, min(u1, hi)
            else:
                lo = max(u, min(u2, hi))
        else:  # slows down: the first root below u0, if any
            if u > u2 and A * u2 + h * (fc + (fs - fc) * math.exp(-((u2 / vs) ** 2))) - gs < 0.0:
                lo, hi = u2, u
            elif phi0 < 0.0:
                hi = min(u, u1)
            else:
                return -1.0, uc, ec
        u = min(max(u, lo), hi)
    for _ in range(30):
        if u != uc:
            uc = u
            ec = math.exp(-((u / vs) ** 2))
        e = ec
        phi = A * u + h * (fc + (fs - fc) * e) - gs
        if abs(phi) <= 1e-12 * (abs(gs) + 1e-30):
            return u, uc, ec
        if phi < 0.0:
            lo = u
        else:
            hi = u
        dphi = A - h * (fs - fc) * e * 2.0 * u / (vs * vs)
        un = u - phi / dphi if dphi > 0.0 else -1.0
        if not (lo < un < hi):
            un = 0.5 * (lo + hi)
        if abs(un - u) <= 1e-15 + 1e-12 * u:
            return un, uc, ec
        u = un
    return u, uc, ec


#: A stem stopped free (see :func:`_karnopp_kernel`, ``band``) is stuck only when the net force turns
#: against its motion by this many stick bands beyond sliding friction.
_STICK_BANDS = 3.0


@compile_cached
def _karnopp_kernel(p, h, m, k, fc, fs, fv, vs, dv, sa, x0, v0, x_min, x_max, half, rest, bias, band, nsub, xm, fine):  # pragma: no cover - compiled
    """:func:`models.karnopp.karnopp_step` over a whole pressure record (tau_p = 0), with the
    Stribeck sliding friction solved implicitly, and the two stick/slip events placed inside the
    step instead of on the sample grid (so that the trajectory is continuous in the parameters):

    * breakaway: the net force crosses ``F_s`` at the fraction of the step found by linear
      interpolation of ``F_ext − k·x`` between samples; the step moves the stem only for the
      remaining time, with viscous friction acting (``karnopp_step`` leaves ``F_v`` out of the
      breakaway step, which gives the stem a one-step kick ``h·ΔF/m`` after a steep force step —
      millimetres for a pressure step on the paper's valve — that depends on how the step falls
      between samples);
    * stop: a stem that stops within the step keeps the distance covered while decelerating
      (half the step speed times the time to stop).

    ``nsub`` sub-steps of ``h / nsub`` per sample, the pressure held at ``p[i]`` over the
    sub-steps of sample ``i`` (the zero-order hold the one-step scheme already assumes for the
    force term); outputs at the samples.  Larger values converge to the continuous solution for
    that held pressure (see :func:`simulate_effects`).  ``fine`` (same length; empty: every
    sample) marks the samples that take the ``nsub`` sub-steps; the others take one step of ``h``,
    bit for bit the one-step scheme (:func:`jump_windows`: the slides after raw command steps).

    The transmitter reading ``y`` follows the stem through a backlash of half-width ``half``.
    ``rest`` (same length, NaN = none) holds measured rest positions (measured coordinate; the
    reading's spring coordinate is ``rest + bias``): at such a sample, if the stem is at rest,
    stem and reading are shifted together so that the reading equals it (a stuck valve's whole
    state is its position).

    ``band`` (same length, N, >= 0) is the stick band of :func:`simulate_effects`: where it is 0
    the stick/slip lines are those of eq. (2) above (bit for bit); where it is ``b > 0``

    * a moving stem is not stuck by the DV test: it slides (first line of eq. 2) until its
      velocity would reverse within a step;
    * a stem that stops there sticks (second line, held by ``F_s``) only if the net force
      ``F_ext − k·x`` opposes its motion by more than ``3·b`` beyond sliding friction
      (``s·F_net < F_c − 3·b``); otherwise it stops *free*: it moves on in the same direction
      against the sliding friction at zero speed (``F_c``; ``F_s`` with Stribeck) and becomes
      stuck only once the force falls below ``F_c − 3·b`` in that direction;
    * a stem stopped free moves on (third line) only when ``F_net`` exceeds the sliding
      friction at zero speed by more than ``b`` in its direction; a *stuck* stem (held after a
      reversal of more than three bands, or at the start) breaks away at its holding friction
      ``F_s``, as in eq. (2): the two thresholds ``F_c − 3·b`` (stick) and ``F_s`` (break away)
      are a hysteresis of at least ``3·b``, so noise within the band cannot break it loose, and
      the breakaway is not delayed by ``b/Ḟ`` (which a slip jump's dead time would absorb).
    * Why ``3·b`` (``_STICK_BANDS``) below and ``b`` above: a stem stopped free at the edge
      of sliding friction sees the recorded noise at every sample of its rest, and over
      thousands of samples the noise dips beyond ``b`` (3 σ) several times; a dip taken for a
      reversal sticks the stem, which then waits for ``F_s − F_c`` more force (a missed slide
      of ``(F_s − F_c)/k``), while a peak beyond ``b`` above only lets it creep on by about
      ``b/k``.  Gaussian noise practically never reaches ``3·b`` (9 σ) (unseen draw 83 record
      25: the truth's own fit, 69.5 µm on noise 16.0 with ``b``, is 17.4 µm with ``3·b``).

    Returns stem position x, velocity v and the recorded position ``x_meas = y − bias`` (eq. 10);
    given a measured position ``xm`` (same length; empty: none), its residual ``xm − x_meas``
    in place of ``x_meas`` (what a fit needs, without two more passes over the record).
    """
    n = p.size
    xs = np.empty(n)
    vsa = np.empty(n)
    ys = np.empty(n)
    x = x0
    y = x0
    v = v0
    hc = h  # one step per sample where not fine
    Ac = m + hc * fv + k * hc * hc
    u1c, u2c = _fold_speeds(Ac, hc, fc, fs, vs)  # where the step equation is not monotone (see _slide_speed)
    hf = h / nsub
    Af = m + hf * fv + k * hf * hf
    u1f, u2f = _fold_speeds(Af, hf, fc, fs, vs)
    fs0 = fs if vs > 0.0 else fc  # sliding friction as the speed goes to zero
    f_prev = sa * p[0] - k * x
    free = 0.0  # direction of a stop inside the stick band (0: none; the stem is held by F_s)
    uc, ec = -1.0, 0.0  # the Stribeck term's last evaluation (see _slide_speed; none yet)
    resid = xm.size == n
    marked = fine.size == n
    for i in range(n):
        b = band[i]
        if marked and fine[i] == 0.0:
            ns, h, A, u1, u2 = 1, hc, Ac, u1c, u2c
        else:
            ns, h, A, u1, u2 = nsub, hf, Af, u1f, u2f
        for _ in range(ns):
            f_net = sa * p[i] - k * x
            g = m * v + h * f_net
            if abs(v) < dv and (b <= 0.0 or v == 0.0):
                fr = fs  # friction holding the stem, and acting at breakaway
                if free != 0.0:
                    if free * f_net < fc - _STICK_BANDS * b:  # the force clearly turned against the motion: stuck
                        free = 0.0
                    elif free * f_net > 0.0:  # stopped free: it moves on against sliding friction
                        fr = fs0
                # the band guards the edge a stem stopped *free* at; a stuck stem got there by a
                # reversal of more than the band and breaks away at its holding friction
                thr = fr + b if free != 0.0 else fr
                if abs(f_net) <= thr:  # stick (2nd line of eq. 2)
                    v = 0.0
                else:  # breakaway (3rd line), for the part of the step after the crossing
                    s = 1.0 if f_net > 0.0 else -1.0
                    hr = h
                    if v == 0.0 and abs(f_prev) <= thr and abs(f_net) > abs(f_prev):
                        hr = h * (abs(f_net) - thr) / (abs(f_net) - abs(f_prev))
                    v = (m * v + hr * (f_net - fr * s)) / (m + hr * fv + k * hr * hr)
                    x = x + hr * v
                    free = 0.0
            else:  # slip (1st line)
                s = 1.0 if v > 0.0 else -1.0
                u, uc, ec = _slide_speed(A, h, s * g, fc, fs, vs, s * v, u1, u2, uc, ec)
                if u > 0.0:
                    v = s * u
                    x = x + h * v
                elif abs(g) <= h * fs:  # the stem stops within the step
                    v_free = (g - h * fs0 * s) / A  # where it would be without stopping (sign −s)
                    x = x + 0.5 * h * v * (v / (v - v_free))
                    v = 0.0
                    if b > 0.0 and s * f_net >= fc - _STICK_BANDS * b:  # not clearly reversed: stopped free
                        free = s
                else:  # it reverses, with friction of the new sign
                    s = -s
                    u, uc, ec = _slide_speed(A, h, s * g, fc, fs, vs, 0.0, u1, u2, uc, ec)
                    v = s * max(u, 0.0)
                    x = x + h * v
            if x > x_max:
                x = x_max
                v = 0.0
            elif x < x_min:
                x = x_min
                v = 0.0
            if x - y > half:
                y = x - half
            elif y - x > half:
                y = x + half
            f_prev = sa * p[i] - k * x
        if v == 0.0 and not math.isnan(rest[i]):
            r = rest[i] + bias
            x += r - y
            y = r
            f_prev = sa * p[i] - k * x
        xs[i] = x
        vsa[i] = v
        ys[i] = xm[i] - (y - bias) if resid else y - bias
    return xs, vsa, ys


@dataclass(frozen=True)
class EffectSim:
    """Result of :func:`simulate_effects`: actuator pressure ``p_act`` (Pa), stem position ``x``
    (spring coordinate, m), velocity ``v`` (m/s) and the recorded position ``x_meas`` (m, through
    the transmitter deadband, minus the bias of eq. 10)."""

    p_act: np.ndarray
    x: np.ndarray
    v: np.ndarray
    x_meas: np.ndarray


def simulate_effects(
    valve: EffectValve,
    p: np.ndarray,
    dt: float,
    *,
    x0_meas: float | None = None,
    rest_meas: np.ndarray | None = None,
    substeps: int = 1,
    fine: np.ndarray | None = None,
    band: float | np.ndarray = 0.0,
) -> EffectSim:
    """Simulate the extended valve driven by the recorded pressure ``p`` (Pa, one per step of
    ``dt`` s).  The stem starts at rest at ``x0_meas + x̄`` (measured coordinate; default: at rest
    under ``p[0]`` with zero net force); the transmitter starts centred on the stem.

    ``rest_meas`` (optional, NaN = none): measured positions at which a stem found at rest is
    re-seated (multiple shooting from measured rest states, used by :mod:`models.reconcile`).

    ``substeps``: integration steps per sample (the pressure held at each sample over its
    sub-steps).  More sub-steps converge (first order) to the continuous solution of
    eq. (1)–(2) for that held pressure: the one-step scheme is off by 0.7 % of an 8 mm slide
    after a pressure step, 0.01 % at 64 sub-steps (``tests/test_valve_effects.py``, against the
    analytic step response).  On a smooth pressure the hold is half a sample early, which the
    one-step scheme's half-step lag cancels: there more sub-steps are not closer to the
    continuous valve.  After a raw command step (a jump of the held pressure) they are: there
    a one-step slide reads up to twice the position noise off the truth on a PRBS record.
    ``fine`` (bool, one per sample; default: all) says which samples take the sub-steps; the
    others take one step, bit for bit as ``substeps = 1``.  The workflow sub-steps the samples
    :func:`jump_windows` marks (:class:`models.reconcile.ReconcileConfig`, ``substeps``).

    ``band``: stick band ``b`` (N, >= 0; one number or one per sample), the force within which
    the stick/slip decisions of eq. (2) are not taken on the recorded pressure.  It stands for
    the noise of the recorded (filtered) pressure expressed as a force, ``b ≈ 3·σ_p·S_a``: that
    noise is not a force on the real stem, yet with ``F_s = F_c`` it keeps breaking a simulated
    stem loose at rest, and it stops a simulated stem that creeps on where a real stem slides
    until the force reverses it.  With a band a moving stem sticks only when the net force
    would reverse it by more than ``b``, a stem stopped within the band moves on only when
    ``S_a·p − k·x`` exceeds the sliding friction by more than ``b``, a stuck stem breaks away at
    ``F_s`` (it got stuck at least ``b`` inside its friction band), and the DV test of eq. (2)
    applies to a stem at rest only (see :func:`_karnopp_kernel`).  0 (the default) is
    eq. (2) as above, bit for bit.  Per sample, the band belongs to the force that acts then:
    a band read off the recorded pressure is delayed with it by the dead time
    (:func:`models.reconcile._residuals`)."""
    p = np.ascontiguousarray(p, dtype=float)
    if p.ndim != 1 or p.size == 0 or not np.all(np.isfinite(p)):
        raise ModelConfigError("p must be a non-empty 1-D array of finite pressures (Pa)")
    if not (math.isfinite(dt) and dt > 0):
        raise ModelConfigError(f"dt = {dt!r}: the step must be a finite number > 0")
    if not (isinstance(substeps, (int, np.integer)) and substeps >= 1):
        raise ModelConfigError(f"substeps = {substeps!r}: the number of integration steps per sample must be an integer >= 1")
    pa = actuator_pressure(p, dt, valve.tau, valve.theta)
    if x0_meas is None:
        x0 = min(max(valve.sa * pa[0] / valve.k, valve.x_min), valve.x_max)
    else:
        x0 = float(x0_meas) + valve.bias
    if rest_meas is None:
        rest = np.full(p.size, np.nan)
    else:
        rest = np.ascontiguousarray(rest_meas, dtype=float)
        if rest.shape != p.shape:
            raise ModelConfigError("rest_meas must have the length of p")
    band_a = np.asarray(band, dtype=float)
    if band_a.shape not in ((), p.shape) or not np.all(np.isfinite(band_a)) or np.any(band_a < 0):
        raise ModelConfigError("band must be a finite force >= 0 (N), one number or one per pressure sample")
    if fine is None:
        marks = _NO_MEAS
    else:
        marks = np.asarray(fine, dtype=float)
        if marks.shape != p.shape:
            raise ModelConfigError("fine must have the length of p (one mark per pressure sample)")
    x, v, xm = _kernel(valve, pa, float(dt), x0, rest, np.array(np.broadcast_to(band_a, p.shape)),  # a writable copy: one compiled type
                       int(substeps), _NO_MEAS, marks)
    return EffectSim(p_act=pa, x=x, v=v, x_meas=xm)


_NO_MEAS = np.empty(0)


def _kernel(valve: EffectValve, pa: np.ndarray, dt: float, x0: float, rest: np.ndarray, band: np.ndarray, substeps: int,
            x_meas: np.ndarray, fine: np.ndarray = _NO_MEAS) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    return _karnopp_kernel(pa, dt, valve.m, valve.k, valve.fc, valve.fs_eff, valve.fv, valve.vs, valve.dv, valve.sa, x0,
                           0.0, valve.x_min, valve.x_max, 0.5 * valve.deadband, rest, valve.bias, band, substeps, x_meas,
                           fine)


def residual_effects(valve: EffectValve, p: np.ndarray, dt: float, x_meas: np.ndarray, *, x0_meas: float,
                     rest_meas: np.ndarray, band: np.ndarray, substeps: int = 1,
                     fine: np.ndarray = _NO_MEAS, p_act: np.ndarray | None = None) -> np.ndarray:
    """``x_meas − simulate_effects(valve, p, dt, x0_meas=x0_meas, rest_meas=rest_meas, band=band,
    substeps=substeps, fine=fine).x_meas``, bit for bit, without its input checks and array
    copies: for a fit that simulates one checked record hundreds of times
    (:mod:`models.reconcile`).  ``p``, ``x_meas``, ``rest_meas``, ``band`` and ``fine`` (if given)
    are contiguous float arrays of one length (``band`` one force per sample).  ``p_act``: the
    caller's ``actuator_pressure(p, dt, valve.tau, valve.theta)``, if it has it (a fit's
    Jacobian column that moves no timing parameter drives the valve with the same pressure)."""
    pa = actuator_pressure(p, dt, valve.tau, valve.theta) if p_act is None else p_act
    return _kernel(valve, pa, dt, float(x0_meas) + valve.bias, rest_meas, band, substeps, x_meas, fine)[2]


def jump_windows(p: np.ndarray, dt: float, noise: np.ndarray | float, *, floor: float = 0.0,
                 window_s: float = 0.2) -> np.ndarray:
    """Samples (bool, one per sample) in the ``window_s`` s after each jump of the pressure
    record ``p`` (Pa, one per ``dt`` s): the slides after raw command steps, where the one-step
    scheme of :func:`simulate_effects` is off by up to twice the position noise and sub-steps
    are not (on a smooth pressure they are no closer to the valve).

    A jump is a change ``|Δp_i|`` more than four times both neighbouring changes and more than
    ``max(6·noise_i, floor)`` (``noise``: the std of the noise left in ``p``, one number or one
    per sample; ``floor``: a least jump, Pa).  A step behind a V/P lag spreads over several
    samples of similar change and is no jump; white noise beyond six standard deviations is as
    good as never seen."""
    p = np.asarray(p, dtype=float)
    out = np.zeros(p.size, dtype=bool)
    if p.size < 4:
        return out
    d = np.abs(np.diff(p))  # d[j] = |p[j+1] - p[j]|
    prev = np.concatenate(([0.0], d[:-1]))
    nxt = np.concatenate((d[1:], [0.0]))
    lim = np.maximum(6.0 * np.broadcast_to(np.asarray(noise, dtype=float), p.shape)[1:], floor)
    jumps = np.flatnonzero((d > 4.0 * prev) & (d > 4.0 * nxt) & (d > lim)) + 1  # the first sample after the jump
    width = max(int(round(window_s / dt)), 1)
    for j in jumps:
        out[j:j + width] = True
    return out


# --------------------------------------------------------------------------- hidden effects


#: Default size of each effect for ``--hide EFFECT`` without a value.
HIDE_DEFAULTS: dict[str, tuple[float, ...]] = {
    "slip_jump": (1.4,),  # Fs / Fc
    "stribeck": (1.4, 3e-3),  # Fs / Fc, vs (m/s)
    "actuator_lag": (0.2,),  # tau (s)
    "dead_time": (0.1,),  # theta (s)
    "deadband": (0.5e-3,),  # d (m)
}
_HIDE_MEANING = {
    "slip_jump": "R: Fs = R*Fc (R > 1)",
    "stribeck": "R[:VS]: Fs = R*Fc (R > 1), Stribeck speed VS in m/s",
    "actuator_lag": "TAU: first-order lag in s",
    "dead_time": "THETA: dead time in s",
    "deadband": "D: total deadband width in m",
}


def parse_hide(spec: str) -> tuple[str, tuple[float, ...]]:
    """Parse ``EFFECT[=value]`` (stribeck: ``stribeck=R:VS``) into a name and its values."""
    name, _, val = spec.partition("=")
    name = name.strip()
    if name not in EFFECTS:
        raise ModelConfigError(f"unknown effect {name!r}; choose one of {', '.join(EFFECTS)}")
    default = HIDE_DEFAULTS[name]
    if not val.strip():
        return name, default
    try:
        vals = tuple(float(v) for v in val.split(":"))
    except ValueError:
        raise ModelConfigError(f"--hide {spec!r}: value must be {_HIDE_MEANING[name]}") from None
    if len(vals) > len(default) or not all(math.isfinite(v) for v in vals):
        raise ModelConfigError(f"--hide {spec!r}: value must be {_HIDE_MEANING[name]}")
    vals = vals + default[len(vals):]
    if name in ("slip_jump", "stribeck") and not vals[0] > 1.0:
        raise ModelConfigError(f"--hide {spec!r}: the ratio Fs/Fc must be > 1 ({_HIDE_MEANING[name]})")
    if any(v <= 0 for v in vals):
        raise ModelConfigError(f"--hide {spec!r}: values must be > 0 ({_HIDE_MEANING[name]})")
    return name, vals


def hide_effects(base: EffectValve, hidden: dict[str, tuple[float, ...]]) -> EffectValve:
    """The valve ``base`` with the effects ``{name: values}`` (values as :func:`parse_hide`)."""
    unknown = set(hidden) - set(EFFECTS)
    if unknown:
        raise ModelConfigError(f"unknown effect(s) {', '.join(sorted(unknown))}; choose from {', '.join(EFFECTS)}")
    if "slip_jump" in hidden and "stribeck" in hidden:
        raise ModelConfigError("slip_jump and stribeck both set F_s; hide one of them")
    ch: dict[str, float] = {}
    if "slip_jump" in hidden:
        ch["fs"] = hidden["slip_jump"][0] * base.fc
    if "stribeck" in hidden:
        ch["fs"], ch["vs"] = hidden["stribeck"][0] * base.fc, hidden["stribeck"][1]
    if "actuator_lag" in hidden:
        ch["tau"] = hidden["actuator_lag"][0]
    if "dead_time" in hidden:
        ch["theta"] = hidden["dead_time"][0]
    if "deadband" in hidden:
        ch["deadband"] = hidden["deadband"][0]
    return base.replace(**ch)


@dataclass(frozen=True)
class HiddenRecord:
    """A simulated record with hidden effects: recorded ``p`` (Pa, the V/P output, with noise),
    recorded ``x`` (m, through the transmitter, with noise), and the noise-free truth."""

    t: np.ndarray
    p: np.ndarray
    x: np.ndarray
    valve: EffectValve
    p_true: np.ndarray = field(repr=False)
    x_true: np.ndarray = field(repr=False)


def hidden_record(
    params: KarnoppParams,
    test,
    hidden: dict[str, tuple[float, ...]] | None = None,
    *,
    noise_x: float = 1e-5,
    noise_p: float = 200.0,
    seed: int | None = 0,
    dt: float = 1e-3,
    substeps: int = 4,
) -> HiddenRecord:
    """Simulate a bench test of ``params`` with hidden effects (see :func:`hide_effects`).

    The pressure command passes the V/P lag ``params.tau_p`` (as in
    :func:`models.valve_tests.bench_record`); that pressure is what is recorded.  The actuator
    sees it through the hidden dead time and lag; the stem moves by eq. (1)–(2) with the hidden
    friction; the transmitter adds the hidden deadband; white Gaussian noise (seeded) is added to
    the recorded pressure and position.  The slides after raw command steps take ``substeps``
    sub-steps per sample (:func:`jump_windows`), as :func:`models.reconcile.reconcile` fits them.
    """
    from .valve_tests import Excitation, excitation

    exc = test if isinstance(test, Excitation) else excitation(test, dt)
    valve = hide_effects(EffectValve.from_karnopp(params), hidden or {})
    p_rec = actuator_pressure(exc.p_cmd, exc.dt, params.tau_p, 0.0)
    fine = jump_windows(p_rec, exc.dt, 0.0, floor=1e-9 * max(float(np.ptp(p_rec)), 1.0))
    sim = simulate_effects(valve, p_rec, exc.dt, substeps=substeps, fine=fine)
    rng = np.random.default_rng(seed)
    p = p_rec + noise_p * rng.standard_normal(p_rec.size)
    x = sim.x_meas + noise_x * rng.standard_normal(p_rec.size)
    return HiddenRecord(t=exc.t, p=p, x=x, valve=valve, p_true=p_rec, x_true=sim.x_meas)
