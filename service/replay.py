"""Replay of monitor recordings: the recorded windows as the monitor saw them, re-analysed.

* :func:`recorded_windows` -- every recorded window as ``(WindowSamples, WindowResult, Alert | None)``
  exactly as the monitor had them (samples, its result, its alert transition), with the analysis
  configuration it ran with.
* :func:`replay_windows` -- re-runs the analysis and the alert hysteresis on them and says, per
  window, whether the recomputed result and alert equal the recorded ones bit for bit; any extra
  :class:`~service.ports.WindowSink` (a dashboard, another recorder) can be fed on the way:
  ``for r in replay_windows(paths, sinks=[sink]): ...``.
* :func:`republish_plan` -- the recorded samples of each loop, once each, in time order, at
  their original time stamps (for ``loopwatch replay --publish``).
"""

from __future__ import annotations

import json
from collections.abc import Iterable, Iterator, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Callable

import numpy as np

from adapters import mcap_codec as codec
from adapters.mcap_reader import RecordedGroup, read_recording

from .monitor import Alert, AnalysisConfig, LoopConfig, MonitorCore, WindowResult, WindowSamples, analyze_window
from .ports import WindowSink

__all__ = ["RecordedWindow", "ReplayedWindow", "recorded_windows", "replay_windows", "to_window",
           "republish_plan"]


@dataclass(frozen=True)
class RecordedWindow:
    """A window as the monitor had it: samples, result and alert transition, plus where it came
    from and the alert hysteresis the monitor ran with."""

    window: WindowSamples
    result: WindowResult
    alert: Alert | None
    source: str
    raise_after: int
    clear_after: int
    group: RecordedGroup

    def __iter__(self):   # window, result, alert = recorded
        return iter((self.window, self.result, self.alert))


@dataclass(frozen=True)
class ReplayedWindow:
    """A recorded window and what the replay computed for it; ``same_*`` compare bit for bit."""

    recorded: RecordedWindow
    result: WindowResult
    alert: Alert | None
    same_result: bool
    same_alert: bool

    @property
    def window(self) -> WindowSamples:
        return self.recorded.window


def to_window(group: RecordedGroup) -> WindowSamples:
    """The :class:`WindowSamples` of a recorded group, with the analysis config it was recorded with."""
    rec = group.window
    analysis = AnalysisConfig(signal=group.config["signal"], diagnosis=codec.decode_diagnosis_config(group.config))
    grid_ns = codec.seconds_to_ns(rec.t)
    offsets = {}
    for name, ns in rec.times_ns.items():
        off = ns - grid_ns
        if np.any(off != 0):
            offsets[name] = off / 1e9
    return WindowSamples(rec.loop_id, rec.seq, rec.index0, rec.t, rec.sample_time_s, rec.signals, analysis, offsets,
                         hop=group.config.get("hop"))


def _recorded(group: RecordedGroup) -> RecordedWindow:
    diag, amplitude, period_s, n_missing = codec.decode_diagnosis(group.result)
    alerts = group.run.get("alerts", {})
    return RecordedWindow(to_window(group), WindowResult(diag, amplitude, period_s, n_missing),
                          Alert.from_json(group.alert) if group.alert is not None else None, group.source,
                          int(alerts.get("raise_after", 3)), int(alerts.get("clear_after", 3)), group)


def _time_ns(t: float | None) -> int | None:
    return None if t is None else codec.seconds_to_ns(float(t))


def recorded_windows(paths: Sequence[str | Path], *, loops: Iterable[str] | None = None,
                     t_from: float | None = None, t_to: float | None = None) -> Iterator[RecordedWindow]:
    """Every recorded window in ``paths`` (files or directories) whose last sample time (Unix s)
    lies in ``[t_from, t_to]``, for ``loops`` (default all), in recording order."""
    for group in read_recording(paths, loops=loops, start_ns=_time_ns(t_from), end_ns=_time_ns(t_to)):
        yield _recorded(group)


class _Hysteresis:
    """The alert state machines of a replay: one :class:`MonitorCore` per monitor run (a run
    starts with fresh alert states, so does its replay) and alert hysteresis."""

    def __init__(self) -> None:
        self.key = None
        self.core: MonitorCore | None = None

    def apply(self, rec: RecordedWindow, result: WindowResult) -> Alert | None:
        key = (rec.group.run.get("run_id"), rec.raise_after, rec.clear_after)
        if key != self.key:
            self.key = key
            self.core = MonitorCore(loop_config=lambda _id: LoopConfig(), raise_after=rec.raise_after,
                                    clear_after=rec.clear_after, clock=lambda: 0.0)
        return self.core.apply(rec.window, result)


