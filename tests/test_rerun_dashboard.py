"""The rerun dashboard sink, read back with rerun's own reader (``rerun.chunk.RrdReader``).

A simulated plant (stiction, tuning, healthy loop; the planted truth) goes through the monitor
core window by window into the sink, as in the live monitor and in replay.  Expected values come
from the planted samples (signals round-trip exactly, over the time range the windows cover),
the planted oscillation frequency, the alert objects the core produced, and the throttling
rules with an injected clock."""

import math
import sys
from pathlib import Path

import numpy as np
import pytest

from adapters.rerun_dashboard import (
    RerunDashboard,
    RerunSpecError,
    TokenBucket,
    open_rerun_sink,
    parse_rerun_spec,
    phase_curve,
)
from pipeline.diagnosis import DiagnosisConfig
from service.cli import main as cli_main
from service.commands.simulate_plant import make_plant
from service.settings import SettingsError, load_settings

from .conftest import loopback_port
from .rerun_helpers import HOP, T0, W, feed_plant, read_rrd, scalars

DURATION = 2600.0
N_WIN = int((DURATION - W) // HOP + 1)           # 7 windows per loop
LAST_END = (N_WIN - 1) * HOP + W - 1             # sample index of the last window's end
MIX = ("stiction-datadriven", "tuning", "healthy")


@pytest.fixture(scope="module")
def plant():
    return make_plant(3, duration_s=DURATION, mix=MIX)


@pytest.fixture(scope="module")
def recorded(plant, tmp_path_factory):
    path = tmp_path_factory.mktemp("rrd") / "plant.rrd"
    sink = open_rerun_sink(f"save:{path}", announce=None)
    fed = feed_plant(sink, plant)
    sink.close()
    return path, fed, read_rrd(path), sink.status()


def test_entities_of_plant_and_loops(plant, recorded):
    _, _, ents, _ = recorded
    for p in ("/plant/overview", "/plant/alerts", "/plant/loops_in_alert"):
        assert p in ents, p
    for lp in plant:
        base = f"/loops/{lp.loop_id}"
        for sig in ("op", "pv", "sp"):
            assert f"{base}/signals/{sig}" in ents
        assert f"{base}/dnl" in ents and f"{base}/phase" in ents
    stiction = f"/loops/{plant[0].loop_id}"
    for p in ("imfs/band", "if/band/if", "if/band/if_z", "alerts"):
        assert f"{stiction}/{p}" in ents, p
    assert not any(p.startswith(f"/loops/{plant[2].loop_id}/imfs") for p in ents), "healthy loop: nothing to explain"


def test_signals_round_trip_over_the_windows_time_range(plant, recorded):
    _, _, ents, _ = recorded
    for lp in plant:
        for sig in ("op", "pv", "sp"):
            t, v = scalars(ents[f"/loops/{lp.loop_id}/signals/{sig}"])
            np.testing.assert_array_equal(t, T0 + np.arange(LAST_END + 1))   # each sample once, no overlap
            np.testing.assert_array_equal(v, getattr(lp.sim, sig)[:LAST_END + 1])


def test_every_window_logs_dnl_and_threshold(plant, recorded):
    """One row per window: TDNL (NaN when not oscillating), the decision threshold of the default
    (robust) method, surrogate 95 %."""
    _, fed, ents, status = recorded
    assert status["windows"] == 3 * N_WIN
    for lp in plant:
        t, v = scalars(ents[f"/loops/{lp.loop_id}/dnl"], column=None)
        np.testing.assert_array_equal(t, T0 + W - 1 + HOP * np.arange(N_WIN))
        assert np.all(v[:, 1] == DiagnosisConfig().robust.min_dnl)
        mine = [r.diagnosis for w, r, _ in fed.windows if w.loop_id == lp.loop_id]
        np.testing.assert_allclose(v[:, 0], [d.tdnl for d in mine], equal_nan=True)
        np.testing.assert_allclose(v[:, 2], [d.robust.threshold if d.robust else math.nan for d in mine],
                                   equal_nan=True)
    assert np.all(np.isnan(scalars(ents[f"/loops/{plant[2].loop_id}/dnl"])[1]))   # healthy: no TDNL


def test_alert_texts_only_for_the_sticking_valve(plant, recorded):
    _, fed, ents, _ = recorded
    alerts = fed.alerts()
    assert [a.loop_id for a in alerts] == [plant[0].loop_id] and alerts[0].state == "raised"
    for path in ("/plant/alerts", f"/loops/{plant[0].loop_id}/alerts"):
        e = ents[path]
        assert len(e.values) == 1
        text = e.values[0][0]
        assert text.startswith(f"{plant[0].loop_id}: alert RAISED - nonlinear")
        assert "valve stiction" in text and e.times == [alerts[0].window_end_t]
    assert not any(p.endswith("/alerts") for p in ents if plant[1].loop_id in p or plant[2].loop_id in p)


def test_overview_sorted_by_severity(plant, recorded):
    _, _, ents, _ = recorded
    last = ents["/plant/overview"].values[-1][0]
    assert "**3 loops, 1 in alert**" in last
    rows = [ln for ln in last.splitlines() if ln.startswith("| ") and ln[2].isdigit()]
    assert [r.split("|")[2].strip() for r in rows] == [lp.loop_id for lp in plant]   # alert, linear, not oscillating
    assert "**ALERT**" in rows[0] and "| ok |" in rows[1]
    t, n = scalars(ents["/plant/loops_in_alert"])
    assert n[-1] == 1.0 and t[-1] == T0 + LAST_END


def test_if_z_of_the_band_component_at_the_planted_frequency(plant, recorded):
    """IF_z is the full-wave zero-crossing frequency: compare with the oscillation frequency
    counted independently from the planted PV's mean crossings."""
    _, _, ents, _ = recorded
    lp = plant[0]
    t, ifz = scalars(ents[f"/loops/{lp.loop_id}/if/band/if_z"])
    k = (t - T0).astype(int)
    pv = lp.sim.pv[k.min():k.max() + 1] - lp.sim.pv[k.min():k.max() + 1].mean()
    crossings = np.flatnonzero(np.signbit(pv[1:]) != np.signbit(pv[:-1]))
    f_ref = (crossings.size - 1) / 2.0 / (crossings[-1] - crossings[0])
    assert np.median(ifz) == pytest.approx(f_ref, rel=0.1)
    _, inst = scalars(ents[f"/loops/{lp.loop_id}/if/band/if"])
    assert np.median(inst) == pytest.approx(f_ref, rel=0.15)


def test_phase_plot_of_the_last_drawn_window(plant, recorded):
    _, _, ents, _ = recorded
    lp = plant[0]
    e = ents[f"/loops/{lp.loop_id}/phase"]
    assert e.times[-1] == T0 + LAST_END
    pts = np.array(e.values[-1][0])
    expect = phase_curve(lp.sim.op[LAST_END + 1 - W:LAST_END + 1], lp.sim.pv[LAST_END + 1 - W:LAST_END + 1])
    np.testing.assert_allclose(pts, expect, atol=1e-6)
    assert pts[:, 0].min() == -1 and pts[:, 0].max() == 1     # OP scaled to [-1, 1]


def test_phase_curve_scaling():
    op, pv = np.array([10.0, 20.0, 30.0]), np.array([1.0, 1.5, 2.0])
    np.testing.assert_allclose(phase_curve(op, pv), [[-1, 1], [0, 0], [1, -1]])   # y = -PV: up is higher PV
    assert np.all(phase_curve(np.ones(3), pv)[:, 0] == 0)


# ----------------------------------------------------------------------------- throttling


class FrozenClock:
    def __init__(self):
        self.t = 0.0

    def __call__(self):
        return self.t


def test_token_bucket():
    clock = FrozenClock()
    b = TokenBucket(2.0, 3, clock)
    assert [b.take() for _ in range(4)] == [True, True, True, False]
    clock.t = 0.5
    assert [b.take(), b.take()] == [True, False]
    clock.t = 100.0
    assert sum(b.take() for _ in range(10)) == 3     # capped at the burst


def test_throttle_draws_little_but_logs_every_window(plant, tmp_path):
    """Frozen wall clock, one token each: signals of the healthy loop at most one window; the focus
    loop and the alert window always; every window's DNL row still logged; overview refreshed
    only at the start and at close."""
    import rerun as rr

    path = tmp_path / "throttled.rrd"
    rec = rr.RecordingStream("loopwatch-test")
    rec.save(path)
    focus = plant[1].loop_id
    sink = RerunDashboard(rec, draw_per_s=0.0, draw_burst=1, explain_per_s=0.0, explain_burst=1,
                          overview_every_s=1000.0, focus=[focus], clock=FrozenClock())
    fed = feed_plant(sink, plant)
    sink.close()
    ents, st = read_rrd(path), sink.status()
    assert st["windows"] == 3 * N_WIN and st["draw_skipped"] > 0
    assert st["drawn"] + st["draw_skipped"] == 3 * N_WIN
    assert st["overview_refreshes"] == 2
    t_focus, _ = scalars(ents[f"/loops/{focus}/signals/pv"])
    assert t_focus.size == LAST_END + 1                                    # focus loop: everything
    healthy = ents.get(f"/loops/{plant[2].loop_id}/signals/pv")
    assert healthy is None or len(healthy.times) <= W                      # at most one window
    alert = fed.alerts()[0]
    t_st, _ = scalars(ents[f"/loops/{alert.loop_id}/signals/pv"])
    assert t_st[-1] >= alert.window_end_t                                  # the alert window was drawn
    t_if, _ = scalars(ents[f"/loops/{alert.loop_id}/if/band/if_z"])
    assert alert.window_end_t in t_if                                      # and explained
    for lp in plant:
        assert len(ents[f"/loops/{lp.loop_id}/dnl"].times) == N_WIN


def test_offline_draws_everything_and_decomposes_each_stretch_once(plant, tmp_path):
    """Replay mode: no wall clock; with windows of 1024 every 256 samples a loop's window is
    explained when it starts after the last explained one (windows 0 and 4) or changes the alert
    state (the stiction loop raises on window 1, so its next stretch starts at window 5)."""
    path = tmp_path / "offline.rrd"
    sink = open_rerun_sink(f"save:{path}", announce=None, offline=True, clock=FrozenClock())
    fed = feed_plant(sink, plant)
    sink.close()
    st, ents = sink.status(), read_rrd(path)
    assert st["drawn"] == 3 * N_WIN and st.get("draw_skipped", 0) == 0
    assert fed.alerts()[0].window_seq == 1
    assert st["explained"] == 3 + 2                       # stiction 0, 1, 5; tuning 0, 4; healthy none
    t, _ = scalars(ents[f"/loops/{plant[0].loop_id}/imfs/band"])
    np.testing.assert_array_equal(t, T0 + np.arange(5 * HOP + W))     # windows 0, 1, 5 tile [0, end of 5] once


def test_publish_does_not_repeat_an_alert_seen_with_its_window(plant, tmp_path):
    path = tmp_path / "a.rrd"
    sink = open_rerun_sink(f"save:{path}", announce=None)
    fed = feed_plant(sink, plant[:1])
    for a in fed.alerts():
        sink.publish(a)                   # a sink wired as both WindowSink and AlertSink
    sink.close()
    assert len(read_rrd(path)["/plant/alerts"].values) == len(fed.alerts()) == 1


# ----------------------------------------------------------------------------- specs


@pytest.mark.parametrize("spec, kind, host, grpc, web", [
    ("serve", "serve", "127.0.0.1", 9876, 9090),
    ("serve:19870", "serve", "127.0.0.1", 19870, 9090),
    ("serve:19870:19871", "serve", "127.0.0.1", 19870, 19871),
    ("serve:0.0.0.0:19870", "serve", "0.0.0.0", 19870, 9090),
    ("serve:19870:0", "serve", "127.0.0.1", 19870, 0),
])
def test_serve_specs(spec, kind, host, grpc, web):
    t = parse_rerun_spec(spec)
    assert (t.kind, t.host, t.grpc_port, t.web_port) == (kind, host, grpc, web)
    assert t.grpc_url == f"rerun+http://{host}:{grpc}/proxy"


@pytest.mark.parametrize("spec, url", [
    ("connect:9876", "rerun+http://127.0.0.1:9876/proxy"),
    ("connect:10.0.0.5:9877", "rerun+http://10.0.0.5:9877/proxy"),
    ("connect:rerun+http://127.0.0.1:9876/proxy", "rerun+http://127.0.0.1:9876/proxy"),
])
def test_connect_specs(spec, url):
    assert parse_rerun_spec(spec).grpc_url == url


def test_save_spec():
    t = parse_rerun_spec("save:out/demo.rrd")
    assert t.kind == "save" and t.path == Path("out/demo.rrd")


@pytest.mark.parametrize("spec, words", [
    ("", "unknown form"),
    ("file:x.rrd", "unknown form"),
    ("save:", "needs a file"),
    ("save:out/demo.mcap", "must end in .rrd"),
    ("serve:abc:x", "port 'x'"),
    ("serve:99999", "0..65535"),
    ("serve:1:2:3", "too many fields"),
    ("serve:9090:9090", "differ"),
    ("connect:", "needs an address"),
    ("connect:rerun+http://127.0.0.1:9876/", "/proxy"),
    ("connect:host:port", "port 'port'"),
])
def test_bad_specs_give_one_line(spec, words):
    with pytest.raises(RerunSpecError) as err:
        parse_rerun_spec(spec)
    msg = str(err.value)
    assert words in msg and "\n" not in msg and repr(spec) in msg


def test_bad_spec_in_settings_names_the_key():
    with pytest.raises(SettingsError, match=r"rerun\.spec: .*must end in \.rrd"):
        load_settings(None, rerun={"spec": "save:x.txt"})
    assert load_settings(None).rerun.spec is None          # off by default


def test_cli_bad_spec_is_one_line_exit_2(capsys, monkeypatch):
    monkeypatch.setattr(sys, "argv", ["loopwatch"])
    assert cli_main(["monitor", "--rerun", "serve:abc:x"]) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith("loopwatch: error: --rerun 'serve:abc:x'") and "\n" not in err


# ----------------------------------------------------------------------------- serving


def _listening(port: int) -> list[str]:
    """Local addresses listening on ``port`` (IPv4, from /proc/net/tcp)."""
    out = []
    for line in Path("/proc/net/tcp").read_text().splitlines()[1:]:
        local, state = line.split()[1], line.split()[3]
        ip_hex, port_hex = local.split(":")
        if state == "0A" and int(port_hex, 16) == port:
            out.append(".".join(str(int(ip_hex[i:i + 2], 16)) for i in (6, 4, 2, 0)))
    return out


def test_serve_binds_loopback_only_and_stops_its_web_viewer(plant):
    grpc, web = loopback_port(60), loopback_port(61)
    sink = open_rerun_sink(f"serve:{grpc}:{web}", announce=None)
    try:
        feed_plant(sink, plant[:1])
        assert _listening(grpc) == ["127.0.0.1"]
        assert _listening(web) == ["127.0.0.1"]
    finally:
        sink.close()
    assert _listening(web) == [] and _listening(grpc) == []
