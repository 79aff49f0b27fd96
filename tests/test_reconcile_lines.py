"""The issue-8 lines computed from stored results (tests/bench/reconcile_lines.py), on records
whose answers are counted by hand."""

from tests.bench.reconcile_lines import lines


def _rec(tag, kind, hidden, effects, base, final, noise=1.0, visible=None):
    return dict(tag=tag, kind=kind, hidden=hidden, effects=effects, base=base, final=final, noise=noise,
                **({"visible": visible} if visible else {}))


def test_lines_count_each_rule_by_hand():
    recs = [
        _rec("1:0", "single", {"slip_jump": [1.5]}, ["slip_jump"], 5.0, 1.0, visible={"slip_jump": 4.0}),
        _rec("1:1", "single", {"stribeck": [1.5, 0.01]}, [], 6.0, 6.0, visible={"stribeck": 6.5}),
        _rec("1:2", "single", {"deadband": [1e-3]}, [], 1.5, 1.5),  # baseline within 2 x noise: not counted
        _rec("1:3", "single", {"dead_time": [0.1]}, ["error"], float("nan"), float("nan")),  # refused
        _rec("1:4", "clean", {}, [], 1.0, 1.0),
        _rec("1:5", "clean", {}, ["deadband"], 1.2, 1.1),
        # a pair found, both visible, each absence costs over twice the truth's error (truth 1.1)
        _rec("1:6", "pair", {"stribeck": [1.5, 0.01], "actuator_lag": [0.2]}, ["actuator_lag", "stribeck"], 9.0, 1.2,
             visible={"stribeck": 5.0, "actuator_lag": 3.0}),
        # a pair missed: both visible against the noise, not against its truth (4.0)
        _rec("1:7", "pair", {"stribeck": [1.5, 0.01], "actuator_lag": [0.2]}, ["stribeck"], 8.0, 5.0,
             visible={"stribeck": 5.0, "actuator_lag": 6.0}),
    ]
    truth = {"1:0": 1.0, "1:1": 6.3, "1:6": 1.1, "1:7": 4.0}
    out = lines(recs, truth)
    assert out[0] == "singles named first, baseline >= 2 x noise: 1/2 = 50.0 %; visible: 1/2 = 50.0 %"
    assert out[1] == "clean, none named: 1/2 = 50.0 %"
    assert out[2].startswith("pairs, both found: 1/2 = 50.0 %; both visible (>= 2 x noise): 1/2 = 50.0 %; "
                             "both visible against the truth (each >= 2 x the truth's RMSE): 1/1 = 100.0 %")
    # final <= 0.5 x baseline on 1:0 (1/5), 1:6, not 1:1 (6/6) nor 1:7 (5/8); the truth reads <= half the
    # baseline on 1:0 (1 <= 2.5), 1:6 (1.1 <= 4.5) and 1:7 (4 <= 4), not on 1:1 (6.3 > 3)
    assert out[3] == ("final <= 0.5 x baseline: 2/4 = 50.0 %; where the truth reads <= 0.5 x baseline: 2/3 = 66.7 % "
                      "(not counted: 1 records whose truth reads more or has no stored ratio)")


def test_truth_files_are_read_in_either_stored_form():
    # what accuracy_reconcile --truth --json writes (a list of records, one refused: NaN) and the
    # {tag: ratio} dict of the older stored files give the same map
    from tests.bench.reconcile_lines import truth_ratios

    written = [{"tag": "3:0", "kind": "single", "truth": 1.25, "error": ""},
               {"tag": "3:1", "kind": "clean", "truth": float("nan"), "error": "ModelConfigError(...)"}]
    got = truth_ratios(written)
    assert list(got) == ["3:0", "3:1"] and got["3:0"] == 1.25 and got["3:1"] != got["3:1"]
    assert truth_ratios({"3:0": 1.25}) == {"3:0": 1.25}
