"""Sliding windows over a record and the overall diagnosis of a loop from its windows."""

from __future__ import annotations

from collections import Counter
from collections.abc import Sequence

import numpy as np

from .diagnosis import Verdict, WindowDiagnosis
from .errors import PipelineConfigError

__all__ = ["window_starts", "overall_verdict"]


def window_starts(n: int, *, window: int, hop: int) -> list[int]:
    """Start indices of windows of ``window`` samples every ``hop`` samples over ``n`` samples.

    The last window is aligned to the end of the record so that no tail is left unanalysed; a
    record shorter than one window gives a single window over all of it.
    """
    if window < 1 or hop < 1:
        raise PipelineConfigError(f"window={window!r} and hop={hop!r} must be >= 1 sample")
    if n <= window:
        return [0]
    starts = list(range(0, n - window + 1, hop))
    if starts[-1] + window < n:
        starts.append(n - window)
    return starts


def overall_verdict(windows: Sequence[WindowDiagnosis]) -> tuple[Verdict, float, str]:
    """The loop's diagnosis from its windows.

    Rules: no analysable window → ``invalid``; fewer than half of the analysable windows
    oscillating (``nonlinear``, ``linear`` or ``uncertain``) → ``not_oscillating``; more
    ``uncertain`` windows than decided ones → ``uncertain``; otherwise the majority of the decided
    windows (a tie counts as ``nonlinear``: a sticking valve should not be missed).  The TDNL
    reported is the median over the oscillating windows.

    Returns
    -------
    (verdict, tdnl, reason)
    """
    counts = Counter(w.verdict for w in windows)
    valid = len(windows) - counts["invalid"]
    decided = counts["nonlinear"] + counts["linear"]
    osc = decided + counts["uncertain"]
    order = ("nonlinear", "linear", "uncertain", "not_oscillating", "invalid")
    summary = ", ".join(f"{counts[k]} {k}" for k in order if counts[k])
    if valid == 0:
        reasons = Counter(w.reason for w in windows)
        return "invalid", float("nan"), f"no analysable window ({reasons.most_common(1)[0][0]})"
    tdnls = [w.tdnl for w in windows if w.verdict in ("nonlinear", "linear", "uncertain") and np.isfinite(w.tdnl)]
    median = float(np.median(tdnls)) if tdnls else float("nan")
    if osc * 2 < valid:
        return "not_oscillating", median, f"{osc} of {valid} analysable windows oscillate ({summary})"
    if counts["uncertain"] > decided:
        return "uncertain", median, f"{counts['uncertain']} of {osc} oscillating windows uncertain ({summary})"
    verdict: Verdict = "nonlinear" if counts["nonlinear"] * 2 >= decided else "linear"
    return verdict, median, f"{counts[verdict]} of {decided} decided oscillating windows {verdict} ({summary})"
