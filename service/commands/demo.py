"""``loopwatch demo``: a simulated plant and the monitor together, on the embedded zenoh default.

The monitor opens its embedded peer session (listening on 127.0.0.1, no router); the plant
simulator connects to it as a second session and publishes a mixed plant (stiction, tuning,
disturbance, deadband, healthy loops) at high speed.  A third party's view is taken at the
end: alerts received on ``loopwatch/alerts/**`` and the status queryable.  The final table
compares, per loop, the truth with the alert state; the exit status is 1 if any loop differs.
"""

from __future__ import annotations

import argparse
import json
import threading
import time
from pathlib import Path

from rich.console import Console
from rich.table import Table


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--loops", type=int, default=12, help="loops in the plant (default 12)")
    p.add_argument("--duration", type=float, default=6000.0, metavar="S", help="plant seconds (default 6000)")
    p.add_argument("--speed", type=float, default=60.0, metavar="X", help="times real time (default 60: ~100 s)")
    p.add_argument("--format", dest="fmt", choices=["single", "json", "binary"], default="binary")
    p.add_argument("--port", type=int, default=7447, help="the monitor's loopback port (default 7447)")
    p.add_argument("--seed", type=int, default=1)
    p.add_argument("--record", type=Path, default=Path("out/demo-mcap"), metavar="DIR",
                   help="MCAP recording of every analysed window (default out/demo-mcap; see `loopwatch replay`)")
    p.add_argument("--no-record", dest="record", action="store_const", const=None, help="do not record")
    p.add_argument("--rerun", default="save:out/demo.rrd", metavar="SPEC",  # issue 6
                   help="rerun dashboard: save:PATH.rrd (default save:out/demo.rrd), serve[:[HOST:]PORT[:WEB_PORT]], "
                        "connect:ADDR, or off")


def run(args: argparse.Namespace) -> int:
    import zenoh

    from adapters.zenoh_session import open_session

    from ..composition import open_dashboard, start_monitor
    from ..settings import load_settings
    from .simulate_plant import PlantPublisher, expects_alert, make_plant

    console = Console(width=150)
    endpoint = f"tcp/127.0.0.1:{args.port}"
    settings = load_settings(None, instance="demo", sample_time_s=1.0,
                             zenoh={"mode": "peer", "listen": [endpoint]}, analysis={"workers": 1},
                             recording={"enabled": args.record is not None, "dir": args.record or "recordings",
                                        "rotate_s": 600.0, "flush_s": 1.0})
    loops = make_plant(args.loops, duration_s=args.duration, seed=args.seed)
    truth = Table(title="simulated plant (truth)")
    for c in ("loop", "case", "truth", "expected alert"):
        truth.add_column(c)
    for lp in loops:
        truth.add_row(lp.loop_id, lp.case, lp.truth, "yes" if expects_alert(lp.truth) else "no")
    console.print(truth)

    dashboard = open_dashboard(settings, None if args.rerun == "off" else args.rerun,  # issue 6
                               announce=lambda m: console.print(m, markup=False, highlight=False))
    running = start_monitor(settings, window_sinks=[dashboard] if dashboard else [])
    plant = open_session("peer", connect=[endpoint])
    alerts: dict[str, list[dict]] = {}
    lock = threading.Lock()

    def on_alert(s: zenoh.Sample) -> None:
        a = json.loads(s.payload.to_bytes())
        with lock:
            alerts.setdefault(a["loop"], []).append(a)
        console.print(f"[bold]alert[/bold] {a['loop']}: {a['state']} (TDNL {a['tdnl']}, period {a['period_s']} s) "
                      f"window end t={a['window']['end_t']:.0f}")

    sub = plant.declare_subscriber(f"{settings.keys.alert_prefix}/**", on_alert)
    time.sleep(0.5)  # let the sessions connect and the subscriptions propagate
    pub = PlantPublisher(plant, loops, prefix=settings.keys.prefix, fmt=args.fmt, speed=args.speed)
    console.print(f"publishing {args.duration:g} plant seconds of {len(loops)} loops at {args.speed:g}x "
                  f"({args.duration / args.speed:.0f} s), format {args.fmt}")
    t = time.monotonic()
    try:
        pub.run()
        running.monitor.drain(60)
        time.sleep(0.5)
        replies = list(plant.get(f"loopwatch/{settings.instance}/status", timeout=5.0))
        status = json.loads(replies[0].ok.payload.to_bytes()) if replies and replies[0].ok else {"loops": {}}
        alive = [str(r.ok.key_expr) for r in plant.liveliness().get("loopwatch/*/alive", timeout=2.0) if r.ok]
    finally:
        sub.undeclare()
        running.close()
        plant.close()
        if dashboard is not None:
            dashboard.close()
    recording = running.monitor.status(loop="").get("sinks", {}).get("recording")

    table = Table(title=f"loopwatch demo: truth vs. alert state ({time.monotonic() - t:.0f} s)")
    for c in ("loop", "case", "truth", "expected", "alert (bus)", "status state", "last verdict", "TDNL",
              "windows", "rejected", "match"):
        table.add_column(c)
    mismatches = 0
    for lp in loops:
        st = status["loops"].get(lp.loop_id, {})
        received = alerts.get(lp.loop_id, [])
        bus_state = received[-1]["state"] if received else "none"
        active = bus_state == "raised"
        ok = active == expects_alert(lp.truth) and (st.get("state") == "alert") == active
        mismatches += not ok
        tdnl = st.get("last_tdnl")
        table.add_row(lp.loop_id, lp.case, lp.truth, "alert" if expects_alert(lp.truth) else "no alert",
                      bus_state, str(st.get("state")), str(st.get("last_verdict")),
                      "-" if tdnl is None else f"{tdnl:.3f}", str(st.get("windows")),
                      str(sum(st.get("rejected", {}).values())), "[green]yes[/green]" if ok else "[red]NO[/red]")
    console.print(table)
    tot = status.get("totals", {})
    console.print(f"published {pub.sent_samples} samples; monitor accepted {tot.get('samples_accepted')}, "
                  f"rejected {tot.get('rejected')}; liveliness: {alive}; "
                  f"{len(loops) - mismatches} of {len(loops)} loops match the truth")
    if recording:
        first = loops[0].loop_id
        # this run's file (the directory also keeps earlier demo runs, made by earlier code)
        rec = recording["last_file"] if recording.get("files_finished") == 1 and recording.get("last_file") \
            else args.record
        console.print(f"recorded {recording['windows_recorded']} windows ({recording['alerts_recorded']} alerts, "
                      f"recording {recording['state']}) to {rec}; replay them with\n"
                      f"  loopwatch replay {rec}            # re-run the pipeline, compare verdicts\n"
                      f"  loopwatch replay {rec} --loop {first} --all\n"
                      f"  loopwatch export {rec} --loop {first} --csv out/{first.replace('/', '_')}.csv\n"
                      f"  loopwatch replay {rec} --publish --speed 60 --connect tcp/127.0.0.1:7447   "
                      "# to a running monitor")
    if args.rerun.startswith("save:"):  # issue 6
        path = args.rerun[len("save:"):]
        from adapters.rerun_dashboard import web_viewer_url

        console.print(f"rerun recording of the demo: {path}\n  open it: .venv/bin/rerun {path}\n  or in a browser: "
                      f".venv/bin/rerun --serve-web --bind 127.0.0.1 {path}  then "
                      f"{web_viewer_url(9090, 'rerun+http://127.0.0.1:9876/proxy')}", markup=False, highlight=False)
    return 0 if mismatches == 0 else 1
