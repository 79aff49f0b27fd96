"""Control-valve blocks for the closed-loop simulators: linear, data-driven stiction, LuGre, backlash.

Every block maps the controller output OP (in %, or any OP unit) to the valve stem position MV
*expressed in the same OP units*, so that a perfect valve is the identity ``MV = OP``.  Blocks are
small stateful objects::

    valve = make_valve(spec)
    valve.reset()
    mv = valve.update(op, dt)      # once per integration step, dt in seconds

The first ``update`` after ``reset`` puts the valve at rest at the given OP (the simulators start
from a steady state), except for :class:`LuGreValve`, which starts with the stem at ``x = 0``.

References
----------
.. [Aftab2016] M. F. Aftab, M. Hovd, N. E. Huang, S. Sivalingam, "An adaptive non-linearity
   detection algorithm for process control loops", IFAC-PapersOnLine 49-7 (2016) 1020-1025,
   §4.4 and Appendix A.
.. [CTS2005] M. A. A. S. Choudhury, N. F. Thornhill, S. L. Shah, "Modelling valve stiction",
   Control Engineering Practice 13 (2005) 641-658, §4 and the flow chart of the two-parameter
   model (Fig. 7).
.. [Olsson1996] H. Olsson, "Control systems with friction", PhD thesis, Lund Institute of
   Technology (1996), ch. 3 (the LuGre model).

This module is pure: no I/O, no clock.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Protocol

import numpy as np

from .errors import ModelConfigError

__all__ = [
    "Valve",
    "LinearValve",
    "ChoudhuryStiction",
    "LuGreParams",
    "LuGreValve",
    "Backlash",
    "LinearValveSpec",
    "ChoudhuryStictionSpec",
    "LuGreSpec",
    "BacklashSpec",
    "KarnoppLoopValve",
    "KarnoppLoopSpec",
    "ValveSpec",
    "make_valve",
    "lugre_rhs",
    "lugre_steady_friction",
    "lugre_force_gain_for_stick_band",
]


def _finite(name: str, value: float, *, minimum: float | None = None, strict: bool = False) -> float:
    """Check that ``value`` is a finite real (and >= / > ``minimum``); return it as float."""
    try:
        v = float(value)
    except (TypeError, ValueError):
        raise ModelConfigError(f"{name} = {value!r} is not a number") from None
    if not math.isfinite(v):
        raise ModelConfigError(f"{name} = {value!r} must be finite")
    if minimum is not None:
        if strict and not v > minimum:
            raise ModelConfigError(f"{name} = {value!r} must be > {minimum:g}")
        if not strict and not v >= minimum:
            raise ModelConfigError(f"{name} = {value!r} must be >= {minimum:g}")
    return v


class Valve(Protocol):
    """What the loop simulator needs from a valve block."""

    def reset(self) -> None: ...

    def update(self, op: float, dt: float) -> float: ...


# --------------------------------------------------------------------------------------------
# Linear valve
# --------------------------------------------------------------------------------------------


class LinearValve:
    """Ideal valve: ``MV = OP`` (no friction, no dynamics)."""

    def reset(self) -> None:
        """Nothing to reset."""

    def update(self, op: float, dt: float) -> float:
        """Return ``op`` unchanged."""
        return float(op)


# --------------------------------------------------------------------------------------------
# Choudhury et al. (2005) two-parameter data-driven stiction model
# --------------------------------------------------------------------------------------------


class ChoudhuryStiction:
    """Two-parameter data-driven stiction model of Choudhury, Thornhill & Shah [CTS2005]_.

    Parameters
    ----------
    S : float
        Deadband plus stickband, in OP units (% of the valve input span), ``S >= 0``.  After the
        valve has stuck on a reversal of the OP, the OP must travel more than ``S`` from the
        reversal point before the valve moves again.
    J : float
        Slip jump, in OP units, ``J >= 0``.  On breakaway the stem jumps by ``J``.  ``J < S``
        is the undershoot case, ``J = S`` no offset, ``J > S`` overshoot, and ``J = 0`` is a
        pure deadband (backlash of width ``S``) [CTS2005]_ §4.3.

    Notes
    -----
    The algorithm follows the flow chart of the paper (Fig. 7 of [CTS2005]_), step by step on
    the samples it is given:

    1. ``v_new = sign(x(k) - x(k-1))`` is the direction of the OP.
    2. If ``v_new`` differs from ``v_old`` the valve sticks: on a *reversal* of the OP
       (``v_new = -v_old``, both non-zero) the valve is stuck at ``x_ss = x(k-1)`` and needs
       ``|x - x_ss| > S`` to move again; when the OP *stops* (``v_new = 0``) while the valve is
       moving it sticks at ``x_ss = x(k-1)`` and, if the OP resumes in the same direction, needs
       only the stickband ``|x - x_ss| > J`` (deadband is crossed only on a reversal).  An OP
       that resumes in the other direction after a pause is a reversal (threshold ``S``).
    3. While stuck the output holds: ``y(k) = y(k-1)``.
    4. When moving (or on breakaway) ``y(k) = x(k) - v_new (S - J) / 2``.

    The OP velocity is the difference of successive ``update`` inputs; the model is meant to be
    fed sampled OP (:func:`models.loop.simulate_loop` calls it once per sample).  After ``reset`` the valve is at rest as
    if the OP had just reversed (threshold ``S`` whichever way the OP moves first).  The OP is
    not clipped to 0-100 %: the simulators work in deviation variables.
    """

    def __init__(self, S: float, J: float) -> None:
        self.S = _finite("stiction S (deadband + stickband)", S, minimum=0.0)
        self.J = _finite("stiction J (slip jump)", J, minimum=0.0)
        self._half_offset = 0.5 * (self.S - self.J)
        self.reset()

    def reset(self) -> None:
        """Forget the history: the next ``update`` puts the valve at rest at its OP."""
        self._started = False
        self._x_prev = 0.0
        self._dir_old = 0
        self._stuck = True
        self._x_ss = 0.0
        self._threshold = self.S
        self._resume_dir = 0
        self._y = 0.0

    @property
    def stuck(self) -> bool:
        """True while the valve is stuck."""
        return self._stuck

    def update(self, op: float, dt: float) -> float:
        """Advance one sample with controller output ``op``; return the stem position (OP units)."""
        x = float(op)
        if not self._started:
            self._started = True
            self._x_prev = x
            self._x_ss = x
            self._y = x
            return x
        dx = x - self._x_prev
        d = 1 if dx > 0.0 else (-1 if dx < 0.0 else 0)
        if d != self._dir_old:
            if d == 0:
                # The OP stops: a moving valve sticks here; going on the same way needs only J.
                if not self._stuck:
                    self._stuck = True
                    self._x_ss = self._x_prev
                    self._threshold = self.J
                self._resume_dir = self._dir_old
            elif self._dir_old == 0:
                # The OP moves again after a pause: same direction keeps x_ss and the threshold.
                if d != self._resume_dir:
                    self._x_ss = self._x_prev
                    self._threshold = self.S
            else:
                # Reversal: deadband + stickband must be overcome from the reversal point.
                self._stuck = True
                self._x_ss = self._x_prev
                self._threshold = self.S
        if self._stuck:
            if d != 0 and abs(x - self._x_ss) > self._threshold:
                self._stuck = False
                self._y = x - d * self._half_offset
        else:
            self._y = x - d * self._half_offset
        self._dir_old = d
        self._x_prev = x
        return self._y


# --------------------------------------------------------------------------------------------
# Backlash (deadband)
# --------------------------------------------------------------------------------------------


class Backlash:
    """Backlash (mechanical play, "deadband") of total width ``width`` in OP units.

    The stem follows the OP at a distance ``width / 2`` behind it, and holds its position while
    the OP travels back through the gap after a reversal:
    ``y = x - width/2`` if ``x - y > width/2``; ``y = x + width/2`` if ``x - y < -width/2``;
    otherwise ``y`` holds.  This is the ``J = 0`` limit of [CTS2005]_.
    """

    def __init__(self, width: float) -> None:
        self.width = _finite("backlash width", width, minimum=0.0)
        self._half = 0.5 * self.width
        self.reset()

    def reset(self) -> None:
        """Forget the history: the next ``update`` puts the stem at rest at its OP."""
        self._started = False
        self._y = 0.0

    def update(self, op: float, dt: float) -> float:
        """Advance one step with controller output ``op``; return the stem position (OP units)."""
        x = float(op)
        if not self._started:
            self._started = True
            self._y = x
            return x
        gap = x - self._y
        if gap > self._half:
            self._y = x - self._half
        elif gap < -self._half:
            self._y = x + self._half
        return self._y


# --------------------------------------------------------------------------------------------
# LuGre physical valve (Aftab et al. 2016, Appendix A; Olsson 1996)
# --------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class LuGreParams:
    """Parameters of the LuGre valve of [Aftab2016]_ Appendix A, Table A.1 (the defaults).

    Attributes
    ----------
    fs, fc : static (breakaway) and Coulomb friction force, ``fs >= fc > 0``.
    fv : viscous friction coefficient (force per unit velocity), ``>= 0``.
    sigma0 : bristle stiffness, ``> 0`` (1e4).
    sigma1 : bristle (micro-)damping, ``>= 0`` (0.2 * sqrt(1e5) = 63.2).
    vs : Stribeck velocity, ``> 0`` (0.01).
    mass : stem + actuator mass, ``> 0`` (1, "unit mass").
    spring : actuator spring constant ``k``, ``>= 0`` (1).  Must be ``> 0`` in a valve (it maps
        force to position); 0 is accepted for the free-mass friction tests.
    """

    fs: float = 1.0
    fc: float = 0.5
    fv: float = 0.3
    sigma0: float = 1.0e4
    sigma1: float = 0.2 * math.sqrt(1.0e5)
    vs: float = 0.01
    mass: float = 1.0
    spring: float = 1.0

    def __post_init__(self) -> None:
        _finite("LuGre fc (Coulomb friction)", self.fc, minimum=0.0, strict=True)
        _finite("LuGre fs (static friction)", self.fs, minimum=0.0, strict=True)
        if self.fs < self.fc:
            raise ModelConfigError(f"LuGre fs = {self.fs!r} must be >= fc = {self.fc!r}")
        _finite("LuGre fv (viscous friction)", self.fv, minimum=0.0)
        _finite("LuGre sigma0 (bristle stiffness)", self.sigma0, minimum=0.0, strict=True)
        _finite("LuGre sigma1 (bristle damping)", self.sigma1, minimum=0.0)
        _finite("LuGre vs (Stribeck velocity)", self.vs, minimum=0.0, strict=True)
        _finite("LuGre mass", self.mass, minimum=0.0, strict=True)
        _finite("LuGre spring", self.spring, minimum=0.0)


def lugre_steady_friction(v: float | np.ndarray, params: LuGreParams) -> float | np.ndarray:
    """Steady-state (constant-velocity) LuGre friction: the Stribeck curve [Olsson1996]_.

    ``F_ss(v) = sign(v) (Fc + (Fs - Fc) exp(-(v/vs)^2)) + Fv v``; at high speed it tends to
    ``Fc + Fv v``.
    """
    p = params
    v = np.asarray(v, dtype=float)
    out = np.sign(v) * (p.fc + (p.fs - p.fc) * np.exp(-((v / p.vs) ** 2))) + p.fv * v
    return float(out) if out.ndim == 0 else out


def lugre_rhs(t: float, state: np.ndarray, u: float, params: LuGreParams) -> np.ndarray:
    """Right-hand side of the LuGre valve, [Aftab2016]_ eqs. (A.1)-(A.2), [Olsson1996]_.

    Parameters
    ----------
    t : time (unused: the model is autonomous for a given ``u``; kept for ODE-solver signatures).
    state : ``(x, v, z)``: stem position, stem velocity, mean bristle deflection.
    u : applied actuator force ``F_e``.
    params : :class:`LuGreParams`.

    Returns
    -------
    ``(dx/dt, dv/dt, dz/dt)`` as a float array.

    Notes
    -----
    ``dz/dt = v - |v| z / g(v)``, ``g(v) = (Fc + (Fs - Fc) exp(-(v/vs)^2)) / sigma0``,
    ``F_f = sigma0 z + sigma1 dz/dt + Fv v`` and ``m dv/dt = F_e - F_f - k x``.  The friction
    force is written with the sign that opposes the motion (the paper's (A.1) writes
    ``F_e + F_f + F_k`` with ``F_k = -k x``; its ``F_f`` must therefore be read as the reaction
    ``-(sigma0 z + ...)``).  The Stribeck exponent is ``-(v/vs)^2`` as in Olsson (1996); the
    paper's ``exp(-(v/vs))`` is a typesetting slip (it is not even in ``v``).
    """
    x, v, z = (float(s) for s in state)
    p = params
    g = (p.fc + (p.fs - p.fc) * math.exp(-((v / p.vs) ** 2))) / p.sigma0
    zdot = v - abs(v) * z / g
    friction = p.sigma0 * z + p.sigma1 * zdot + p.fv * v
    vdot = (u - friction - p.spring * x) / p.mass
    return np.array([v, vdot, zdot])


def lugre_force_gain_for_stick_band(stick_band: float, params: LuGreParams | None = None) -> float:
    """Force gain (force per OP unit) that gives the LuGre valve a stick band of ``stick_band``.

    The equivalence with the two-parameter model of [CTS2005]_ used for the "stiction-lugre"
    case: a sliding stem stops with its friction at about ``F_c``; to move it the other way the
    applied force must swing from ``+F_c`` to ``-F_s``, an OP travel of ``(F_s + F_c) / gain``,
    which plays the role of the deadband + stickband ``S``.  Hence ``gain = (F_s + F_c) / S``
    (3/14 = 0.214 per % for ``S = 7`` with Table A.1).  The slip jump then follows: released at
    ``F_s`` against a kinetic friction ``F_c``, the undamped mass-spring stem would travel
    ``2 (F_s - F_c) / k``, i.e. ``2 (F_s - F_c) / gain = 4.7 %`` of OP, close to ``J = 5``
    (viscous friction makes the actual jump somewhat smaller).
    """
    p = params or LuGreParams()
    band = _finite("stick band", stick_band, minimum=0.0, strict=True)
    return (p.fs + p.fc) / band


class LuGreValve:
    """Pneumatic valve with LuGre friction, [Aftab2016]_ Appendix A, [Olsson1996]_.

    The applied actuator force is ``F_e = force_gain * OP`` (OP in deviation from the operating
    point where the stem rests at ``x = 0``).  The returned stem position is expressed in OP
    units, ``MV = k x / force_gain``, so that a frictionless valve would give ``MV = OP``.

    Parameters
    ----------
    params : :class:`LuGreParams` (defaults: Table A.1 of [Aftab2016]_).
    force_gain : force per OP unit, ``> 0``; see :func:`lugre_force_gain_for_stick_band`.
    max_step_s : largest integration sub-step; ``update(op, dt)`` takes ``ceil(dt/max_step_s)``
        equal sub-steps with ``F_e`` interpolated linearly from the previous OP to ``op``.
    coarse_when_stuck : take stuck intervals far from breakaway in one step (see Notes).

    Notes
    -----
    **Integration scheme.**  With ``sigma0 = 1e4`` and unit mass the bristle (pre-sliding) mode
    has ``sqrt(sigma0/m) = 100 rad/s`` and the bristle ODE relaxes at ``sigma0 |v| / F_c`` per
    second (2e4/s at ``v = 1``), so explicit schemes would need steps below ~1e-4 s.  Each
    sub-step of length ``h`` instead:

    1. freezes the relaxation rate ``a = |v_n| / g(v_n)`` at the old velocity and integrates
       ``dz/dt = v_{n+1} - a z`` *exactly* for a constant velocity ``v_{n+1}``:
       ``z_{n+1} = e^{-a h} z_n + v_{n+1} (1 - e^{-a h}) / a``;
    2. solves the momentum balance implicitly in ``v_{n+1}`` (and ``x_{n+1} = x_n + h v_{n+1}``):
       ``m (v_{n+1} - v_n)/h = F_e - k x_{n+1} - sigma0 z_{n+1} - sigma1 (z_{n+1} - z_n)/h
       - Fv v_{n+1}``, which is linear in ``v_{n+1}`` (one scalar division).

    The step is unconditionally stable (it is linearly implicit in every stiff term).  What it
    damps: the pre-sliding bristle vibration at ~100 rad/s is only marginally resolved at the
    default ``h = 0.002 s`` (``omega h = 0.2``) and is damped numerically somewhat beyond its
    physical damping ratio of 0.32 (at coarse steps it is simply killed within a step); the
    stem's own mass-spring mode (``sqrt(k/m) = 1 rad/s``) gets an artificial damping ratio of
    about ``omega h / 2 = 0.001`` on top of the physical ``Fv / (2 sqrt(k m)) = 0.15``.  The
    main error is the first-order lag of the frozen relaxation rate at breakaway, which delays
    breakaway slightly: in the paper's closed loop the limit-cycle amplitude is 13 % too large
    at ``h = 0.02``, 4 % at 0.005 and 1.5 % at the default 0.002 (period: 6 %, 2 %, 0.7 %)
    relative to ``h = 5e-4``.  Stick, breakaway at ``F_s``, sliding at ``F_c + F_v v`` and the
    slip jump are kept (see the tests).

    **Stuck intervals in one step** (``coarse_when_stuck=True``): when the stem is at rest
    (``|v| < 0.01 vs``) and the net force ``|F_e - k x|`` stays below ``0.8 F_s`` at both ends of
    the ``update`` interval, the bristles only deflect quasi-statically and the whole interval is
    one (stable) step.  In the paper's closed loop this changes PV by < 1e-3 and cuts a 4000 s
    run from ~2.5 s to ~1 s.
    """

    def __init__(self, params: LuGreParams | None = None, force_gain: float = 3.0 / 14.0,
                 *, max_step_s: float = 0.002, coarse_when_stuck: bool = True) -> None:
        self.params = params if params is not None else LuGreParams()
        if not isinstance(self.params, LuGreParams):
            raise ModelConfigError(f"LuGre params = {params!r} must be a LuGreParams")
        self.force_gain = _finite("LuGre force_gain", force_gain, minimum=0.0, strict=True)
        self.max_step_s = _finite("LuGre max_step_s", max_step_s, minimum=0.0, strict=True)
        self.coarse_when_stuck = bool(coarse_when_stuck)
        self._v_stuck = 1e-2 * self.params.vs
        self._f_stuck = 0.8 * self.params.fs
        self.reset()

    def reset(self) -> None:
        """Stem at rest at ``x = 0`` with relaxed bristles."""
        self.x = 0.0
        self.v = 0.0
        self.z = 0.0
        self.friction = 0.0
        self._f_prev: float | None = None

    @property
    def position(self) -> float:
        """Stem position in OP units, ``k x / force_gain``."""
        return self.params.spring * self.x / self.force_gain

    def step_force(self, force_start: float, force_end: float, dt: float) -> None:
        """Integrate ``dt`` seconds with the applied force ramping from ``force_start`` to ``force_end``."""
        p = self.params
        n = max(1, math.ceil(dt / self.max_step_s - 1e-9))
        if n > 1 and self.coarse_when_stuck and abs(self.v) < self._v_stuck:
            # Stuck with a net force far from breakaway at both ends of the interval: the stem
            # only deflects the bristles quasi-statically, and the (stable) scheme can take the
            # whole interval in one step.
            kx = p.spring * self.x
            if max(abs(force_start - kx), abs(force_end - kx)) < self._f_stuck:
                n = 1
        h = dt / n
        m_h = p.mass / h
        k_h = p.spring * h
        s0, s1, fv, k = p.sigma0, p.sigma1, p.fv, p.spring
        s1_h = s1 / h
        fc, dfs, inv_vs, s0_inv = p.fc, p.fs - p.fc, 1.0 / p.vs, 1.0 / p.sigma0
        base = m_h + k_h + fv
        exp = math.exp
        x, v, z = self.x, self.v, self.z
        df = (force_end - force_start) / n
        fe = force_start
        zdot = 0.0
        for _ in range(n):
            fe += df
            r = v * inv_vs
            g = (fc + dfs * exp(-r * r)) * s0_inv
            ah = abs(v) * h / g
            if ah > 1e-9:
                e = exp(-ah)
                phi = (1.0 - e) * h / ah
            else:
                e = 1.0 - ah
                phi = h * (1.0 - 0.5 * ah)
            v = (m_h * v + fe - k * x - s0 * e * z - s1_h * (e - 1.0) * z) / (base + (s0 + s1_h) * phi)
            z_new = e * z + phi * v
            zdot = (z_new - z) / h
            z = z_new
            x += h * v
        self.x, self.v, self.z = x, v, z
        self.friction = s0 * z + s1 * zdot + fv * v

    def update(self, op: float, dt: float) -> float:
        """Advance ``dt`` seconds towards controller output ``op``; return ``k x / force_gain``."""
        f = self.force_gain * float(op)
        f0 = f if self._f_prev is None else self._f_prev
        self.step_force(f0, f, dt)
        self._f_prev = f
        return self.params.spring * self.x / self.force_gain


# --------------------------------------------------------------------------------------------
# Karnopp valve at loop time scales (quasi-static)
# --------------------------------------------------------------------------------------------


class KarnoppLoopValve:
    """Karnopp friction (Romano & Garcia, eq. 1–2; :mod:`models.karnopp`) at control-loop time scales.

    The stem of the paper's valve has a mass-spring mode at ``sqrt(k/m) = 360 rad/s`` and a
    viscous time constant ``tau = F_v / k`` of 24 ms (Table 1, low friction): far faster than a
    1 s control loop, whose simulator steps 0.1 s.  Dropping the inertia (``m -> 0``) leaves
    eq. (1)–(2) in force units of the OP (``F / (S_a Δp_span)``, so that a frictionless valve
    follows ``MV = OP``):

    * stick, ``|v| < DV`` and ``|OP - MV| <= F_s``: the stem holds;
    * breakaway, ``|v| < DV`` and ``|OP - MV| > F_s``: it slides in the direction ``s`` of the net force;
    * slip: ``tau dMV/dt = OP - MV - s F_c`` (viscous friction balances the net force less the
      Coulomb friction), integrated exactly over the step for the OP at the end of the step;
      when the velocity falls below ``DV`` or would reverse, the stem sticks again.

    A slowly ramping OP therefore gives the stick-slip of the paper's valve: the stem breaks
    away at ``F_s``, jumps by ``F_s - F_c``, and sticks again once its speed drops below ``DV``.

    Parameters
    ----------
    fc, fs : Coulomb and static friction in OP units (``fs >= fc >= 0``).
    tau_s : viscous time constant ``F_v / k`` in seconds.
    dv : the limit velocity ``DV`` of eq. (2) in OP units per second.
    """

    def __init__(self, fc: float, fs: float, tau_s: float = 4865.0 / 2.05e5, dv: float = 0.7) -> None:
        self.fc = _finite("Karnopp fc (Coulomb friction, OP units)", fc, minimum=0.0)
        self.fs = _finite("Karnopp fs (static friction, OP units)", fs, minimum=0.0)
        if self.fs < self.fc:
            raise ModelConfigError(f"Karnopp fs = {fs!r} must be >= fc = {fc!r}")
        self.tau_s = _finite("Karnopp tau_s (F_v / k)", tau_s, minimum=0.0, strict=True)
        self.dv = _finite("Karnopp dv (limit velocity, OP units/s)", dv, minimum=0.0)
        self.reset()

    def reset(self) -> None:
        """Forget the history: the next ``update`` puts the stem at rest at its OP."""
        self._started = False
        self._y = 0.0
        self._dir = 0

    def update(self, op: float, dt: float) -> float:
        """Advance ``dt`` seconds with controller output ``op``; return the stem position (OP units)."""
        x = float(op)
        if not self._started:
            self._started, self._y, self._dir = True, x, 0
            return x
        net = x - self._y
        if self._dir == 0:
            if abs(net) <= self.fs:
                return self._y
            self._dir = 1 if net > 0 else -1
        s = self._dir
        target = x - s * self.fc
        if (target - self._y) * s <= 0.0:  # the net force no longer beats Coulomb friction
            self._dir = 0
            return self._y
        self._y = target + (self._y - target) * math.exp(-dt / self.tau_s)
        if abs(target - self._y) / self.tau_s < self.dv:  # slower than DV: stuck (eq. 2)
            self._dir = 0
        return self._y


# --------------------------------------------------------------------------------------------
# Specs (frozen, held by a LoopScenario) and the factory
# --------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class LinearValveSpec:
    """A perfect valve, ``MV = OP``."""

    kind: str = field(default="linear", init=False)


@dataclass(frozen=True)
class ChoudhuryStictionSpec:
    """Data-driven stiction of [CTS2005]_: deadband + stickband ``S`` and slip jump ``J`` (OP units)."""

    S: float
    J: float
    kind: str = field(default="stiction", init=False)

    def __post_init__(self) -> None:
        _finite("stiction S (deadband + stickband)", self.S, minimum=0.0)
        _finite("stiction J (slip jump)", self.J, minimum=0.0)


@dataclass(frozen=True)
class LuGreSpec:
    """LuGre valve, [Aftab2016]_ Appendix A: parameters, force per OP unit, integration sub-step."""

    params: LuGreParams = field(default_factory=LuGreParams)
    force_gain: float = 3.0 / 14.0
    max_step_s: float = 0.002
    kind: str = field(default="stiction", init=False)

    def __post_init__(self) -> None:
        if not isinstance(self.params, LuGreParams):
            raise ModelConfigError(f"LuGre params = {self.params!r} must be a LuGreParams")
        _finite("LuGre force_gain", self.force_gain, minimum=0.0, strict=True)
        _finite("LuGre max_step_s", self.max_step_s, minimum=0.0, strict=True)
        if self.params.spring <= 0.0:
            raise ModelConfigError(
                f"LuGre spring = {self.params.spring!r} must be > 0 in a valve (it maps force to position)"
            )


@dataclass(frozen=True)
class BacklashSpec:
    """Backlash (deadband) of total width ``width`` in OP units."""

    width: float
    kind: str = field(default="deadband", init=False)

    def __post_init__(self) -> None:
        _finite("backlash width", self.width, minimum=0.0)


@dataclass(frozen=True)
class KarnoppLoopSpec:
    """Karnopp valve at loop time scales (:class:`KarnoppLoopValve`), frictions in OP units."""

    fc: float
    fs: float
    tau_s: float = 4865.0 / 2.05e5
    dv: float = 0.7
    kind: str = field(default="stiction", init=False)

    def __post_init__(self) -> None:
        KarnoppLoopValve(self.fc, self.fs, self.tau_s, self.dv)  # validates

    @classmethod
    def from_karnopp(cls, params, *, span_pa: float = 206.84e3 - 41.74e3) -> "KarnoppLoopSpec":
        """From :class:`models.karnopp.KarnoppParams`: forces over ``S_a * span / 100`` (OP %),
        ``tau = F_v / k``, ``DV`` over the travel (the stops, else the paper's 28.6 mm)."""
        per_pct = params.sa * span_pa / 100.0
        travel = params.x_max - params.x_min if math.isfinite(params.x_max - params.x_min) else 2.8575e-2
        return cls(params.fc / per_pct, params.fs / per_pct, params.fv / params.k, params.dv / travel * 100.0)


ValveSpec = LinearValveSpec | ChoudhuryStictionSpec | LuGreSpec | BacklashSpec | KarnoppLoopSpec


def make_valve(spec: ValveSpec | None) -> LinearValve | ChoudhuryStiction | LuGreValve | Backlash | KarnoppLoopValve:
    """Build a fresh (reset) valve block from its spec; ``None`` means a linear valve."""
    if spec is None or isinstance(spec, LinearValveSpec):
        return LinearValve()
    if isinstance(spec, ChoudhuryStictionSpec):
        return ChoudhuryStiction(spec.S, spec.J)
    if isinstance(spec, LuGreSpec):
        return LuGreValve(spec.params, spec.force_gain, max_step_s=spec.max_step_s)
    if isinstance(spec, BacklashSpec):
        return Backlash(spec.width)
    if isinstance(spec, KarnoppLoopSpec):
        return KarnoppLoopValve(spec.fc, spec.fs, spec.tau_s, spec.dv)
    raise ModelConfigError(f"valve spec = {spec!r} is not a ValveSpec")
