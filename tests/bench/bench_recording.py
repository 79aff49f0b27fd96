"""Cost of MCAP recording (issue 5): monitor throughput with and without recording, replay speed.

``test_recording_throughput`` -- the monitor of issue 4 (``loopwatch monitor``: ingest process +
``LOOPWATCH_BENCH_WORKERS`` analysis worker processes) takes a plant of ``LOOPWATCH_BENCH_LOOPS``
loops (default 10,000) pushed as fast as a publisher process can send it: OP and PV, one window
(1024 samples, binary batches of 256) per loop, the paper's cases in turn.  Throughput = windows
analysed per second of wall time, from the publisher's first put to the last window applied
(and recorded: the run ends when the recorder has written every window).  The same run is done
without and with recording, alternating (``LOOPWATCH_BENCH_REPEATS`` pairs, default 1), on the
same machine at the same time; the ratio is the figure.  Also: CPU seconds of the monitor's
ingest process (where the recorder's writer thread runs) per window, and bytes per window.

``test_replay_speed`` -- one loop over 24 h (86,400 samples at 1 s, the paper's stiction loop),
recorded through the real monitor (window 1024, hop 256: 334 windows); then timed: reading the
recorded windows, and ``loopwatch replay`` (read, re-analyse, compare, write the JSON report).
Speed-up = 86,400 s of data / wall time.

Run: ``.venv/bin/python -m pytest -q -m bench -s tests/bench/bench_recording.py``.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from tests.bench.bench_monitor import _tree, read_phases
from tests.conftest import loopback_port

PORT = loopback_port(22)
W, HOP = 1024, 256
T_DATA0 = 1_750_000_000.0
MIX = ("stiction-datadriven", "tuning", "disturbance", "healthy", "stiction-lugre", "deadband")
ROOT = Path(__file__).resolve().parents[2]


# ------------------------------------------------------------------------------ publisher process


def publish(n: int, port: int) -> None:
    """Every loop's first window (OP and PV), batches of 256, as fast as possible."""
    import zenoh

    from adapters.payloads import BINARY_ENCODING, encode_binary_batch
    from adapters.zenoh_session import open_session
    from models.loop import scenario_for_case, simulate_loop

    traces = {c: simulate_loop(scenario_for_case(c, duration_s=float(W + 64)), seed=0) for c in MIX}
    session = open_session("peer", connect=[f"tcp/127.0.0.1:{port}"])
    enc, block = zenoh.Encoding(BINARY_ENCODING), zenoh.CongestionControl.BLOCK
    time.sleep(1.0)
    print(json.dumps({"phase": "start", "wall": time.time()}), flush=True)
    sent = 0
    for k0 in range(0, W, 256):
        for i in range(n):
            sim = traces[MIX[i % len(MIX)]]
            for sig in ("op", "pv"):
                p, a = encode_binary_batch(T_DATA0 + k0, 1.0, getattr(sim, sig)[k0:k0 + 256])
                session.put(f"plant/area{i // 100}/L{i:05d}/{sig}", p, encoding=enc, attachment=a,
                            congestion_control=block)
                sent += 256
    print(json.dumps({"phase": "done", "wall": time.time(), "sent": sent}), flush=True)
    time.sleep(1.0)
    session.close()


# ------------------------------------------------------------------------------ orchestrator


def _cpu_s(pid: int) -> float:
    """utime + stime of one process (not its children), seconds."""
    f = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
    return (int(f[11]) + int(f[12])) / os.sysconf("SC_CLK_TCK")


def _tree_cpu_s(pid: int) -> float:
    """CPU seconds of the monitor and its live descendants (forkserver, analysis workers)."""
    total = 0.0
    for p in _tree(pid):
        try:
            total += _cpu_s(p)
        except OSError:
            pass
    return total


