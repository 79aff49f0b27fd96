"""Data-quality guards: conditions that fake a non-linearity in a window.

Each guard returns ``None`` when the window is clean, else a sentence for the window's reason.
A window that fails a guard is not declared ``nonlinear``: the verdict becomes ``uncertain``
(a linear or not-oscillating verdict stands, with the guard noted).

* quantisation: a PV that takes few distinct values is a staircase, whose steps are intra-wave
  frequency modulation of their own (Thornhill & Horch 2007 list quantisation among the causes
  of apparent non-linearity);
* historian compression: swinging-door or boxcar compression stores only the turning points,
  the rest is straight-line interpolation or repeated values: corners everywhere (Thornhill,
  Choudhury & Shah 2004, "The impact of compression on data-driven process analyses");
* saturation: an OP at its limit clips the loop, a non-linearity of the controller, not of the
  valve.

One note does not change the verdict: a PV that holds one value to the bit over the whole window
while the OP moves (:func:`frozen_pv`).  A dead transmitter or a stale tag does that, but so does a
valve that does not move (a noise-free measurement of a valve resting in its deadband, a flow held
at 0 by the transmitter's low-flow cut-off under a valve stuck closed), so the window is not
declared broken; the reason says what was seen.
"""

from __future__ import annotations

import numpy as np

__all__ = ["quantisation", "compression", "saturation", "frozen_pv", "window_guards"]


def quantisation(x: np.ndarray, *, min_levels: int = 16) -> str | None:
    """Fewer than ``min_levels`` distinct values in the window."""
    levels = np.unique(x[np.isfinite(x)]).size
    if levels < min_levels:
        return f"quantised: only {levels} distinct values (fewer than {min_levels})"
    return None


def compression(x: np.ndarray, *, max_fraction: float = 0.5) -> str | None:
    """More than ``max_fraction`` of the samples on straight lines (zero second difference)
    or repeating the previous value."""
    x = x[np.isfinite(x)]
    if x.size < 3:
        return None
    scale = max(float(np.ptp(x)), 1e-300)
    flat = np.abs(np.diff(x, 2)) <= 1e-9 * scale
    frac = float(np.mean(flat))
    if frac > max_fraction:
        return f"historian compression: {frac:.0%} of samples on straight lines or repeated"
    return None


def saturation(op: np.ndarray, *, max_fraction: float = 0.05, limits: tuple[float, float] | None = None) -> str | None:
    """OP at a limit for more than ``max_fraction`` of the window.

    ``limits`` are the OP limits when known; otherwise the 0 % / 100 % of a valve signal are
    assumed when the OP lies within them, and an OP resting at its own extreme value for many
    samples counts as saturated.
    """
    op = op[np.isfinite(op)]
    if op.size == 0:
        return None
    lo, hi = limits if limits is not None else (float(op.min()), float(op.max()))
    span = max(hi - lo, 1e-12)
    at = (op <= lo + 1e-3 * span) | (op >= hi - 1e-3 * span)
    frac = float(np.mean(at))
    if frac > max_fraction and (limits is not None or np.any(np.diff(op)[at[1:]] == 0)):
        return f"OP saturated: at its limit for {frac:.0%} of the window"
    return None


def frozen_pv(pv: np.ndarray, op: np.ndarray) -> str | None:
    """The PV holds one value over the whole window (at least two finite samples) while the OP
    moves: a sentence for the reason, else None."""
    pv = pv[np.isfinite(pv)]
    op = op[np.isfinite(op)]
    if pv.size >= 2 and op.size >= 2 and np.all(pv == pv[0]) and np.ptp(op) > 0:
        return (f"the PV holds {pv[0]:.6g} to the bit for the whole window while the OP moves over {np.ptp(op):.3g}: "
                "the valve does not move, or the measurement is dead (transmitter, stale tag, low-flow cut-off)")
    return None


def window_guards(x: np.ndarray, *, op: np.ndarray | None = None) -> list[str]:
    """All guard findings for an analysed series ``x`` (and the OP, when known)."""
    found = [quantisation(x), compression(x)]
    if op is not None:
        found.append(saturation(op))
    return [f for f in found if f]
