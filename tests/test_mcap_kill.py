"""Crash safety: ``loopwatch monitor`` (a real process, recording on, fed over zenoh on loopback)
is killed with SIGKILL in the middle of a run.  The file it was writing is then recovered --
by ``loopwatch recover`` and by the next monitor start -- and keeps every window the monitor had
reported flushed before the kill; the recovered file opens with the ``mcap`` reader and its
samples are the planted plant's."""

from __future__ import annotations

import json
import os
import shutil
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path

import numpy as np
from mcap.reader import make_reader

from adapters.mcap_reader import read_recording
from adapters.zenoh_session import open_session
from service.cli import main
from service.commands.simulate_plant import PlantPublisher, make_plant
from service.composition import build_recorder
from service.settings import load_settings

from .conftest import loopback_port

PORT = loopback_port(20)
ROOT = Path(__file__).resolve().parents[1]
T0 = 1_750_000_000.0
LENGTH, HOP = 256, 64


def test_sigkill_mid_run_then_recover_keeps_every_flushed_window(tmp_path):
    rec_dir = tmp_path / "rec"
    cfg = tmp_path / "kill.toml"
    cfg.write_text(f"""instance = "kill"\nsample_time_s = 1.0\n[zenoh]\nlisten = ["tcp/127.0.0.1:{PORT}"]\n
[window]\nlength = {LENGTH}\nhop = {HOP}\n[analysis]\nworkers = 0\n
[recording]\nenabled = true\ndir = "{rec_dir}"\nflush_s = 0.2\n""")
    env = dict(os.environ, PYTHONPATH=str(ROOT))
    mon = subprocess.Popen([sys.executable, "-m", "service.cli", "monitor", "--config", str(cfg), "--report-every", "0"],
                           cwd=ROOT, env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    client = None
    pub = None
    try:
        assert "loopwatch monitor kill" in mon.stdout.readline()
        client = open_session("peer", connect=[f"tcp/127.0.0.1:{PORT}"])
        time.sleep(0.5)
        loops = make_plant(4, duration_s=3000.0)
        pub = PlantPublisher(client, loops, fmt="binary", batch=16, speed=150.0, t0=T0)
        th = threading.Thread(target=pub.run, daemon=True)
        th.start()
        flushed = 0
        deadline = time.monotonic() + 120
        while time.monotonic() < deadline:
            replies = list(client.get("loopwatch/kill/status?loop=", timeout=5.0))
            st = json.loads(replies[0].ok.payload.to_bytes())["sinks"]["recording"]
            flushed = st["windows_flushed"]
            if flushed >= 15:
                os.kill(mon.pid, signal.SIGKILL)                # mid-run: the plant is still publishing
                break
            time.sleep(0.05)
        assert mon.wait(30) == -signal.SIGKILL
        assert th.is_alive(), "the plant finished before the kill: not a mid-run kill"
    finally:
        if pub is not None:
            pub.stop_event.set()
        if mon.poll() is None:
            mon.kill()
            mon.wait(30)
        if client is not None:
            client.close()
    assert st["state"] == "ok" and flushed >= 15
    parts = list(rec_dir.glob("kill-*.mcap.part"))
    assert len(parts) == 1 and not list(rec_dir.glob("*.mcap"))
    with parts[0].open("rb") as fh:
        try:
            unreadable = make_reader(fh).get_summary() is None
        except Exception:   # noqa: BLE001 - the seeking reader fails on a file without footer
            unreadable = True
    assert unreadable
    spare = tmp_path / "spare"
    spare.mkdir()
    shutil.copy(parts[0], spare / parts[0].name)

    # 1. loopwatch recover FILE
    assert main(["recover", str(parts[0])]) == 0
    fixed = parts[0].with_suffix("")
    with fixed.open("rb") as fh:
        summary = make_reader(fh).get_summary()
    assert summary is not None and summary.statistics.message_count > 0
    groups = list(read_recording([fixed]))
    assert len(groups) >= flushed
    by_id = {lp.loop_id: lp for lp in loops}
    seqs: dict[str, list[int]] = {}
    for g in groups:
        w = g.window
        seqs.setdefault(w.loop_id, []).append(w.seq)
        np.testing.assert_array_equal(w.signals["pv"], by_id[w.loop_id].sim.pv[w.index0:w.index0 + LENGTH])
        assert w.t[0] == T0 + w.index0
    assert all(s == list(range(len(s))) for s in seqs.values())   # no window lost in the middle

    # 2. the monitor's own start in that directory recovers it too (and leaves nothing behind)
    settings = load_settings(None, instance="kill", recording={"enabled": True, "dir": str(spare)})
    rec = build_recorder(settings)
    rec.close()
    assert rec.status()["recovered_on_start"] == [str(spare / fixed.name)]
    assert not list(spare.glob("*.part"))
    assert len(list(read_recording([spare / fixed.name]))) == len(groups)
