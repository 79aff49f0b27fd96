"""Throughput of the always-on monitor (issue 4): N loops, OP and PV at 1 sample/s, batched per loop.

Three processes on this machine: this test (orchestrator: starts the others, samples the
monitor's status, receives the alerts), the monitor (``loopwatch monitor``, with its analysis
worker processes), and a publisher (this module run as a script).

The publisher first back-fills every loop with ``P_i < window`` samples of history (as fast as it
can; no window closes yet), chosen so that the loops' windows close evenly spread over one hop;
then it publishes in real time (speed 1) for ``SECONDS``: loop ``i`` sends its OP and PV batches
of ``BATCH`` samples every ``BATCH`` seconds, at offset ``i * BATCH / N``.  Signals are the
paper's closed loops (stiction, tuning, disturbance, healthy, deadband in turn), no noise.

Figures: samples sent vs. accepted (+ rejected), windows expected vs. analysed, the monitor's
window latency (message that completed a window -> result applied and alert published), the
end-to-end alert latency (scheduled send of the batch that completed the window -> alert
received here), the monitor's analysis backlog over time, and resident memory (monitor + its
workers) per loop.

Environment: ``LOOPWATCH_BENCH_LOOPS`` (default 2000), ``LOOPWATCH_BENCH_SECONDS`` (default 120),
``LOOPWATCH_BENCH_WORKERS`` (default 2), ``LOOPWATCH_BENCH_BATCH`` (default 16).  The acceptance
run: ``LOOPWATCH_BENCH_LOOPS=10000 LOOPWATCH_BENCH_SECONDS=600 make bench``.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import threading
import time
from pathlib import Path

import numpy as np
import pytest

PORT = 17611
W, HOP = 1024, 256
T_DATA0 = 1_750_000_000.0
MIX = ("stiction-datadriven", "tuning", "disturbance", "healthy", "stiction-lugre", "deadband")
ROOT = Path(__file__).resolve().parents[2]


def _rank(i: int, n: int) -> int:
    """A fixed pseudo-random permutation of ``range(n)`` (``i * a mod n`` with ``gcd(a, n) = 1``): it
    decorrelates a loop's window phase from its batch phase (``i * BATCH / n``).  With ``rank = i``
    the loops whose batches go out in the same second also close their windows together: bursts of
    ``n / BATCH`` windows every ``BATCH`` seconds (the first 10,000-loop run, see BENCHMARKS.md)."""
    if os.environ.get("LOOPWATCH_BENCH_BURSTY"):
        return i
    a = 7919
    while np.gcd(a, n) != 1:
        a += 2
    return (i * a) % n


def history(i: int, n: int) -> int:
    """Back-filled samples of loop ``i``: its first window closes at real-time second ``rank * HOP / n``."""
    return W - 1 - (_rank(i, n) * HOP) // n


def offset(i: int, n: int, batch: int) -> float:
    return i * batch / n


# ------------------------------------------------------------------------------ publisher process


def publish(n: int, seconds: float, batch: int, port: int) -> None:
    import zenoh

    from adapters.payloads import BINARY_ENCODING, encode_binary_batch
    from adapters.zenoh_session import open_session
    from models.loop import scenario_for_case, simulate_loop

    length = W + int(seconds) + 2 * batch + 64
    traces = {c: simulate_loop(scenario_for_case(c, duration_s=float(length)), seed=0) for c in MIX}
    loops = [(f"area{i // 100}/L{i:05d}", traces[MIX[i % len(MIX)]]) for i in range(n)]
    session = open_session("peer", connect=[f"tcp/127.0.0.1:{port}"])
    enc = zenoh.Encoding(BINARY_ENCODING)
    block = zenoh.CongestionControl.BLOCK
    sent = 0
    time.sleep(1.0)

    def send(i: int, k0: int, k1: int) -> None:
        nonlocal sent
        loop_id, sim = loops[i]
        for sig in ("op", "pv"):
            p, a = encode_binary_batch(T_DATA0 + k0, 1.0, getattr(sim, sig)[k0:k1])
            session.put(f"plant/{loop_id}/{sig}", p, encoding=enc, attachment=a, congestion_control=block)
            sent += k1 - k0

    t = time.monotonic()
    for i in range(n):
        p = history(i, n)
        for k0 in range(0, p, 256):
            send(i, k0, min(p, k0 + 256))
    print(json.dumps({"phase": "backfilled", "sent": sent, "seconds": time.monotonic() - t}), flush=True)
    time.sleep(5.0)   # let the monitor take the back-fill before the clock starts

    start_wall, start = time.time(), time.monotonic()
    print(json.dumps({"phase": "realtime", "start_wall": start_wall}), flush=True)
    lags = []
    j = 0
    while True:
        due0 = (j + 1) * batch
        if due0 > seconds:
            break
        for i in range(n):
            due = due0 + offset(i, n, batch)
            now = time.monotonic() - start
            if due > now:
                time.sleep(due - now)
            else:
                lags.append(now - due)
            p = history(i, n)
            send(i, p + j * batch, p + (j + 1) * batch)
        j += 1
    lag = np.array(lags or [0.0])
    print(json.dumps({"phase": "done", "sent": sent, "batches": j, "lag_p99": float(np.percentile(lag, 99)),
                      "lag_max": float(lag.max())}), flush=True)
    time.sleep(1.0)
    session.close()


# ------------------------------------------------------------------------------ orchestrator


def _tree(pid: int) -> list[int]:
    """``pid`` and all its descendants (the forkserver and the analysis workers), from /proc."""
    out, todo = [], [pid]
    while todo:
        p = todo.pop()
        out.append(p)
        for task in Path(f"/proc/{p}/task").glob("*"):
            try:
                todo += [int(c) for c in (task / "children").read_text().split()]
            except OSError:
                pass
    return out


def _rss_tree(pid: int) -> tuple[int, int]:
    """(sum of RSS, sum of PSS) in bytes over the process tree; PSS shares pages between the
    processes that map them (the workers share most of the forkserver's pages), RSS counts them
    once per process."""
    rss = pss = 0
    for p in _tree(pid):
        try:
            for line in Path(f"/proc/{p}/smaps_rollup").read_text().splitlines():
                if line.startswith("Rss:"):
                    rss += int(line.split()[1]) * 1024
                elif line.startswith("Pss:"):
                    pss += int(line.split()[1]) * 1024
        except OSError:
            pass
    return rss, pss


def read_phases(proc: subprocess.Popen) -> tuple[dict, threading.Thread]:
    """Collect a publisher process's JSON lines by ``phase`` (in a thread); returns (dict, thread)."""
    lines: dict = {}

    def read():
        for line in proc.stdout:
            d = json.loads(line)
            lines[d["phase"]] = d

    th = threading.Thread(target=read, daemon=True)
    th.start()
    return lines, th


_SECONDS = float(os.environ.get("LOOPWATCH_BENCH_SECONDS", 120))


@pytest.mark.bench
@pytest.mark.timeout(_SECONDS + 600)
def test_monitor_throughput(tmp_path):
    from adapters.zenoh_session import open_session

    from .conftest import machine_note

    n = int(os.environ.get("LOOPWATCH_BENCH_LOOPS", 2000))
    seconds = _SECONDS
    workers = int(os.environ.get("LOOPWATCH_BENCH_WORKERS", 2))
    batch = int(os.environ.get("LOOPWATCH_BENCH_BATCH", 16))
    cfg = tmp_path / "bench.toml"
    cfg.write_text(f"""instance = "bench"\nsample_time_s = 1.0\n[zenoh]\nlisten = ["tcp/127.0.0.1:{PORT}"]\n
[window]\nlength = {W}\nhop = {HOP}\n[alerts]\nraise_after = 2\nclear_after = 3\n
[analysis]\nworkers = {workers}\n[ingest]\nmax_loops = {n + 10}\n""")
    env = dict(os.environ, PYTHONPATH=str(ROOT))
    mon = subprocess.Popen([sys.executable, "-m", "service.cli", "monitor", "--config", str(cfg),
                            "--report-every", "0"], cwd=ROOT, env=env, stdout=subprocess.PIPE, text=True)
    assert "loopwatch monitor bench" in mon.stdout.readline()
    client = open_session("peer", connect=[f"tcp/127.0.0.1:{PORT}"])
    alerts = []

    def on_alert(s):
        alerts.append((time.time(), json.loads(s.payload.to_bytes())))

    sub = client.declare_subscriber("loopwatch/alerts/**", on_alert)

    def status(loop=""):
        r = list(client.get(f"loopwatch/bench/status?loop={loop}", timeout=10.0))
        return json.loads(r[0].ok.payload.to_bytes())

    time.sleep(1.0)
    rss_idle = _rss_tree(mon.pid)
    pub = subprocess.Popen([sys.executable, "-m", "tests.bench.bench_monitor", "--loops", str(n), "--seconds",
                            str(seconds), "--batch", str(batch), "--port", str(PORT)],
                           cwd=ROOT, env=env, stdout=subprocess.PIPE, text=True)
    lines, reader = read_phases(pub)
    samples = []   # (t since realtime start, windows analysed, queued, rss)
    while "done" not in lines and pub.poll() is None:
        time.sleep(5.0)
        if "realtime" in lines:
            s = status()
            samples.append((time.time() - lines["realtime"]["start_wall"], s["runtime"]["windows_analysed"],
                            s["runtime"]["windows_queued"], _rss_tree(mon.pid)))
    pub.wait(60)
    reader.join(10)
    # let the monitor finish what it has, then read the final figures
    deadline = time.monotonic() + 120
    while time.monotonic() < deadline:
        s = status()
        if s["runtime"]["windows_queued"] == 0:
            time.sleep(2.0)
            s2 = status()
            if s2["totals"]["samples_accepted"] == s["totals"]["samples_accepted"]:
                break
        time.sleep(1.0)
    final = status()
    rss_end = _rss_tree(mon.pid)
    sub.undeclare()
    client.close()
    mon.terminate()
    mon.wait(60)

    done, start_wall = lines["done"], lines["realtime"]["start_wall"]
    sent = done["sent"]
    tot = final["totals"]
    received = tot["samples_accepted"] + sum(tot["rejected"].values())
    n_batches = done["batches"]
    expected_windows = 0
    for i in range(n):
        total = history(i, n) + n_batches * batch
        expected_windows += (total - W) // HOP + 1 if total >= W else 0
    lat = final["runtime"]["latency_s"]
    e2e = []
    for t_recv, a in alerts:
        i = int(a["loop"].rsplit("L", 1)[1])
        k = int(round(a["window"]["end_t"] - T_DATA0)) - history(i, n)   # real-time sample index
        if k >= 0:
            j = k // batch
            e2e.append(t_recv - (start_wall + (j + 1) * batch + offset(i, n, batch)))
    e2e_a = np.array(e2e) if e2e else np.array([0.0])
    rt = [x for x in samples if x[0] > 0]
    max_queue = max((x[2] for x in rt), default=0)
    peak_rss = max([rss_end[0], *(x[3][0] for x in rt)])
    peak_pss = max([rss_end[1], *(x[3][1] for x in rt)])
    keeps_up = (received == sent and final["runtime"]["windows_analysed"] == expected_windows
                and (lat["p99"] or 0) <= 2.0 and done["lag_p99"] < 1.0)
    print(f"\n[bench_monitor] {machine_note()}")
    print(f"loops {n}, OP+PV at 1 sample/s, batches of {batch}, window {W}/hop {HOP}, {workers} worker process(es), "
          f"{seconds:g} s real time after a back-fill of {lines['backfilled']['sent']} samples "
          f"({lines['backfilled']['seconds']:.1f} s)")
    print(f"samples: sent {sent}, accepted {tot['samples_accepted']}, rejected {tot['rejected']} -> lost {sent - received}")
    print(f"windows: expected {expected_windows}, analysed {final['runtime']['windows_analysed']} "
          f"({final['runtime']['windows_analysed'] / seconds:.1f}/s); analysis errors {final['runtime']['errors']}")
    print(f"window latency (completing message -> result applied/alert published): p50 {lat['p50']:.3f} s, "
          f"p99 {lat['p99']:.3f} s, max {lat['max']:.3f} s")
    print(f"alerts received {len(alerts)} ({len(e2e)} timed); end-to-end alert latency (scheduled send -> received): "
          f"p50 {np.percentile(e2e_a, 50):.3f} s, p99 {np.percentile(e2e_a, 99):.3f} s, max {np.max(e2e_a):.3f} s")
    print(f"publisher lag behind schedule: p99 {done['lag_p99']:.3f} s, max {done['lag_max']:.3f} s")
    print(f"analysis backlog (windows queued) sampled every 5 s: max {max_queue}; "
          f"series {[x[2] for x in rt][:40]}")
    for name, k, peak in (("RSS", 0, peak_rss), ("PSS", 1, peak_pss)):
        print(f"{name} monitor+forkserver+workers: idle {rss_idle[k] / 2**20:.0f} MiB, end {rss_end[k] / 2**20:.0f} MiB, "
              f"peak sampled {peak / 2**20:.0f} MiB -> {peak / n / 1024:.1f} KiB/loop total, "
              f"{(peak - rss_idle[k]) / n / 1024:.1f} KiB/loop above idle")
    print(f"keeps up: {'yes' if keeps_up else 'NO'}")
    assert received == sent, "samples lost between publisher and monitor"
    assert final["runtime"]["windows_analysed"] == expected_windows


if __name__ == "__main__":
    ap = argparse.ArgumentParser()
    ap.add_argument("--loops", type=int, required=True)
    ap.add_argument("--seconds", type=float, required=True)
    ap.add_argument("--batch", type=int, default=16)
    ap.add_argument("--port", type=int, default=PORT)
    a = ap.parse_args()
    publish(a.loops, a.seconds, a.batch, a.port)
