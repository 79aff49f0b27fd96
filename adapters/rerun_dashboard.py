"""Rerun dashboards: a :class:`~service.ports.WindowSink` / :class:`~service.ports.AlertSink` that draws
the plant and its loops in a rerun recording (file, served to a web viewer, or pushed to a viewer).

What is drawn (entity paths; one timeline ``time`` = the data's time stamps):

* ``plant/overview`` -- a markdown table, one row per loop (state, last verdict, TDNL, windows),
  most severe first; refreshed at most every ``overview_every_s`` seconds of wall time;
  ``plant/alerts`` -- every alert as a text log; ``plant/loops_in_alert`` -- a count over time.
* ``loops/{id}/signals/{op,pv,sp}`` -- the samples of the drawn windows, one ``send_columns``
  call per signal and window (only the part after what was drawn before: windows overlap);
* ``loops/{id}/dnl`` -- every window's TDNL, the verdict threshold and, for the robust method,
  the surrogates' 95th percentile (the DNL a linear loop would show): three series in one row,
  NaN where a window has no value (not oscillating);
* ``loops/{id}/phase`` -- OP (x) against PV (y) over the drawn window: the classic stiction
  picture (a parallelogram or ellipse with flat edges for a sticking valve, a tilted ellipse for a
  linear loop);
* ``loops/{id}/imfs/{imf1,...,band}``, ``loops/{id}/if/{name}/{if,if_z}`` -- for *explained*
  windows (:func:`pipeline.explain.explain_window`): the kept IMFs, the robust band-passed
  component, and the instantaneous frequency against the full-wave zero-crossing frequency;
* ``loops/{id}/alerts`` -- the loop's alerts as a text log.

Throttling (what is drawn, never what is analysed): every window updates the overview state and
logs its DNL row (cheap).  Signals and the phase plot are drawn for at most ``draw_per_s``
windows per wall second (token bucket), EMD is re-run for at most ``explain_per_s`` windows per
wall second (half of that budget is kept for windows that change a loop's alert state); windows
that change a loop's alert state are always drawn, windows of ``focus`` loops always drawn and
explained.  All of it runs on the caller's thread (the monitor's result collector).

:func:`open_rerun_sink` turns a spec into a sink: ``save:PATH.rrd``, ``serve[:[HOST:]PORT[:WEB_PORT]]``
(gRPC server and web viewer bound to 127.0.0.1 unless a host is given), ``connect:ADDR``.
"""

from __future__ import annotations

import logging
import math
import os
import subprocess
import threading
import time
import urllib.parse
from collections import Counter
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any, Callable, Iterable, Literal

import numpy as np

from pipeline.errors import PipelineError
from pipeline.explain import WindowDetails, explain_window

from .errors import AdapterError

if TYPE_CHECKING:  # the sink depends on the port's data types only, never on the monitor runtime
    from service.monitor import Alert, WindowResult, WindowSamples

__all__ = [
    "RerunSpecError",
    "RerunTarget",
    "parse_rerun_spec",
    "TokenBucket",
    "RerunDashboard",
    "dashboard_blueprint",
    "phase_curve",
    "open_rerun_sink",
    "start_web_viewer",
    "web_viewer_url",
]

log = logging.getLogger("loopwatch.rerun")

APPLICATION_ID = "loopwatch"
TIMELINE = "time"
DEFAULT_GRPC_PORT = 9876
DEFAULT_WEB_PORT = 9090
#: colours of the signals (RGB); tests look for PV's colour in the web viewer's screenshot
COLORS = {"pv": (31, 119, 180), "op": (255, 127, 14), "sp": (44, 160, 44), "tdnl": (214, 39, 40),
          "threshold": (127, 127, 127), "linear_95": (148, 103, 189), "if": (31, 119, 180),
          "if_z": (214, 39, 40), "phase": (31, 119, 180)}
_SIGNALS = ("op", "pv", "sp")
#: the three series of ``loops/{id}/dnl``, in column order (NaN where a window has none)
DNL_SERIES = ("tdnl", "threshold", "linear_95")
_SEVERITY = {"nonlinear": 4, "uncertain": 3, "linear": 2, "invalid": 1, "not_oscillating": 0}
_EXPLAINABLE = ("nonlinear", "uncertain", "linear")


