"""Zero-phase filters applied in the frequency domain (shared by the gate and the robust test)."""

from __future__ import annotations

import numpy as np

__all__ = ["band_weights"]


def band_weights(f: np.ndarray, *, f_lo: float, f_hi: float, order: int = 2) -> np.ndarray:
    """Zero-phase band-pass gain: squared Butterworth high-pass at ``f_lo`` times squared
    Butterworth low-pass at ``f_hi``, both of ``order`` (what forward–backward filtering gives).

    ``f`` are non-negative frequencies in the unit of the edges; the gain at ``f = 0`` is 0.
    """
    p = 2 * order
    with np.errstate(divide="ignore", over="ignore"):
        hp = 1.0 / (1.0 + (f_lo / f) ** p)
    lp = 1.0 / (1.0 + (f / f_hi) ** p)
    return np.where(f > 0, hp, 0.0) * lp
