"""The monitor core with in-memory fakes: grid alignment, windows, counters, alert hysteresis,
ordering of results, bad input.  Expected values come from the planted samples."""

import json
import math
import threading
from concurrent.futures import ThreadPoolExecutor

import numpy as np
import pytest

from adapters.payloads import BINARY_ENCODING, encode_binary_batch, encode_json_batch, encode_sample
from pipeline.diagnosis import WindowDiagnosis
from service.errors import ServiceError
from service.monitor import (
    AlertTracker,
    LoopBuffer,
    LoopConfig,
    Monitor,
    MonitorCore,
    RateLimitedLog,
    WindowResult,
)

T0 = 1_700_000_000.0
W, HOP = 128, 32


def planted(n, seed=0):
    return np.random.default_rng(seed).standard_normal(n).round(6)


def cfg(**kw):
    base = dict(sample_time_s=1.0, length=W, hop=HOP, lateness=8)
    base.update(kw)
    return LoopConfig(**base)


def core(**kw):
    c = cfg(**{k: v for k, v in kw.items() if k in ("sample_time_s", "lateness", "length", "hop")})
    return MonitorCore(loop_config=lambda _id: c, raise_after=kw.get("raise_after", 2),
                       clear_after=kw.get("clear_after", 2), clock=lambda: 0.0)


def feed_binary(c, loop, signal, t0, v, batch):
    out = []
    for i in range(0, v.size, batch):
        p, a = encode_binary_batch(t0 + i, 1.0, v[i:i + batch])
        out += c.ingest(f"plant/{loop}/{signal}", p, BINARY_ENCODING, a)
    return out


# ----------------------------------------------------------------------------- windows


def test_windows_equal_slices_of_the_stream():
    """Streaming equals batch: window j holds exactly samples [j*HOP, j*HOP + W) of the record."""
    x = planted(400)
    ws = feed_binary(core(), "L1", "pv", T0, x, batch=7)
    # windows close once pv reaches their end: starts 0, 32, ..., last start s with s + W <= 400
    starts = list(range(0, 400 - W + 1, HOP))
    assert [w.index0 for w in ws] == starts
    for w in ws:
        np.testing.assert_array_equal(w.signals["pv"], x[w.index0:w.index0 + W])
        np.testing.assert_array_equal(w.t, T0 + np.arange(w.index0, w.index0 + W))
    assert [w.seq for w in ws] == list(range(len(starts)))


@pytest.mark.parametrize("fmt", ["single", "json", "binary"])
def test_formats_and_batchings_give_identical_windows(fmt):
    x = planted(300, seed=1)
    ref = feed_binary(core(), "L", "pv", T0, x, batch=300)
    c = core()
    got = []
    if fmt == "single":
        for i, v in enumerate(x):
            got += c.ingest("plant/L/pv", encode_sample(T0 + i, v))
    elif fmt == "json":
        for i in range(0, 300, 13):
            got += c.ingest("plant/L/pv", encode_json_batch(T0 + i, 1.0, x[i:i + 13]))
    else:
        got = feed_binary(c, "L", "pv", T0, x, batch=1)
    assert len(got) == len(ref) == (300 - W) // HOP + 1
    for a, b in zip(got, ref):
        np.testing.assert_array_equal(a.signals["pv"], b.signals["pv"])
        assert a.index0 == b.index0


def test_jitter_out_of_order_duplicates_and_gaps():
    x = planted(200, seed=2)
    rng = np.random.default_rng(3)
    order = np.arange(200)
    # out of order within blocks of 5 (less than the lateness), jitter +-0.3 s
    for i in range(0, 200, 5):
        order[i:i + 5] = rng.permutation(order[i:i + 5])
    missing = {17, 18, 60, 150}
    dups = [10, 11, 99]
    c = core()
    ws = []
    for n, k in enumerate(order):
        if k in missing:
            continue
        ws += c.ingest("plant/L/pv", encode_sample(T0 + k + rng.uniform(-0.3, 0.3), x[k]))
        if n == 120:  # a second value for an occupied grid point is rejected, the first kept
            for d in dups:
                ws += c.ingest("plant/L/pv", encode_sample(T0 + d + 0.1, 999.0))
    st = c.loop_status("L")
    assert st["samples"] == {"pv": 200 - len(missing)}
    assert st["rejected"] == {"duplicate": len(dups)}
    w0 = ws[0]
    expect = x[:W].copy()
    expect[[17, 18, 60]] = np.nan
    np.testing.assert_array_equal(w0.signals["pv"], expect)