def _run(n: int, workers: int, record_dir: Path | None, tmp: Path) -> dict:
    from adapters.zenoh_session import open_session

    cfg = tmp / "bench.toml"
    rec = (f'\n[recording]\nenabled = true\ndir = "{record_dir}"\nflush_s = 2.0\nqueue_windows = 1000\n'
           if record_dir else "")
    cfg.write_text(f"""instance = "rbench"\nsample_time_s = 1.0\n[zenoh]\nlisten = ["tcp/127.0.0.1:{PORT}"]\n
[window]\nlength = {W}\nhop = {HOP}\n[analysis]\nworkers = {workers}\n[ingest]\nmax_loops = {n + 10}\n{rec}""")
    env = dict(os.environ, PYTHONPATH=str(ROOT))
    mon = subprocess.Popen([sys.executable, "-m", "service.cli", "monitor", "--config", str(cfg), "--report-every",
                            "0"], cwd=ROOT, env=env, stdout=subprocess.PIPE, text=True)
    assert "loopwatch monitor rbench" in mon.stdout.readline()
    client = open_session("peer", connect=[f"tcp/127.0.0.1:{PORT}"])

    def status():
        r = list(client.get("loopwatch/rbench/status?loop=", timeout=30.0))
        return json.loads(r[0].ok.payload.to_bytes())

    time.sleep(1.0)
    cpu0, tree0 = _cpu_s(mon.pid), _tree_cpu_s(mon.pid)
    pub = subprocess.Popen([sys.executable, "-m", "tests.bench.bench_recording", "--loops", str(n), "--port",
                            str(PORT)], cwd=ROOT, env=env, stdout=subprocess.PIPE, text=True)
    lines, th = read_phases(pub)
    deadline = time.monotonic() + 3600
    while time.monotonic() < deadline:
        time.sleep(0.5)
        s = status()
        done = s["runtime"]["windows_analysed"] >= n
        if record_dir:
            done = done and s["sinks"]["recording"]["windows_recorded"] + sum(
                s["sinks"]["recording"]["windows_dropped"].values()) >= n
        if done:
            break
    t_end = time.time()
    cpu, tree_cpu = _cpu_s(mon.pid) - cpu0, _tree_cpu_s(mon.pid) - tree0
    pub.wait(60)
    th.join(10)
    final = status()
    client.close()
    mon.terminate()
    mon.wait(120)
    wall = t_end - lines["start"]["wall"]
    out = {"recording": record_dir is not None, "wall_s": wall, "windows": final["runtime"]["windows_analysed"],
           "windows_per_s": final["runtime"]["windows_analysed"] / wall, "ingest_cpu_s": cpu,
           "ingest_cpu_ms_per_window": 1000 * cpu / max(1, final["runtime"]["windows_analysed"]),
           "total_cpu_ms_per_window": 1000 * tree_cpu / max(1, final["runtime"]["windows_analysed"]),
           "publish_s": lines["done"]["wall"] - lines["start"]["wall"], "sent": lines["done"]["sent"],
           "accepted": final["totals"]["samples_accepted"], "latency_p99": final["runtime"]["latency_s"]["p99"]}
    if record_dir:
        r = final["sinks"]["recording"]
        size = sum(p.stat().st_size for p in record_dir.glob("*.mcap*"))
        out.update(recorded=r["windows_recorded"], dropped=r["windows_dropped"], state=r["state"], bytes=size,
                   writer_cpu_ms_per_window=1000 * r["writer_cpu_s"] / max(1, r["windows_recorded"]),
                   bytes_per_window=size / max(1, r["windows_recorded"]))
    return out


@pytest.mark.bench
@pytest.mark.timeout(7200)
def test_recording_throughput(tmp_path):
    from .conftest import machine_note

    n = int(os.environ.get("LOOPWATCH_BENCH_LOOPS", 10000))
    workers = int(os.environ.get("LOOPWATCH_BENCH_WORKERS", 2))
    repeats = int(os.environ.get("LOOPWATCH_BENCH_REPEATS", 1))
    runs = []
    for k in range(repeats):
        for rec in (False, True):
            d = tmp_path / f"run{k}-{int(rec)}"
            d.mkdir()
            runs.append(_run(n, workers, d / "rec" if rec else None, d))
            print(json.dumps(runs[-1]), flush=True)
    off = [r for r in runs if not r["recording"]]
    on = [r for r in runs if r["recording"]]
    med = lambda rs, k: float(np.median([r[k] for r in rs]))  # noqa: E731
    print(f"\n[bench_recording] {machine_note()}")
    print(f"{n} loops x 1 window (OP+PV, {W} samples, batches of 256) pushed as fast as possible; "
          f"{workers} analysis worker process(es); {repeats} pair(s) of runs, alternating without/with recording")
    for name, rs in (("without recording", off), ("with recording", on)):
        print(f"{name}: {med(rs, 'windows_per_s'):.1f} windows/s (wall {med(rs, 'wall_s'):.1f} s; publisher "
              f"{med(rs, 'publish_s'):.1f} s), ingest-process CPU {med(rs, 'ingest_cpu_ms_per_window'):.2f} ms/window, "
              f"latency p99 {med(rs, 'latency_p99'):.1f} s")
    ratio = med(on, "windows_per_s") / med(off, "windows_per_s")
    print(f"throughput with / without recording: {ratio:.3f} ({(ratio - 1) * 100:+.1f} %); pairs: "
          f"{[round(b['windows_per_s'] / a['windows_per_s'], 3) for a, b in zip(off, on)]}")
    extra, total = med(on, "writer_cpu_ms_per_window"), med(off, "total_cpu_ms_per_window")
    print(f"CPU: monitor + workers {total:.1f} ms/window without recording; the recorder's writer thread "
          f"{extra:.2f} ms/window -> on a CPU-bound machine recording costs {extra / (total + extra) * 100:.1f} % "
          f"of the throughput (load-independent estimate)")
    print(f"recording: {on[-1]['recorded']} windows recorded, dropped {on[-1]['dropped']}, state {on[-1]['state']}, "
          f"{on[-1]['bytes'] / 2**20:.1f} MiB ({on[-1]['bytes_per_window'] / 1024:.1f} KiB/window)")
    for r in runs:
        assert r["accepted"] == r["sent"] and r["windows"] == n
    assert all(r["recorded"] == n for r in on)


