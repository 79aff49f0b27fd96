"""Stuck valve without a limit cycle: the OP travels, the PV does not follow, then it jumps.

A sticking valve does not always limit-cycle.  After a set-point change or a load step the
integral action ramps the OP while the stem stays put; the PV sits away from the set point
until the force beats static friction and the stem slips.  A window of such a loop has one or
two stick-slip episodes and no sustained oscillation, so the oscillation gate rightly rejects
it and the DNL test never sees it.

Phases in which the OP moves while the PV stays steady (Yamashita 2006, "An automatic method
for detection of valve stiction in process control loops", Control Eng. Practice 14:503–510)
are not enough: a healthy loop absorbing a load does the same, and the PV's move after a
set-point step looks like a slip.  The test used here asks whether the loop's own OP→PV
response needs a sticking valve: a Hammerstein model (two-parameter stiction + first-order
lag with dead time) fitted to the window against the linear model of the same family
(:func:`pipeline.hammerstein.stiction_test`).  A set-point step is then no false alarm (the
controller's kick is in the OP, and the linear model follows it), and a slip with no OP step
is what only the stiction model explains.  A held stem and a load that the valve follows and
cancels predict the same PV while it lasts; what differs is the OP: integral action against a
stuck stem ramps it one way, a compensated load makes it go back and forth.  So the fitted
stem's holds must see the (smoothed) OP travel mostly one way (:data:`MIN_MONOTONIC` of its
path net).  What it cannot tell apart: a deadband (backlash) is the same family; the finding
is "the valve does not follow the OP (stiction or deadband)".  Measured on planted and plant
windows in ACCURACY.md (issue 3); compensated loads still read as stick-slip in
about a third of planted windows.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .hammerstein import stiction_test

__all__ = ["StickSlip", "stick_slip_episodes"]


@dataclass(frozen=True)
class StickSlip:
    """Stick-slip finding of one window: ``episodes`` slips of the fitted stem (0 when the
    linear valve explains the PV as well), ``stuck_fraction`` of the window the fitted stem
    held while the OP moved, and the reason (with the Hammerstein test's figures).  Plain
    numbers and text: it is recorded with the window."""

    episodes: int
    stuck_fraction: float
    reason: str


MAX_SAMPLES = 768
MIN_MONOTONIC = 0.5


def _monotonic_share(op: np.ndarray, stem: np.ndarray) -> float:
    """Share of the (smoothed) OP's path length while the fitted stem is held that is net
    travel: 1 when the OP ramps one way through every stuck phase (integral action against a
    stuck stem), small when it goes back and forth (a load the valve follows and compensates)."""
    k = max(3, op.size // 40)
    c = np.cumsum(np.r_[0.0, op])
    ops = np.r_[np.full(k // 2, np.nan), (c[k:] - c[:-k]) / k, np.full(k - 1 - k // 2, np.nan)]  # centred, NaN ends
    held = np.r_[False, np.diff(stem) == 0, False]
    edges = np.flatnonzero(np.diff(held.astype(np.int8)))
    net = path = 0.0
    for a, b in zip(edges[::2], edges[1::2]):  # stem[a-1 .. b-1] constant
        seg = ops[max(a - 1, 0):b]
        seg = seg[np.isfinite(seg)]
        if seg.size > k:
            net += abs(seg[-1] - seg[0])
            path += np.abs(np.diff(seg)).sum()
    return net / path if path > 0 else 0.0


def stick_slip_episodes(pv: np.ndarray, op: np.ndarray) -> StickSlip | None:
    """Stick-slip episodes in one window of PV and OP (see the module docstring).

    A window longer than :data:`MAX_SAMPLES` is first averaged over blocks of ``q`` samples
    (the smallest ``q`` that brings it within): the test's cost grows with the window squared
    (dead times searched up to a tenth of it), and stick-slip episodes last many samples.

    Returns
    -------
    StickSlip, or None when the OP or PV does not move (nothing to judge).
    """
    pv = np.asarray(pv, dtype=np.float64)
    op = np.asarray(op, dtype=np.float64)
    q = -(-pv.size // MAX_SAMPLES)
    if q > 1:
        m = pv.size // q * q
        pv, op = (v[pv.size - m:].reshape(-1, q).mean(axis=1) for v in (pv, op))
    t = stiction_test(pv, op)
    if t is None:
        return None
    if not t.sticking:
        return StickSlip(0, 0.0, t.reason)
    mono = _monotonic_share(op, t.stem)
    if mono < MIN_MONOTONIC:
        return StickSlip(0, 0.0, f"{t.reason}, but the OP goes back and forth while the stem is held "
                         f"({mono:.0%} of its travel is net: a disturbance compensated, not a stuck valve)")
    episodes = max(1, t.slips)
    return StickSlip(episodes, t.stuck_fraction, f"{t.reason}; {episodes} slip(s) of the fitted stem")