def _same(a: dict | None, b: dict | None) -> bool:
    return json.dumps(a, sort_keys=True) == json.dumps(b, sort_keys=True)


def replay_windows(paths: Sequence[str | Path], *, loops: Iterable[str] | None = None,
                   t_from: float | None = None, t_to: float | None = None, sinks: Sequence[WindowSink] = (),
                   analyze: Callable[[WindowSamples], WindowResult] = analyze_window) -> Iterator[ReplayedWindow]:
    """Re-analyse every recorded window (see :func:`recorded_windows`) with the configuration it was
    recorded with, re-run the alert hysteresis, and feed ``sinks`` the recomputed result and alert.

    Alert states: before ``t_from``, the recorded results of the same files bring the alert
    state machines to where the monitor had them (so a replay of the hour of an incident gives
    the alerts the monitor gave); a new monitor run (``run_id`` of the file) starts them afresh,
    as the monitor did.  When the files given start in the middle of a run, the first alerts of
    the replay can differ from the recorded ones (``same_alert`` False), the verdicts cannot.
    """
    hysteresis = _Hysteresis()
    if t_from is not None:   # warm-up on the recorded results: no analysis
        for group in read_recording(paths, loops=loops, end_ns=_time_ns(t_from) - 1):
            rec = _recorded(group)
            hysteresis.apply(rec, rec.result)
    for rec in recorded_windows(paths, loops=loops, t_from=t_from, t_to=t_to):
        w = rec.window
        result = analyze(w)
        alert = hysteresis.apply(rec, result)
        end_ns = rec.group.window.log_time
        same_result = _same(json.loads(codec.dumps(codec.encode_result(w.loop_id, w.seq, end_ns, result))),
                            rec.group.result)
        rec_alert = rec.group.alert
        same_alert = (alert is None and rec_alert is None) or (
            alert is not None and rec_alert is not None
            and _same(json.loads(json.dumps(alert.to_json())), {k: rec_alert.get(k) for k in alert.to_json()}))
        for sink in sinks:
            sink.on_window(w.loop_id, w, result, alert)
        yield ReplayedWindow(rec, result, alert, same_result, same_alert)


@dataclass(frozen=True)
class PublishBatch:
    """Samples of one signal of one loop to publish: values and their own time stamps (Unix ns);
    ``regular`` when they are consecutive grid points stamped on the grid (a binary batch)."""

    loop_id: str
    signal: str
    t_ns: np.ndarray
    v: np.ndarray
    sample_time_s: float
    regular: bool

    @property
    def due_ns(self) -> int:
        return int(self.t_ns[-1])


#: publication order within a window's new samples: pacing signals (op, pv) last, as a plant sends them
_ORDER = ("mode", "sp", "mv", "op", "pv")


def republish_plan(windows: Iterable[RecordedWindow], *, batch: int = 16) -> Iterator[PublishBatch]:
    """The recorded samples of each loop, each grid point once (windows overlap), in recording
    order, as a plant sends them: slices of ``batch`` grid points, all signals of a slice before
    the next (OP and PV last; a monitor closes a window once its pacing signals reach the end),
    consecutive on-grid samples as one batch, off-grid samples one by one."""
    published: dict[str, int] = {}
    for rec in windows:
        w, g = rec.window, rec.group.window
        lo = max(0, published.get(w.loop_id, -(2**62)) + 1 - w.index0)
        if lo >= w.t.size:
            continue
        published[w.loop_id] = w.index0 + w.t.size - 1
        grid_ns = codec.seconds_to_ns(w.t)
        names = sorted(w.signals, key=lambda n: _ORDER.index(n) if n in _ORDER else -1)
        for c0 in range(lo, w.t.size, batch):
            c1 = min(w.t.size, c0 + batch)
            for name in names:
                v, ns = w.signals[name][c0:c1], g.times_ns[name][c0:c1]
                ok = np.isfinite(v)
                on_grid = ok & (ns == grid_ns[c0:c1])
                i = 0
                while i < v.size:
                    if not ok[i]:
                        i += 1
                    elif on_grid[i]:
                        j = i + 1
                        while j < v.size and on_grid[j]:
                            j += 1
                        yield PublishBatch(w.loop_id, name, ns[i:j], v[i:j], w.sample_time_s, True)
                        i = j
                    else:
                        yield PublishBatch(w.loop_id, name, ns[i:i + 1], v[i:i + 1], w.sample_time_s, False)
                        i += 1
