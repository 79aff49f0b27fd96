"""Offline analysis of one loop record: choose the signal, slide windows, diagnose each, conclude.

The use case behind ``loopwatch analyze``; pure apart from what the caller passes in.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

import numpy as np

from adapters.loop_csv import LoopData
from adapters.payloads import json_number
from pipeline.diagnosis import DiagnosisConfig, WindowDiagnosis, diagnose_window
from pipeline.record import overall_verdict, window_starts

from .errors import UsageError

__all__ = ["SignalChoice", "WindowReport", "LoopReport", "analyze_loop", "witnesses", "hold", "DEFAULT_WINDOW"]

SignalChoice = Literal["auto", "pv", "op", "error"]

#: default window length in samples (FFT-friendly; about 68 min at 1 s)
DEFAULT_WINDOW = 4096


@dataclass(frozen=True)
class WindowReport:
    start_s: float
    end_s: float
    diagnosis: WindowDiagnosis

    def to_json(self) -> dict:
        d, g = self.diagnosis, self.diagnosis.gate
        return {
            "start_s": self.start_s,
            "end_s": self.end_s,
            "oscillating": bool(g is not None and g.oscillating and d.verdict != "not_oscillating"),
            "period_s": json_number(g.period_s) if g else None,
            "regularity": json_number(g.regularity) if g else None,
            "imfs_kept": list(d.imfs_kept),
            "dnl": [json_number(v) for v in d.dnl],
            "tdnl": json_number(d.tdnl),
            "verdict": d.verdict,
            "reason": d.reason,
            "method": d.method,
            "p_value": json_number(d.robust.p_value) if d.robust else None,
            "dnl_threshold": json_number(d.robust.threshold) if d.robust else None,
            "amplitude": json_number(g.amplitude) if g else None,
            "guards": list(d.guards),
            "harmonic_ratio": json_number(d.robust.harmonic_ratio) if d.robust else None,
            "stick_slip_episodes": d.stick_slip.episodes if d.stick_slip else None,
        }


@dataclass(frozen=True)
class LoopReport:
    source: str
    signal: str
    n_samples: int
    sample_time_s: float
    verdict: str
    tdnl: float
    reason: str
    windows: tuple[WindowReport, ...]
    n_duplicates: int = 0

    @property
    def stick_slip_windows(self) -> int:
        """Windows without a sustained oscillation in which the valve did not follow the OP."""
        return sum(1 for w in self.windows if w.diagnosis.stick_slip and w.diagnosis.stick_slip.episodes)

    def to_json(self) -> dict:
        return {
            "source": self.source,
            "signal": self.signal,
            "n_samples": self.n_samples,
            "sample_time_s": self.sample_time_s,
            "verdict": self.verdict,
            "tdnl": json_number(self.tdnl),
            "reason": self.reason,
            "duplicate_rows_dropped": self.n_duplicates,
            "stick_slip_windows": self.stick_slip_windows,
            "windows": [w.to_json() for w in self.windows],
        }


def _has_data(v: np.ndarray | None) -> bool:
    return v is not None and bool(np.isfinite(v).any())


def hold(v: np.ndarray) -> np.ndarray:
    """A signal often sent or logged on change only (the set point) held between its samples: each
    NaN takes the last value before it, leading NaNs the first value of the window."""
    ok = np.isfinite(v)
    if not ok.any():
        return v
    idx = np.maximum.accumulate(np.where(ok, np.arange(v.size), -1))
    idx[idx < 0] = int(np.argmax(ok))
    return v[idx]


def witnesses(name: str, *, op: np.ndarray | None, sp: np.ndarray | None) -> dict[str, np.ndarray]:
    """The companion signals that go with the analysed series ``name`` to
    :func:`pipeline.diagnosis.diagnose_window`: the OP (second witness of a non-linearity and
    saturation guard) when the PV or the control error is analysed, and the set point held
    between its samples (a change inside the window -> the control error) when the PV is.
    The one rule for ``loopwatch analyze`` and the monitor."""
    extra = {}
    if name in ("pv", "error") and _has_data(op):
        extra["op"] = op
    if name == "pv" and _has_data(sp):
        extra["sp"] = hold(sp)
    return extra


def select_signal(data: LoopData, choice: SignalChoice) -> tuple[str, np.ndarray]:
    """The series to analyse; ``auto`` takes PV, or OP when the record has no PV (e.g. ISDB)."""
    if choice == "auto":
        choice = "pv" if _has_data(data.pv) else "op"
    if choice == "error":
        if not (_has_data(data.sp) and _has_data(data.pv)):
            raise UsageError(f"{data.source}: --signal error needs both 'sp' and 'pv' columns with data")
        return "error", data.sp - data.pv
    series = getattr(data, choice)
    if not _has_data(series):
        raise UsageError(f"{data.source}: column {choice!r} has no data; choose another --signal")
    return choice, series


def analyze_loop(
    data: LoopData,
    *,
    signal: SignalChoice = "auto",
    window: int | None = None,
    hop: int | None = None,
    config: DiagnosisConfig = DiagnosisConfig(),
) -> LoopReport:
    """Diagnose every window of a loop record and the loop as a whole.

    Windows during which the loop is not in automatic (``mode`` present and not 1) are
    ``invalid``: a loop in manual cannot show a control-loop oscillation.  When the PV is
    analysed, the set point and the OP go with it: a window with a set-point change is
    analysed as control error, the OP is the second witness of a non-linearity and, in a
    window that does not oscillate, PV/OP/SP are searched for stick-slip episodes
    (:func:`pipeline.diagnosis.diagnose_window`).
    """
    name, x = select_signal(data, signal)
    n = x.size
    window = min(window or DEFAULT_WINDOW, n)
    hop = hop or max(1, window // 2)
    fs = 1.0 / data.sample_time_s
    reports = []
    for s in window_starts(n, window=window, hop=hop):
        sl = slice(s, s + window)
        mode = None if data.mode is None else data.mode[sl]
        extra = witnesses(name, op=None if data.op is None else data.op[sl],
                          sp=None if data.sp is None else data.sp[sl])
        diag = diagnose_window(x[sl], fs=fs, config=config, mode=mode, **extra)
        reports.append(WindowReport(float(data.t[s]), float(data.t[min(s + window, n) - 1]), diag))
    verdict, tdnl_value, reason = overall_verdict([r.diagnosis for r in reports])
    stuck = sum(1 for r in reports if r.diagnosis.stick_slip and r.diagnosis.stick_slip.episodes)
    if stuck:
        reason += f"; the valve did not follow the OP (stiction or deadband) in {stuck} non-oscillating window(s)"
    return LoopReport(data.source, name, n, data.sample_time_s, verdict, tdnl_value, reason, tuple(reports),
                      n_duplicates=data.n_duplicates)
