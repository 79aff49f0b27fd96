"""Karnopp friction model of a pneumatic sliding-stem control valve.

Implements the valve of Romano & Garcia, *Karnopp friction model identification for a real
control valve* (the spec paper, ``/work/shared/papers/romano-garcia-karnopp-valve-identification.md``):

* the force balance, eq. (1): ``m·ẍ = F_ext − k·x + F_friction`` with ``F_ext = S_a·P``;
* Karnopp friction, eq. (2): slip (``|ẋ| ≥ DV``: ``−F_c·sgn ẋ − F_v·ẋ``), stick
  (``|ẋ| < DV`` and ``|F_ext − k·x| ≤ F_s``: friction cancels the net force) and breakaway
  (``|ẋ| < DV`` and ``|F_ext − k·x| > F_s``: ``−F_s·sgn(F_ext − k·x)``);
* DV as the paper sets it for simulation: 1 % of the largest stem speed (section 3);
* a stem-position measurement bias, eq. (10): ``x = x_meas + x̄``.

Beyond the paper (bench realism): a first-order V/P converter / positioner lag on the pressure
command, and travel limits (hard stops) at which the stem stops inelastically.

Physics is written as pure functions of ``(state, input, params)``; :func:`simulate` runs them
over a whole record, :class:`KarnoppValve` steps them one sample at a time for closed-loop use.
No I/O and no clock in this module.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace
from typing import NamedTuple

import numpy as np

from .errors import ModelConfigError

__all__ = [
    "P_MIN_PA",
    "P_MAX_PA",
    "SA_M2",
    "TRAVEL_M",
    "M_KG",
    "K_NM",
    "BIAS_M",
    "TABLE1",
    "PRESETS",
    "KarnoppParams",
    "ValveState",
    "SimResult",
    "KarnoppValve",
    "karnopp_friction",
    "karnopp_step",
    "simulate",
    "preset",
    "pct_to_pa",
    "pa_to_pct",
]

#: Input pressure range of the paper's bench, 41.74–206.84 kPa (section 4).
P_MIN_PA = 41.74e3
P_MAX_PA = 206.84e3
#: Fisher ET valve of section 4: diaphragm area, travel, mass of the moving parts.
SA_M2 = 0.0445
TRAVEL_M = 2.8575e-2
M_KG = 1.6
#: Spring constant identified in Table 1 (model 1, both friction levels).
K_NM = 2.05e5
#: Stem-position bias of eq. (16), mean of the low- and high-friction estimates.
BIAS_M = 1.13e-3

#: Table 1 of the paper, verbatim: (friction level, model) -> parameters in SI units.
TABLE1: dict[tuple[str, str], dict[str, float]] = {
    ("low", "model 1"): {"m": 1.542, "k": 2.05e5, "fv": 4865.0, "fc": 152.7, "fs": 152.7},
    ("low", "model 2"): {"m": 1.6, "k": 2.03e5, "fv": 1.15e4, "fc": 157.5, "fs": 157.5},
    ("high", "model 1"): {"m": 1.75, "k": 2.05e5, "fv": 4.48e4, "fc": 606.0, "fs": 606.0},
    ("high", "model 2"): {"m": 1.6, "k": 2.04e5, "fv": 2.15e4, "fc": 691.27, "fs": 691.27},
}


def pct_to_pa(pct: float | np.ndarray) -> float | np.ndarray:
    """Percentage of the 41.74–206.84 kPa input range (section 4) to pressure in Pa."""
    return P_MIN_PA + pct / 100.0 * (P_MAX_PA - P_MIN_PA)


def pa_to_pct(p: float | np.ndarray) -> float | np.ndarray:
    """Pressure in Pa to a percentage of the 41.74–206.84 kPa input range."""
    return (p - P_MIN_PA) / (P_MAX_PA - P_MIN_PA) * 100.0


@dataclass(frozen=True)
class KarnoppParams:
    """Parameters of the valve force balance (eq. 1) with Karnopp friction (eq. 2).

    Attributes
    ----------
    m : mass of the moving parts, kg.
    k : spring constant, N/m; the spring force is ``k·x`` with ``x`` measured from the spring's
        free length (eq. 1).
    fc : Coulomb friction ``F_c``, N.
    fs : static friction ``F_s``, N (``fs ≥ fc``; ``fs > fc`` gives a slip jump).
    fv : viscous friction ``F_v``, N·s/m.
    sa : diaphragm area ``S_a``, m²; ``F_ext = S_a·P`` (eq. 1).
    dv : limit velocity ``DV`` of eq. (2), m/s: below it the stem counts as not moving.
    tau_p : time constant of the first-order V/P converter / positioner lag on the pressure
        command, s (0: the command is the actuator pressure).
    x_min, x_max : travel limits (hard stops) in the spring coordinate ``x``, m; ±inf: none.
    bias : stem-position measurement bias ``x̄`` of eq. (10), m: ``x_meas = x − x̄``.
    """

    m: float = M_KG
    k: float = K_NM
    fc: float = 152.7
    fs: float = 152.7
    fv: float = 4865.0
    sa: float = SA_M2
    dv: float = 2e-4
    tau_p: float = 0.0
    x_min: float = -math.inf
    x_max: float = math.inf
    bias: float = 0.0

    def __post_init__(self) -> None:
        def bad(name: str, why: str) -> ModelConfigError:
            return ModelConfigError(f"KarnoppParams.{name} = {getattr(self, name)!r}: {why}")

        for name in ("m", "k", "fc", "fs", "fv", "sa", "dv", "tau_p", "bias"):
            value = getattr(self, name)
            if not isinstance(value, (int, float)) or not math.isfinite(value):
                raise bad(name, "must be a finite number; the force balance (eq. 1) is undefined otherwise")
        if self.m <= 0:
            raise bad("m", "must be > 0; a massless stem makes the force balance (eq. 1) singular")
        if self.k <= 0:
            raise bad("k", "must be > 0; without a spring the single-action valve has no rest position")
        if self.sa <= 0:
            raise bad("sa", "must be > 0; the actuator could not exert a force")
        for name in ("fc", "fv", "dv", "tau_p"):
            if getattr(self, name) < 0:
                raise bad(name, "must be >= 0; a negative value would feed energy into the valve")
        if self.fs < self.fc:
            raise bad(
                "fs",
                f"must be >= fc ({self.fc!r}); with F_s < F_c the stem would re-stick at once after every breakaway",
            )
        if math.isnan(self.x_min) or math.isnan(self.x_max) or not self.x_min < self.x_max:
            raise ModelConfigError(
                f"KarnoppParams.x_min = {self.x_min!r}, x_max = {self.x_max!r}: need x_min < x_max; "
                "the stem would have no travel"
            )

    @property
    def has_stops(self) -> bool:
        """True when at least one hard stop is finite."""
        return math.isfinite(self.x_min) or math.isfinite(self.x_max)

    def replace(self, **changes: float) -> KarnoppParams:
        """A copy with some fields changed (validated again)."""
        unknown = set(changes) - set(self.__dataclass_fields__)
        if unknown:
            raise ModelConfigError(f"KarnoppParams has no field(s) {', '.join(sorted(unknown))}")
        return replace(self, **changes)


def _paper_valve(fc: float, fv: float, dv: float) -> KarnoppParams:
    # Hard stops: the lower stop is where the spring is compressed by the force of the lowest
    # range pressure (bench set starts at 41.74 kPa); the upper stop is one travel (28.575 mm)
    # above it.  The paper does not state where its stops are: this is our choice, made so that
    # the paper's excitations (up to 75 % of the range) stay inside the travel.
    x_lo = SA_M2 * P_MIN_PA / K_NM
    return KarnoppParams(
        m=M_KG, k=K_NM, fc=fc, fs=fc, fv=fv, sa=SA_M2, dv=dv, tau_p=1.0,
        x_min=x_lo, x_max=x_lo + TRAVEL_M, bias=BIAS_M,
    )


#: The paper's valve with the two friction sets of Table 1 (model 1 columns; Fs = Fc because
#: the signatures showed no slip jump).  DV is set as the paper sets it (section 3): 1 % of the peak
#: stem speed, here the peak each preset reaches in its own square-wave test (0.0189 and
#: 0.0121 m/s).  The 1 s V/P lag is our choice: the paper shows the lag (Fig. 1) but does not give
#: its time constant; with it the peak speed is close to the ≈ 0.02 m/s of the paper's Fig. 3.
PRESETS: dict[str, KarnoppParams] = {
    "low": _paper_valve(fc=152.7, fv=4865.0, dv=1.9e-4),
    "high": _paper_valve(fc=606.0, fv=4.48e4, dv=1.2e-4),
}


def preset(name: str, *, fs_ratio: float | None = None) -> KarnoppParams:
    """A named preset (``low`` / ``high``), optionally with a slip jump ``F_s = fs_ratio·F_c``."""
    try:
        params = PRESETS[name]
    except KeyError:
        raise ModelConfigError(f"unknown valve preset {name!r}; choose one of {', '.join(PRESETS)}") from None
    if fs_ratio is not None:
        if not (isinstance(fs_ratio, (int, float)) and math.isfinite(fs_ratio) and fs_ratio >= 1.0):
            raise ModelConfigError(f"fs_ratio = {fs_ratio!r}: must be a finite number >= 1 (F_s >= F_c)")
        params = params.replace(fs=fs_ratio * params.fc)
    return params


def karnopp_friction(v: float, f_net: float, params: KarnoppParams) -> float:
    """Karnopp friction force, eq. (2).

    Parameters
    ----------
    v : stem velocity ẋ, m/s.
    f_net : ``F_ext − k·x``, N (external force minus spring force).
    params : valve parameters (uses ``fc, fs, fv, dv``).

    Returns
    -------
    Friction force in N, with the sign convention of eq. (1) (it is *added* to the net force).
    """
    if abs(v) >= params.dv:  # slip, first line of (2)
        return -params.fc * math.copysign(1.0, v) - params.fv * v
    if abs(f_net) <= params.fs:  # stick, second line
        return -f_net
    return -params.fs * math.copysign(1.0, f_net)  # breakaway, third line


class ValveState(NamedTuple):
    """State of the valve: stem position x (spring coordinate, m), velocity v (m/s), actuator
    pressure p (Pa, after the V/P lag)."""

    x: float
    v: float
    p: float


def karnopp_step(state: ValveState, p_cmd: float, h: float, params: KarnoppParams) -> ValveState:
    """Advance the valve by one fixed step ``h`` (pure function).

    The V/P lag is integrated exactly for a command held over the step.  The mechanics use a
    semi-implicit (backward-Euler) step of eq. (1) with the friction of eq. (2) treated as a
    set-valued force, which is stable for the stiff viscous term (``h·F_v/m`` ≫ 1 at 1 ms) and
    resolves stick/slip events without chatter:

    * ``|v| < DV`` and ``|F_ext − k·x| ≤ F_s`` (stick, 2nd line of eq. 2): ``v⁺ = 0`` and ``x⁺ = x``
      exactly;
    * ``|v| < DV`` and ``|F_ext − k·x| > F_s`` (breakaway, 3rd line): friction ``F_s·sgn(F_ext − k·x)``;
    * ``|v| ≥ DV`` (slip, 1st line): friction ``F_c·sgn(v) + F_v·v⁺``; when the step would reverse
      the velocity the stem stops instead (``v⁺ = 0``) if the friction needed to stop it is at most
      ``F_s``, otherwise it reverses with Coulomb friction of the new sign.

    In every moving step the discrete force balance
    ``m·(v⁺ − v)/h = S_a·p⁺ − k·x⁺ + F_friction`` holds, with ``x⁺ = x + h·v⁺``.
    Hard stops clamp ``x⁺`` and set ``v⁺ = 0`` (inelastic impact).
    """
    x, v, p = state
    m, k = params.m, params.k
    if params.tau_p > 0.0:
        p = p_cmd + (p - p_cmd) * math.exp(-h / params.tau_p)
    else:
        p = p_cmd
    f_net = params.sa * p - k * x
    g = m * v + h * f_net  # momentum available after one step without friction
    if abs(v) < params.dv:
        if abs(f_net) <= params.fs:  # stick: the stuck stem holds exactly
            return ValveState(x, 0.0, p)
        v_new = (g - h * params.fs * math.copysign(1.0, f_net)) / (m + k * h * h)  # breakaway
    else:
        s = 1.0 if v > 0.0 else -1.0
        v_new = (g - h * params.fc * s) / (m + h * params.fv + k * h * h)
        if v_new * s <= 0.0:  # the step would reverse the stem: it stops within the step
            if abs(g) <= h * params.fs:
                return _clamp(x, 0.0, p, params)
            v_new = (g + h * params.fc * s) / (m + h * params.fv + k * h * h)
    return _clamp(x + h * v_new, v_new, p, params)


def _clamp(x: float, v: float, p: float, params: KarnoppParams) -> ValveState:
    if x > params.x_max:
        return ValveState(params.x_max, 0.0, p)
    if x < params.x_min:
        return ValveState(params.x_min, 0.0, p)
    return ValveState(x, v, p)


def rest_state(p: float, params: KarnoppParams) -> ValveState:
    """The valve at rest under a constant pressure: zero net force, clamped to the travel."""
    x = min(max(params.sa * p / params.k, params.x_min), params.x_max)
    return ValveState(x, 0.0, p)


@dataclass(frozen=True)
class SimResult:
    """Result of :func:`simulate` (all arrays of the input's length).

    Attributes
    ----------
    t : time, s.
    p_cmd : pressure command, Pa.
    p : actuator pressure after the V/P lag, Pa (``F_ext = S_a·p``).
    x : stem position in the spring coordinate of eq. (1), m.
    v : stem velocity, m/s.
    x_meas : measured stem position ``x − x̄`` (eq. 10), m (noise-free).
    params : the parameters simulated.
    """

    t: np.ndarray
    p_cmd: np.ndarray
    p: np.ndarray
    x: np.ndarray
    v: np.ndarray
    x_meas: np.ndarray
    params: KarnoppParams = field(repr=False)

    @property
    def stuck(self) -> np.ndarray:
        """Samples at which the stem is at rest (v = 0 exactly)."""
        return self.v == 0.0


def simulate(
    params: KarnoppParams,
    p_cmd: np.ndarray,
    dt: float,
    *,
    t0: float = 0.0,
    initial: ValveState | None = None,
) -> SimResult:
    """Fixed-step simulation of the valve driven by a pressure command (eq. 1–2).

    Parameters
    ----------
    params : valve parameters.
    p_cmd : pressure command in Pa, one value per step (held over the step).  With
        ``params.tau_p = 0`` it is the actuator pressure itself (use this to re-simulate from a
        measured actuator pressure).
    dt : step, s.
    t0 : time of the first sample, s.
    initial : state before the first sample; default: at rest under ``p_cmd[0]``
        (:func:`rest_state`).

    Returns
    -------
    SimResult, where sample ``i`` is the state after the step driven by ``p_cmd[i]``
    (sample 0 is the initial state when ``initial`` is the default rest state).
    """
    p_cmd = np.asarray(p_cmd, dtype=float)
    if p_cmd.ndim != 1 or p_cmd.size == 0:
        raise ModelConfigError(f"p_cmd must be a non-empty 1-D array, got shape {p_cmd.shape}")
    if not np.all(np.isfinite(p_cmd)):
        raise ModelConfigError(f"p_cmd has {int(np.sum(~np.isfinite(p_cmd)))} non-finite value(s); cannot simulate")
    if not (math.isfinite(dt) and dt > 0):
        raise ModelConfigError(f"dt = {dt!r}: the step must be a finite number > 0")
    n = p_cmd.size
    state = initial if initial is not None else rest_state(float(p_cmd[0]), params)
    xs = np.empty(n)
    vs = np.empty(n)
    ps = np.empty(n)
    step = karnopp_step
    for i, u in enumerate(p_cmd.tolist()):
        state = step(state, u, dt, params)
        xs[i], vs[i], ps[i] = state
    t = t0 + dt * np.arange(n)
    return SimResult(t=t, p_cmd=p_cmd, p=ps, x=xs, v=vs, x_meas=xs - params.bias, params=params)


class KarnoppValve:
    """Stateful stepping valve for closed-loop simulations.

    ``KarnoppValve(params).update(p_command_pa, dt)`` advances by one step with
    :func:`karnopp_step` and returns the measured stem position ``x − x̄`` in metres, exactly as
    :func:`simulate` would for the same command sequence.

    Parameters
    ----------
    params : valve parameters.
    p0 : pressure at which the valve starts at rest (default: ``P_MIN_PA``).
    """

    def __init__(self, params: KarnoppParams, p0: float = P_MIN_PA) -> None:
        if not isinstance(params, KarnoppParams):
            raise ModelConfigError(f"params must be KarnoppParams, got {type(params).__name__}")
        if not math.isfinite(p0):
            raise ModelConfigError(f"p0 = {p0!r}: the initial pressure must be finite")
        self.params = params
        self._p0 = float(p0)
        self.state = rest_state(self._p0, params)

    def reset(self, p0: float | None = None) -> None:
        """Back to rest under ``p0`` (default: the constructor's)."""
        if p0 is not None:
            self._p0 = float(p0)
        self.state = rest_state(self._p0, self.params)

    def update(self, p_command_pa: float, dt: float) -> float:
        """One step of ``dt`` seconds under the pressure command; returns ``x_meas`` in m."""
        if not (math.isfinite(dt) and dt > 0):
            raise ModelConfigError(f"dt = {dt!r}: the step must be a finite number > 0")
        if not math.isfinite(p_command_pa):
            raise ModelConfigError(f"p_command_pa = {p_command_pa!r}: the pressure command must be finite")
        self.state = karnopp_step(self.state, float(p_command_pa), dt, self.params)
        return self.state.x - self.params.bias

    @property
    def x_meas(self) -> float:
        """Current measured stem position ``x − x̄``, m."""
        return self.state.x - self.params.bias

    @property
    def travel_fraction(self) -> float:
        """Current position as a fraction of the travel between the hard stops (nan without stops)."""
        lo, hi = self.params.x_min, self.params.x_max
        if not (math.isfinite(lo) and math.isfinite(hi)):
            return math.nan
        return (self.state.x - lo) / (hi - lo)