class RerunSpecError(AdapterError, ValueError):
    """A ``--rerun`` spec cannot be understood; the message says what forms are accepted."""


_FORMS = "use save:PATH.rrd, serve, serve:PORT, serve:HOST:PORT, serve:PORT:WEB_PORT or connect:ADDR"


@dataclass(frozen=True)
class RerunTarget:
    """Where a recording goes: a file, a gRPC server (+ web viewer) of our own, or a viewer."""

    kind: Literal["save", "serve", "connect"]
    path: Path | None = None
    host: str = "127.0.0.1"
    grpc_port: int = DEFAULT_GRPC_PORT
    web_port: int = DEFAULT_WEB_PORT
    url: str | None = None

    @property
    def grpc_url(self) -> str:
        return self.url or f"rerun+http://{self.host}:{self.grpc_port}/proxy"


def _port(text: str, spec: str) -> int:
    if not text.isdigit() or not 0 <= int(text) <= 65535:
        raise RerunSpecError(f"--rerun {spec!r}: port {text!r} must be a number in 0..65535")
    return int(text)


def parse_rerun_spec(spec: str, *, host: str = "127.0.0.1", grpc_port: int = DEFAULT_GRPC_PORT,
                     web_port: int = DEFAULT_WEB_PORT) -> RerunTarget:
    """Parse a ``--rerun`` spec (see the module docstring); ``host``/ports are the defaults.

    ``serve:PORT:0`` serves gRPC only (no web viewer).  ``connect:ADDR`` takes a
    ``rerun+http://HOST:PORT/proxy`` URL, ``HOST:PORT`` or ``PORT`` (on 127.0.0.1).

    Raises
    ------
    RerunSpecError
        one line naming the bad spec and the accepted forms.
    """
    kind, _, arg = (spec or "").strip().partition(":")
    if kind == "save":
        if not arg:
            raise RerunSpecError(f"--rerun {spec!r}: save needs a file, e.g. save:out/demo.rrd")
        if not arg.endswith(".rrd"):
            raise RerunSpecError(f"--rerun {spec!r}: the recording file must end in .rrd (rerun opens it by suffix)")
        return RerunTarget("save", path=Path(arg))
    if kind == "serve":
        parts = arg.split(":") if arg else []
        if parts and not parts[0].isdigit():
            host, parts = parts[0], parts[1:]
            if not host:
                raise RerunSpecError(f"--rerun {spec!r}: empty host; {_FORMS}")
        if len(parts) > 2:
            raise RerunSpecError(f"--rerun {spec!r}: too many fields; {_FORMS}")
        if parts:
            grpc_port = _port(parts[0], spec)
        if len(parts) == 2:
            web_port = _port(parts[1], spec)
        if grpc_port == 0 or (web_port and web_port == grpc_port):
            raise RerunSpecError(f"--rerun {spec!r}: the gRPC port must be > 0 and differ from the web viewer's")
        return RerunTarget("serve", host=host, grpc_port=grpc_port, web_port=web_port)
    if kind == "connect":
        if not arg:
            raise RerunSpecError(f"--rerun {spec!r}: connect needs an address, e.g. connect:127.0.0.1:9876")
        if arg.startswith(("rerun://", "rerun+http://", "rerun+https://")):
            if not urllib.parse.urlparse(arg).path.endswith("/proxy"):
                raise RerunSpecError(f"--rerun {spec!r}: a viewer URL ends in /proxy, e.g. rerun+http://127.0.0.1:9876/proxy")
            return RerunTarget("connect", url=arg)
        h, _, p = arg.rpartition(":")
        port = _port(p, spec)
        return RerunTarget("connect", host=h or "127.0.0.1", grpc_port=port,
                           url=f"rerun+http://{h or '127.0.0.1'}:{port}/proxy")
    raise RerunSpecError(f"--rerun {spec!r}: unknown form; {_FORMS}")


