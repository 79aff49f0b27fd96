"""``loopwatch replay FILE_OR_DIR``: re-run the pipeline on recorded windows, or re-publish them.

Default: every recorded window (optionally of ``--loop`` and between ``--from`` and ``--to``) is
analysed again with the configuration it was recorded with, and the alert hysteresis re-run;
the report gives, per window, the recorded and the recomputed verdict and figures, and whether
they are equal bit for bit.  Exit status 1 when any window differs.

``--publish``: instead, the recorded raw samples are put back on zenoh at their original time
stamps, paced at ``--speed`` times real time, so that a running monitor sees the incident again.
"""

from __future__ import annotations

import argparse
import json
import math
import time
from datetime import datetime, timezone
from pathlib import Path

from rich.console import Console
from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn, TimeRemainingColumn
from rich.table import Table

from adapters.payloads import json_number

from ..errors import UsageError


def parse_time(text: str) -> float:
    """Unix seconds, or an ISO 8601 date-time (UTC unless it has an offset)."""
    try:
        return float(text)
    except ValueError:
        pass
    try:
        dt = datetime.fromisoformat(text)
    except ValueError:
        raise UsageError(f"time {text!r}: give Unix seconds or an ISO 8601 time such as 2025-06-15T03:00:00Z") from None
    if dt.tzinfo is None:
        dt = dt.replace(tzinfo=timezone.utc)
    return dt.timestamp()


def add_selection(p: argparse.ArgumentParser) -> None:
    p.add_argument("--loop", action="append", default=None, metavar="ID", help="only this loop (repeatable)")
    p.add_argument("--from", dest="t_from", type=parse_time, default=None, metavar="T",
                   help="only windows ending at or after T (Unix s or ISO 8601, UTC by default)")
    p.add_argument("--to", dest="t_to", type=parse_time, default=None, metavar="T",
                   help="only windows ending at or before T")


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("paths", nargs="+", type=Path, metavar="FILE_OR_DIR", help="recording files or directories")
    add_selection(p)
    p.add_argument("--json", type=Path, default=None, metavar="OUT", help="write the per-window report as JSON")
    p.add_argument("--all", action="store_true", help="list every window (default: only those that differ)")
    p.add_argument("--rerun", default=None, metavar="SPEC",
                   help="also render the replayed windows as a rerun dashboard: save:OUT.rrd, serve[:PORT], "
                        "connect:ADDR (every window drawn)")
    p.add_argument("--publish", action="store_true",
                   help="re-publish the recorded raw samples over zenoh instead of re-analysing")
    p.add_argument("--speed", type=float, default=1.0, metavar="X",
                   help="--publish: times real time (default 1; inf = as fast as possible)")
    p.add_argument("--connect", action="append", default=None, metavar="ENDPOINT",
                   help="--publish: zenoh endpoint (default tcp/127.0.0.1:7447, the monitor's default)")
    p.add_argument("--mode", choices=["peer", "client"], default="peer", help="--publish: zenoh mode")
    p.add_argument("--prefix", default=None,
                   help="--publish: key prefix (default: the recorded monitor's, else 'plant')")


def _progress(console: Console) -> Progress:
    return Progress(TextColumn("{task.description}"), BarColumn(), MofNCompleteColumn(), TimeRemainingColumn(),
                    console=console, transient=True)


def _figures(result) -> dict:
    d = result.diagnosis
    return {"verdict": d.verdict, "tdnl": json_number(d.tdnl), "dnl": [json_number(v) for v in d.dnl],
            "imfs_kept": list(d.imfs_kept),
            "period_s": json_number(result.period_s), "reason": d.reason}


