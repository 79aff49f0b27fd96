"""MCAP recording of the monitor: real files written by the real monitor, read back with the
``mcap`` reader, every message validated against its JSON Schema (``jsonschema``), samples and
time stamps checked against the planted plant, replay bit for bit, rotation, retention,
recovery of truncated files, degraded recording on an unwritable directory and a full disk."""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
import textwrap
import time
from fractions import Fraction
from pathlib import Path

import jsonschema
import numpy as np
import pytest
from mcap.reader import make_reader

from adapters.mcap_codec import SCHEMAS, decode_f64
from adapters.mcap_reader import RecordingReadError, read_recording
from adapters.mcap_recorder import McapRecorder, RecordingError, recover_file
from pipeline.diagnosis import WindowDiagnosis
from service.cli import main
from service.monitor import AnalysisConfig, WindowResult, WindowSamples, analyze_window
from service.replay import recorded_windows, replay_windows
from service.settings import SettingsError, load_settings

from .mcap_helpers import (
    DURATION,
    HOP,
    JITTER_LOOP,
    LENGTH,
    N_WINDOWS,
    PAPER_CONFIG,
    PAPER_LOOP,
    T0,
    record_plant,
)

ROOT = Path(__file__).resolve().parents[1]


@pytest.fixture(scope="module")
def rec(tmp_path_factory):
    return record_plant(tmp_path_factory.mktemp("rec") / "recordings")


def _files(d: Path) -> list[Path]:
    return sorted(d.glob("*.mcap"))


def _messages(path: Path):
    with path.open("rb") as fh:
        r = make_reader(fh)
        summary = r.get_summary()
        return summary, [(s, c, m) for s, c, m in r.iter_messages(log_time_order=False)]


# ----------------------------------------------------------------------------- the files


def test_monitor_writes_finished_files_that_the_mcap_reader_opens(rec):
    files = _files(rec.dir)
    assert files and not list(rec.dir.glob("*.part"))
    n_windows = 0
    for f in files:
        summary, msgs = _messages(f)
        assert summary is not None and summary.statistics.message_count == len(msgs)
        with f.open("rb") as fh:                      # zstd chunks, as asked
            assert {ci.compression for ci in make_reader(fh).get_summary().chunk_indexes} == {"zstd"}
        n_windows += sum(1 for _, c, _ in msgs if c.topic.endswith("/window"))
    assert rec.monitor_windows == 6 * N_WINDOWS == n_windows


def test_every_message_validates_against_its_json_schema(rec):
    seen = set()
    for f in _files(rec.dir):
        _, msgs = _messages(f)
        for schema, channel, msg in msgs:
            assert schema.encoding == "jsonschema" and channel.message_encoding == "json"
            sch = json.loads(schema.data)
            jsonschema.Draft202012Validator.check_schema(sch)
            jsonschema.validate(json.loads(msg.data), sch, cls=jsonschema.Draft202012Validator)
            seen.add(sch["title"])
    assert seen == {s["title"] for s in SCHEMAS.values()}
    # the validator does reject a message that breaks the schema
    bad = {"timestamp": {"sec": 1, "nsec": 2}, "loop": "x", "seq": -1}
    with pytest.raises(jsonschema.ValidationError):
        jsonschema.validate(bad, SCHEMAS["window"], cls=jsonschema.Draft202012Validator)


