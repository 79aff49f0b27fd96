"""Monitor settings: TOML + environment overrides, readable errors naming the bad key."""

import textwrap

import pytest

from service.composition import loop_config_factory
from service.settings import SettingsError, load_settings


def write(tmp_path, text):
    p = tmp_path / "m.toml"
    p.write_text(textwrap.dedent(text))
    return p


def test_defaults_bind_loopback_only():
    s = load_settings(None)
    assert s.zenoh.mode == "peer" and s.zenoh.listen == ["tcp/127.0.0.1:7447"]
    assert (s.keys.prefix, s.keys.alert_prefix) == ("plant", "loopwatch/alerts")
    assert (s.alerts.raise_after, s.alerts.clear_after) == (3, 3)


def test_deploy_examples_load():
    s = load_settings("deploy/monitor.toml")
    assert s.loops["area1/FIC101"].sample_time_s == 0.5
    c = loop_config_factory(s)
    assert (c("area1/FIC101").length_s, c("area1/FIC101").hop_s, c("area1/FIC101").analysis.signal) == (600.0, 120.0, "op")
    assert (c("other").length, c("other").hop, c("other").sample_time_s) == (1024, 256, 1.0)
    assert load_settings("deploy/monitor-client.toml").zenoh.connect == ["tcp/127.0.0.1:7446"]


def test_environment_overrides_file(tmp_path, monkeypatch):
    p = write(tmp_path, """
        instance = "a"
        [alerts]
        raise_after = 4
        clear_after = 6
    """)
    monkeypatch.setenv("LOOPWATCH_ALERTS__RAISE_AFTER", "7")
    monkeypatch.setenv("LOOPWATCH_ZENOH__LISTEN", '["tcp/127.0.0.1:17999"]')
    s = load_settings(p)
    assert (s.instance, s.alerts.raise_after, s.alerts.clear_after) == ("a", 7, 6)
    assert s.zenoh.listen == ["tcp/127.0.0.1:17999"]


def test_errors_name_every_bad_key_and_value(tmp_path):
    p = write(tmp_path, """
        [zenoh]
        mode = "server"
        listen = ["127.0.0.1:7447"]
        [alerts]
        raise_aftr = 2
        [window]
        length = 10
        hop_s = 5.0
        hop = 3
        [analysis]
        signal = "flow"
        [loops."area1/*"]
        sample_time_s = -1
    """)
    with pytest.raises(SettingsError) as e:
        load_settings(p)
    msg = str(e.value)
    for fragment in [
        "zenoh.mode: Input should be 'peer' or 'client' (got 'server')",
        "zenoh.listen: Value error, endpoint(s) ['127.0.0.1:7447'] must look like 'tcp/127.0.0.1:7447'",
        "alerts.raise_aftr: Extra inputs are not permitted (got 2)",
        "window.length: Input should be greater than or equal to 64 (got 10)",
        "analysis.signal: Input should be 'pv', 'op' or 'error' (got 'flow')",
        "loops.area1/*.sample_time_s: Input should be greater than 0 (got -1)",
    ]:
        assert fragment in msg, msg
    assert str(p) in msg


def test_env_value_errors_are_reported_too(monkeypatch):
    monkeypatch.setenv("LOOPWATCH_ANALYSIS__WORKERS", "many")
    with pytest.raises(SettingsError, match=r"analysis.workers: Input should be a valid integer.*'many'"):
        load_settings(None)


@pytest.mark.parametrize(
    "text, fragment",
    [
        ('[window]\nlength = 128\nlength_s = 60.0', "not both"),
        ('[zenoh]\nmode = "client"\nconnect = []', "needs at least one connect endpoint"),
        ('[keys]\nprefix = "plant/**"', "keys.prefix"),
        ('[ingest]\ntime_min = 5.0\ntime_max = 1.0', "time_min (5.0) must be < time_max (1.0)"),
        ('instance = "a/b"', "instance"),
        ("[alerts\nraise_after = 1", "not valid TOML"),
    ],
)
def test_invalid_combinations(tmp_path, text, fragment):
    with pytest.raises(SettingsError) as e:
        load_settings(write(tmp_path, text))
    assert fragment in str(e.value)


def test_missing_file():
    with pytest.raises(SettingsError, match="not found"):
        load_settings("/nonexistent/monitor.toml")


def test_analysis_threshold_goes_to_the_method_in_use():
    from pipeline.diagnosis import DiagnosisConfig
    from service.composition import loop_config_factory

    def diag(**analysis):
        return loop_config_factory(load_settings(None, analysis=analysis))("L1").analysis.diagnosis

    default = DiagnosisConfig()
    assert diag() == default                                    # unset: each method's own default
    robust = diag(threshold=0.2)
    assert robust.method == "robust" and robust.robust.min_dnl == 0.2 and robust.decision_threshold == 0.2
    paper = diag(method="paper", threshold=0.3)
    assert paper.method == "paper" and paper.threshold == 0.3 and paper.robust == default.robust