class TokenBucket:
    """At most ``rate`` takes per second on average, ``burst`` at once; ``clock`` is injected."""

    def __init__(self, rate: float, burst: float, clock: Callable[[], float]) -> None:
        if not (rate >= 0 and burst >= 1):
            raise RerunSpecError(f"rate={rate!r} must be >= 0 and burst={burst!r} >= 1")
        self.rate, self.burst, self.clock = float(rate), float(burst), clock
        self.tokens = float(burst)
        self.last = clock()

    def take(self, reserve: float = 0.0) -> bool:
        """Take a token if one is left above ``reserve`` (tokens kept for more important takers)."""
        now = self.clock()
        if math.isinf(self.rate):
            return True
        self.tokens = min(self.burst, self.tokens + (now - self.last) * self.rate)
        self.last = now
        if self.tokens >= 1.0 + reserve:
            self.tokens -= 1.0
            return True
        return False


# ---------------------------------------------------------------------------------------- layout


def dashboard_blueprint(loop_id: str | None, *, window_s: float | None = None):
    """Plant overview and alerts on the left, one loop's drill-down on the right.

    ``window_s`` (the window length in seconds) limits the time-series views to the last two
    windows before the time cursor; ``None`` shows the whole timeline.
    """
    import rerun.blueprint as rrb

    whole = rrb.TimeAxis(view_range=rrb.TimeRange(start=rrb.TimeRangeBoundary.infinite(),
                                                  end=rrb.TimeRangeBoundary.cursor_relative()))
    overview = rrb.Vertical(
        rrb.TextDocumentView(origin="/plant/overview", name="plant overview (most severe first)"),
        rrb.TimeSeriesView(origin="/plant/loops_in_alert", name="loops in alert", axis_x=whole),
        rrb.TextLogView(origin="/plant/alerts", name="alerts"),
        row_shares=[5, 1, 2],
    )
    time_panel = rrb.TimePanel(timeline=TIMELINE, play_state="following", state="collapsed")
    if loop_id is None:
        return rrb.Blueprint(overview, time_panel, collapse_panels=True)
    base = f"/loops/{loop_id}"
    ranges, recent = None, whole
    if window_s:  # query two windows, show the last one, before the time cursor
        ranges = rrb.VisibleTimeRange(TIMELINE, start=rrb.TimeRangeBoundary.cursor_relative(seconds=-2.0 * window_s),
                                      end=rrb.TimeRangeBoundary.cursor_relative())
        recent = rrb.TimeAxis(view_range=rrb.TimeRange(start=rrb.TimeRangeBoundary.cursor_relative(seconds=-window_s),
                                                       end=rrb.TimeRangeBoundary.cursor_relative()))
    drill = rrb.Vertical(
        rrb.TimeSeriesView(origin=f"{base}/signals", name=f"{loop_id}: OP, PV, SP", time_ranges=ranges, axis_x=recent),
        rrb.Horizontal(
            rrb.TimeSeriesView(origin=f"{base}/dnl", name=f"{loop_id}: TDNL vs threshold", axis_x=whole),
            rrb.Spatial2DView(origin=f"{base}/phase", name=f"{loop_id}: phase plot, OP (x) vs PV (y), normalised"),
            column_shares=[3, 2],
        ),
        rrb.TimeSeriesView(origin=f"{base}/imfs", name=f"{loop_id}: IMFs kept / band component",
                           time_ranges=ranges, axis_x=recent),
        rrb.TimeSeriesView(origin=f"{base}/if", name=f"{loop_id}: IF vs IF_z (Hz)", time_ranges=ranges, axis_x=recent),
        rrb.TextLogView(origin=f"{base}/alerts", name=f"{loop_id}: alerts"),
        row_shares=[3, 3, 2, 2, 2],
    )
    return rrb.Blueprint(rrb.Horizontal(overview, drill, column_shares=[2, 3]), time_panel, collapse_panels=True)


# ------------------------------------------------------------------------------------------ sink


