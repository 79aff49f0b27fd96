"""Bench-test excitations of the spec paper (Romano & Garcia) and simulated bench records.

Pressure commands (Pa, sampled at ``dt``, 1 ms by default as in section 4) for the V/P converter:

* ``square``: 10.4 s period, 15 % ↔ 75 % of the 41.74–206.84 kPa range (identification data, Fig. 1);
* ``triangle``: a slow triangular wave over the same range (the valve signature, Fig. 2);
* ``sine``: 35.5 s period, 63.95–160.44 kPa (validation, section 5, Fig. 6–7);
* ``isa-steps``: ANSI/ISA-75.25.01 step sequence of 0.1, 0.2, 0.5, 1, 2, 5, 10, 20 and 50 % around
  50 % of the range (validation, section 5, Fig. 8–9).

:func:`bench_record` runs one through the Karnopp valve (:func:`models.karnopp.simulate`) and adds
Gaussian measurement noise to the actuator pressure and the stem position, seeded.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from .errors import ModelConfigError
from .karnopp import KarnoppParams, SimResult, pct_to_pa, simulate

__all__ = [
    "DT",
    "ISA_STEPS_PCT",
    "Excitation",
    "BenchRecord",
    "square",
    "triangle",
    "sine",
    "isa_steps",
    "EXCITATIONS",
    "excitation",
    "bench_record",
]

#: Sampling period of the paper's bench, s (section 4).
DT = 1e-3
#: Step amplitudes of the ISA-75.25 test, % of the input range (section 5).
ISA_STEPS_PCT = (0.1, 0.2, 0.5, 1.0, 2.0, 5.0, 10.0, 20.0, 50.0)


@dataclass(frozen=True)
class Excitation:
    """A pressure command: ``t`` (s) and ``p_cmd`` (Pa), equally spaced by ``dt``."""

    name: str
    t: np.ndarray
    p_cmd: np.ndarray
    dt: float


def _check(name: str, value: float, *, positive: bool = True) -> float:
    if not (isinstance(value, (int, float)) and math.isfinite(value)) or (positive and value <= 0):
        raise ModelConfigError(f"{name} = {value!r}: must be a finite number{' > 0' if positive else ''}")
    return float(value)


def _time(dt: float, duration: float) -> np.ndarray:
    _check("dt", dt)
    _check("duration", duration)
    n = int(round(duration / dt))
    if n < 2:
        raise ModelConfigError(f"duration {duration!r} s at dt {dt!r} s gives {n} sample(s); need at least 2")
    return dt * np.arange(n)


def square(
    dt: float = DT, *, period: float = 10.4, low_pct: float = 15.0, high_pct: float = 75.0, periods: float = 4.0
) -> Excitation:
    """Square wave between ``low_pct`` and ``high_pct`` of the range, starting low (section 4)."""
    _check("period", period)
    t = _time(dt, periods * period)
    high = np.mod(t, period) >= period / 2
    return Excitation("square", t, np.where(high, pct_to_pa(high_pct), pct_to_pa(low_pct)), dt)


def triangle(
    dt: float = DT, *, period: float = 30.0, low_pct: float = 15.0, high_pct: float = 75.0, periods: float = 3.0
) -> Excitation:
    """Triangular wave low → high → low (valve signature, Fig. 2); slow, so that breakaway points
    can be located in force (eq. 11–12)."""
    _check("period", period)
    t = _time(dt, periods * period)
    phase = np.mod(t, period) / period
    frac = 1.0 - np.abs(2.0 * phase - 1.0)  # 0 → 1 → 0
    return Excitation("triangle", t, pct_to_pa(low_pct + (high_pct - low_pct) * frac), dt)


def sine(
    dt: float = DT, *, period: float = 35.5, p_low: float = 63.95e3, p_high: float = 160.44e3, periods: float = 2.0
) -> Excitation:
    """Sine between ``p_low`` and ``p_high`` Pa starting at its minimum (section 5, Fig. 6–7)."""
    _check("period", period)
    t = _time(dt, periods * period)
    mid, amp = (p_high + p_low) / 2, (p_high - p_low) / 2
    return Excitation("sine", t, mid - amp * np.cos(2 * np.pi * t / period), dt)


def isa_steps(
    dt: float = DT, *, center_pct: float = 50.0, steps_pct: tuple[float, ...] = ISA_STEPS_PCT, hold: float = 4.0
) -> Excitation:
    """ISA-75.25 step sequence (section 5, Fig. 8–9): after ``hold`` s at ``center_pct``, for each
    amplitude ``a`` a step to ``center + a/2`` then to ``center − a/2``, each held ``hold`` s."""
    _check("hold", hold)
    levels = [center_pct]
    for a in steps_pct:
        levels += [center_pct + a / 2, center_pct - a / 2]
    per = int(round(hold / dt))
    pct = np.repeat(np.asarray(levels, dtype=float), per)
    t = _time(dt, pct.size * dt)
    return Excitation("isa-steps", t, pct_to_pa(pct), dt)


EXCITATIONS: dict[str, Callable[..., Excitation]] = {
    "square": square,
    "triangle": triangle,
    "sine": sine,
    "isa-steps": isa_steps,
}


def excitation(name: str, dt: float = DT, **options: float) -> Excitation:
    """The named excitation (``square``, ``triangle``, ``sine``, ``isa-steps``)."""
    try:
        make = EXCITATIONS[name]
    except KeyError:
        raise ModelConfigError(f"unknown bench test {name!r}; choose one of {', '.join(EXCITATIONS)}") from None
    return make(dt, **options)


@dataclass(frozen=True)
class BenchRecord:
    """A simulated bench record: what a smart positioner would log.

    ``p`` is the measured actuator pressure (Pa) and ``x`` the measured stem position
    (m, ``x_true − x̄`` of eq. 10, plus noise); ``truth`` holds the noise-free simulation.
    """

    t: np.ndarray
    p: np.ndarray
    x: np.ndarray
    truth: SimResult = field(repr=False)
    noise_x: float
    noise_p: float
    seed: int | None


def bench_record(
    params: KarnoppParams,
    test: str | Excitation,
    *,
    noise_x: float = 1e-5,
    noise_p: float = 200.0,
    seed: int | None = 0,
    dt: float = DT,
) -> BenchRecord:
    """Simulate one bench test and add white Gaussian measurement noise.

    Parameters
    ----------
    params : the valve.
    test : excitation name or an :class:`Excitation`.
    noise_x : standard deviation of the stem-position noise, m (default 10 µm, 0.035 % of travel).
    noise_p : standard deviation of the pressure noise, Pa (default 200 Pa, 0.12 % of the range).
    seed : seed of the noise generator.
    dt : sampling period, s (ignored when ``test`` is an Excitation).
    """
    _check("noise_x", noise_x, positive=False)
    _check("noise_p", noise_p, positive=False)
    if noise_x < 0 or noise_p < 0:
        raise ModelConfigError(f"noise_x = {noise_x!r}, noise_p = {noise_p!r}: standard deviations must be >= 0")
    exc = test if isinstance(test, Excitation) else excitation(test, dt)
    truth = simulate(params, exc.p_cmd, exc.dt, t0=float(exc.t[0]))
    rng = np.random.default_rng(seed)
    p = truth.p + noise_p * rng.standard_normal(truth.p.size)
    x = truth.x_meas + noise_x * rng.standard_normal(truth.x.size)
    return BenchRecord(t=truth.t, p=p, x=x, truth=truth, noise_x=noise_x, noise_p=noise_p, seed=seed)