def test_sample_time_inferred_from_single_samples_and_from_batch_dt():
    x = planted(200, seed=4)
    c = MonitorCore(loop_config=lambda _id: cfg(sample_time_s=None), clock=lambda: 0.0)
    ws = []
    for i, v in enumerate(x):
        ws += c.ingest("plant/L/pv", encode_sample(T0 + 2.0 * i, v))
    assert c.loop_status("L")["sample_time_s"] == 2.0
    np.testing.assert_array_equal(ws[0].signals["pv"], x[:W])
    assert ws[0].sample_time_s == 2.0
    c.ingest("plant/M/pv", encode_json_batch(T0, 0.5, x[:10]))
    assert c.loop_status("M")["sample_time_s"] == 0.5


def test_window_in_seconds_uses_the_sample_time():
    b = LoopBuffer("L", LoopConfig(sample_time_s=0.5, length=None, hop=None, length_s=100.0, hop_s=25.0))
    ws = b.add("pv", T0 + 0.5 * np.arange(260), planted(260))
    assert (b.length, b.hop) == (200, 50)
    assert [w.index0 for w in ws] == [0, 50]


def test_late_samples_are_rejected_and_counted():
    x = planted(200)
    c = core()
    feed_binary(c, "L", "pv", T0, x, batch=10)      # windows at 0 and 32 closed -> next start 64
    c.ingest("plant/L/pv", encode_sample(T0 + 5, 1.0))      # before the next window: late
    c.ingest("plant/L/pv", encode_sample(T0 + 63, 1.0))     # still late
    st = c.loop_status("L")
    assert st["rejected"] == {"late": 2}
    assert st["samples"] == {"pv": 200}


def test_both_pacing_signals_must_reach_the_end_unless_too_late():
    x, y = planted(200, 1), planted(200, 2)
    c = core()
    ws = feed_binary(c, "L", "pv", T0, x[:10], batch=10)
    ws += feed_binary(c, "L", "op", T0, y[:130], batch=130)  # op at 129 < 127 + lateness 8
    assert ws == []
    ws = feed_binary(c, "L", "pv", T0 + 10, x[10:127], batch=117)   # pv only at 126
    assert ws == []
    ws = feed_binary(c, "L", "pv", T0 + 127, x[127:128], batch=1)
    assert [w.index0 for w in ws] == [0]
    np.testing.assert_array_equal(ws[0].signals["op"], y[:W])
    np.testing.assert_array_equal(ws[0].signals["pv"], x[:W])
    # op stops: pv alone closes the next window only `lateness` (8) samples past its end (159)
    ws = feed_binary(c, "L", "pv", T0 + 128, x[128:167], batch=39)   # pv up to 166
    assert ws == []
    ws = feed_binary(c, "L", "pv", T0 + 167, x[167:168], batch=1)    # 167 = 159 + 8
    assert [w.index0 for w in ws] == [32]
    assert np.isnan(ws[0].signals["op"][130 - 32:]).all()


def test_outage_longer_than_the_ring_skips_empty_windows():
    x = planted(200)
    c = core()
    ws = feed_binary(c, "L", "pv", T0, x[:150], batch=50)
    assert [w.index0 for w in ws] == [0]
    # data resumes 10,000 samples later
    ws = feed_binary(c, "L", "pv", T0 + 10_000, x, batch=50)
    starts = [w.index0 for w in ws]
    # the windows holding old data (starts <= 149) are flushed, then the next window starts at
    # or just before the first new sample on the hop grid: 10000 // 32 * 32 = 9984
    assert starts[:5] == [32, 64, 96, 128, 9984]
    assert c.loop_status("L")["skipped_windows"] == (9984 - 160) // 32