@dataclass
class _LoopView:
    state: str = "ok"
    verdict: str = "-"
    tdnl: float = math.nan
    windows: int = 0
    alerts: int = 0
    last_end: float = math.nan
    drawn_end: float = -math.inf
    explained_end: float = -math.inf
    styled: bool = False
    explained_names: set[str] = field(default_factory=set)
    last_alert: tuple | None = None


def phase_curve(op: np.ndarray, pv: np.ndarray) -> np.ndarray:
    """OP-PV points for the phase plot: each signal scaled to [-1, 1] over the window (a 2-D
    view keeps the aspect ratio, and OP and PV rarely share a range), y = -PV because image
    coordinates point down, so that up is a higher PV."""
    def unit(v: np.ndarray) -> np.ndarray:
        lo, hi = float(v.min()), float(v.max())
        return np.zeros_like(v) if hi <= lo else (2.0 * (v - lo) / (hi - lo) - 1.0)

    return np.c_[unit(op), -unit(pv)].astype(np.float32)


def _ts(t: np.ndarray) -> Any:
    import rerun as rr

    return [rr.TimeColumn(TIMELINE, timestamp=np.asarray(t, dtype=np.float64))]


def _fmt(v: float, spec: str = ".3f") -> str:
    return "-" if v is None or not math.isfinite(v) else format(v, spec)


def _iso(t: float) -> str:
    if not math.isfinite(t):
        return "-"
    return time.strftime("%Y-%m-%d %H:%M:%S", time.gmtime(t))


