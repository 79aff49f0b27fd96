"""The always-on monitor: per-loop grid buffers, sliding windows, analysis, alert state machine.

Layers, from pure to not:

* :class:`LoopBuffer` -- one loop: aligns samples onto the loop's sample grid (configured or
  inferred sample time), keeps a ring buffer per signal, counts duplicates, late samples and
  gaps, and cuts sliding windows.  Time is the data's time only.
* :func:`analyze_window` -- the analysis of one window; depends only on the window's samples and
  the :class:`AnalysisConfig` (a top-level function, so it can run in a worker process).
* :class:`AlertTracker` -- raise after N consecutive non-linear windows, clear after M clean ones.
* :class:`MonitorCore` -- all loops: decodes messages (:mod:`adapters.payloads`), routes them to
  the loop buffers, counts rejections per loop and reason, applies results to the trackers, and
  answers status.  Pure and deterministic given the messages in order (the clock is injected
  and used only for rate-limited logging and latency statistics).
* :class:`Monitor` -- the runtime: core + an executor (thread or worker processes) that analyses
  windows off the message-delivery threads + the sinks (:mod:`service.ports`).  Results are
  applied strictly in the order the windows closed.
"""

from __future__ import annotations

import logging
import math
import queue
import threading
import time
from collections import Counter, deque
from concurrent.futures import Executor, ProcessPoolExecutor, ThreadPoolExecutor
from dataclasses import dataclass, field
from typing import Any, Callable, Literal

import numpy as np

from adapters.payloads import SIGNALS, PayloadError, decode_payload, json_number, parse_key
from pipeline.diagnosis import DiagnosisConfig, WindowDiagnosis, diagnose_window
from pipeline.gate import detrend_linear, robust_amplitude

from .analysis import witnesses
from .errors import ServiceError
from .ports import AlertSink, Clock, Closeable, SinkHealth, WindowSink

__all__ = [
    "AnalysisConfig",
    "LoopConfig",
    "WindowSamples",
    "WindowResult",
    "Alert",
    "LoopBuffer",
    "AlertTracker",
    "RateLimitedLog",
    "MonitorCore",
    "Monitor",
    "analyze_window",
]

log = logging.getLogger("loopwatch.monitor")

AnalysedSignal = Literal["pv", "op", "error"]
#: samples needed before the sample time of a loop is inferred from single samples
_INFER_SAMPLES = 8
#: signals whose progress decides that a window is complete (others only via ``lateness``)
_PACING_SIGNALS = ("op", "pv")
#: a sample's own time stamp is kept (as an offset from its grid point) once it is further than
#: this from the grid point it is placed on; closer stamps are taken as the grid time (float64 Unix
#: seconds only resolve ~0.24 us today, so this is a few units of their last place)
RAW_TIME_TOLERANCE_S = 1e-6


@dataclass(frozen=True)
class AnalysisConfig:
    """How a window is analysed: the signal and the pipeline's configuration."""

    signal: AnalysedSignal = "pv"
    diagnosis: DiagnosisConfig = field(default_factory=DiagnosisConfig)

    def __post_init__(self) -> None:
        if self.signal not in ("pv", "op", "error"):
            raise ServiceError(f"analysis signal {self.signal!r} must be 'pv', 'op' or 'error'")


@dataclass(frozen=True)
class LoopConfig:
    """Resolved settings of one loop.

    Parameters
    ----------
    sample_time_s : grid spacing; ``None`` infers it (a batch's ``dt``, else the median spacing
        of the first 8 single samples).
    length, hop : window length and hop in samples, or ``None`` to use ``length_s`` / ``hop_s``.
    length_s, hop_s : the same in seconds (converted with the sample time).
    lateness : samples the newest sample may run past a window's end before the window is
        closed although a pacing signal (OP, PV) has not reached its end yet.
    analysis : :class:`AnalysisConfig`.
    """

    sample_time_s: float | None = None
    length: int | None = 1024
    hop: int | None = 256
    length_s: float | None = None
    hop_s: float | None = None
    lateness: int = 64
    analysis: AnalysisConfig = field(default_factory=AnalysisConfig)

    def __post_init__(self) -> None:
        if self.sample_time_s is not None and not (math.isfinite(self.sample_time_s) and self.sample_time_s > 0):
            raise ServiceError(f"sample_time_s={self.sample_time_s!r} must be a finite number > 0")
        if (self.length is None) == (self.length_s is None):
            raise ServiceError(f"give exactly one of length={self.length!r} and length_s={self.length_s!r}")
        if (self.hop is None) == (self.hop_s is None):
            raise ServiceError(f"give exactly one of hop={self.hop!r} and hop_s={self.hop_s!r}")
        if self.lateness < 0:
            raise ServiceError(f"lateness={self.lateness!r} must be >= 0 samples")

    def window_samples(self, ts: float) -> tuple[int, int]:
        """``(length, hop)`` in samples at sample time ``ts``; rejects windows too short to analyse."""
        length = self.length if self.length is not None else int(round(self.length_s / ts))
        hop = self.hop if self.hop is not None else int(round(self.hop_s / ts))
        if length < 64:
            raise ServiceError(f"window of {length} samples (at {ts:g} s) is too short: need >= 64 for a diagnosis")
        if not 1 <= hop <= length:
            raise ServiceError(f"hop of {hop} samples must be in [1, window length {length}]")
        return length, hop