def test_mode_manual_makes_window_invalid():
    from service.monitor import analyze_window

    c = core()
    feed_binary(c, "L", "mode", T0, np.ones(200), batch=200)
    m = np.ones(200)
    m[50] = 0
    c2 = core()
    feed_binary(c2, "L", "mode", T0, m, batch=200)
    ws = feed_binary(c2, "L", "pv", T0, np.sin(np.arange(200) / 5.0), batch=200)
    assert analyze_window(ws[0]).diagnosis.verdict == "invalid"
    assert "not in automatic for 1 of 128" in analyze_window(ws[0]).diagnosis.reason


# ----------------------------------------------------------------------------- bad input


def test_bad_input_is_counted_per_loop_and_never_raises():
    c = core()
    good = feed_binary(c, "A", "pv", T0, planted(50), batch=50)
    assert good == []
    for i in range(8):  # 8 single samples fix loop B's grid
        c.ingest("plant/B/pv", encode_sample(T0 + i, 1.0))
    bad = [
        ("plant/A/pv", b"{not json", "", None, "malformed"),
        ("plant/A/pv", b'{"t": 1700000000, "v": "x"}', "", None, "wrong_type"),
        ("plant/A/pv", b'{"t": 1700000000, "v": NaN}', "", None, "non_finite"),
        ("plant/A/pv", b'{"t": 99, "v": 1}', "", None, "bad_timestamp"),
        ("plant/A/pv", b'{"t": 1e300, "v": 1}', "", None, "bad_timestamp"),
        ("plant/A/flow", encode_sample(T0, 1.0), "", None, "unknown_signal"),
        ("plant/A/pv", b"\x00" * 7, BINARY_ENCODING, b'{"t0": 1700000000, "dt": 1}', "malformed"),
    ]
    for key, payload, enc, att, _ in bad:
        assert c.ingest(key, payload, enc, att) == []
    c.ingest("plant/A/pv", encode_json_batch(T0 + 50, 1.0, np.array([1.0, np.nan, np.inf, 2.0])))
    st = c.loop_status("A")
    assert st["rejected"] == {"malformed": 2, "wrong_type": 1, "non_finite": 3, "bad_timestamp": 2,
                              "unknown_signal": 1}
    assert st["samples"] == {"pv": 52}
    assert c.loop_status("B")["rejected"] == {} and c.loop_status("B")["samples"] == {"pv": 8}
    c.ingest("plant/pv", b"{}")             # no loop id: counted globally
    c.ingest("elsewhere/X/pv", b"{}")
    assert c.status()["unrouted_rejects"] == {"bad_key": 2}


def test_max_loops_bounds_memory():
    c = MonitorCore(loop_config=lambda _id: cfg(), max_loops=2, clock=lambda: 0.0)
    for name in ("A", "B", "C", "D"):
        c.ingest(f"plant/{name}/pv", encode_sample(T0, 1.0))
    assert sorted(c.loops) == ["A", "B"]
    assert c.status()["unrouted_rejects"] == {"too_many_loops": 2}


def test_rate_limited_log_with_injected_clock(caplog):
    import logging

    now = [0.0]
    rl = RateLimitedLog(logging.getLogger("t"), rate=1.0, clock=lambda: now[0], burst=2)
    sent = [rl.warning(f"m{i}") for i in range(10)]
    assert sent == [True, True] + [False] * 8
    now[0] = 1.0
    assert rl.warning("again") is True
    assert "8 similar message(s) suppressed" in caplog.records[-1].getMessage()
    assert rl.warning("x") is False


# ----------------------------------------------------------------------------- alerts


@pytest.mark.parametrize(
    "verdicts, raise_after, clear_after, expected",
    [
        (["nonlinear", "linear", "nonlinear", "linear"], 2, 2, [None] * 4),        # one odd window: no page
        (["nonlinear", "nonlinear", "nonlinear"], 2, 2, [None, "raised", None]),
        (["nonlinear", "invalid", "nonlinear"], 2, 2, [None, None, "raised"]),     # invalid keeps the streak
        (["nonlinear"] * 3 + ["linear", "nonlinear", "not_oscillating", "linear"], 3, 2,
         [None, None, "raised", None, None, None, "cleared"]),
        (["nonlinear", "nonlinear", "uncertain", "linear", "linear"], 2, 2, [None, "raised", None, None, "cleared"]),
    ],
)
def test_alert_tracker_hysteresis(verdicts, raise_after, clear_after, expected):
    tr = AlertTracker(raise_after, clear_after)
    assert [tr.update(v, 0.3) for v in verdicts] == expected