class RerunDashboard:
    """The sink (see the module docstring).

    Parameters
    ----------
    rec : an open ``rerun.RecordingStream`` (its sinks set by the caller, see :func:`open_rerun_sink`).
    draw_per_s, draw_burst : windows whose signals and phase plot are drawn per wall second.
    explain_per_s, explain_burst : windows re-decomposed (EMD, IF, IF_z) per wall second.
    overview_every_s : wall seconds between refreshes of the plant overview.
    overview_rows : loops listed in the overview (the most severe; the counts cover all).
    focus : loops always drawn and explained; the first one is the blueprint's drill-down
        (else the first loop that raises an alert, else the first loop seen).
    clock : monotonic wall clock in seconds (injected; only used for throttling).
    offline : for recordings rendered after the fact (``loopwatch replay``): no wall-clock
        throttle; every window is drawn, and a window is explained when it raises or clears an
        alert or starts after the last explained window of its loop (each stretch of data is
        decomposed once).
    on_close : called after the recording is flushed and disconnected (e.g. stop a web viewer).
    """

    def __init__(self, rec, *, draw_per_s: float = 50.0, draw_burst: float = 100.0, explain_per_s: float = 2.0,
                 explain_burst: float = 10.0, overview_every_s: float = 2.0, overview_rows: int = 50,
                 focus: Iterable[str] = (), clock: Callable[[], float] = time.monotonic,
                 send_blueprint: bool = True, on_close: Callable[[], None] | None = None,
                 offline: bool = False) -> None:
        self.rec = rec
        self.offline = offline
        self.clock = clock
        self.draw_bucket = TokenBucket(draw_per_s, draw_burst, clock)
        self.explain_bucket = TokenBucket(explain_per_s, explain_burst, clock)
        self.overview_every_s = float(overview_every_s)
        self.overview_rows = int(overview_rows)
        self.focus = list(focus)
        self._focus_set = set(self.focus)
        self.loops: dict[str, _LoopView] = {}
        self.stats: Counter[str] = Counter()
        self.latest_t = -math.inf
        self.drill_loop: str | None = None
        self._drill_fixed = bool(self.focus)
        self._send_blueprint = send_blueprint
        self._window_s: float | None = None
        self._last_refresh = -math.inf
        self._dirty = False
        self._lock = threading.RLock()
        self._on_close = on_close
        self._closed = False
        self._static_done = False

    # ------------------------------------------------------------------ ports
    def on_window(self, loop_id: str, window: "WindowSamples", result: "WindowResult",
                  alert: "Alert | None") -> None:
        """The :class:`~service.ports.WindowSink`: update the loop's row, log its DNL, draw if due."""
        import rerun as rr

        with self._lock:
            self._static()
            st = self.loops.get(loop_id)
            if st is None:
                st = self.loops[loop_id] = _LoopView()
            d = result.diagnosis
            st.windows += 1
            st.verdict, st.tdnl, st.last_end = d.verdict, d.tdnl, window.end_t
            self.latest_t = max(self.latest_t, window.end_t)
            self.stats["windows"] += 1
            self._dirty = True
            if self._window_s is None:
                self._window_s = window.t.size * window.sample_time_s
            # one row of three series per window (one chunk: a single-row chunk costs ~1.3 kB in a file)
            thr = window.analysis.diagnosis.decision_threshold
            lin95 = d.robust.threshold if d.robust is not None else math.nan
            self.rec.send_columns(f"loops/{loop_id}/dnl", indexes=_ts([window.end_t]),
                                  columns=rr.Scalars.columns(scalars=np.array([[d.tdnl, thr, lin95]])))
            if alert is not None:
                self._log_alert(alert)
            if self.drill_loop is None or (alert is not None and alert.state == "raised" and not self._drill_fixed):
                self._set_drill(self.focus[0] if self.focus else loop_id, fixed=alert is not None)
            focus = loop_id in self._focus_set
            priority = alert is not None or focus
            # EMD is the expensive part: only focus loops bypass its budget; an alert's window may use
            # the whole budget, other windows only what is above half of it
            if self.offline:
                explain = d.verdict in _EXPLAINABLE and (priority or window.start_t > st.explained_end)
            else:
                explain = d.verdict in _EXPLAINABLE and (focus or self.explain_bucket.take(
                    reserve=0.0 if alert is not None else self.explain_bucket.burst / 2))
            if explain or priority or self.offline or self.draw_bucket.take():
                self._draw(loop_id, st, window)
                if explain:
                    self._explain(loop_id, st, window, result)
            else:
                self.stats["draw_skipped"] += 1
            if self.clock() - self._last_refresh >= self.overview_every_s:
                self.refresh()

    def publish(self, alert: "Alert") -> None:
        """The :class:`~service.ports.AlertSink`: log the alert unless :meth:`on_window` already did."""
        with self._lock:
            self._static()
            self._log_alert(alert)

    def status(self) -> dict[str, Any]:
        """Counters: windows seen, drawn, explained, skipped, alerts logged, explain errors."""
        with self._lock:
            return {"loops": len(self.loops), **dict(self.stats)}

    def close(self) -> None:
        """Refresh the overview, flush and disconnect the recording; idempotent."""
        with self._lock:
            if self._closed:
                return
            self._closed = True
            self.refresh(force=True)
            self.rec.flush()
            self.rec.disconnect()
        if self._on_close is not None:
            self._on_close()

    # ------------------------------------------------------------------ drawing
    def _static(self) -> None:
        if self._static_done:
            return
        import rerun as rr

        self._static_done = True
        self.rec.log("plant/loops_in_alert", rr.SeriesLines(colors=[COLORS["tdnl"]], names="loops in alert"),
                     static=True)

    def _set_drill(self, loop_id: str, *, fixed: bool) -> None:
        self._drill_fixed = self._drill_fixed or fixed
        if loop_id == self.drill_loop:
            return
        self.drill_loop = loop_id
        if self._send_blueprint:
            self.rec.send_blueprint(dashboard_blueprint(loop_id, window_s=self._window_s), make_active=True,
                                    make_default=True)

    def _style(self, loop_id: str, st: _LoopView) -> None:
        """Names and colours of a loop's series (static); the archetypes are built once."""
        import rerun as rr

        if not hasattr(self, "_styles"):
            self._styles = [(f"signals/{sig}", rr.SeriesLines(colors=[COLORS[sig]], names=sig.upper())) for sig in _SIGNALS]
            self._styles.append(("dnl", rr.SeriesLines(colors=[COLORS[k] for k in DNL_SERIES],
                                                        names=["TDNL", "threshold", "linear 95 %"])))
        st.styled = True
        for sub, style in self._styles:
            self.rec.log(f"loops/{loop_id}/{sub}", style, static=True)

    def _draw(self, loop_id: str, st: _LoopView, window: "WindowSamples") -> None:
        import rerun as rr

        if not st.styled:
            self._style(loop_id, st)
        base = f"loops/{loop_id}"
        new = window.t > st.drawn_end
        for sig in _SIGNALS:
            v = window.signals.get(sig)
            if v is None:
                continue
            ok = new & np.isfinite(v)
            if ok.any():
                self.rec.send_columns(f"{base}/signals/{sig}", indexes=_ts(window.t[ok]),
                                      columns=rr.Scalars.columns(scalars=v[ok]))
        op, pv = window.signals.get("op"), window.signals.get("pv")
        if op is not None and pv is not None:
            ok = np.isfinite(op) & np.isfinite(pv)
            if np.count_nonzero(ok) >= 2:
                self._log_at(window.end_t, f"{base}/phase",
                             rr.LineStrips2D([phase_curve(op[ok], pv[ok])], colors=[COLORS["phase"]], radii=-0.75))
        st.drawn_end = max(st.drawn_end, window.end_t)
        self.stats["drawn"] += 1

    def _explain(self, loop_id: str, st: _LoopView, window: "WindowSamples", result: "WindowResult") -> None:
        import rerun as rr

        try:
            det: WindowDetails = explain_window(window.series(), fs=1.0 / window.sample_time_s,
                                                config=window.analysis.diagnosis, period_s=result.period_s)
        except PipelineError as exc:
            self.stats["explain_errors"] += 1
            log.debug("loop %s window %d not explained: %s", loop_id, window.seq, exc)
            return
        base = f"loops/{loop_id}"
        new = window.t > st.explained_end
        if not new.any():
            return
        t = window.t[new]
        series = [(f"imf{n}", c) for n, c in zip(det.imf_numbers, det.imfs)]
        if det.method == "robust":
            series += list(zip(det.component_names, det.components))
        for name, c in series:
            if name not in st.explained_names:
                st.explained_names.add(name)
                self.rec.log(f"{base}/imfs/{name}", rr.SeriesLines(names=name), static=True)
                if name in det.component_names:
                    for part, label in (("if", f"IF {name}"), ("if_z", f"IF_z {name}")):
                        self.rec.log(f"{base}/if/{name}/{part}", rr.SeriesLines(colors=[COLORS[part]], names=label),
                                     static=True)
            self.rec.send_columns(f"{base}/imfs/{name}", indexes=_ts(t), columns=rr.Scalars.columns(scalars=c[new]))
        for i, name in enumerate(det.component_names):
            for part, arr in (("if", det.inst_freq[i]), ("if_z", det.if_z[i])):
                ok = np.isfinite(arr[new])
                if ok.any():
                    self.rec.send_columns(f"{base}/if/{name}/{part}", indexes=_ts(t[ok]),
                                          columns=rr.Scalars.columns(scalars=arr[new][ok]))
        st.explained_end = window.end_t
        self.stats["explained"] += 1

    def _log_at(self, t: float, path: str, archetype) -> None:
        self.rec.set_time(TIMELINE, timestamp=t)
        self.rec.log(path, archetype)
        self.rec.reset_time()

    def _log_alert(self, alert: "Alert") -> None:
        import rerun as rr

        st = self.loops.get(alert.loop_id)
        if st is None:
            st = self.loops[alert.loop_id] = _LoopView()
        key = (alert.window_seq, alert.state)
        if st.last_alert == key:
            return
        st.last_alert = key
        st.state = "alert" if alert.state == "raised" else "ok"
        st.alerts += alert.state == "raised"
        self._dirty = True
        text = (f"{alert.loop_id}: alert {alert.state.upper()} - {alert.verdict}, TDNL {_fmt(alert.tdnl)} "
                f"(threshold {alert.threshold:g}), period {_fmt(alert.period_s, '.1f')} s, amplitude "
                f"{_fmt(alert.amplitude, '.3g')}, window {alert.window_seq} ending {_iso(alert.window_end_t)} UTC. "
                f"{alert.evidence}")
        level = rr.TextLogLevel.WARN if alert.state == "raised" else rr.TextLogLevel.INFO
        for path in (f"loops/{alert.loop_id}/alerts", "plant/alerts"):
            self.rec.send_columns(path, indexes=_ts([alert.window_end_t]),
                                  columns=rr.TextLog.columns(text=[text], level=[level]))
        self.stats["alerts"] += 1

    def overview_markdown(self) -> str:
        """The plant overview: counts, then the ``overview_rows`` most severe loops."""
        with self._lock:
            rows = sorted(self.loops.items(), key=lambda kv: (kv[1].state != "alert", -_SEVERITY.get(kv[1].verdict, -1),
                                                               -(kv[1].tdnl if math.isfinite(kv[1].tdnl) else -1.0),
                                                               kv[0]))
            n_alert = sum(st.state == "alert" for st in self.loops.values())
            verdicts = Counter(st.verdict for st in self.loops.values())
            head = (f"**{len(self.loops)} loops, {n_alert} in alert** - last verdicts: "
                    + ", ".join(f"{k} {v}" for k, v in sorted(verdicts.items(), key=lambda kv: -_SEVERITY.get(kv[0], -1)))
                    + f" - data time {_iso(self.latest_t)} UTC\n\n")
            lines = ["| # | loop | state | last verdict | TDNL | windows | alerts | last window end (UTC) |",
                     "|---|---|---|---|---|---|---|---|"]
            for i, (loop_id, st) in enumerate(rows[: self.overview_rows], 1):
                state = "**ALERT**" if st.state == "alert" else "ok"
                lines.append(f"| {i} | {loop_id} | {state} | {st.verdict} | {_fmt(st.tdnl)} | {st.windows} | "
                             f"{st.alerts} | {_iso(st.last_end)} |")
            more = len(rows) - self.overview_rows
            tail = f"\n\n... and {more} more loop(s), less severe" if more > 0 else ""
            return head + "\n".join(lines) + tail

    def refresh(self, force: bool = False) -> None:
        """Log the overview (and the alert count) at the newest data time, if anything changed."""
        import rerun as rr

        with self._lock:
            self._last_refresh = self.clock()
            if not (self._dirty or force) or not math.isfinite(self.latest_t):
                return
            self._dirty = False
            self._log_at(self.latest_t, "plant/overview", rr.TextDocument(self.overview_markdown(),
                                                                          media_type=rr.MediaType.MARKDOWN))
            n_alert = sum(st.state == "alert" for st in self.loops.values())
            self.rec.send_columns("plant/loops_in_alert", indexes=_ts([self.latest_t]),
                                  columns=rr.Scalars.columns(scalars=[float(n_alert)]))
            self.stats["overview_refreshes"] += 1