@dataclass(frozen=True)
class WindowSamples:
    """One closed window of a loop: grid times and the raw samples of every signal (NaN = missing).

    ``seq`` numbers the loop's windows from 0; ``index0`` is the grid index of the first sample.
    ``t_offset[name]`` (only for signals whose samples were stamped off the grid by more than
    :data:`RAW_TIME_TOLERANCE_S`) is each sample's own time minus its grid time; see :meth:`sample_times`.
    """

    loop_id: str
    seq: int
    index0: int
    t: np.ndarray
    sample_time_s: float
    signals: dict[str, np.ndarray]
    analysis: AnalysisConfig
    t_offset: dict[str, np.ndarray] = field(default_factory=dict)
    hop: int | None = None

    @property
    def searches_stick_slip(self) -> bool:
        """Whether this window is searched for stick-slip episodes when it does not oscillate:
        one window per window length of data (the one whose start is within a hop past a
        multiple of the length), not every overlapping window, since the search costs ~5x a
        non-oscillating window's diagnosis; every window when the hop is unknown."""
        return self.hop is None or self.index0 % self.t.size < self.hop

    def sample_times(self, name: str) -> np.ndarray:
        """The data's own time stamps (Unix s) of signal ``name``: grid time plus its offset."""
        off = self.t_offset.get(name)
        return self.t if off is None else self.t + off

    @property
    def start_t(self) -> float:
        return float(self.t[0])

    @property
    def end_t(self) -> float:
        return float(self.t[-1])

    def series(self) -> np.ndarray:
        """The analysed series (PV, OP or SP - PV), NaN where missing."""
        sig = self.analysis.signal
        if sig == "error":
            return self.signals.get("sp", _nan_like(self.t)) - self.signals.get("pv", _nan_like(self.t))
        return self.signals.get(sig, _nan_like(self.t))


def _nan_like(t: np.ndarray) -> np.ndarray:
    return np.full(t.shape, np.nan)


@dataclass(frozen=True)
class WindowResult:
    """What the analysis says about one window (see :func:`analyze_window`)."""

    diagnosis: WindowDiagnosis
    amplitude: float
    period_s: float
    n_missing: int


def analyze_window(window: WindowSamples) -> WindowResult:
    """Diagnose one window; a pure function of the window's samples and its analysis config.

    A window in which the loop is in manual (a finite ``mode`` sample other than 1) is
    ``invalid``.  ``amplitude`` and ``period_s`` are the oscillation gate's (half the 5-95 %
    percentile range of the detrended analysed series; NaN period when none); a window the gate did
    not see gets the same amplitude over its finite samples.
    """
    x = window.series()
    n_missing = int(np.count_nonzero(~np.isfinite(x)))
    signals = window.signals
    extra = witnesses(window.analysis.signal, op=signals.get("op"), sp=signals.get("sp"))
    diag = diagnose_window(x, fs=1.0 / window.sample_time_s, config=window.analysis.diagnosis,
                           mode=signals.get("mode"), stick_slip=window.searches_stick_slip, **extra)
    if diag.gate is not None:
        amplitude, period = diag.gate.amplitude, diag.gate.period_s
    else:   # not analysed (manual, too many gaps): the same figure over the samples there are
        ok = np.isfinite(x)
        amplitude = robust_amplitude(detrend_linear(x[ok])) if np.count_nonzero(ok) >= 8 else math.nan
        period = math.nan
    return WindowResult(diag, float(amplitude), float(period), n_missing)