def test_alert_tracker_validates():
    with pytest.raises(ServiceError):
        AlertTracker(0, 1)
    with pytest.raises(ServiceError):
        LoopConfig(length=1024, hop=None)


# ----------------------------------------------------------------------------- runtime with fakes


class FakeAlertSink:
    def __init__(self):
        self.alerts = []

    def publish(self, alert):
        self.alerts.append(alert)


class FakeWindowSink:
    def __init__(self):
        self.windows = []

    def on_window(self, loop_id, window, result, alert):
        self.windows.append((loop_id, window.seq, result.diagnosis.verdict, alert and alert.state))


def fake_analyze(window):
    """Planted verdict: the loop is 'nonlinear' while its pv is positive at the window's end."""
    import time

    time.sleep(0.002 * (window.seq % 3))        # results finish out of order on a pool
    v = "nonlinear" if window.signals["pv"][-1] > 0 else "linear"
    return WindowResult(WindowDiagnosis(v, f"planted {v}", tdnl=0.5 if v == "nonlinear" else 0.01),
                        amplitude=1.0, period_s=20.0, n_missing=0)


def test_monitor_applies_results_in_window_order_and_publishes_transitions():
    # pv > 0 for grid points < 260, < 0 after: windows ending before 260 are nonlinear
    n = 600
    pv = np.where(np.arange(n) < 260, 1.0, -1.0)
    c = MonitorCore(loop_config=lambda _id: cfg(), raise_after=2, clear_after=3, clock=lambda: 0.0)
    alerts, windows = FakeAlertSink(), FakeWindowSink()
    m = Monitor(c, ThreadPoolExecutor(4), alert_sinks=[alerts], window_sinks=[windows], clock=lambda: 0.0,
                analyze=fake_analyze)
    for loop in ("X", "Y"):
        for i in range(0, n, 25):
            p, a = encode_binary_batch(T0 + i, 1.0, pv[i:i + 25])
            m.on_message(f"plant/{loop}/pv", p, BINARY_ENCODING, a)
    assert m.drain(10)
    m.close()
    ends = [s + W - 1 for s in range(0, n - W + 1, HOP)]
    expected_verdicts = ["nonlinear" if e < 260 else "linear" for e in ends]
    for loop in ("X", "Y"):
        got = [w for w in windows.windows if w[0] == loop]
        assert [w[1] for w in got] == list(range(len(ends)))
        assert [w[2] for w in got] == expected_verdicts
    first_linear = expected_verdicts.index("linear")
    for loop in ("X", "Y"):
        la = [a for a in alerts.alerts if a.loop_id == loop]
        assert [(a.state, a.window_seq) for a in la] == [("raised", 1), ("cleared", first_linear + 2)]
        body = json.loads(json.dumps(la[0].to_json()))
        assert body["loop"] == loop and body["state"] == "raised" and body["verdict"] == "nonlinear"
        assert body["window"]["end_t"] == T0 + HOP + W - 1
        assert body["period_s"] == 20.0 and "2 consecutive non-linear windows" in body["evidence"]
    st = m.status()
    assert st["totals"]["alerts_active"] == 0
    assert st["runtime"]["windows_analysed"] == 2 * len(ends)


def test_a_failing_analysis_or_sink_does_not_stop_the_monitor():
    def boom(window):
        raise RuntimeError("planted failure")

    class BadSink:
        def on_window(self, *a):
            raise RuntimeError("sink down")

    c = core()
    m = Monitor(c, ThreadPoolExecutor(1), window_sinks=[BadSink()], analyze=boom, clock=lambda: 0.0)
    x = planted(200)
    for i in range(0, 200, 20):
        p, a = encode_binary_batch(T0 + i, 1.0, x[i:i + 20])
        m.on_message("plant/L/pv", p, BINARY_ENCODING, a)
    assert m.drain(10)
    m.close()
    assert m.windows_done == 3 and m.errors == 6
    assert c.loop_status("L")["last_verdict"] == "invalid"