# ------------------------------------------------------------------------------------- opening


def web_viewer_url(web_port: int, grpc_url: str, host: str = "127.0.0.1") -> str:
    """The address that opens rerun's web viewer on ``grpc_url``."""
    return f"http://{host}:{web_port}/?url={urllib.parse.quote(grpc_url, safe='')}"


def _rerun_cli() -> str:
    """The rerun viewer binary shipped in the rerun-sdk wheel (not the ``rerun`` entry-point script,
    which runs it as a child process that a terminate would leave behind)."""
    try:
        import rerun_cli

        exe = Path(rerun_cli.__file__).with_name("rerun")
        if exe.is_file():
            return str(exe)
    except ImportError:
        pass
    raise AdapterError("the rerun viewer binary (package rerun_cli of rerun-sdk) is missing: cannot serve the web viewer")


def _die_with_parent() -> None:
    """In the viewer's child process (Linux): SIGTERM when loopwatch dies, even by SIGKILL, so
    that no viewer is left holding the port."""
    try:
        import ctypes
        import signal

        ctypes.CDLL("libc.so.6", use_errno=True).prctl(1, signal.SIGTERM)  # PR_SET_PDEATHSIG
    except (OSError, AttributeError):
        pass


def start_web_viewer(source: str, *, host: str = "127.0.0.1", web_port: int = DEFAULT_WEB_PORT,
                     grpc_port: int | None = None, timeout_s: float = 20.0) -> subprocess.Popen:
    """Serve rerun's web viewer on ``host:web_port`` with the ``rerun`` CLI (bound to ``host``
    only: ``rerun.serve_web_viewer`` always binds 0.0.0.0).

    ``source`` is a gRPC URL (the viewer connects to it) or an ``.rrd`` file, which the CLI then
    also serves over gRPC on ``host:grpc_port``.  Returns once the web port accepts connections.
    """
    import socket

    with socket.socket() as probe:  # a viewer left running on the port would be mistaken for ours
        try:
            probe.bind((host, web_port))
        except OSError as exc:
            raise AdapterError(f"cannot serve the rerun web viewer on {host}:{web_port}: {exc.strerror}") from None
    cmd = [_rerun_cli(), "--serve-web", "--bind", host, "--web-viewer-port", str(web_port)]
    if grpc_port is not None:
        cmd += ["--port", str(grpc_port)]
    proc = subprocess.Popen([*cmd, source], stdout=subprocess.DEVNULL, stderr=subprocess.PIPE,
                            env={**os.environ, "RUST_LOG": "warn"}, preexec_fn=_die_with_parent)
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        if proc.poll() is not None:
            err = proc.stderr.read().decode(errors="replace").strip().splitlines()
            raise AdapterError(f"rerun web viewer exited ({proc.returncode}): {err[-1] if err else 'no output'}")
        try:
            with socket.create_connection((host, web_port), timeout=0.5):
                return proc
        except OSError:
            time.sleep(0.1)
    proc.terminate()
    raise AdapterError(f"rerun web viewer did not listen on {host}:{web_port} within {timeout_s:g} s")