def test_topics_one_family_per_loop_and_times_from_the_data(rec):
    summary, msgs = _messages(_files(rec.dir)[0])
    topics = {c.topic for c in summary.channels.values()}
    for lp in rec.loops:
        assert {f"/loopwatch/{lp.loop_id}/{k}" for k in ("config", "window", "result")} <= topics
    assert "/loopwatch/config" in topics
    for _, c, m in msgs:
        if c.topic.endswith("/window"):
            body = json.loads(m.data)
            # log time = the window's last grid time, in integer ns of the data's clock
            end = T0 + body["index0"] + body["n"] - 1
            if c.topic != f"/loopwatch/{rec.loops[JITTER_LOOP].loop_id}/window":
                assert m.log_time == int(end) * 10**9
            assert body["timestamp"] == {"sec": m.log_time // 10**9, "nsec": m.log_time % 10**9}


def test_recorded_samples_are_the_planted_plant_bit_for_bit(rec):
    by_id = {lp.loop_id: lp for lp in rec.loops}
    n = 0
    for g in read_recording([rec.dir]):
        w = g.window
        lp = by_id[w.loop_id]
        assert w.t.size == LENGTH and w.index0 == w.seq * HOP
        for sig in ("sp", "mv", "op", "pv"):
            np.testing.assert_array_equal(w.signals[sig], getattr(lp.sim, sig)[w.index0:w.index0 + LENGTH])
        # the data's own time stamps, in ns (planted: jittered for one loop, on the 1 s grid otherwise)
        planted = rec.times[w.loop_id][w.index0:w.index0 + LENGTH]
        exact = np.array([round(Fraction(t) * 10**9) for t in planted], dtype=object)
        for sig in ("op", "pv"):
            assert np.all(np.abs(w.times_ns[sig].astype(object) - exact) <= 1)
        n += 1
    assert n == 6 * N_WINDOWS


def test_recorded_alerts_and_configuration(rec):
    groups = list(read_recording([rec.dir]))
    alerts = [g.alert for g in groups if g.alert is not None]
    assert [a["loop"] for a in alerts] == [a.loop_id for a in rec.alerts] and len(alerts) == 2
    for got, sent in zip(alerts, rec.alerts):
        assert {k: got[k] for k in sent.to_json()} == json.loads(json.dumps(sent.to_json()))
        assert got["level"] == 3 and got["message"].startswith(f"{sent.loop_id}: alert raised")
    paper = rec.loops[PAPER_LOOP].loop_id
    cfg = next(g.config for g in groups if g.loop_id == paper)
    assert cfg["diagnosis"]["method"] == "paper" and cfg["diagnosis"]["threshold"] == 0.2
    assert groups[0].run["alerts"] == {"raise_after": 2, "clear_after": 2}


# ----------------------------------------------------------------------------- replay


def test_replay_reproduces_every_verdict_and_figure_bit_for_bit(rec):
    out = list(replay_windows([rec.dir]))
    assert len(out) == 6 * N_WINDOWS
    verdicts = set()
    for r in out:
        a, b = r.recorded.result.diagnosis, r.result.diagnosis
        assert a.verdict == b.verdict and a.reason == b.reason
        assert a.dnl == b.dnl or (np.isnan(a.dnl).all() and np.isnan(b.dnl).all() and len(a.dnl) == len(b.dnl))
        assert a.tdnl == b.tdnl or (np.isnan(a.tdnl) and np.isnan(b.tdnl))
        assert r.same_result and r.same_alert
        verdicts.add(b.verdict)
    assert {"nonlinear", "linear", "not_oscillating"} <= verdicts
    alerts = [r.alert for r in out if r.alert is not None]
    assert [a.to_json() for a in alerts] == [a.to_json() for a in rec.alerts]


def test_replay_uses_the_recorded_configuration(rec):
    paper = rec.loops[PAPER_LOOP].loop_id
    got = [r for r in recorded_windows([rec.dir], loops=[paper])]
    assert len(got) == N_WINDOWS and all(r.window.analysis.diagnosis == PAPER_CONFIG for r in got)
    d = got[-1].result.diagnosis
    assert d.method == "paper" and d.imfs_kept
    # the default configuration would have given other figures: the replay did not fall back to it
    other = analyze_window(WindowSamples(**{**got[-1].window.__dict__, "analysis": AnalysisConfig()}))
    assert other.diagnosis.method == "robust" and other.diagnosis.tdnl != d.tdnl


def test_replay_cli_filters_and_json(rec, tmp_path):
    loop = rec.loops[0].loop_id
    ends = [T0 + s * HOP + LENGTH - 1 for s in range(N_WINDOWS)]
    out = tmp_path / "r.json"
    assert main(["replay", str(rec.dir), "--loop", loop, "--from", str(ends[2]), "--to", str(ends[4]),
                 "--json", str(out)]) == 0
    rep = json.loads(out.read_text())
    assert [w["end_t"] for w in rep["windows"]] == ends[2:5]
    assert rep["identical"] == rep["total"] == 3 and {w["loop"] for w in rep["windows"]} == {loop}
    iso = time.strftime("%Y-%m-%dT%H:%M:%S", time.gmtime(ends[5]))
    assert main(["replay", str(rec.dir), "--loop", loop, "--from", iso, "--json", str(out)]) == 0
    assert [w["end_t"] for w in json.loads(out.read_text())["windows"]] == ends[5:]


def test_export_writes_the_csv_that_analyze_reads(rec, tmp_path):
    from adapters.loop_csv import read_loop_csv

    lp = rec.loops[0]
    out = tmp_path / "loop.csv"
    assert main(["export", str(rec.dir), "--loop", lp.loop_id, "--csv", str(out)]) == 0
    data = read_loop_csv(out)
    n = (N_WINDOWS - 1) * HOP + LENGTH
    assert data.t.size == n and data.t[0] == T0 and data.sample_time_s == 1.0
    for sig in ("pv", "op", "sp", "mv"):
        np.testing.assert_array_equal(getattr(data, sig), getattr(lp.sim, sig)[:n])
    assert main(["analyze", str(out), "--window", str(LENGTH), "--hop", str(HOP)]) == 0
    assert main(["export", str(rec.dir), "--csv", str(out)]) == 2      # one --loop is required
    assert main(["export", str(rec.dir), "--loop", "no/such", "--csv", str(out)]) == 2


# ----------------------------------------------------------------------------- crash safety


def test_recover_keeps_every_complete_window_of_a_cut_file(rec, tmp_path):
    src = _files(rec.dir)[0]
    full = src.read_bytes()
    reference = {(g.loop_id, g.window.seq): g.window.signals["pv"] for g in read_recording([src])}
    last = -1
    for frac in (0.05, 0.2, 0.35, 0.5, 0.65, 0.8, 0.95, 0.999):
        cut = tmp_path / f"cut-{frac}.mcap.part"
        cut.write_bytes(full[:int(len(full) * frac)])
        with cut.open("rb") as fh, pytest.raises(Exception):
            make_reader(fh).get_summary()                       # not readable as it is
        res = recover_file(cut)
        assert res.truncated and Path(res.target) == cut.with_suffix("")
        groups = list(read_recording([res.target]))           # opens with the mcap reader
        for g in groups:
            np.testing.assert_array_equal(g.window.signals["pv"], reference[(g.loop_id, g.window.seq)])
        assert len(groups) >= last                             # a longer prefix never keeps less
        last = len(groups)
    assert 0 < last < len(reference) or last == len(reference)
    with pytest.raises(RecordingReadError, match="loopwatch recover"):
        list(read_recording([cut]))
    (tmp_path / "junk.mcap.part").write_bytes(b"not an mcap file at all")
    with pytest.raises(RecordingError, match="not an MCAP file"):
        recover_file(tmp_path / "junk.mcap.part")


def test_leftover_part_files_are_recovered_on_start_unless_locked(rec, tmp_path):
    import fcntl

    src = _files(rec.dir)[0]
    d = tmp_path / "d"
    d.mkdir()
    left = d / "test-20250101T000000Z-0001.mcap.part"
    left.write_bytes(src.read_bytes()[: src.stat().st_size // 2])
    live = d / "test-20250101T000000Z-0002.mcap.part"
    live.write_bytes(src.read_bytes()[: 1000])
    other = d / "other-20250101T000000Z-0001.mcap.part"
    shutil.copy(left, other)
    with live.open("rb") as fh:
        fcntl.flock(fh.fileno(), fcntl.LOCK_EX)                 # a live writer holds it
        r = McapRecorder(d, instance="test")
        r.close()
    assert r.status()["recovered_on_start"] == [str(d / "test-20250101T000000Z-0001.mcap")]
    assert not left.exists() and live.exists() and other.exists()
    assert len(list(read_recording([d / "test-20250101T000000Z-0001.mcap"]))) > 0


# ----------------------------------------------------------------------------- rotation, retention


def _window(seq: int, n: int = 256) -> tuple[WindowSamples, WindowResult]:
    rng = np.random.default_rng(seq)
    t = T0 + seq * n + np.arange(n, dtype=float)
    w = WindowSamples("area9/X1", seq, seq * n, t, 1.0, {"pv": rng.standard_normal(n), "op": rng.standard_normal(n)},
                      AnalysisConfig())
    return w, WindowResult(WindowDiagnosis("invalid", "planted"), float("nan"), float("nan"), 0)


def _wait(pred, timeout=20.0):
    end = time.monotonic() + timeout
    while not pred():
        assert time.monotonic() < end, "timed out"
        time.sleep(0.02)


def test_rotation_by_size_and_retention_by_bytes(tmp_path):
    r = McapRecorder(tmp_path, instance="rot", rotate_bytes=40_000, chunk_size=8_000, retention_bytes=120_000,
                     flush_s=0.05)
    for seq in range(60):
        w, res = _window(seq)
        r.on_window(w.loop_id, w, res, None)
        _wait(lambda: r.status()["windows_recorded"] == seq + 1)
    r.close()
    st = r.status()
    files = _files(tmp_path)
    assert st["state"] == "closed" and not list(tmp_path.glob("*.part"))
    assert st["files_finished"] >= 5 and st["files_deleted_by_retention"] >= 1
    assert len(files) == st["files_finished"] - st["files_deleted_by_retention"]
    sizes = [f.stat().st_size for f in files]
    assert sum(sizes) <= 120_000 + max(sizes)
    seqs = sorted(g.window.seq for g in read_recording(files))
    assert seqs == list(range(60 - len(seqs), 60))              # the oldest went first, nothing else lost


def test_rotation_by_duration_and_retention_by_age(tmp_path):
    now = [0.0]
    old = tmp_path / "age-20200101T000000Z-0001.mcap"
    foreign = tmp_path / "notes-20200101T000000Z-0001.mcap"
    for p in (old, foreign):
        p.write_bytes(b"x")
        os.utime(p, (time.time() - 7200, time.time() - 7200))
    r = McapRecorder(tmp_path, instance="age", rotate_s=10.0, retention_s=3600.0, flush_s=1.0,
                     clock=lambda: now[0])
    for seq in range(3):
        w, res = _window(seq)
        r.on_window(w.loop_id, w, res, None)
        _wait(lambda: r.status()["windows_recorded"] == seq + 1)
        now[0] += 11.0                                         # each window lands in its own file
        _wait(lambda: r.status()["files_finished"] == seq + 1)
    r.close()
    assert r.status()["files_finished"] == 3
    assert not old.exists() and foreign.exists()                # only this instance's files are pruned
    assert [len(list(read_recording([f]))) for f in _files(tmp_path) if f.name.startswith("age-")] == [1, 1, 1]


def test_full_queue_drops_and_counts_never_blocks(tmp_path):
    r = McapRecorder(tmp_path, instance="q", queue_max=1)
    w, res = _window(0, n=4096)
    t = time.monotonic()
    for _ in range(300):
        r.on_window(w.loop_id, w, res, None)
    assert time.monotonic() - t < 1.0
    r.close()
    st = r.status()
    assert st["windows_recorded"] + st["windows_dropped"].get("queue_full", 0) == 300
    assert st["windows_dropped"].get("queue_full", 0) > 0


# ----------------------------------------------------------------------------- degraded recording


def test_unwritable_directory_degrades_recording_and_monitoring_continues(tmp_path):
    blocker = tmp_path / "not-a-dir"
    blocker.write_text("a file where the recording directory should be")
    got = record_plant(blocker / "rec", retry_s=0.2)
    assert got.monitor_windows == 6 * N_WINDOWS and len(got.alerts) == 2   # monitoring unaffected
    st = got.recorder_status
    assert st["state"] == "degraded" and "NotADirectoryError" in st["last_error"]
    assert st["windows_recorded"] == 0 and st["windows_dropped"]["degraded"] >= 1
    # once the directory can be written, the recorder resumes on its own
    blocker.unlink()
    r = McapRecorder(blocker / "rec", instance="late", retry_s=0.1)
    w, res = _window(0)
    r.on_window(w.loop_id, w, res, None)
    r.close()
    assert r.status()["windows_recorded"] == 1 and _files(blocker / "rec")


def test_full_disk_degrades_recording_and_monitoring_continues(tmp_path):
    """A real write failure: the monitor runs in a process whose file-size limit (RLIMIT_FSIZE)
    is hit by the recording, so the kernel fails the write with EFBIG, as a full disk would fail it."""
    script = textwrap.dedent(f"""
        import json, resource, signal, sys
        from pathlib import Path
        sys.path.insert(0, {str(ROOT)!r})
        signal.signal(signal.SIGXFSZ, signal.SIG_IGN)
        resource.setrlimit(resource.RLIMIT_FSIZE, (150_000, 150_000))
        from tests.mcap_helpers import record_plant
        got = record_plant(Path({str(tmp_path / 'rec')!r}), retry_s=600)
        print(json.dumps({{"windows": got.monitor_windows, "alerts": len(got.alerts), "status": got.recorder_status}}))
    """)
    p = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, timeout=240, cwd=ROOT)
    assert p.returncode == 0, p.stderr[-2000:]
    out = json.loads(p.stdout.strip().splitlines()[-1])
    assert out["windows"] == 6 * N_WINDOWS and out["alerts"] == 2          # monitoring unaffected
    st = out["status"]
    assert st["state"] == "degraded" and "File too large" in st["last_error"]
    assert st["windows_dropped"]["degraded"] >= 1
    assert "recording degraded" in p.stderr
    # what was written before the failure is recovered by the next start in that directory
    r = McapRecorder(tmp_path / "rec", instance="test")
    r.close()
    kept = list(read_recording(_files(tmp_path / "rec")))
    assert r.status()["recovered_on_start"] or kept
    assert 0 < len(kept) < 6 * N_WINDOWS


# ----------------------------------------------------------------------------- settings


def test_recording_settings_validated_and_documented():
    s = load_settings(ROOT / "deploy" / "monitor.toml")
    assert s.recording.enabled and s.recording.flush_s <= s.recording.rotate_s
    with pytest.raises(SettingsError, match="retention_bytes"):
        load_settings(None, recording={"retention_bytes": 2 << 20, "rotate_bytes": 8 << 20})
    with pytest.raises(SettingsError, match="flush_s"):
        load_settings(None, recording={"flush_s": 30, "rotate_s": 10})
    with pytest.raises(SettingsError, match="recording.rotat"):
        load_settings(None, recording={"rotat_bytes": 1})


def test_a_window_without_its_result_is_skipped_not_fatal(rec, tmp_path, caplog):
    """A recovered file can end between a window's messages (they may straddle two chunks)."""
    from mcap.writer import Writer

    src = _files(rec.dir)[0]
    summary, msgs = _messages(src)
    dropped = next((c.topic, m.sequence) for _, c, m in msgs if c.topic.endswith("/result"))
    out = tmp_path / "holed.mcap"
    with out.open("wb") as fh:
        w = Writer(fh)
        w.start()
        sids = {sid: w.register_schema(s.name, s.encoding, s.data) for sid, s in summary.schemas.items()}
        cids = {cid: w.register_channel(c.topic, c.message_encoding, sids[c.schema_id], c.metadata)
                for cid, c in summary.channels.items()}
        for _, c, m in msgs:
            if (c.topic, m.sequence) != dropped:
                w.add_message(cids[c.id], m.log_time, m.data, m.publish_time, m.sequence)
        w.finish()
    got = list(read_recording([out]))
    assert len(got) == len(list(read_recording([src]))) - 1
    assert "lacks its result message" in caplog.text
