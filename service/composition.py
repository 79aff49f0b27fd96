"""Composition root: settings -> monitor core, executor, zenoh adapters.  The only place that
knows which adapters implement which port."""

from __future__ import annotations

import logging
import time
from dataclasses import dataclass, field

from pipeline.diagnosis import DiagnosisConfig

from .monitor import AnalysisConfig, LoopConfig, Monitor, MonitorCore, make_executor
from .ports import AlertSink, WindowSink
from .settings import LoopSettings, MonitorSettings, WindowSettings

__all__ = ["loop_config_factory", "build_core", "build_recorder", "RunningMonitor", "start_monitor", "open_dashboard"]

log = logging.getLogger("loopwatch.composition")


def _diagnosis_config(settings: MonitorSettings) -> DiagnosisConfig:
    config = DiagnosisConfig(method=settings.analysis.method)
    t = settings.analysis.threshold
    return config if t is None else config.with_decision_threshold(t)


def _loop_config(settings: MonitorSettings, over: LoopSettings | None) -> LoopConfig:
    win: WindowSettings = (over.window if over and over.window else settings.window)
    signal = (over.signal if over and over.signal else settings.analysis.signal)
    ts = over.sample_time_s if over and over.sample_time_s else settings.sample_time_s
    length, length_s = win.length, win.length_s
    if length is None and length_s is None:
        length = 1024
    hop, hop_s = win.hop, win.hop_s
    if hop is None and hop_s is None:
        hop = max(1, (length or 1024) // 4) if length is not None else None
        hop_s = None if hop is not None else length_s / 4
    return LoopConfig(
        sample_time_s=ts, length=length, hop=hop, length_s=length_s, hop_s=hop_s, lateness=win.lateness,
        analysis=AnalysisConfig(signal=signal, diagnosis=_diagnosis_config(settings)),
    )


def loop_config_factory(settings: MonitorSettings):
    """``loop_id -> LoopConfig`` from the global settings and the per-loop overrides."""
    default = _loop_config(settings, None)
    overrides = {k: _loop_config(settings, v) for k, v in settings.loops.items()}
    return lambda loop_id: overrides.get(loop_id, default)


def build_core(settings: MonitorSettings, clock=time.monotonic) -> MonitorCore:
    """The pure monitor core configured from ``settings``."""
    return MonitorCore(
        prefix=settings.keys.prefix,
        loop_config=loop_config_factory(settings),
        raise_after=settings.alerts.raise_after,
        clear_after=settings.alerts.clear_after,
        time_range=(settings.ingest.time_min, settings.ingest.time_max),
        max_loops=settings.ingest.max_loops,
        clock=clock,
        max_logs_per_s=settings.ingest.max_logs_per_s,
    )


def build_recorder(settings: MonitorSettings):
    """The MCAP recorder of ``settings.recording`` (a window sink), or ``None`` when disabled.
    Recovers the instance's leftover ``.part`` files first; never raises for an unwritable
    directory (the recorder starts degraded and retries)."""
    rec = settings.recording
    if not rec.enabled:
        return None
    from adapters.mcap_recorder import McapRecorder

    run_config = {"instance": settings.instance,
                  "alerts": {"raise_after": settings.alerts.raise_after, "clear_after": settings.alerts.clear_after},
                  "settings": settings.model_dump(mode="json")}
    recorder = McapRecorder(rec.dir, instance=settings.instance, run_config=run_config,
                            rotate_bytes=rec.rotate_bytes, rotate_s=rec.rotate_s,
                            retention_bytes=rec.retention_bytes, retention_s=rec.retention_s,
                            flush_s=rec.flush_s, queue_max=rec.queue_windows)
    log.info("recording every analysed window to %s (%s)", rec.dir, recorder.state)
    return recorder


# --- rerun dashboard (issue 6) ---------------------------------------------------------------
def open_dashboard(settings: MonitorSettings, spec: str | None = None, announce=print):
    """The rerun dashboard sink for ``spec`` (default ``settings.rerun.spec``), or ``None`` when off.

    Pass it to :func:`start_monitor` as a window sink (it logs the alerts it is given with the
    windows) and close it after the monitor.
    """
    r = settings.rerun
    spec = spec or r.spec
    if not spec:
        return None
    from adapters.rerun_dashboard import open_rerun_sink

    return open_rerun_sink(spec, host=r.host, web_port=r.web_port, announce=announce, draw_per_s=r.draw_per_s,
                           explain_per_s=r.explain_per_s, overview_every_s=r.overview_every_s,
                           overview_rows=r.overview_rows, focus=r.focus)
# --- end rerun dashboard ----------------------------------------------------------------------


@dataclass
class RunningMonitor:
    """A started monitor and what it opened; :meth:`close` tears everything down in order."""

    settings: MonitorSettings
    monitor: Monitor
    session: object
    source: object
    status: object
    alert_sink: object
    extra: list = field(default_factory=list)

    def close(self) -> None:
        self.source.close()           # stop taking messages
        self.monitor.close()          # finish queued windows (alerts still go out), close the sinks (recorder)
        self.status.close()           # liveliness DELETE
        self.session.close()


def start_monitor(settings: MonitorSettings, *, alert_sinks: list[AlertSink] = (),
                  window_sinks: list[WindowSink] = ()) -> RunningMonitor:
    """Open the zenoh session and wire source -> monitor -> alert/status adapters.

    The worker pool is created before the session is opened, so worker processes never
    inherit zenoh's threads.
    """
    from adapters.zenoh_alerts import ZenohAlertSink
    from adapters.zenoh_session import open_session
    from adapters.zenoh_source import ZenohSampleSource
    from adapters.zenoh_status import ZenohStatus

    executor = make_executor(settings.analysis.workers)
    if settings.analysis.workers > 0:  # start the worker processes now (before zenoh opens)
        executor.submit(int, 0).result()
    z = settings.zenoh
    session = open_session(z.mode, listen=z.listen, connect=z.connect, gossip=z.gossip)
    alert_sink = ZenohAlertSink(session, settings.keys.alert_prefix, settings.instance)
    recorder = build_recorder(settings)
    monitor = Monitor(build_core(settings), executor, alert_sinks=[alert_sink, *alert_sinks],
                      window_sinks=[*([recorder] if recorder else []), *window_sinks], instance=settings.instance)
    status = ZenohStatus(session, settings.instance, monitor.status)
    source = ZenohSampleSource(session, settings.keys.prefix, monitor.on_message)
    log.info("monitor %s: %s on %s%s, samples %s/**, alerts %s/<loop>", settings.instance, z.mode,
             z.listen, f" -> {z.connect}" if z.connect else "", settings.keys.prefix, settings.keys.alert_prefix)
    return RunningMonitor(settings, monitor, session, source, status, alert_sink)
