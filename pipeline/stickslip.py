"""Stuck valve without a limit cycle: the OP travels, the PV does not follow, then it jumps.

A sticking valve does not always limit-cycle.  After a set-point change or a load step the
integral action ramps the OP while the stem stays put; the PV sits away from the set point
until the force beats static friction and the stem slips.  A window of such a loop has one or
two stick-slip episodes and no sustained oscillation, so the oscillation gate rightly rejects
it and the DNL test never sees it.  This module looks for the episodes directly in PV, OP and
SP, after the qualitative-shape idea of Yamashita (2006, "An automatic method for detection of
valve stiction in process control loops", Control Eng. Practice 14:503–510): stiction shows as
phases in which the OP moves while the PV stays steady.  Yamashita's index counts such phases
over the whole record, which a healthy loop absorbing a load change also produces (the OP
moves while the PV stays at the set point).  We add the two conditions that make the phase a
stuck valve rather than good control, and ask for the end of it:

* **stuck**: over a segment of ``W`` samples the OP travels monotonically by more than
  ``z`` standard errors while the PV moves by less than ``z`` standard errors, *and* the PV is
  held away from the set point (``|mean(sp - pv)|`` above ``z`` PV noise deviations): the
  integral action is pushing against a stem that does not move;
* **slip**: within ``W`` samples after the stuck phase the PV moves towards the set point by
  more than ``z`` standard errors: the stem has broken away.

Noise levels are the white-noise deviations of PV and OP estimated from their first
differences (median absolute deviation / 0.6745 / sqrt 2, robust to the steps themselves);
``z = 4``.  ``W`` is a twentieth of the window (at least 10 samples): a stuck phase must
last that long, which also keeps a healthy loop's dead time (the PV not yet responding to an
OP move) from counting as stuck unless the dead time is that long.  What it cannot tell apart:
a deadband (backlash) also lets the OP cross a gap with the PV steady; the finding is
therefore "the valve does not follow the OP (stiction or deadband)".
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = ["StickSlip", "stick_slip_episodes"]


@dataclass(frozen=True)
class StickSlip:
    """Stuck phases that ended in a slip; ``stuck_fraction`` of the window spent stuck."""

    episodes: int
    stuck_fraction: float
    reason: str


def _noise_std(x: np.ndarray) -> float:
    d = np.diff(x)
    return float(np.median(np.abs(d - np.median(d))) / 0.6745 / np.sqrt(2.0))


def _smooth(x: np.ndarray, k: int) -> np.ndarray:
    c = np.cumsum(np.r_[0.0, x])
    out = (c[k:] - c[:-k]) / k
    pad = k // 2
    return np.r_[np.full(pad, out[0]), out, np.full(x.size - out.size - pad, out[-1])]


def stick_slip_episodes(pv: np.ndarray, op: np.ndarray, sp: np.ndarray, *, z: float = 4.0,
                        min_segment: int = 10) -> StickSlip | None:
    """Count stick-slip episodes in one window (see the module docstring).

    Parameters
    ----------
    pv, op, sp : finite 1-D arrays of one window, same length.
    z : standard errors a move must exceed (and a steady signal stay below).
    min_segment : the shortest segment ``W`` in samples.

    Returns
    -------
    StickSlip, or None when a signal is constant (nothing to judge).
    """
    n = pv.size
    w = max(min_segment, n // 20)
    if n < 3 * w:
        return None
    s_pv, s_op = _noise_std(pv), _noise_std(op)
    if not (s_pv > 0 and s_op > 0):
        return None
    k = max(3, w // 3)  # moving average against the noise; its differences have se sigma sqrt(2/k)
    pv_s, op_s, e_s = _smooth(pv, k), _smooth(op, k), _smooth(sp - pv, k)
    se_pv, se_op = s_pv * np.sqrt(2.0 / k), s_op * np.sqrt(2.0 / k)
    d_op = op_s[w:] - op_s[:-w]
    d_pv = pv_s[w:] - pv_s[:-w]
    # monotonic OP over the segment: its range is no larger than its net travel plus noise
    seg = np.lib.stride_tricks.sliding_window_view(op_s, w + 1)
    mono = seg.max(axis=1) - seg.min(axis=1) <= np.abs(d_op) + z * se_op
    held = np.abs(e_s[:-w] + e_s[w:]) / 2.0 > z * s_pv
    stuck = (np.abs(d_op) > z * se_op) & (np.abs(d_pv) < z * se_pv) & held & mono
    episodes = 0
    stuck_samples = np.zeros(n, dtype=bool)
    i = 0
    while i < stuck.size:
        if not stuck[i]:
            i += 1
            continue
        j = i
        while j + 1 < stuck.size and stuck[j + 1]:
            j += 1
        end = j + w  # the last sample of the stuck phase
        after = slice(end, min(n, end + w + 1))
        e0 = e_s[end]
        towards = (np.abs(e_s[after]) < abs(e0) - z * se_pv) & (np.sign(e_s[after]) == np.sign(e0))
        slipped = bool(np.any(towards) or np.any(np.sign(e_s[after]) == -np.sign(e0)))
        # abrupt: the PV moves after the stuck phase by more than twice its move over the
        # phase's last segment plus z standard errors (a jump in the PV's rate, which neither
        # a first-order creep towards the SP nor an integrating PV turning round makes), and
        # no set-point move explains it
        before = abs(pv_s[end] - pv_s[end - w])
        jump = np.abs(pv_s[after] - pv_s[end]).max() if end < n else 0.0
        sp_still = np.ptp(sp[end - w:min(n, end + w + 1)]) <= z * s_pv
        if slipped and jump > 2.0 * before + z * se_pv and sp_still:
            episodes += 1
            stuck_samples[i:end + 1] = True
        i = j + 1
    frac = float(stuck_samples.mean())
    if episodes:
        reason = (f"valve does not follow the OP (stiction or deadband): {episodes} stick-slip episode(s), "
                  f"OP travelling with the PV held off the set point for {frac:.0%} of the window")
    else:
        reason = "no stick-slip episode (the PV follows the OP)"
    return StickSlip(episodes, frac, reason)