def test_concurrent_ingest_from_many_threads_loses_nothing():
    c = core()
    x = planted(1000)

    def feed(loop):
        feed_binary(c, loop, "pv", T0, x, batch=10)

    threads = [threading.Thread(target=feed, args=(f"L{i}",)) for i in range(8)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    assert c.totals()["samples_accepted"] == 8000 and c.totals()["rejected"] == {}


def test_status_selects_all_one_or_no_loop():
    c = core()
    for name in ("A", "B"):
        feed_binary(c, name, "pv", T0, planted(20), batch=20)
    assert sorted(c.status()["loops"]) == ["A", "B"]
    assert list(c.status("B")["loops"]) == ["B"]
    assert c.status("")["loops"] == {} and c.status("nope")["loops"] == {}
    assert c.status("")["totals"]["samples_accepted"] == 40


def test_hold_carries_a_sent_on_change_signal_between_its_samples():
    from service.analysis import hold as _hold

    v = np.array([np.nan, np.nan, 2.0, np.nan, 3.0, np.nan])
    assert _hold(v).tolist() == [2.0, 2.0, 2.0, 2.0, 3.0, 3.0]


def test_set_point_sent_on_change_makes_the_window_analyse_the_control_error():
    """SP published only when it changes (two samples in the window): the monitor holds it, sees the
    step inside the window and the diagnosis analyses sp - pv (said in the reason)."""
    from service.monitor import AnalysisConfig, WindowSamples, analyze_window

    n = 1024
    t = T0 + np.arange(n, dtype=float)
    sp = np.full(n, np.nan)
    sp[3], sp[600] = 50.0, 55.0                       # sent on change only
    held = np.where(np.arange(n) < 600, 50.0, 55.0)
    pv = held + 2.0 * np.sin(2 * np.pi * np.arange(n) / 64.0)
    op = 40.0 + 3.0 * np.cos(2 * np.pi * np.arange(n) / 64.0)
    w = WindowSamples("L", 0, 0, t, 1.0, {"pv": pv, "op": op, "sp": sp}, AnalysisConfig())
    reason = analyze_window(w).diagnosis.reason
    assert "analysing the control error" in reason, reason
    w2 = WindowSamples("L", 0, 0, t, 1.0, {"pv": pv, "op": op}, AnalysisConfig())
    assert "control error" not in analyze_window(w2).diagnosis.reason


def test_stick_slip_search_runs_once_per_window_length_of_overlapping_windows():
    """Window 1024, hop 256: of the windows starting at 0, 256, ..., 3840 exactly those starting at
    a multiple of 1024 are searched (one per 1024 samples of data), and a stick-slip finding is
    reported only in those; without a hop every window is searched."""
    from service.monitor import AnalysisConfig, WindowSamples, analyze_window

    t = np.arange(1024, dtype=float)
    starts = range(0, 4096, 256)
    searched = [WindowSamples("L", k, s, t, 1.0, {}, AnalysisConfig(), hop=256).searches_stick_slip
                for k, s in enumerate(starts)]
    assert [s for s, yes in zip(starts, searched) if yes] == [0, 1024, 2048, 3072]
    assert WindowSamples("L", 0, 256, t, 1.0, {}, AnalysisConfig()).searches_stick_slip
    # a healthy, non-oscillating window with PV, OP and SP: the search (and its reason) only when due
    rng = np.random.default_rng(3)
    pv = 50 + 0.2 * rng.standard_normal(1024)
    op = 40 + 0.2 * rng.standard_normal(1024)
    sig = {"pv": pv, "op": op, "sp": np.full(1024, 50.0)}
    due = analyze_window(WindowSamples("L", 4, 1024, t, 1.0, sig, AnalysisConfig(), hop=256)).diagnosis
    skip = analyze_window(WindowSamples("L", 5, 1280, t, 1.0, sig, AnalysisConfig(), hop=256)).diagnosis
    assert due.verdict == skip.verdict == "not_oscillating"
    assert due.stick_slip is not None and skip.stick_slip is None
