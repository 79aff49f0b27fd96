"""``loopwatch replay FILE --rerun save:OUT.rrd``: a recorded plant rendered offline, read back with
rerun's own reader.  Expected entities, times and alert texts come from the planted plant and
the alerts the monitor recorded."""

import numpy as np

from service.cli import main
from service.replay import recorded_windows

from .mcap_helpers import N_WINDOWS, record_plant
from .rerun_helpers import read_rrd, scalars


def test_replay_renders_the_recording_as_a_rerun_dashboard(tmp_path):
    rec = record_plant(tmp_path / "recordings")
    out = tmp_path / "incident.rrd"
    assert main(["replay", str(rec.dir), "--rerun", f"save:{out}"]) == 0
    ents = read_rrd(out)
    for lp in rec.loops:
        ends = [r.window.end_t for r in recorded_windows([rec.dir], loops=[lp.loop_id])]
        assert len(ends) == N_WINDOWS
        base = f"/loops/{lp.loop_id}"
        for sig in ("op", "pv", "sp"):
            assert f"{base}/signals/{sig}" in ents, (base, sig)
        t, _ = scalars(ents[f"{base}/dnl"])
        np.testing.assert_array_equal(t, ends)                     # one DNL row per recorded window
    assert rec.alerts, "the recorded plant must raise at least one alert"
    texts = [v[0] for v in ents["/plant/alerts"].values]
    for a in rec.alerts:
        assert any(tx.startswith(f"{a.loop_id}: alert {a.state.upper()}") for tx in texts), (a, texts)


def test_replay_rerun_and_publish_do_not_mix(tmp_path):
    assert main(["replay", str(tmp_path), "--rerun", "save:x.rrd", "--publish"]) == 2
