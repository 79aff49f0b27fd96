"""Closed-loop simulator: FOPDT plant + PI controller + valve block, after Aftab et al. (2016) §4.

The loop of Fig. 3 of [Aftab2016]_::

    sp --(+)--> PI --op--> valve --mv--(+ load noise)--> K e^{-theta s}/(tau s + 1) --y--(+ d(t))--> pv
         (-)^                                                                                    |
           |________________________________ pv = y + d(t) + measurement noise ________________|

Conventions (where the paper is silent, chosen as a control engineer would expect):

* All signals are **deviation variables** around a steady operating point: at ``t = 0`` the
  plant, the controller and the valve are at rest with ``sp = pv = op = mv = 0``.  OP and MV are
  in % of the valve span (the unit of the stiction parameters ``S, J``); SP and PV are in the
  process unit (PV % for a unit-gain transmitter).  The OP is unbounded unless the controller
  has ``op_min / op_max``.
* **Set-point steps** start the transients (the paper keeps transients in its 4000 s records):
  :class:`SetpointStep` ``(time_s, value)`` sets the set point to ``value`` from ``time_s`` on.
* **External sinusoidal disturbances** ([Aftab2016]_ §4.2-4.3) are added to the *plant output*,
  i.e. to the measured PV, as an unmeasured output disturbance ``d(t) = sum A sin(w t + phi)``.
* **Measurement noise**: white, Gaussian, one value per sample ``sample_time_s`` held over the
  sample (what a transmitter sampled by the DCS gives); the recorded PV is what the controller
  saw.  **Load noise**: white Gaussian in OP units, one value per sample, added to the stem
  position at the plant input (an unmeasured load disturbance, filtered by the plant).

Numerics: the plant is integrated exactly on an internal step ``h = sample_time_s / substeps``
(default 1 s / 10).  The PI runs on the same internal step (a continuous-like controller, its
integral by the trapezoidal rule), and the valve block is updated on every internal step.  The
dead time is a delay buffer of ``round(theta / h)`` internal steps.  Because the plant input is
delayed by at least one internal step, the plant can be fed the *piecewise-linear* interpolation
of its input samples (a first-order hold), and the lag is integrated exactly for that input.
This matters: a zero-order hold adds on average ``h/2`` of delay, which for the "tuning" case
(gain margin 1.011) is enough to turn the slowly decaying oscillation of the continuous loop
(dominant poles -0.00088 +/- 0.2734j) into a growing one (+0.0006 +/- 0.272j for 50 ms more delay).
With the hold and the trapezoidal integral the discretisation error is O((omega h)^2).  When
the dead time is shorter than ``h/2`` the hold falls back to ZOH.  Records are taken every
``sample_time_s`` (``t = 0, Ts, ..., duration - Ts``).

The valve blocks run on the internal step, except the two-parameter stiction model of
[CTS2005]_, which is defined on sampled OP (its velocity is ``x(k) - x(k-1)``): it is updated once
per sample and its MV held.  Evaluated on the internal step, the sample-held measurement noise
(OP jumps of ``Kc * noise`` at each sample against an integral ramp ten times finer) makes the
OP reverse at almost every sample; since the published flow chart stores a new stick point at
every reversal, the valve then never travels ``S`` and freezes while the integral winds up
(OP drifting to +-1000 % with 0.1 PV units of noise).  Once per sample the limit cycle is kept
up to a noise of about 0.5 PV units (std) in the paper's loop; at 1.0 the same freezing
begins (a property of the published model with noisy OP, not of the simulator).

References
----------
.. [Aftab2016] M. F. Aftab, M. Hovd, N. E. Huang, S. Sivalingam, IFAC-PapersOnLine 49-7 (2016)
   1020-1025, §4 (eq. 13, Table 3) and Appendix A.
.. [CTS2005] M. A. A. S. Choudhury, N. F. Thornhill, S. L. Shah, Control Eng. Practice 13 (2005)
   641-658.
.. [Olsson1996] H. Olsson, PhD thesis, Lund Institute of Technology (1996).

This module is pure: no I/O, no clock.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace

import numpy as np

from .errors import ModelConfigError
from .valves import (
    BacklashSpec,
    ChoudhuryStictionSpec,
    KarnoppLoopSpec,
    LinearValveSpec,
    LuGreParams,
    LuGreSpec,
    ValveSpec,
    _finite,
    lugre_force_gain_for_stick_band,
    make_valve,
)

__all__ = [
    "FOPDT",
    "PIController",
    "Sinusoid",
    "SetpointStep",
    "LoopScenario",
    "LoopSimResult",
    "TRUTHS",
    "CASES",
    "PAPER_PLANT",
    "NOMINAL_PI",
    "FAST_PI",
    "PAPER_STICTION",
    "PAPER_LUGRE",
    "DEADBAND_WIDTH",
    "scenario_for_case",
    "simulate_loop",
    "simulate_loops",
    "fopdt_response",
    "loop_frequency_response",
    "gain_margin",
]

#: The causes a simulated record can carry as ``truth``.
TRUTHS = ("healthy", "tuning", "disturbance", "tuning+disturbance", "stiction", "deadband")


@dataclass(frozen=True)
class FOPDT:
    """First-order plus dead-time plant ``G(s) = gain e^{-dead_time_s s} / (tau_s s + 1)``."""

    gain: float
    tau_s: float
    dead_time_s: float

    def __post_init__(self) -> None:
        g = _finite("plant gain", self.gain)
        if g == 0.0:
            raise ModelConfigError(f"plant gain = {self.gain!r} must be non-zero")
        _finite("plant tau_s (time constant)", self.tau_s, minimum=0.0, strict=True)
        _finite("plant dead_time_s", self.dead_time_s, minimum=0.0)

    def transfer(self, omega: np.ndarray) -> np.ndarray:
        """Frequency response ``G(j omega)``."""
        jw = 1j * np.asarray(omega, dtype=float)
        return self.gain * np.exp(-jw * self.dead_time_s) / (self.tau_s * jw + 1.0)


@dataclass(frozen=True)
class PIController:
    """Parallel PI ``u = kc e + ki integral(e dt)``, ``e = sp - pv``, with output limits.

    Anti-windup by integrator clamping: when the unclamped output leaves ``[op_min, op_max]`` the
    integral is reset so that the output sits exactly on the limit.
    """

    kc: float
    ki: float
    op_min: float = -math.inf
    op_max: float = math.inf

    def __post_init__(self) -> None:
        _finite("controller kc", self.kc)
        _finite("controller ki", self.ki, minimum=0.0)
        for name, v in (("op_min", self.op_min), ("op_max", self.op_max)):
            if not isinstance(v, (int, float)) or math.isnan(v):
                raise ModelConfigError(f"controller {name} = {v!r} is not a number")
        if not self.op_min < self.op_max:
            raise ModelConfigError(f"controller op_min = {self.op_min!r} must be < op_max = {self.op_max!r}")
        if self.op_min > 0.0 or self.op_max < 0.0:
            raise ModelConfigError(
                f"controller limits [{self.op_min!r}, {self.op_max!r}] must contain the operating point OP = 0 "
                "(OP is a deviation variable)"
            )

    def transfer(self, omega: np.ndarray) -> np.ndarray:
        """Frequency response ``C(j omega) = kc + ki / (j omega)``."""
        jw = 1j * np.asarray(omega, dtype=float)
        return self.kc + self.ki / jw


@dataclass(frozen=True)
class Sinusoid:
    """External disturbance ``amplitude * sin(omega_rad_s * t + phase_rad)`` on the plant output."""

    amplitude: float
    omega_rad_s: float
    phase_rad: float = 0.0

    def __post_init__(self) -> None:
        _finite("disturbance amplitude", self.amplitude, minimum=0.0)
        _finite("disturbance omega_rad_s", self.omega_rad_s, minimum=0.0, strict=True)
        _finite("disturbance phase_rad", self.phase_rad)


@dataclass(frozen=True)
class SetpointStep:
    """From ``time_s`` on, the set point is ``value`` (it is 0 before the first step)."""

    time_s: float
    value: float

    def __post_init__(self) -> None:
        _finite("set-point step time_s", self.time_s, minimum=0.0)
        _finite("set-point step value", self.value)


@dataclass(frozen=True)
class LoopScenario:
    """Everything that defines one closed-loop simulation (see the module docstring).

    Attributes
    ----------
    plant, controller : :class:`FOPDT`, :class:`PIController`.
    valve : a :data:`models.valves.ValveSpec`, or ``None`` for a perfect valve.
    setpoint_steps : tuple of :class:`SetpointStep`, times non-decreasing.
    disturbances : tuple of :class:`Sinusoid`, added to the plant output.
    measurement_noise_std : PV noise standard deviation (PV units, one value per sample).
    load_noise_std : load noise standard deviation (OP units, one value per sample, plant input).
    sample_time_s, duration_s : recording period and length (``duration_s / sample_time_s``
        samples, an integer).
    substeps : internal integration steps per sample (the PI and the valve run on them).
    truth : the cause of any oscillation, one of :data:`TRUTHS`; ``None`` derives it: a
        stiction valve gives ``"stiction"``, a backlash ``"deadband"``, otherwise ``"tuning"``
        when the continuous loop's gain margin is below 1.5, ``"disturbance"`` when there are
        sinusoidal disturbances, both joined by ``+``, else ``"healthy"``.
    """

    plant: FOPDT
    controller: PIController
    valve: ValveSpec | None = None
    setpoint_steps: tuple[SetpointStep, ...] = ()
    disturbances: tuple[Sinusoid, ...] = ()
    measurement_noise_std: float = 0.0
    load_noise_std: float = 0.0
    sample_time_s: float = 1.0
    duration_s: float = 4000.0
    substeps: int = 10
    truth: str | None = None

    def __post_init__(self) -> None:
        if not isinstance(self.plant, FOPDT):
            raise ModelConfigError(f"plant = {self.plant!r} must be an FOPDT")
        if not isinstance(self.controller, PIController):
            raise ModelConfigError(f"controller = {self.controller!r} must be a PIController")
        if self.valve is not None and not isinstance(
            self.valve, (LinearValveSpec, ChoudhuryStictionSpec, LuGreSpec, BacklashSpec, KarnoppLoopSpec)
        ):
            raise ModelConfigError(f"valve = {self.valve!r} must be a ValveSpec or None")
        steps = tuple(self.setpoint_steps)
        if any(not isinstance(s, SetpointStep) for s in steps):
            raise ModelConfigError(f"setpoint_steps = {self.setpoint_steps!r} must be SetpointStep items")
        times = [s.time_s for s in steps]
        if times != sorted(times):
            raise ModelConfigError(f"setpoint_steps times {times} must be non-decreasing")
        object.__setattr__(self, "setpoint_steps", steps)
        dist = tuple(self.disturbances)
        if any(not isinstance(d, Sinusoid) for d in dist):
            raise ModelConfigError(f"disturbances = {self.disturbances!r} must be Sinusoid items")
        object.__setattr__(self, "disturbances", dist)
        _finite("measurement_noise_std", self.measurement_noise_std, minimum=0.0)
        _finite("load_noise_std", self.load_noise_std, minimum=0.0)
        ts = _finite("sample_time_s", self.sample_time_s, minimum=0.0, strict=True)
        dur = _finite("duration_s", self.duration_s, minimum=0.0, strict=True)
        n = dur / ts
        if round(n) < 1 or abs(n - round(n)) > 1e-6 * max(1.0, n):
            raise ModelConfigError(
                f"duration_s = {self.duration_s!r} must be a positive whole number of sample_time_s = {ts!r}"
            )
        if isinstance(self.substeps, bool) or not isinstance(self.substeps, (int, np.integer)) or self.substeps < 1:
            raise ModelConfigError(f"substeps = {self.substeps!r} must be an integer >= 1")
        if self.truth is not None and self.truth not in TRUTHS:
            raise ModelConfigError(f"truth = {self.truth!r} must be one of {', '.join(TRUTHS)}")

    @property
    def n_samples(self) -> int:
        """Number of recorded samples."""
        return int(round(self.duration_s / self.sample_time_s))

    @property
    def cause(self) -> str:
        """The ground-truth cause (``truth`` or the derived one, see the class docstring)."""
        if self.truth is not None:
            return self.truth
        if isinstance(self.valve, (ChoudhuryStictionSpec, LuGreSpec, KarnoppLoopSpec)):
            return "stiction"
        if isinstance(self.valve, BacklashSpec):
            return "deadband"
        parts = []
        if gain_margin(self.plant, self.controller) < 1.5:
            parts.append("tuning")
        if any(d.amplitude > 0.0 for d in self.disturbances):
            parts.append("disturbance")
        return "+".join(parts) or "healthy"


@dataclass(frozen=True)
class LoopSimResult:
    """Recorded samples of one simulation.

    Attributes
    ----------
    t : sample times (s), ``0, Ts, ..., duration - Ts``.
    sp, pv : set point and measured process value (PV includes disturbance and measurement noise).
    op : controller output (OP units).
    mv : valve stem position in OP units (``mv = op`` for a perfect valve).
    truth : the cause, one of :data:`TRUTHS`.
    """

    t: np.ndarray
    sp: np.ndarray
    pv: np.ndarray
    op: np.ndarray
    mv: np.ndarray
    truth: str
    scenario: LoopScenario | None = field(default=None, repr=False, compare=False)


# --------------------------------------------------------------------------------------------
# Frequency domain helpers (continuous loop)
# --------------------------------------------------------------------------------------------


def loop_frequency_response(plant: FOPDT, controller: PIController, omega: np.ndarray) -> np.ndarray:
    """Open-loop frequency response ``L(j omega) = C(j omega) G(j omega)`` of the continuous loop."""
    return controller.transfer(omega) * plant.transfer(omega)


def gain_margin(plant: FOPDT, controller: PIController) -> float:
    """Gain margin ``1 / |L(j omega_180)|`` of the continuous loop at its first phase crossover.

    The phase of ``L = C G`` is ``-omega theta - atan(omega tau) - atan2(ki, kc omega)`` (for a
    negative-feedback loop, ``kc K >= 0``); the first frequency where it reaches -180 degrees is
    bracketed on a log grid and refined with Brent's method.  Returns ``inf`` when the phase
    never reaches -180 degrees (no dead time).
    """
    from scipy.optimize import brentq

    th, tau = plant.dead_time_s, plant.tau_s
    kc, ki = abs(controller.kc), controller.ki
    if kc == 0.0 and ki == 0.0:
        return math.inf  # no feedback at all

    def phase(w: float | np.ndarray) -> float | np.ndarray:
        return -w * th - np.arctan(w * tau) - np.arctan2(ki, kc * w)

    w = np.geomspace(1e-6, 1e4, 4001) / max(tau, th)
    p = phase(w) + np.pi
    idx = np.nonzero(p <= 0.0)[0]
    if idx.size == 0:
        return math.inf
    i = int(idx[0])
    if i == 0:
        return 1.0 / float(abs(loop_frequency_response(plant, controller, w[:1])[0]))
    w180 = brentq(lambda x: float(phase(x)) + np.pi, w[i - 1], w[i], xtol=1e-14, rtol=1e-14)
    return 1.0 / float(abs(loop_frequency_response(plant, controller, np.array([w180]))[0]))


# --------------------------------------------------------------------------------------------
# The paper's cases
# --------------------------------------------------------------------------------------------

#: Plant of [Aftab2016]_ eq. (13): ``G(s) = 2.25 e^{-3s} / (4.5 s + 1)``.
PAPER_PLANT = FOPDT(gain=2.25, tau_s=4.5, dead_time_s=3.0)
#: Nominal PI of [Aftab2016]_ §4: ``Kc = 0.1``, ``Ki = 0.05``.
NOMINAL_PI = PIController(kc=0.1, ki=0.05)
#: Aggressive integral action of §4.1 ("Fast Cont"): ``Ki = 0.19``, gain margin 1.011.
FAST_PI = PIController(kc=0.1, ki=0.19)

#: Set-point step that starts the transients of the oscillating cases (PV units, at t = 50 s).
_START_STEP = (SetpointStep(50.0, 5.0),)
#: Set-point schedule of the healthy case: up, down, back, so that every slow segment is a
#: well-damped step response.
_HEALTHY_STEPS = (
    SetpointStep(50.0, 5.0),
    SetpointStep(1000.0, -3.0),
    SetpointStep(2000.0, 2.0),
    SetpointStep(3000.0, 0.0),
)
#: Stiction of §4.4: stickband + deadband S = 7 % and slip jump J = 5 % of the OP span.
PAPER_STICTION = ChoudhuryStictionSpec(S=7.0, J=5.0)
#: LuGre valve of Appendix A; force gain (Fs + Fc) / S = 3/14 per % so that its stick band matches S = 7
#: (see :func:`models.valves.lugre_force_gain_for_stick_band`).
PAPER_LUGRE = LuGreSpec(params=LuGreParams(), force_gain=lugre_force_gain_for_stick_band(7.0))
#: Backlash width of the "deadband" case (% of OP span).  Note: backlash alone does not sustain a
#: limit cycle in this loop (self-regulating plant + PI): the describing-function locus
#: ``-1/N(A)`` of backlash lies left of ``Re = -1`` while ``L(j omega)`` stays right of -0.62 in
#: the third quadrant, so the "deadband" case shows slow, lagging responses after each
#: set-point reversal (the valve must cross the gap) but no sustained oscillation.
DEADBAND_WIDTH = 7.0

CASES: dict[str, LoopScenario] = {
    "healthy": LoopScenario(
        PAPER_PLANT, NOMINAL_PI, None, _HEALTHY_STEPS, (), 0.0, 0.5, truth="healthy"
    ),
    "tuning": LoopScenario(PAPER_PLANT, FAST_PI, None, _START_STEP, (), truth="tuning"),
    "disturbance": LoopScenario(
        PAPER_PLANT, NOMINAL_PI, None, _START_STEP, (Sinusoid(5.0, 0.25),), truth="disturbance"
    ),
    "tuning+disturbance": LoopScenario(
        PAPER_PLANT, FAST_PI, None, _START_STEP, (Sinusoid(10.0, 0.1),), truth="tuning+disturbance"
    ),
    "stiction-datadriven": LoopScenario(PAPER_PLANT, NOMINAL_PI, PAPER_STICTION, _START_STEP, truth="stiction"),
    "stiction-lugre": LoopScenario(PAPER_PLANT, NOMINAL_PI, PAPER_LUGRE, _START_STEP, truth="stiction"),
    "deadband": LoopScenario(
        PAPER_PLANT, NOMINAL_PI, BacklashSpec(DEADBAND_WIDTH), _HEALTHY_STEPS, (), truth="deadband"
    ),
}


def scenario_for_case(name: str, *, noise_std: float = 0.0, duration_s: float | None = None) -> LoopScenario:
    """The scenario of case ``name`` (a key of :data:`CASES`) with measurement noise and length.

    ``noise_std`` is the PV measurement noise standard deviation (PV units, per sample); the
    case's own load noise (the healthy case has 0.5 % OP) is kept.  ``duration_s`` replaces the
    4000 s of the paper.
    """
    try:
        base = CASES[name]
    except KeyError:
        raise ModelConfigError(f"case = {name!r} is not one of {', '.join(CASES)}") from None
    changes: dict = {"measurement_noise_std": noise_std}
    if duration_s is not None:
        changes["duration_s"] = duration_s
    return replace(base, **changes)


# --------------------------------------------------------------------------------------------
# Simulation
# --------------------------------------------------------------------------------------------


def _setpoint_series(steps: tuple[SetpointStep, ...], t: np.ndarray) -> np.ndarray:
    sp = np.zeros_like(t)
    for s in steps:
        sp[t >= s.time_s - 1e-9] = s.value
    return sp


def _plant_coefficients(plant: FOPDT, h: float) -> tuple[float, float, float, int]:
    """``(a, b0, b1, d)`` of ``y[k+1] = a y[k] + b0 w[k-d] + b1 w[k-d+1]``.

    Exact for an input that is linear between its internal-step samples (first-order hold)
    when ``d >= 1``; for ``d = 0`` the ZOH form ``b0 = K (1 - a), b1 = 0``.
    """
    a = math.exp(-h / plant.tau_s)
    d = int(round(plant.dead_time_s / h))
    if d == 0:
        return a, plant.gain * (1.0 - a), 0.0, 0
    c = 1.0 - plant.tau_s * (1.0 - a) / h  # weight of the end-of-step sample
    return a, plant.gain * (1.0 - a - c), plant.gain * c, d


def fopdt_response(plant: FOPDT, u: np.ndarray, h: float, *, hold: str = "foh") -> np.ndarray:
    """Open-loop response of ``plant`` to input samples ``u[k] = u(k h)``, from rest.

    ``hold="foh"`` treats the input as linear between samples (what :func:`simulate_loop`
    feeds the plant), ``"zoh"`` as constant over ``[k h, (k+1) h)``.  Exact for such inputs
    (dead time rounded to a whole number of steps ``h``).  Returns ``y[k] = y(k h)``.
    """
    h = _finite("step h", h, minimum=0.0, strict=True)
    if hold not in ("foh", "zoh"):
        raise ModelConfigError(f"hold = {hold!r} must be 'foh' or 'zoh'")
    u = np.asarray(u, dtype=float)
    a, b0, b1, d = _plant_coefficients(plant, h)
    if hold == "zoh":
        d = int(round(plant.dead_time_s / h))
        b0, b1 = plant.gain * (1.0 - a), 0.0
    w = np.concatenate([np.zeros(max(d, 1)), u, [u[-1] if u.size else 0.0]])
    off = max(d, 1) - d  # w[k + off] is the input d steps before step k
    y = np.zeros(u.size)
    yk = 0.0
    for k in range(u.size):
        y[k] = yk
        yk = a * yk + b0 * w[k + off] + b1 * w[k + off + 1]
    return y


def simulate_loop(scenario: LoopScenario, *, seed: int) -> LoopSimResult:
    """Simulate one closed loop; deterministic for a given ``seed``.

    Parameters
    ----------
    scenario : the :class:`LoopScenario`.
    seed : seed of the noise generator (``numpy.random.default_rng``); both noise sequences
        are always drawn, so a given seed gives the same noise whatever the noise levels.

    Returns
    -------
    :class:`LoopSimResult` with ``scenario.n_samples`` samples.
    """
    if not isinstance(scenario, LoopScenario):
        raise ModelConfigError(f"scenario = {scenario!r} must be a LoopScenario")
    sc = scenario
    n = sc.n_samples
    nsub = int(sc.substeps)
    h = sc.sample_time_s / nsub
    n_int = n * nsub

    rng = np.random.default_rng(seed)
    meas = rng.standard_normal(n) * sc.measurement_noise_std
    load = rng.standard_normal(n) * sc.load_noise_std

    t_int = np.arange(n_int) * h
    sp_int = _setpoint_series(sc.setpoint_steps, t_int).tolist()
    dist = np.zeros(n_int)
    for s in sc.disturbances:
        dist += s.amplitude * np.sin(s.omega_rad_s * t_int + s.phase_rad)
    # The measured output adds the (sample-held) measurement noise to the disturbance.
    out_add = (dist + np.repeat(meas, nsub)).tolist()
    load_int = np.repeat(load, nsub).tolist()

    a, b0, b1, d = _plant_coefficients(sc.plant, h)
    kc = sc.controller.kc
    ki_half_h = 0.5 * sc.controller.ki * h
    op_min, op_max = sc.controller.op_min, sc.controller.op_max

    valve = make_valve(sc.valve)
    valve.reset()
    linear = sc.valve is None or isinstance(sc.valve, LinearValveSpec)
    # The two-parameter stiction model is a sampled-data model: its OP velocity is
    # x(k) - x(k-1) over the sampling interval [CTS2005].  It is therefore fed the OP once per
    # sample (the DCS writes the OP to the positioner once per scan) and its MV is held.
    sampled_valve = isinstance(sc.valve, ChoudhuryStictionSpec)
    ts = sc.sample_time_s
    mv = 0.0
    vupd = valve.update

    # w[j + d] is the plant input (stem position + load) at internal step j; zeros before t = 0.
    w = [0.0] * (n_int + d + 1)
    rec_pv = [0.0] * n
    rec_op = [0.0] * n
    rec_mv = [0.0] * n

    y = 0.0
    integ = 0.0
    e_prev = 0.0
    k = 0
    for j in range(n):
        for s in range(nsub):
            pv = y + out_add[k]
            e = sp_int[k] - pv
            integ += ki_half_h * (e + e_prev)
            u = kc * e + integ
            if u > op_max:
                integ = op_max - kc * e
                u = op_max
            elif u < op_min:
                integ = op_min - kc * e
                u = op_min
            e_prev = e
            if linear:
                mv = u
            elif not sampled_valve:
                mv = vupd(u, h)
            elif s == 0:
                mv = vupd(u, ts)
            w[k + d] = mv + load_int[k]
            if s == 0:
                rec_pv[j] = pv
                rec_op[j] = u
                rec_mv[j] = mv
            y = a * y + b0 * w[k] + b1 * w[k + 1]
            k += 1

    t = np.arange(n) * sc.sample_time_s
    sp = np.asarray(sp_int[::nsub])
    return LoopSimResult(
        t=t,
        sp=sp,
        pv=np.asarray(rec_pv),
        op=np.asarray(rec_op),
        mv=np.asarray(rec_mv),
        truth=sc.cause,
        scenario=sc,
    )


def simulate_loops(scenarios: list[LoopScenario] | tuple[LoopScenario, ...], *, seeds) -> list[LoopSimResult]:
    """Simulate many loops (``seeds`` an int for ``seed + i`` or one seed per scenario)."""
    scenarios = list(scenarios)
    if isinstance(seeds, (int, np.integer)):
        seed_list = [int(seeds) + i for i in range(len(scenarios))]
    else:
        seed_list = [int(s) for s in seeds]
    if len(seed_list) != len(scenarios):
        raise ModelConfigError(f"seeds: {len(seed_list)} given for {len(scenarios)} scenarios")
    return [simulate_loop(sc, seed=s) for sc, s in zip(scenarios, seed_list)]