@dataclass(frozen=True)
class Alert:
    """A state transition of a loop's alert: ``raised`` or ``cleared``; JSON via :meth:`to_json`."""

    loop_id: str
    state: Literal["raised", "cleared"]
    verdict: str
    tdnl: float
    dnl: tuple[float, ...]
    threshold: float
    period_s: float
    amplitude: float
    signal: str
    window_start_t: float
    window_end_t: float
    window_seq: int
    consecutive: int
    evidence: str

    def to_json(self) -> dict[str, Any]:
        return {
            "loop": self.loop_id,
            "state": self.state,
            "verdict": self.verdict,
            "tdnl": json_number(self.tdnl),
            "dnl": [json_number(v) for v in self.dnl],
            "threshold": self.threshold,
            "period_s": json_number(self.period_s),
            "amplitude": json_number(self.amplitude),
            "signal": self.signal,
            "window": {"start_t": self.window_start_t, "end_t": self.window_end_t, "seq": self.window_seq},
            "consecutive_windows": self.consecutive,
            "evidence": self.evidence,
        }

    @classmethod
    def from_json(cls, d: dict[str, Any]) -> "Alert":
        """Inverse of :meth:`to_json` (``null`` figures back to NaN); extra keys are ignored."""
        num = lambda v: math.nan if v is None else float(v)  # noqa: E731
        w = d["window"]
        return cls(d["loop"], d["state"], d["verdict"], num(d["tdnl"]), tuple(num(v) for v in d["dnl"]),
                   float(d["threshold"]), num(d["period_s"]), num(d["amplitude"]), d["signal"],
                   float(w["start_t"]), float(w["end_t"]), int(w["seq"]), int(d["consecutive_windows"]),
                   d["evidence"])


class AlertTracker:
    """Hysteresis of one loop's alert.

    ``raised`` after ``raise_after`` consecutive ``nonlinear`` windows; ``cleared`` after
    ``clear_after`` consecutive clean windows (``linear`` or ``not_oscillating``).  ``invalid``
    windows (no usable data) neither raise nor clear and do not break a streak.
    """

    def __init__(self, raise_after: int = 3, clear_after: int = 3) -> None:
        if raise_after < 1 or clear_after < 1:
            raise ServiceError(f"raise_after={raise_after!r} and clear_after={clear_after!r} must be >= 1")
        self.raise_after = raise_after
        self.clear_after = clear_after
        self.active = False
        self.nonlinear_streak = 0
        self.clean_streak = 0
        self.recent_tdnl: deque[float] = deque(maxlen=raise_after)

    def update(self, verdict: str, tdnl: float = math.nan) -> Literal["raised", "cleared"] | None:
        """Feed one window's verdict; returns the transition it causes, if any."""
        if verdict == "nonlinear":
            self.nonlinear_streak += 1
            self.clean_streak = 0
            self.recent_tdnl.append(tdnl)
            if not self.active and self.nonlinear_streak >= self.raise_after:
                self.active = True
                return "raised"
        elif verdict in ("linear", "not_oscillating"):
            self.clean_streak += 1
            self.nonlinear_streak = 0
            self.recent_tdnl.clear()
            if self.active and self.clean_streak >= self.clear_after:
                self.active = False
                return "cleared"
        return None


class RateLimitedLog:
    """At most ``rate`` log lines per second (token bucket of ``burst``); suppressed lines are counted
    and the count is reported with the next line that gets through.  ``clock`` is injected."""

    def __init__(self, logger: logging.Logger, rate: float, clock: Clock, burst: int = 5) -> None:
        self.logger, self.rate, self.clock, self.burst = logger, float(rate), clock, burst
        self.tokens = float(burst)
        self.last = clock()
        self.suppressed = 0

    def warning(self, msg: str) -> bool:
        now = self.clock()
        self.tokens = min(self.burst, self.tokens + (now - self.last) * self.rate)
        self.last = now
        if self.tokens < 1.0:
            self.suppressed += 1
            return False
        self.tokens -= 1.0
        if self.suppressed:
            msg = f"{msg} ({self.suppressed} similar message(s) suppressed)"
            self.suppressed = 0
        self.logger.warning(msg)
        return True


