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
cancels predict the same PV while it lasts; what differs is the OP.  With the stem held the PV
is at rest, the control error is constant between set-point changes, and the PI output is a
straight ramp, kicked and re-sloped only at set-point changes; a compensated load moves the
error with it and the OP curves.  So straight PI ramps (one line per stretch between
set-point changes) must explain at least :data:`MIN_RAMP_SHARE` of the OP's variance while the
fitted stem is held (:func:`_ramp_share`).  What it cannot tell apart: a deadband (backlash) is the same family;
the finding is "the valve does not follow the OP (stiction or deadband)".  Measured on planted
and plant windows in ACCURACY.md (issue 3).
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
MIN_RAMP_SHARE = 0.8


def _holds(stem: np.ndarray) -> list[tuple[int, int]]:
    """``(a, b)``: the fitted stem is constant over ``stem[a:b]`` (at least two samples)."""
    held = np.r_[False, np.diff(stem) == 0, False]  # held[j]: stem[j] == stem[j - 1]
    edges = np.flatnonzero(np.diff(held.astype(np.int8)))  # held turns on at a + 1, off at b + 1
    return [(a, b + 1) for a, b in zip(edges[::2], edges[1::2])]


def _setpoint_moves(sp: np.ndarray, k: int) -> np.ndarray:
    """Indices where the set point changes, as breaks of the PI ramps: changes less than ``k``
    samples apart form one move (an operator's clicks); a move that goes on for more than ``k``
    samples (a cascade's wandering remote set point) is no step, and gives no breaks."""
    c = np.flatnonzero(np.diff(sp) != 0) + 1
    if c.size == 0:
        return c
    group = np.r_[0, np.cumsum(np.diff(c) >= k)]  # consecutive changes < k apart: one move
    first, last = np.full(group[-1] + 1, c[-1]), np.zeros(group[-1] + 1, dtype=int)
    np.minimum.at(first, group, c)
    np.maximum.at(last, group, c)
    return c[(last - first)[group] <= k]


def _ramp_share(op: np.ndarray, stem: np.ndarray, sp: np.ndarray | None = None) -> float:
    """Share of the OP's variance during the fitted stem's holds that PI ramps explain.

    While the stem is held the PV is at rest (noise aside), so the control error is constant
    between set-point changes, and a PI controller's output ``kc e + ki ∫e`` is a straight
    line in time, with a kick and a new slope at each set-point change: the OP ramps while the
    PV sits still (Yamashita 2006).  A load that the valve follows and the loop compensates
    moves the error with it, and the OP curves with the load.  So fit, in every hold longer
    than ``k = n/40`` samples, one straight line to the OP between consecutive set-point
    changes (:func:`_setpoint_moves`: the clicks of one move, each a break; a set point that
    keeps moving for more than ``k`` samples, none) and return ``1 - SS_res / SS_tot`` pooled
    over the holds (``SS_tot`` about each hold's mean).  A ramp reversed by a set-point step is
    a stuck valve's, a reversal with the set point unchanged is not.  0 when no hold is long
    enough."""
    n = op.size
    k = max(3, n // 40)
    brk = _setpoint_moves(sp, k) if sp is not None else np.zeros(0, dtype=int)
    ss_res = ss_tot = 0.0
    for a, b in _holds(stem):
        if b - a <= k:
            continue
        y = op[a:b]
        ss_tot += float(np.sum((y - y.mean()) ** 2))
        cuts = np.r_[a, brk[(brk > a) & (brk < b)], b]
        for c0, c1 in zip(cuts[:-1], cuts[1:]):
            y = op[c0:c1]
            if y.size < 3:
                continue  # one or two samples: a line through them leaves nothing
            t = np.arange(y.size) - (y.size - 1) / 2.0
            yc = y - y.mean()
            ss_res += float(yc @ yc - (t @ yc) ** 2 / (t @ t))
    return 1.0 - ss_res / ss_tot if ss_tot > 0 else 0.0


def stick_slip_episodes(pv: np.ndarray, op: np.ndarray, sp: np.ndarray | None = None) -> StickSlip | None:
    """Stick-slip episodes in one window of PV and OP, and the set point if known (see the
    module docstring; without it, only a single ramp per hold counts as the PI's).

    A window longer than :data:`MAX_SAMPLES` is first averaged over blocks of ``q`` samples
    (the smallest ``q`` that brings it within): the test's cost grows with the window squared
    (dead times searched up to a tenth of it), and stick-slip episodes last many samples.  At
    the window's own sampling the dead times searched start at one sample (a PV sample cannot
    answer the OP computed from it: :func:`pipeline.hammerstein.stiction_test`); after block
    averaging they start at 0, because a loop that answers within a few samples answers mostly
    within the same block (synthetic check, a linear valve one sample behind the OP, blocks of
    6: with lag 0 excluded the linear model's error grew so that a stiction model's error ratio
    fell from 0.90-0.96 to 0.74-0.77).

    Returns
    -------
    StickSlip, or None when the OP or PV does not move (nothing to judge).
    """
    pv = np.asarray(pv, dtype=np.float64)
    op = np.asarray(op, dtype=np.float64)
    sp = None if sp is None else np.asarray(sp, dtype=np.float64)
    q = -(-pv.size // MAX_SAMPLES)
    if q > 1:
        m = pv.size // q * q
        pv, op, sp = (None if v is None else v[pv.size - m:].reshape(-1, q).mean(axis=1) for v in (pv, op, sp))
    t = stiction_test(pv, op, min_dead_time=1 if q == 1 else 0)
    if t is None:
        return None
    if not t.sticking:
        return StickSlip(0, 0.0, t.reason)
    ramps = _ramp_share(op, t.stem, sp)
    if ramps < MIN_RAMP_SHARE:
        return StickSlip(0, 0.0, f"{t.reason}, but the OP is no PI ramp while the stem is held (ramps explain "
                         f"{ramps:.0%} of its variance: a disturbance compensated, not a stuck valve)")
    episodes = max(1, t.slips)
    return StickSlip(episodes, t.stuck_fraction, f"{t.reason}; {episodes} slip(s) of the fitted stem")
