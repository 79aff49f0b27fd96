"""``loopwatch replay --publish``: the recorded raw samples go back on zenoh (real sessions on
loopback) at their original time stamps, and a second, running monitor sees the incident again:
the same windows (samples and time stamps bit for bit), the same verdicts and figures, the same
alerts -- which its own recording shows."""

from __future__ import annotations

import json
import time

import numpy as np
import pytest

from adapters.mcap_reader import read_recording
from service.cli import main
from service.composition import start_monitor
from service.settings import load_settings

from .conftest import loopback_port
from .mcap_helpers import CLEAR_AFTER, HOP, LENGTH, N_WINDOWS, PAPER_LOOP, RAISE_AFTER, record_plant

PORT = loopback_port(21)
ENDPOINT = f"tcp/127.0.0.1:{PORT}"


@pytest.mark.timeout(300)
def test_publish_makes_a_running_monitor_see_the_incident_again(tmp_path):
    first = record_plant(tmp_path / "first")
    settings = load_settings(None, instance="again", sample_time_s=1.0, zenoh={"mode": "peer", "listen": [ENDPOINT]},
                             window={"length": LENGTH, "hop": HOP, "lateness": 16},
                             alerts={"raise_after": RAISE_AFTER, "clear_after": CLEAR_AFTER},
                             analysis={"workers": 0},
                             recording={"enabled": True, "dir": str(tmp_path / "again"), "flush_s": 0.2})
    running = start_monitor(settings)
    try:
        assert main(["replay", str(tmp_path / "first"), "--publish", "--speed", "inf", "--connect", ENDPOINT]) == 0
        deadline = time.monotonic() + 120
        while running.monitor.windows_done < 6 * N_WINDOWS and time.monotonic() < deadline:
            time.sleep(0.1)
        assert running.monitor.drain(60)
    finally:
        running.close()
    assert running.monitor.windows_done == 6 * N_WINDOWS
    a = {(g.loop_id, g.window.seq): g for g in read_recording([tmp_path / "first"])}
    b = {(g.loop_id, g.window.seq): g for g in read_recording([tmp_path / "again"])}
    assert a.keys() == b.keys() and len(a) == 6 * N_WINDOWS
    paper = first.loops[PAPER_LOOP].loop_id          # analysed with another config the first time
    for key, ga in a.items():
        wa, wb = ga.window, b[key].window
        assert wa.index0 == wb.index0
        np.testing.assert_array_equal(wa.t, wb.t)
        assert wa.signals.keys() == wb.signals.keys()
        for sig in wa.signals:
            np.testing.assert_array_equal(wa.signals[sig], wb.signals[sig])
            np.testing.assert_array_equal(wa.times_ns[sig], wb.times_ns[sig])   # original time stamps
        if key[0] != paper:
            strip = lambda m: {k: v for k, v in m.items() if k != "name"}  # noqa: E731
            assert json.dumps(ga.result, sort_keys=True) == json.dumps(b[key].result, sort_keys=True)
            assert (ga.alert is None) == (b[key].alert is None)
            if ga.alert is not None:
                assert strip(ga.alert) == strip(b[key].alert)
    assert sum(g.alert is not None for g in b.values()) == 2


@pytest.mark.timeout(120)
def test_publish_without_a_subscriber_warns_and_still_publishes(tmp_path, monkeypatch, capsys):
    """zenoh drops a put that no known subscriber matches: the publisher waits for a matching
    subscriber before its first put, and after the wait publishes anyway with a warning."""
    import service.commands.replay as replay_cmd
    from adapters.zenoh_session import open_session

    record_plant(tmp_path / "rec")
    monkeypatch.setattr(replay_cmd, "_MATCH_WAIT_S", 0.3)
    endpoint = f"tcp/127.0.0.1:{loopback_port(65)}"
    bus = open_session("peer", listen=[endpoint])  # a bus on which nothing subscribes to the samples
    try:
        assert main(["replay", str(tmp_path / "rec"), "--publish", "--speed", "inf", "--connect", endpoint]) == 0
    finally:
        bus.close()
    assert "no subscriber for" in capsys.readouterr().err