@pytest.mark.bench
@pytest.mark.timeout(1800)
def test_replay_speed(tmp_path):
    from concurrent.futures import ThreadPoolExecutor

    from adapters.mcap_recorder import McapRecorder
    from adapters.payloads import BINARY_ENCODING, encode_binary_batch
    from models.loop import scenario_for_case, simulate_loop
    from service.cli import main
    from service.monitor import LoopConfig, Monitor, MonitorCore
    from service.replay import recorded_windows

    from .conftest import machine_note

    day = 86_400
    sim = simulate_loop(scenario_for_case("stiction-datadriven", duration_s=float(day)), seed=0)
    core = MonitorCore(loop_config=lambda _id: LoopConfig(sample_time_s=1.0, length=W, hop=HOP))
    rec = McapRecorder(tmp_path / "rec", instance="day")
    mon = Monitor(core, ThreadPoolExecutor(max_workers=1), window_sinks=[rec])
    t = time.perf_counter()
    for k0 in range(0, day, 256):
        for sig in ("sp", "mv", "op", "pv"):
            p, a = encode_binary_batch(T_DATA0 + k0, 1.0, getattr(sim, sig)[k0:k0 + 256])
            mon.on_message(f"plant/area1/FIC101/{sig}", p, BINARY_ENCODING, a)
    mon.drain(1200)
    mon.close()
    t_record = time.perf_counter() - t
    n_windows = (day - W) // HOP + 1
    assert rec.status()["windows_recorded"] == n_windows
    size = sum(p.stat().st_size for p in (tmp_path / "rec").glob("*.mcap"))

    reads, replays = [], []
    for _ in range(3):
        t = time.perf_counter()
        got = sum(1 for _ in recorded_windows([tmp_path / "rec"]))
        reads.append(time.perf_counter() - t)
        assert got == n_windows
        t = time.perf_counter()
        code = main(["replay", str(tmp_path / "rec"), "--json", str(tmp_path / "r.json")])
        replays.append(time.perf_counter() - t)
        assert code == 0
    report = json.loads((tmp_path / "r.json").read_text())
    assert report["identical"] == report["total"] == n_windows
    print(f"\n[bench_replay] {machine_note()}")
    print(f"one loop, 24 h at 1 s (sp, mv, op, pv), window {W}/hop {HOP}: {n_windows} windows; recorded through the "
          f"monitor in {t_record:.1f} s; {size / 2**20:.1f} MiB on disk")
    r, p = float(np.median(reads)), float(np.median(replays))
    print(f"read the recorded windows: {r:.2f} s (median of 3) -> {day / r:,.0f}x real time")
    print(f"loopwatch replay (read + re-analyse + compare + JSON): {p:.2f} s (median of 3) -> {day / p:,.0f}x real time; "
          f"{report['identical']}/{report['total']} windows identical")
    assert day / p >= 100


if __name__ == "__main__":
    ap = argparse.ArgumentParser()
    ap.add_argument("--loops", type=int, required=True)
    ap.add_argument("--port", type=int, default=PORT)
    a = ap.parse_args()
    publish(a.loops, a.port)
