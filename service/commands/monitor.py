"""``loopwatch monitor --config FILE``: run the always-on monitor until SIGINT / SIGTERM."""

from __future__ import annotations

import argparse
import logging
import signal
import threading
from pathlib import Path

from ..composition import open_dashboard, start_monitor
from ..settings import load_settings

log = logging.getLogger("loopwatch.monitor")


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--config", type=Path, default=None, metavar="FILE",
                   help="TOML settings (see deploy/monitor.toml); LOOPWATCH_* environment variables override")
    p.add_argument("--report-every", type=float, default=60.0, metavar="S",
                   help="log a one-line summary every S seconds of wall time (0: never; default 60)")
    p.add_argument("--rerun", default=None, metavar="SPEC",  # issue 6
                   help="rerun dashboard: save:PATH.rrd, serve[:[HOST:]PORT[:WEB_PORT]] (127.0.0.1 by default) "
                        "or connect:ADDR (default: [rerun] spec of the settings; off)")


def run(args: argparse.Namespace) -> int:
    settings = load_settings(args.config)
    stop = threading.Event()
    for sig in (signal.SIGINT, signal.SIGTERM):
        signal.signal(sig, lambda *_: stop.set())
    dashboard = open_dashboard(settings, args.rerun)  # issue 6: rerun sink, None when off
    try:
        running = start_monitor(settings, window_sinks=[dashboard] if dashboard else [])
    except BaseException:
        if dashboard is not None:
            dashboard.close()
        raise
    print(f"loopwatch monitor {settings.instance}: zenoh {settings.zenoh.mode} listen {settings.zenoh.listen} "
          f"connect {settings.zenoh.connect}; samples {settings.keys.prefix}/**, alerts "
          f"{settings.keys.alert_prefix}/<loop>, status loopwatch/{settings.instance}/status", flush=True)
    try:
        while not stop.wait(args.report_every if args.report_every > 0 else None):
            s = running.monitor.status(loop="")
            t, r = s["totals"], s["runtime"]
            log.warning("loops %d, samples %d, rejected %s, windows %d (queued %d), alerts active %d, "
                        "latency p99 %s s", t["loops"], t["samples_accepted"], t["rejected"], r["windows_analysed"],
                        r["windows_queued"], t["alerts_active"], r["latency_s"]["p99"])
    finally:
        running.close()
        if dashboard is not None:
            dashboard.close()
    return 0