def run(args: argparse.Namespace) -> int:
    from adapters.mcap_reader import count_windows

    if args.t_from is not None and args.t_to is not None and args.t_to < args.t_from:
        raise UsageError(f"--to ({args.t_to}) is before --from ({args.t_from})")
    if not args.speed > 0:
        raise UsageError(f"--speed {args.speed}: must be > 0")
    console = Console()
    err = Console(stderr=True)
    total = count_windows(args.paths, args.loop) if args.t_from is None and args.t_to is None else None
    if args.publish:
        if args.rerun:
            raise UsageError("--rerun renders the recomputed windows; it cannot be combined with --publish")
        return _publish(args, console, err, total)
    from ..replay import replay_windows

    sinks = []
    if args.rerun:
        from adapters.rerun_dashboard import open_rerun_sink

        sinks.append(open_rerun_sink(args.rerun, offline=True,
                                     announce=lambda m: err.print(m, markup=False, highlight=False)))

    rows, per_loop = [], {}
    t = time.monotonic()
    try:
        with _progress(err) as progress:
            task = progress.add_task("replaying windows", total=total)
            for r in replay_windows(args.paths, loops=args.loop, t_from=args.t_from, t_to=args.t_to,
                                    sinks=sinks):
                w = r.window
                rows.append({"loop": w.loop_id, "seq": w.seq, "start_t": w.start_t, "end_t": w.end_t,
                             "source": r.recorded.source, "recorded": _figures(r.recorded.result),
                             "recomputed": _figures(r.result), "same_result": r.same_result,
                             "recorded_alert": r.recorded.alert.state if r.recorded.alert else None,
                             "recomputed_alert": r.alert.state if r.alert else None, "same_alert": r.same_alert})
                s = per_loop.setdefault(w.loop_id, {"windows": 0, "same": 0, "alerts_recorded": 0, "alerts_recomputed": 0})
                s["windows"] += 1
                s["same"] += r.same_result and r.same_alert
                s["alerts_recorded"] += r.recorded.alert is not None
                s["alerts_recomputed"] += r.alert is not None
                progress.advance(task)
    finally:
        for sink in sinks:
            sink.close()
    elapsed = time.monotonic() - t
    differ = [x for x in rows if not (x["same_result"] and x["same_alert"])]
    shown = rows if args.all else differ
    if shown:
        table = Table(title="windows" if args.all else "windows whose replay differs from the recording")
        for c in ("loop", "seq", "end t", "recorded", "recomputed", "TDNL rec.", "TDNL recomp.", "alert rec./recomp.",
                  "same"):
            table.add_column(c)
        f = lambda v: "-" if v is None else f"{v:.6g}"  # noqa: E731
        for x in shown:
            table.add_row(x["loop"], str(x["seq"]), f"{x['end_t']:.0f}", x["recorded"]["verdict"],
                          x["recomputed"]["verdict"], f(x["recorded"]["tdnl"]), f(x["recomputed"]["tdnl"]),
                          f"{x['recorded_alert'] or '-'}/{x['recomputed_alert'] or '-'}",
                          "[green]yes[/green]" if x["same_result"] and x["same_alert"] else "[red]NO[/red]")
        console.print(table)
    summary = Table(title=f"replay of {len(rows)} window(s) in {elapsed:.1f} s")
    for c in ("loop", "windows", "identical", "alerts recorded", "alerts recomputed"):
        summary.add_column(c)
    for loop, s in per_loop.items():
        summary.add_row(loop, str(s["windows"]), str(s["same"]), str(s["alerts_recorded"]), str(s["alerts_recomputed"]))
    console.print(summary)
    if not rows:
        console.print("no recorded windows match the selection")
    console.print(f"{len(rows) - len(differ)} of {len(rows)} window(s) reproduce the recorded verdict, figures "
                  f"and alert bit for bit")
    if args.json:
        args.json.parent.mkdir(parents=True, exist_ok=True)
        args.json.write_text(json.dumps({"windows": rows, "loops": per_loop, "identical": len(rows) - len(differ),
                                         "total": len(rows)}, indent=1) + "\n")
    return 0 if not differ else 1


#: Longest wait for a subscriber before the first put of ``--publish``, s.
_MATCH_WAIT_S = 10.0


def _wait_for_subscriber(session, key: str, timeout_s: float, err: Console) -> bool:
    """Wait until a subscriber matching ``key`` is known to ``session`` (zenoh drops a put that
    no known subscriber matches, so the first samples of a replay published the moment the session
    opened were lost whenever the subscriber's declaration had not yet arrived: a fixed half-second
    pause flaked under load); after ``timeout_s`` publish anyway, with a warning."""
    pub = session.declare_publisher(key)
    try:
        deadline = time.monotonic() + timeout_s
        while not pub.matching_status.matching:
            if time.monotonic() >= deadline:
                err.print(f"warning: no subscriber for {key} after {timeout_s:g} s; publishing anyway")
                return False
            time.sleep(0.005)
        return True
    finally:
        pub.undeclare()


def _publish(args, console: Console, err: Console, total: int | None) -> int:
    import zenoh

    from adapters.mcap_codec import ns_to_seconds
    from adapters.payloads import BINARY_ENCODING, encode_binary_batch, encode_sample
    from adapters.zenoh_session import open_session

    from ..replay import recorded_windows, republish_plan

    session = open_session(args.mode, connect=args.connect or ["tcp/127.0.0.1:7447"])
    block = zenoh.CongestionControl.BLOCK
    enc_bin, enc_json = zenoh.Encoding(BINARY_ENCODING), zenoh.Encoding.APPLICATION_JSON
    windows = 0
    prefix = args.prefix

    def counted():
        nonlocal windows, prefix
        for rec in recorded_windows(args.paths, loops=args.loop, t_from=args.t_from, t_to=args.t_to):
            if prefix is None:
                prefix = rec.group.run.get("settings", {}).get("keys", {}).get("prefix", "plant")
            windows += 1
            progress.update(task, completed=windows)
            yield rec

    sent = messages = 0
    start = first_due = None
    matched = False
    try:
        with _progress(err) as progress:
            task = progress.add_task("re-publishing windows", total=total)
            for b in republish_plan(counted()):
                if not matched:  # zenoh drops a put that no known subscriber matches: wait for the route
                    matched = True
                    _wait_for_subscriber(session, f"{prefix}/{b.loop_id}/{b.signal}", _MATCH_WAIT_S, err)
                if math.isfinite(args.speed):
                    if start is None:
                        start, first_due = time.monotonic(), b.due_ns
                    delay = start + (b.due_ns - first_due) / 1e9 / args.speed - time.monotonic()
                    if delay > 0:
                        time.sleep(delay)
                key = f"{prefix}/{b.loop_id}/{b.signal}"
                if b.regular:
                    payload, att = encode_binary_batch(float(ns_to_seconds(int(b.t_ns[0]))), b.sample_time_s, b.v)
                    session.put(key, payload, encoding=enc_bin, attachment=att, congestion_control=block)
                else:
                    session.put(key, encode_sample(float(ns_to_seconds(int(b.t_ns[0]))), float(b.v[0])),
                                encoding=enc_json, congestion_control=block)
                sent += int(b.v.size)
                messages += 1
        time.sleep(0.5)   # let the last puts leave before closing
    finally:
        session.close()
    console.print(f"re-published {sent} samples of {windows} recorded window(s) in {messages} messages "
                  f"under {prefix}/<loop>/<signal>")
    return 0