def _stop(proc: subprocess.Popen) -> None:
    if proc.poll() is None:
        proc.terminate()
        try:
            proc.wait(5)
        except subprocess.TimeoutExpired:
            proc.kill()


def open_rerun_sink(spec: str, *, host: str = "127.0.0.1", grpc_port: int = DEFAULT_GRPC_PORT,
                    web_port: int = DEFAULT_WEB_PORT, recording_id: str | None = None,
                    announce: Callable[[str], None] | None = print, **options) -> RerunDashboard:
    """Open a rerun recording for ``spec`` (see :func:`parse_rerun_spec`) and return its sink.

    ``options`` go to :class:`RerunDashboard` (throttling, focus loops, clock).  ``announce``
    receives one line saying where the recording goes and how to open it.
    """
    import rerun as rr

    target = parse_rerun_spec(spec, host=host, grpc_port=grpc_port, web_port=web_port)
    rec = rr.RecordingStream(APPLICATION_ID, recording_id=recording_id)
    blueprint = dashboard_blueprint(options["focus"][0] if options.get("focus") else None)
    on_close = None
    if target.kind == "save":
        target.path.parent.mkdir(parents=True, exist_ok=True)
        rec.save(target.path, default_blueprint=blueprint)
        msg = f"rerun: recording to {target.path}; open it with `rerun {target.path}` (or the web viewer: `rerun --serve-web --bind 127.0.0.1 {target.path}`)"
    elif target.kind == "serve":
        rec.set_sinks(rr.GrpcServerSink(bind_ip=target.host, port=target.grpc_port), default_blueprint=blueprint)
        msg = f"rerun: serving gRPC on {target.grpc_url} (viewer: `rerun {target.grpc_url}`)"
        if target.web_port:
            try:
                proc = start_web_viewer(target.grpc_url, host=target.host, web_port=target.web_port)
            except AdapterError:
                rec.disconnect()
                raise
            on_close = lambda: _stop(proc)  # noqa: E731
            msg += f"; web viewer at {web_viewer_url(target.web_port, target.grpc_url, target.host)}"
    else:
        rec.connect_grpc(target.grpc_url, default_blueprint=blueprint)
        msg = f"rerun: sending to the viewer at {target.grpc_url}"
    if announce is not None:
        announce(msg)
    return RerunDashboard(rec, on_close=on_close, **options)