class LoopBuffer:
    """Grid-aligned ring buffer and sliding-window cutter of one loop.

    Samples are placed on the grid ``origin + k * Ts`` (nearest point; the grid is fixed by the
    first samples, see :meth:`_try_infer`).  The ring holds ``length + lateness + hop`` grid
    points; a window ``[s, s + length)`` is cut as soon as every pacing signal seen so far (OP,
    PV) has every sample of it, else when one of them is ``lateness`` points beyond its end (a
    window with gaps or late samples waits that long; signals such as SP or mode, often sent on
    change only, never hold a window back).  A sample for a grid point that no future window can contain is ``late``;
    a second sample for an occupied grid point is a ``duplicate`` (the first is kept).  After a
    gap longer than the ring, windows that would contain no sample are skipped (counted).
    """

    def __init__(self, loop_id: str, config: LoopConfig) -> None:
        self.loop_id = loop_id
        self.config = config
        self.ts: float | None = config.sample_time_s
        self.origin: float | None = None
        self.length = self.hop = self.cap = 0
        self.data: dict[str, np.ndarray] = {}
        self.offsets: dict[str, np.ndarray] = {}   # allocated per signal on its first off-grid sample
        self.sig_hi: dict[str, int] = {}
        self.hi = -(2**62)
        self.next_start = 0
        self.seq = 0
        self.pending: list[tuple[str, np.ndarray, np.ndarray, float | None]] = []
        self.accepted: Counter[str] = Counter()
        self.rejected: Counter[str] = Counter()
        self.skipped_windows = 0

    # ------------------------------------------------------------------ grid set-up
    def _setup(self, ts: float, origin: float) -> None:
        self.ts, self.origin = ts, origin
        self.length, self.hop = self.config.window_samples(ts)
        self.cap = self.length + self.config.lateness + self.hop

    def _try_infer(self) -> list[WindowSamples]:
        """Fix the grid from the first samples: the sample time (configured, a batch's ``dt``, or
        the median spacing of 8 single samples) and its phase (circular mean of the times modulo
        the sample time, so that jitter of the first sample does not shift the grid)."""
        batch_dt = next((dt for _, _, _, dt in self.pending if dt is not None), None)
        times = np.concatenate([t for _, t, _, _ in self.pending])
        uniq = np.unique(times)
        if batch_dt is None and uniq.size < _INFER_SAMPLES:
            return []
        ts = self.ts or batch_dt or float(np.median(np.diff(uniq)))
        t_min = float(times.min())
        ang = 2.0 * np.pi * ((times - t_min) / ts)
        phase = float(np.angle(np.mean(np.exp(1j * ang)))) / (2.0 * np.pi) * ts
        self._setup(float(ts), t_min + phase)
        self.next_start = int(np.rint((t_min - self.origin) / self.ts))
        pending, self.pending = self.pending, []
        out: list[WindowSamples] = []
        for signal, t, v, _ in pending:
            out.extend(self._place(signal, t, v))
        return out

    # ------------------------------------------------------------------ ingest
    def add(self, signal: str, t: np.ndarray, v: np.ndarray, dt: float | None = None) -> list[WindowSamples]:
        """Add samples (times ``t``, finite values ``v``) of one signal; return the windows closed."""
        if self.origin is None:
            self.pending.append((signal, np.asarray(t, dtype=np.float64), np.asarray(v, dtype=np.float64), dt))
            return self._try_infer()
        return self._place(signal, t, v)

    def _place(self, signal: str, t: np.ndarray, v: np.ndarray) -> list[WindowSamples]:
        t = np.asarray(t, dtype=np.float64)
        k = np.rint((t - self.origin) / self.ts).astype(np.int64)
        v = np.asarray(v, dtype=np.float64)
        off = t - (self.origin + k * self.ts)
        if signal not in self.offsets and not np.any(np.abs(off) > RAW_TIME_TOLERANCE_S):
            off = None   # on the grid: the grid time is the sample's time
        if k.size > 1 and np.any(k[1:] <= k[:-1]):
            order = np.argsort(k, kind="stable")
            k, v = k[order], v[order]
            off = None if off is None else off[order]
            first = np.r_[True, k[1:] != k[:-1]]
            if not first.all():
                self.rejected["duplicate"] += int(k.size - np.count_nonzero(first))
                k, v = k[first], v[first]
                off = None if off is None else off[first]
        late = k < self.next_start
        if late.any():
            self.rejected["late"] += int(np.count_nonzero(late))
            k, v = k[~late], v[~late]
            off = None if off is None else off[~late]
        out: list[WindowSamples] = []
        i = 0
        while i < k.size:
            # never write past the ring: close (or skip) windows until k[i] fits
            while k[i] >= self.next_start + self.cap:
                if self.next_start > self.hi:
                    steps = max(1, (int(k[i]) - self.next_start) // self.hop)
                    self.next_start += steps * self.hop
                    self.skipped_windows += steps
                else:
                    out.append(self._cut())
            j = int(np.searchsorted(k, self.next_start + self.cap, side="left"))
            self._write(signal, k[i:j], v[i:j], None if off is None else off[i:j])
            i = j
            out.extend(self._close_due())
        return out

    def _write(self, signal: str, k: np.ndarray, v: np.ndarray, off: np.ndarray | None = None) -> None:
        cap = self.cap
        top = int(k[-1]) if k.size else self.hi
        if top > self.hi:  # grid points beyond the newest one reuse ring slots: clear them first
            fresh = np.arange(max(self.hi + 1, top - cap + 1), top + 1) % cap
            for arr in self.data.values():
                arr[fresh] = np.nan
            for arr in self.offsets.values():
                arr[fresh] = 0.0
        s = k % cap
        arr = self.data.get(signal)
        if arr is None:
            arr = self.data[signal] = np.full(cap, np.nan)
        dup = np.isfinite(arr[s])
        if dup.any():
            self.rejected["duplicate"] += int(np.count_nonzero(dup))
            s, k, v = s[~dup], k[~dup], v[~dup]
            off = None if off is None else off[~dup]
        arr[s] = v
        if off is not None:
            offs = self.offsets.get(signal)
            if offs is None:
                offs = self.offsets[signal] = np.zeros(cap)
            offs[s] = off
        self.accepted[signal] += int(k.size)
        if k.size:
            if top > self.sig_hi.get(signal, -(2**62)):
                self.sig_hi[signal] = top
            if top > self.hi:
                self.hi = top

    def _close_due(self) -> list[WindowSamples]:
        out = []
        while True:
            end = self.next_start + self.length - 1
            names = [s for s in _PACING_SIGNALS if s in self.sig_hi]
            if not names:
                return out
            hi = [self.sig_hi[s] for s in names]
            if not (max(hi) >= end + self.config.lateness or (min(hi) >= end and self._full(names))):
                return out
            out.append(self._cut())

    def _full(self, names: list[str]) -> bool:
        idx = np.arange(self.next_start, self.next_start + self.length, dtype=np.int64)
        s = idx % self.cap
        valid = idx <= self.hi
        return all(bool(np.all(valid & np.isfinite(self.data[n][s]))) for n in names)

    def _cut(self) -> WindowSamples:
        idx = np.arange(self.next_start, self.next_start + self.length, dtype=np.int64)
        s = idx % self.cap
        valid = idx <= self.hi   # older grid points than hi - cap never lie in a window still to cut
        signals = {}
        for name in SIGNALS:
            arr = self.data.get(name)
            if arr is None:
                continue
            x = arr[s]
            x[~valid] = np.nan
            signals[name] = x
        offsets = {name: np.where(np.isfinite(signals[name]), arr[s], 0.0)
                   for name, arr in self.offsets.items() if name in signals}
        w = WindowSamples(self.loop_id, self.seq, self.next_start, self.origin + idx * self.ts, self.ts,
                          signals, self.config.analysis, offsets, hop=self.hop)
        self.seq += 1
        self.next_start += self.hop
        return w

    # ------------------------------------------------------------------ status
    def last_time(self) -> float | None:
        if self.origin is None or self.hi < -(2**61):
            return None
        return self.origin + self.hi * self.ts


@dataclass
class _LoopState:
    buffer: LoopBuffer
    tracker: AlertTracker
    last_verdict: str | None = None
    last_tdnl: float = math.nan
    last_reason: str = ""
    last_window: tuple[float, float] | None = None
    windows: int = 0
    missing_samples: int = 0


class MonitorCore:
    """All loops: message decoding, routing, rejection counting, alert state, status.

    Parameters
    ----------
    prefix : key prefix of the samples (``{prefix}/{loop_id}/{signal}``).
    loop_config : ``loop_id -> LoopConfig`` for every loop (a callable, so that loops are
        discovered on first message).
    raise_after, clear_after : alert hysteresis (see :class:`AlertTracker`).
    time_range : accepted ``[min, max]`` Unix time of samples.
    max_loops : most loops tracked; messages for further loop ids are rejected (``too_many_loops``).
    clock : monotonic clock used only for rate-limited logging.
    max_logs_per_s : log-line rate of rejection warnings.
    """

    def __init__(
        self,
        *,
        prefix: str = "plant",
        loop_config: Callable[[str], LoopConfig] = lambda loop_id: LoopConfig(),
        raise_after: int = 3,
        clear_after: int = 3,
        time_range: tuple[float, float] = (946684800.0, 4102444800.0),
        max_loops: int = 100_000,
        clock: Clock = time.monotonic,
        max_logs_per_s: float = 1.0,
    ) -> None:
        AlertTracker(raise_after, clear_after)  # validates
        self.prefix = prefix
        self.loop_config = loop_config
        self.raise_after, self.clear_after = raise_after, clear_after
        self.time_range = time_range
        self.max_loops = max_loops
        self.loops: dict[str, _LoopState] = {}
        self.unrouted: Counter[str] = Counter()
        self.messages = 0
        self.lock = threading.RLock()
        self.rate_log = RateLimitedLog(log, max_logs_per_s, clock)

    def _loop(self, loop_id: str) -> _LoopState | None:
        st = self.loops.get(loop_id)
        if st is None:
            if len(self.loops) >= self.max_loops:
                return None
            st = self.loops[loop_id] = _LoopState(LoopBuffer(loop_id, self.loop_config(loop_id)),
                                                  AlertTracker(self.raise_after, self.clear_after))
        return st

    def ingest(self, key: str, payload: bytes, encoding: str = "", attachment: bytes | None = None
               ) -> list[WindowSamples]:
        """Handle one message; return the windows it closed.  Never raises on bad input."""
        with self.lock:
            self.messages += 1
            try:
                loop_id, signal = parse_key(key, self.prefix)
            except PayloadError as exc:
                if exc.reason == "unknown_signal":
                    loop_id = key[len(self.prefix) + 1:].rpartition("/")[0]
                    st = self.loops.get(loop_id)
                    if st is not None:
                        st.buffer.rejected[exc.reason] += 1
                        self.rate_log.warning(f"loop {loop_id}: rejected message ({exc.reason}): {exc}")
                        return []
                self.unrouted[exc.reason] += 1
                self.rate_log.warning(f"rejected message on {key!r} ({exc.reason}): {exc}")
                return []
            st = self._loop(loop_id)
            if st is None:
                self.unrouted["too_many_loops"] += 1
                self.rate_log.warning(f"rejected loop {loop_id!r}: already tracking max_loops={self.max_loops}")
                return []
            buf = st.buffer
            try:
                batch = decode_payload(payload, encoding=encoding, attachment=attachment, time_range=self.time_range)
            except PayloadError as exc:
                buf.rejected[exc.reason] += 1
                self.rate_log.warning(f"loop {loop_id} {signal}: rejected message ({exc.reason}): {exc}")
                return []
            if batch.n_nonfinite:
                buf.rejected["non_finite"] += batch.n_nonfinite
                self.rate_log.warning(f"loop {loop_id} {signal}: {batch.n_nonfinite} non-finite value(s) dropped")
            try:
                return buf.add(signal, batch.times, batch.v, batch.dt)
            except ServiceError as exc:  # e.g. a window too short for the inferred sample time
                buf.rejected["bad_config"] += int(batch.v.size)
                buf.pending.clear()
                self.rate_log.warning(f"loop {loop_id}: {exc}")
                return []

    def apply(self, window: WindowSamples, result: WindowResult) -> Alert | None:
        """Apply one window's result (in window order per loop); return the alert transition, if any."""
        with self.lock:
            st = self.loops.get(window.loop_id) or self._loop(window.loop_id)
            if st is None:
                return None
            d = result.diagnosis
            st.windows += 1
            st.missing_samples += result.n_missing
            st.last_verdict, st.last_tdnl, st.last_reason = d.verdict, d.tdnl, d.reason
            st.last_window = (window.start_t, window.end_t)
            recent = list(st.tracker.recent_tdnl)
            change = st.tracker.update(d.verdict, d.tdnl)
            if change is None:
                return None
            thr = window.analysis.diagnosis.decision_threshold
            if change == "raised":
                recent = list(st.tracker.recent_tdnl)
                evidence = (f"{st.tracker.nonlinear_streak} consecutive non-linear windows "
                            f"(TDNL {', '.join(f'{v:.3f}' for v in recent)} > {thr:g}): intra-wave frequency "
                            f"modulation of the {window.analysis.signal.upper()} oscillation"
                            + (f" (period {result.period_s:.1f} s, amplitude {result.amplitude:.3g})"
                               if math.isfinite(result.period_s) else "")
                            + "; a non-linear cause such as valve stiction is likely. Last window: " + d.reason)
                n = st.tracker.nonlinear_streak
            else:
                evidence = (f"{st.tracker.clean_streak} consecutive windows without a non-linear oscillation "
                            f"(last: {d.verdict}): {d.reason}")
                n = st.tracker.clean_streak
            return Alert(window.loop_id, change, d.verdict, d.tdnl, d.dnl, thr, result.period_s, result.amplitude,
                         window.analysis.signal, window.start_t, window.end_t, window.seq, n, evidence)

    def totals(self) -> dict[str, Any]:
        with self.lock:
            acc = sum(sum(st.buffer.accepted.values()) for st in self.loops.values())
            rej: Counter[str] = Counter(self.unrouted)
            for st in self.loops.values():
                rej.update(st.buffer.rejected)
            return {"loops": len(self.loops), "messages": self.messages, "samples_accepted": acc,
                    "rejected": dict(rej), "alerts_active": sum(st.tracker.active for st in self.loops.values())}

    def loop_status(self, loop_id: str) -> dict[str, Any]:
        with self.lock:
            st = self.loops[loop_id]
            b = st.buffer
            return {
                "state": "alert" if st.tracker.active else "ok",
                "last_verdict": st.last_verdict,
                "last_tdnl": json_number(st.last_tdnl),
                "last_reason": st.last_reason,
                "last_window": None if st.last_window is None else
                {"start_t": st.last_window[0], "end_t": st.last_window[1]},
                "sample_time_s": b.ts,
                "last_sample_t": b.last_time(),
                "windows": st.windows,
                "skipped_windows": b.skipped_windows,
                "missing_samples_in_windows": st.missing_samples,
                "samples": dict(b.accepted),
                "pending_samples": sum(int(v.size) for _, _, v, _ in b.pending),
                "rejected": dict(b.rejected),
            }

    def status(self, loop: str | None = None) -> dict[str, Any]:
        """Totals plus every loop (``loop=None``), one loop, or none (``loop=""``)."""
        with self.lock:
            ids = list(self.loops) if loop is None else ([loop] if loop in self.loops else [])
            return {"totals": self.totals(), "unrouted_rejects": dict(self.unrouted),
                    "loops": {i: self.loop_status(i) for i in ids}}


class _Latency:
    """Latency samples (seconds) kept in a bounded reservoir for percentiles."""

    def __init__(self, maxlen: int = 100_000) -> None:
        self.values: deque[float] = deque(maxlen=maxlen)
        self.max = 0.0
        self.count = 0

    def add(self, v: float) -> None:
        self.values.append(v)
        self.count += 1
        self.max = max(self.max, v)

    def summary(self) -> dict[str, float | int | None]:
        if not self.values:
            return {"count": 0, "p50": None, "p99": None, "max": None}
        a = np.fromiter(self.values, float)
        return {"count": self.count, "p50": float(np.percentile(a, 50)), "p99": float(np.percentile(a, 99)),
                "max": self.max}


def make_executor(workers: int) -> Executor:
    """``workers = 0``: one analysis thread; else a pool of worker processes (forkserver)."""
    if workers <= 0:
        return ThreadPoolExecutor(max_workers=1, thread_name_prefix="loopwatch-analysis")
    import multiprocessing

    ctx = multiprocessing.get_context("forkserver")
    ctx.set_forkserver_preload(["pipeline.diagnosis", "service.monitor"])
    return ProcessPoolExecutor(max_workers=workers, mp_context=ctx)


class Monitor:
    """The running monitor: feeds messages to the core, analyses closed windows on an executor, and
    applies the results in closing order (one collector thread), publishing to the sinks.

    Parameters
    ----------
    core : :class:`MonitorCore`.
    executor : where :func:`analyze_window` runs (see :func:`make_executor`).
    alert_sinks, window_sinks : :class:`~service.ports.AlertSink` / :class:`~service.ports.WindowSink`.
    instance : name of this monitor (in the status).
    clock : monotonic clock for latency statistics (window closed -> result applied).
    analyze : the window analysis (default :func:`analyze_window`; must be picklable for worker
        processes).
    """

    def __init__(self, core: MonitorCore, executor: Executor, *, alert_sinks: list[AlertSink] = (),
                 window_sinks: list[WindowSink] = (), instance: str = "main", clock: Clock = time.monotonic,
                 analyze: Callable[[WindowSamples], WindowResult] = analyze_window) -> None:
        self.core = core
        self.analyze = analyze
        self.executor = executor
        self.alert_sinks = list(alert_sinks)
        self.window_sinks = list(window_sinks)
        self.instance = instance
        self.clock = clock
        self.latency = _Latency()
        self.alerts_published = 0
        self.windows_done = 0
        self.errors = 0
        self._pending: queue.Queue = queue.Queue()
        self._in_flight = 0
        self._idle = threading.Condition()
        self._collector = threading.Thread(target=self._collect, name="loopwatch-collector", daemon=True)
        self._collector.start()

    def on_message(self, key: str, payload: bytes, encoding: str = "", attachment: bytes | None = None) -> None:
        """The :class:`~service.ports.MessageHandler`: ingest, then queue the closed windows."""
        windows = self.core.ingest(key, payload, encoding, attachment)
        if windows:
            now = self.clock()
            with self._idle:
                self._in_flight += len(windows)
            for w in windows:
                self._pending.put((w, self.executor.submit(self.analyze, w), now))

    def _collect(self) -> None:
        while True:
            item = self._pending.get()
            if item is None:
                return
            window, fut, closed_at = item
            try:
                result = fut.result()
            except Exception as exc:  # noqa: BLE001 - a failing window must not stop the monitor
                self.errors += 1
                log.error("analysis of %s window %d failed: %r", window.loop_id, window.seq, exc)
                result = WindowResult(WindowDiagnosis("invalid", f"analysis failed: {exc!r}"), math.nan, math.nan, 0)
            alert = self.core.apply(window, result)
            for sink in self.window_sinks:
                try:
                    sink.on_window(window.loop_id, window, result, alert)
                except Exception as exc:  # noqa: BLE001
                    self.errors += 1
                    log.error("window sink %r failed: %r", sink, exc)
            if alert is not None:
                for sink in self.alert_sinks:
                    try:
                        sink.publish(alert)
                    except Exception as exc:  # noqa: BLE001
                        self.errors += 1
                        log.error("alert sink %r failed: %r", sink, exc)
                self.alerts_published += 1
            self.latency.add(self.clock() - closed_at)
            self.windows_done += 1
            with self._idle:
                self._in_flight -= 1
                self._idle.notify_all()

    def drain(self, timeout: float | None = None) -> bool:
        """Wait until every closed window has been analysed and applied; False on timeout."""
        with self._idle:
            return self._idle.wait_for(lambda: self._in_flight == 0, timeout)

    def status(self, loop: str | None = None) -> dict[str, Any]:
        """The :class:`~service.ports.StatusProvider` answer: core status plus runtime figures."""
        s = self.core.status(loop)
        s["instance"] = self.instance
        s["runtime"] = {"windows_analysed": self.windows_done, "windows_queued": self._in_flight,
                        "alerts_published": self.alerts_published, "errors": self.errors,
                        "latency_s": self.latency.summary()}
        sinks = {}
        for sink in self._sinks():
            if isinstance(sink, SinkHealth):
                try:
                    sinks[sink.name] = sink.status()
                except Exception as exc:  # noqa: BLE001 - a sink's status must not break the monitor's
                    sinks[sink.name] = {"state": "error", "error": repr(exc)}
        if sinks:
            s["sinks"] = sinks
        return s

    def _sinks(self) -> list:
        """Every sink once (a sink may be both a window and an alert sink)."""
        seen, out = set(), []
        for sink in (*self.window_sinks, *self.alert_sinks):
            if id(sink) not in seen:
                seen.add(id(sink))
                out.append(sink)
        return out

    def close(self, timeout: float | None = 30.0) -> None:
        """Finish the queued windows, stop the collector and the executor, then close the sinks
        that hold resources (:class:`~service.ports.Closeable`), so recorders see every window."""
        self.drain(timeout)
        self._pending.put(None)
        self._collector.join(timeout)
        self.executor.shutdown(wait=True, cancel_futures=True)
        for sink in self._sinks():
            if isinstance(sink, Closeable):
                try:
                    sink.close()
                except Exception as exc:  # noqa: BLE001
                    self.errors += 1
                    log.error("closing sink %r failed: %r", sink, exc)
