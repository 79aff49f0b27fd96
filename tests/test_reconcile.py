"""The discrepancy workflow (models/reconcile.py, `loopwatch reconcile`) on records with a planted
hidden effect (or none).  Short records keep the default run fast; the full suite is
tests/bench/accuracy_reconcile.py."""

from __future__ import annotations

import json
from dataclasses import replace

import numpy as np
import pytest
from scipy.signal import lfilter

from models.errors import IdentificationError, ModelConfigError
from models.identification import ValveData
from models.karnopp import PRESETS, pct_to_pa
from models.reconcile import (
    REGIMES,
    Prepared,
    _MEMO,
    _THREAD_MAP,
    ReconcileConfig,
    _alternatives,
    backward_eliminate,
    _fit,
    _fold_mask,
    _global_fit,
    _grid,
    _initial_baseline,
    _joint_starts,
    _noise_z_p,
    _pool,
    _residuals,
    _score,
    _signed_rank_p,
    _split_seed,
    _stribeck_search,
    prepare,
    pressure_floor,
    reconcile,
    smooth_pressure,
)
from models.valve_effects import EffectValve, actuator_pressure, hidden_record, residual_effects, simulate_effects
from models.valve_tests import Excitation, isa_steps, sine, square
from service.cli import main
from service.commands.reconcile import _named

SHORT = isa_steps(steps_pct=(1.0, 5.0, 20.0, 50.0), hold=2.0)  # 18 s of ISA-75.25 steps


def _run(hidden, seed, tau_p=0.0):
    rec = hidden_record(PRESETS["low"].replace(tau_p=tau_p), SHORT, hidden, seed=seed)
    return reconcile(ValveData(rec.t, rec.p, rec.x, "short"))


def test_smoothing_keeps_steps_and_removes_noise():
    rng = np.random.default_rng(0)
    clean = np.r_[np.full(3000, 1e5), np.full(3000, 1.6e5)]
    p = clean + 200 * rng.standard_normal(clean.size)
    ps = smooth_pressure(p, 1e-3)
    assert np.std((ps - clean)[500:2500]) < 40  # steady: averaged well below the 200 Pa noise
    assert abs(ps[3005] - 1.6e5) < 1000 and abs(ps[2994] - 1e5) < 1000  # no smear across the step


def test_clean_record_names_no_effect():
    r = _run({}, seed=1)
    assert r.effects == []
    assert "no missing effect found" in r.message and "still misses" not in r.message
    assert r.final.rmse < 1.2 * r.noise_floor
    assert r.noise_floor == pytest.approx(1e-5, rel=0.1)
    assert set(r.regime_share) <= set(REGIMES) and sum(r.regime_share.values()) == pytest.approx(1.0)


def test_a_search_stopped_by_its_effect_limit_says_the_model_still_misses():
    # planted truth: the dead time of the test below, 50 ms, misses the baseline by several times the
    # noise; with no effect allowed (max_effects = 0) the search stops at the baseline, and that is
    # the limit's doing, not "no missing effect found"
    rec = hidden_record(PRESETS["low"].replace(tau_p=0.0), SHORT, {"dead_time": (0.05,)}, seed=3)
    r = reconcile(ValveData(rec.t, rec.p, rec.x, "short"), config=ReconcileConfig(max_effects=0))
    assert r.effects == [] and r.baseline.rmse > 4 * r.noise_floor
    assert "no missing effect found" not in r.message
    assert r.message.startswith("stopped after 0 effect(s), the most max_effects allows; the model still misses the data")


def test_a_misfit_no_candidate_explains_is_not_reported_as_nothing_missing():
    # planted truth: a dead time of 50 ms after command steps, which a deadband cannot produce (it
    # delays nothing on the first step, nor a step in the direction of the last); with the deadband
    # as the only candidate nothing is named, and the result must say that the model still misses
    # the data rather than "no missing effect found"
    rec = hidden_record(PRESETS["low"].replace(tau_p=0.0), SHORT, {"dead_time": (0.05,)}, seed=3)
    r = reconcile(ValveData(rec.t, rec.p, rec.x, "short"), config=ReconcileConfig(candidates=("deadband",)))
    assert r.effects == [] and r.baseline.rmse > 4 * r.noise_floor
    assert "no missing effect found" not in r.message
    assert "no candidate effect passes the held-out test; the model still misses the data" in r.message
    # a dead-time record's baseline (Karnopp, F_s = F_c) hardly feels the pressure noise: the
    # misfit is not the pressure's, and the message says how little of it is
    assert r.pressure_floor < 0.5 * r.noise_floor
    assert "the recorded pressure's noise alone moves this model's stem by" in r.message
    assert r.message.endswith("more than the pressure noise explains")


def test_the_pressure_floor_predicts_what_the_recorded_pressures_noise_does_to_the_truth():
    # planted truth: a Stribeck valve (F_s = 1.5 F_c, v_s 5 mm/s) on ramps, driven by the noiseless
    # pressure and recorded with 200 Pa of pressure noise.  Simulated from that noiseless pressure,
    # the truth reads the position noise; from the smoothed recorded pressure it reads above it (a
    # Stribeck runaway turns the newton the smoother leaves into milliseconds).  The bootstrap
    # floor never sees the noiseless pressure; its draws must be distributed like the truth's
    # realised excess over four noise draws of the record (medians within a factor 1.5)
    from tests.bench.accuracy_reconcile import ramps

    cfg = ReconcileConfig()
    realised, boot = [], []
    for seed in (1, 2, 3, 4):
        rec = hidden_record(PRESETS["low"], ramps(3, 30.0), {"stribeck": (1.5, 0.005)}, seed=seed)
        r = prepare(ValveData(rec.t, rec.p, rec.x, "ramps"), cfg.block_s, cfg.sa)
        v = rec.valve
        truth = {"k": v.k, "fc": v.fc, "fv": v.fv, "bias": v.bias, "dv": v.dv, "nb": 0.0, "dfs": v.fs - v.fc, "vs": v.vs}
        dv = 0.01 * r.speed_max

        def ratio2(rr):
            return float(np.mean(_residuals(truth, [rr], cfg, dv)[0] ** 2)) / r.sigma_x**2

        noiseless = ratio2(replace(r, p_smooth=rec.p_true))
        assert noiseless < 1.1**2
        realised.append(np.sqrt(max(ratio2(r) - noiseless, 0.0)))
        boot += list(pressure_floor(truth, [r], cfg, dv) / r.sigma_x)
    assert np.median(realised) > 1.0  # the truth reads above 1.4 times the noise
    assert 1 / 1.5 < np.median(boot) / np.median(realised) < 1.5
    # a valve without Stribeck friction on the same ramps hardly feels the pressure noise
    rec = hidden_record(PRESETS["low"], ramps(3, 30.0), {}, seed=1)
    r = prepare(ValveData(rec.t, rec.p, rec.x, "ramps"), cfg.block_s, cfg.sa)
    v = rec.valve
    clean = {"k": v.k, "fc": v.fc, "fv": v.fv, "bias": v.bias, "dv": v.dv, "nb": 0.0}
    assert np.median(pressure_floor(clean, [r], cfg, 0.01 * r.speed_max)) < 0.5 * r.sigma_x


def test_the_search_memo_and_threads_change_no_number():
    # the balances read from the memo are the balances read afresh (a copy each time: a caller may
    # change its start), a balance the record cannot give is refused every time, and the pressure
    # floor's draws on threads are the draws one after the other, bit for bit
    from concurrent.futures import ThreadPoolExecutor

    cfg = ReconcileConfig()
    kws = [{}, {"at": "head"}, {"at": "breakaway"}, {"at": "head", "fast_slides": True}, {"tau": 0.1}, {"k_scale": 0.3}]
    for hidden in ({}, {"stribeck": (1.5, 0.005)}):  # the Stribeck record last: its recs serve the floor below
        rec = hidden_record(PRESETS["low"], SHORT, hidden, seed=2)
        recs = [prepare(ValveData(rec.t, rec.p, rec.x, "short"), cfg.block_s, cfg.sa)]
        fresh = []
        for kw in kws:
            try:
                fresh.append(_initial_baseline(recs, cfg, **kw))
            except IdentificationError as e:
                fresh.append(e)
        # the premise: the clean record gives no breakaway balance (no slip jump to read)
        assert isinstance(fresh[2], IdentificationError) == (not hidden)
        token = _MEMO.set({})  # one memo per record, as in a search
        try:
            for _ in range(2):
                for kw, want in zip(kws, fresh):
                    if isinstance(want, IdentificationError):
                        with pytest.raises(IdentificationError):
                            _initial_baseline(recs, cfg, **kw)
                        continue
                    got = _initial_baseline(recs, cfg, **kw)
                    assert got == want
                    got["fc"] = -1.0  # the memo's copy is not the caller's
        finally:
            _MEMO.reset(token)
    v = rec.valve
    truth = {"k": v.k, "fc": v.fc, "fv": v.fv, "bias": v.bias, "dv": v.dv, "nb": 0.0, "dfs": v.fs - v.fc, "vs": v.vs}
    dv = 0.01 * recs[0].speed_max
    serial = pressure_floor(truth, recs, cfg, dv, draws=4)
    with ThreadPoolExecutor(2) as ex:
        token = _THREAD_MAP.set(ex.map)
        try:
            threaded = pressure_floor(truth, recs, cfg, dv, draws=4)
        finally:
            _THREAD_MAP.reset(token)
    assert np.array_equal(serial, threaded) and np.all(serial > 0)


def test_backward_elimination_takes_out_unresolved_and_unneeded_effects_and_keeps_the_planted_ones():
    # planted truth: a slip jump (F_s = 1.4 F_c) and a deadband of 10 times the position noise on
    # ramps.  The truth's own effects are favoured by the held-out blocks and kept
    from tests.bench.accuracy_reconcile import ramps

    cfg = ReconcileConfig()
    rec = hidden_record(PRESETS["low"], ramps(3, 30.0), {"slip_jump": (1.4,), "deadband": (1e-4,)}, seed=1)
    r = prepare(ValveData(rec.t, rec.p, rec.x, "ramps"), cfg.block_s, cfg.sa)
    v = rec.valve
    truth = {"k": v.k, "fc": v.fc, "fv": v.fv, "bias": v.bias, "dv": v.dv, "nb": 0.0, "dfs": v.fs - v.fc,
             "deadband": v.deadband}
    dv, rule = 0.01 * r.speed_max, {"nb": 0.0}
    assert backward_eliminate(truth, ["slip_jump", "deadband"], [r], cfg, dv, rule) == (truth, [])
    # a dead time of 0.4 sampling periods and a lag of none beside them are finer than a 1 ms record
    # resolves: taken out, whatever they do to the fit, and the model is left as it was
    padded = {**truth, "theta": 0.4 * r.dt, "tau": 0.0}
    vals, gone = backward_eliminate(padded, ["slip_jump", "dead_time", "deadband", "actuator_lag"], [r], cfg, dv, rule)
    assert vals == truth
    assert sorted(e for e, _ in gone) == ["actuator_lag", "dead_time"]
    assert all(why.startswith("finer than the records resolve") for _, why in gone)
    # on the same valve without the deadband, the truth carrying a deadband of 3 × the noise, or a
    # dead time of 5 samples, resolvable but not in the record: the held-out blocks do not favour
    # either, and each is taken out
    rec = hidden_record(PRESETS["low"], ramps(3, 30.0), {"slip_jump": (1.4,)}, seed=1)
    r = prepare(ValveData(rec.t, rec.p, rec.x, "ramps"), cfg.block_s, cfg.sa)
    for e, extra in (("deadband", {"deadband": 3 * r.sigma_x}), ("dead_time", {"theta": 5 * r.dt})):
        clean = {n: x for n, x in truth.items() if n != "deadband"}
        vals, gone = backward_eliminate({**clean, **extra}, ["slip_jump", e], [r], cfg, dv, rule)
        assert [g for g, _ in gone] == [e] and vals == clean
        assert gone[0][1].startswith("with the later effects the held-out blocks no longer favour it")


def test_a_pair_without_friction_effects_starts_without_static_friction():
    # the breakaway balance reads F_s as well as F_c (planted slip jump, F_s = 1.5 F_c); a pair of
    # a deadband and a dead time must not start with it: the pair's fit would hold it, unnamed and
    # uncounted in the penalty
    from tests.bench.accuracy_reconcile import ramps

    cfg = ReconcileConfig()
    rec = hidden_record(PRESETS["low"], ramps(3, 30.0), {"slip_jump": (1.5,)}, seed=1)
    r = prepare(ValveData(rec.t, rec.p, rec.x, "ramps"), cfg.block_s, cfg.sa)
    assert _initial_baseline([r], cfg, at="breakaway").get("dfs", 0.0) > 0  # the premise
    rules = [{"nb": 3.0, "dv": 0.01 * r.speed_max}]
    starts = _joint_starts(("deadband", "dead_time"), [r], cfg, rules)
    assert starts and not any("dfs" in g or "vs" in g for g in starts)
    assert any(g.get("dfs", 0.0) > 0 for g in _joint_starts(("slip_jump", "deadband"), [r], cfg, rules))


def _unseen(tag: str) -> tuple[ValveData, ReconcileConfig]:
    """Record ``tag`` (``DRAW:I``, ``I`` from 0: ``61:27`` is unseen draw 61, record 28) of the
    accuracy bench's independent simulator, with the workflow's configuration for its valve (S_a).
    The draws are seeded: the record is the one the bench runs."""
    from tests.bench.accuracy_reconcile import make_record, select

    ((_, case),) = select(tag)
    t, p, x, sa = make_record(case)
    return ValveData(t, p, x, tag), ReconcileConfig(sa=sa)


def test_a_misfit_only_the_training_blocks_show_is_not_reported_as_nothing_missing():
    # unseen 189 #4: Stribeck friction (F_s/F_c 1.52) on PRBS; its planted truth reads 1.09 x the
    # noise.  Four of the five blocks with a breakaway are training blocks: the baseline fitted
    # there fits the held-out blocks within the noise (1.04 x) and misses its own training blocks
    # by 5 x.  No held-out test can pass a candidate on this split, and the result must not say
    # that nothing is missing (on main before session 44 it said "no missing effect found")
    data, cfg = _unseen("189:3")
    r = reconcile(data, config=cfg)
    assert r.effects == []
    assert r.baseline.rmse > 3 * r.noise_floor  # the whole record: the hidden curve is there
    assert "no missing effect found" not in r.message
    assert ("but it misses the training blocks it was fitted on by 5.2 × the noise, most of it in breakaway "
            "(blocks with breakaway samples: 1 of 5 held out)") in r.message


def test_an_earlier_effect_that_a_later_one_refitted_stands_in_for_is_taken_out():
    # unseen 177 #8: an actuator lag of 0.21 s on PRBS, nothing else hidden.  The first step names a
    # dead time (it stands in for the lag), the second the lag; with the lag refitted without it the
    # dead time (2.8 ms) removes 0.5 % of the noise power on the held-out blocks, under the relevance
    # bar the forward search holds every effect to: it leaves the final model (planted truth; on main
    # before session 44 it was named first)
    data, cfg = _unseen("177:7")
    r = reconcile(data, config=cfg)
    # a knife edge after it: with OpenBLAS's SkylakeX kernels the search stops at the lag; with its
    # Haswell kernels (what it picks on an AMD EPYC of family 26) it adds a Stribeck curve of 1.2 N
    # over F_c = 557 N (a 6 nm jump) at the same 1.01 times the noise (ACCURACY.md, issue 8, session 54)
    assert r.effects in (["actuator_lag"], ["actuator_lag", "stribeck"])
    assert r.steps[0].params["tau_s"] == pytest.approx(0.2136, rel=0.1)
    assert "dead_time taken out of the final model: the later effects, refitted without it" in r.message
    assert r.final.heldout_rmse < 1.1 * r.noise_floor


@pytest.mark.slow
def test_a_misfit_the_pressure_noise_explains_is_said_to_be_so():
    # unseen 145 #5: Stribeck friction on random steps.  Its planted truth, simulated by the
    # workflow from the smoothed recorded pressure, reads several times the position noise (the
    # runaways move with the newton of noise the smoother leaves), so a model left at that level
    # after `stribeck` is named may be right: the message must say the misfit is within what the
    # pressure noise explains rather than only that the model misses the data
    from tests.bench.accuracy_reconcile import select, truth_values

    data, cfg = _unseen("145:4")
    r = reconcile(data, config=cfg)
    rec = r.records[0]
    truth, _ = truth_values(select("145:4")[0][1], cfg)
    truth_rmse = float(np.sqrt(np.mean(_residuals(truth, [rec], cfg, 0.01 * rec.speed_max)[0] ** 2)))
    assert truth_rmse > 3 * r.noise_floor  # the premise: even the truth reads far above the noise
    assert r.effects == ["stribeck"]
    assert "the model still misses the data" in r.message
    # the search's own verdict on its misfit (a second search's report, where one ran, follows it)
    assert "the misfit is within what the pressure noise explains, so it need not be a missing effect" in r.message
    assert r.pressure_floor > 2 * r.noise_floor


@pytest.mark.slow
def test_effects_the_later_steps_take_to_nothing_leave_the_final_model():
    # unseen 157 #3: a slip jump (F_s = 1.44 F_c), nothing else hidden.  The search names a deadband
    # first, then Stribeck friction, whose fit takes the deadband to 0 m, then a dead time of about
    # 10 µs; neither is in the record and the final model must not carry them
    data, cfg = _unseen("157:2")
    r = reconcile(data, config=cfg)
    assert "deadband" not in r.effects and "dead_time" not in r.effects
    assert r.effects and r.effects[-1] in ("slip_jump", "stribeck")
    assert "deadband taken out of the final model" in r.message
    assert "deadband_m" not in r.final.params and "theta_s" not in r.final.params


@pytest.mark.slow
def test_effects_finer_than_the_record_resolves_are_not_named():
    # unseen 125 #21: a clean record (random steps, nothing hidden).  The search accepts a dead time
    # of 0.4 ms (under one 1 ms sample) and a slip jump of 0.6 N (a stem jump of a third of the
    # position noise): neither can be told from nothing on this record, and nothing is named
    data, cfg = _unseen("125:20")
    r = reconcile(data, config=cfg)
    assert r.effects == []
    assert r.message.startswith("no missing effect found")
    assert "finer than the records resolve" in r.message


@pytest.mark.slow
def test_an_effect_fitted_at_size_zero_is_not_named():
    # unseen draw 89, record 3 of the accuracy bench: a slip jump of 1.26 on a sine sweep behind a
    # 0.3 s V/P lag (planted truth: the slip jump alone).  A deadband passed first (it halves F_c);
    # with the slip jump, the swap's alternative actuator_lag fitted at tau = 1e-11 s and was named
    # first: its gain was the other stick rule.  A swap to an effect of size zero takes the swapped
    # effect out instead
    data, cfg = _unseen("89:2")
    r = reconcile(data, config=cfg)
    assert r.effects == ["slip_jump"]
    assert r.final.params["Fs"] / r.final.params["Fc"] == pytest.approx(1.26, rel=0.1)
    assert r.final.rmse < 1.2 * r.noise_floor


@pytest.mark.slow
def test_hidden_dead_time_is_named_and_the_gap_shrinks():
    r = _run({"dead_time": (0.03,)}, seed=2)
    assert r.effects[:1] == ["dead_time"]
    assert r.steps[0].params["theta_s"] == pytest.approx(0.03, rel=0.2)
    assert r.final.rmse <= 0.5 * r.baseline.rmse


def test_progress_names_each_stage_as_it_begins_and_changes_no_number():
    rec = hidden_record(PRESETS["low"], SHORT, {"dead_time": (0.03,)}, seed=2)
    data = ValveData(rec.t, rec.p, rec.x, "short")
    said = []
    r = reconcile(data, progress=said.append)
    assert r.effects == ["dead_time"]  # the premise: one effect, found in the first round
    assert said[0] == "fitting the baseline"
    assert said[1].startswith("round 1: 5 candidates beside the baseline (")
    added = [i for i, m in enumerate(said) if m.startswith("added dead_time (")]
    assert len(added) == 1 and any(m.startswith("round ") for m in said[1:added[0]])
    # the model is then within the noise: no further round, the search ends
    assert said[added[0] + 1:] == ["weighing the effects again"]
    assert reconcile(data).as_dict() == r.as_dict()


def test_split_check_runs_the_search_on_other_draws_of_the_held_out_blocks():
    # the draws differ only in which blocks are held out, about half of them each time
    rec = hidden_record(PRESETS["low"].replace(tau_p=0.0), SHORT, {"dead_time": (0.08,)}, seed=3)
    data = ValveData(rec.t, rec.p, rec.x, "short")
    a, b = prepare(data, 0.5, split_seed=8), prepare(data, 0.5, split_seed=1)
    assert np.array_equal(a.block, b.block) and not np.array_equal(a.train, b.train)
    assert 0.4 < b.train.mean() < 0.6
    # planted truth: a dead time of 80 ms after raw command steps, 30 times the noise: every draw
    # names it; the result is the first draw's (the default run's) with the counts added
    r = reconcile(data, config=ReconcileConfig(split_check=3))
    one = reconcile(data)
    assert r.effects == one.effects and r.effects[:1] == ["dead_time"]
    assert r.split_draws == 3 and r.split_named["dead_time"] == 3
    assert set(r.effects) <= set(r.split_named) and all(1 <= k <= 3 for k in r.split_named.values())
    assert "dead_time 3/3" in r.message and r.as_dict()["split_check"] == {"draws": 3, "named": r.split_named}
    assert one.split_draws == 1 and one.split_named == {} and "draws of the held-out" not in one.message


def test_split_check_draws_never_repeat_the_results_draw():
    # the held-out blocks of any number of draws are all different draws (a repeat of the result's
    # seed would count the same split twice and inflate "named under every draw")
    seeds = [_split_seed(i) for i in range(20)]
    assert seeds[0] == 8 and len(set(seeds)) == 20 and seeds[1:4] == [1, 2, 3]


@pytest.mark.parametrize("exc, hidden, seed, alike", [
    # raw ISA steps: a lag rounds every edge that a dead time only shifts, the record tells them apart
    (SHORT, 0.03, 7, False),
    # a slow sine: a dead time and a lag both shift it by about the same time, it cannot
    (sine(period=10.0, periods=2.0), 0.08, 11, True),
])
def test_a_lag_and_a_dead_time_are_reported_indistinguishable_only_where_the_record_cannot_tell_them(
        exc, hidden, seed, alike):
    rec = hidden_record(PRESETS["low"].replace(tau_p=0.0), exc, {"dead_time": (hidden,)}, seed=seed)
    r = reconcile(ValveData(rec.t, rec.p, rec.x, "t"))
    first = r.steps[0]
    assert first.effect in ("dead_time", "actuator_lag")
    other = "actuator_lag" if first.effect == "dead_time" else "dead_time"
    assert (other in first.indistinguishable_from) == alike
    named = _named(r)  # the summary line of `loopwatch reconcile` and its report's headline
    if alike:
        assert "cannot tell them apart" in first.evidence
        assert r.as_dict()["steps"][0]["indistinguishable_from"] == list(first.indistinguishable_from)
        assert named.startswith(f"{first.effect} (or ") and other in named
    else:
        assert first.effect == "dead_time"
        assert "actuator_lag" not in named.split(", ")[0]


def test_cli_reconcile_json_and_report(tmp_path, capsys):
    data = tmp_path / "lag.csv"
    assert main(["simulate", "valve", "--test", "isa-steps", "--preset", "low", "--vp-lag", "0",
                 "--hide", "actuator_lag=0.05", "--seed", "5", "--out", str(data)]) == 0
    js, rep = tmp_path / "out.json", tmp_path / "out.html"
    assert main(["reconcile", str(data), "--json", str(js), "--report", str(rep), "--split-check", "2"]) == 0
    doc = json.loads(js.read_text())
    assert doc["split_check"]["draws"] == 2 and doc["split_check"]["named"]["actuator_lag"] >= 1
    for key in ("baseline", "steps", "effects", "final_rmse_m", "noise_floor_m", "pressure_floor_m"):
        assert key in doc
    assert doc["effects"][:1] == ["actuator_lag"]
    assert doc["steps"][0]["params"]["tau_s"] == pytest.approx(0.05, rel=0.2)
    assert doc["final_rmse_m"] <= 0.5 * doc["baseline"]["rmse_m"]
    assert "evidence" in doc["steps"][0] and "rmse_m" in doc["baseline"]
    html = rep.read_text()
    assert html.count("data:image/png;base64,") >= 2 and "actuator_lag" in html


def test_a_valve_that_slides_once_is_reconciled_and_one_that_never_stops_is_refused():
    # one step of 12 kPa slides the low valve once (0.0445 m² x 12 kPa = 534 N > 2 F_c = 305 N);
    # after it, a sine of ±2 kPa (178 N peak to peak) never overcomes friction again.  Clean data
    # (planted truth: no effect); F_c and the bias cannot be told apart, and the result says so
    t = 1e-3 * np.arange(20000)
    p = np.where(t < 2.0, 100e3, 112e3 + 2e3 * np.sin(2 * np.pi * (t - 2.0) / 5.0))
    rec = hidden_record(PRESETS["low"].replace(tau_p=0.0), Excitation("step, then a small sine", t, p, 1e-3), {},
                        seed=3)
    r = reconcile(ValveData(rec.t, rec.p, rec.x, "one slide"))
    assert r.effects == []
    assert "no missing effect found" in r.message and "one direction only" in r.message
    assert r.baseline.rmse < 1.3 * r.noise_floor
    # a stem that never comes to rest after a slide gives the balances nothing: refused, with its
    # travel and force span (0.0445 m² x a ramp over 20 kPa: 0.89 kN)
    p = 100e3 + 1e3 * t
    rec = hidden_record(PRESETS["low"].replace(tau_p=0.0), Excitation("one ramp", t, p, 1e-3), {}, seed=3)
    with pytest.raises(IdentificationError, match=r"no slide ending at rest.*spans 0\.8\d* kN"):
        reconcile(ValveData(rec.t, rec.p, rec.x, "no stop"))


def test_a_valve_its_friction_holds_through_most_of_the_record_starts_from_springs_below_the_frictionless_one():
    # planted truth, the independent simulator's record 149 #5 of the bench: random steps behind a
    # 1 s V/P lag, a valve that slides twice in 40 s (once each way, 0.4 mm), Stribeck friction
    # with v_s = 7.5 mm/s, ten times its fastest slide: within the record a Karnopp valve with
    # F_c = F_s.  Two stops at two force levels cannot separate spring and friction; the force span
    # over the position span (the frictionless spring) is ten times the truth's k, and the starts
    # at 0.7-1.4 times it ended in a valve without friction (16.9 times the noise, before session 33)
    from tests.bench.accuracy_reconcile import make_record, select

    (_, case), = select("149:4")
    t, p, x, sa = make_record(case)
    r = reconcile(ValveData(t, p, x, "two slides"), config=ReconcileConfig(sa=sa))
    assert r.baseline.rmse < 1.2 * r.noise_floor
    assert r.effects == []
    v = case["valve"]
    assert abs(r.baseline.params["k"] / v["k"] - 1) < 0.1
    assert abs(r.baseline.params["Fc"] / (v["fc"] * case["hidden"]["stribeck"][0]) - 1) < 0.05


def test_two_hidden_effects_that_no_single_effect_explains_are_found_together():
    # a record of the independent simulator of the accuracy bench (unseen draw 53, record 28): a
    # slip jump of 1.43 and a 1.38 mm deadband on a PRBS through a 1 s V/P lag.  Either effect
    # alone fits worse than the baseline out of sample, so no single effect passes; the two
    # together fit at the noise (planted truth)
    data, cfg = _unseen("53:27")
    assert reconcile(data, config=replace(cfg, pair_search=False)).effects == []
    r = reconcile(data, config=cfg)
    assert set(r.effects) == {"slip_jump", "deadband"}  # the planted pair
    assert r.final.rmse < 1.1 * r.noise_floor
    assert "added together" in r.steps[-1].evidence
    # every reported model is fitted on the training blocks, so its held-out RMSE is out of sample:
    # the baseline's is near its RMSE on the whole record, and the first effect alone (the baseline
    # is nested in it) is not far from the baseline out of sample
    assert r.baseline.heldout_rmse < 2 * r.baseline.rmse
    assert r.steps[0].heldout_rmse < 2 * r.baseline.heldout_rmse


def _block_sums(e: np.ndarray, n: int = 500) -> np.ndarray:
    return np.add.reduceat(e, np.arange(0, e.size, n))


def test_the_noise_test_holds_its_level_where_the_two_models_are_equally_near():
    # planted: two models at the same distance from the truth (one smooth misfit and the same shifted),
    # white and AR(1) measurement noise; the share of draws with p < 5 % stays near 5 %.  Without the
    # autocorrelation time (9 samples here) it would be 23 % on the AR(1) draws
    rng = np.random.default_rng(11)
    n = 20_000
    a = 2.0 * np.sin(2 * np.pi * np.arange(n) / 3000.0)
    b = np.roll(a, 700)  # the same norm
    for phi in (0.0, 0.8):
        hits = 0
        for _ in range(400):
            eps = lfilter([np.sqrt(1 - phi**2)], [1.0, -phi], rng.standard_normal(n))  # unit variance
            hits += _noise_z_p(a + eps, b + eps, 5000) < 0.05
        assert hits / 400 < 0.05 + 3 * np.sqrt(0.05 * 0.95 / 400)


def test_the_noise_test_sees_an_effect_at_a_few_events_that_the_block_tests_cannot():
    # planted: one model misses three breakaways by 20 noise sd for 50 samples each, the other fits
    # them; everywhere else the two are the same model
    rng = np.random.default_rng(3)
    n = 20_000
    miss = np.zeros(n)
    for s in (2_100, 9_700, 15_200):
        miss[s : s + 50] = 20.0
    eps = rng.standard_normal(n)
    e_ref, e_new = miss + eps, eps
    assert _signed_rank_p(_block_sums(e_ref**2) - _block_sums(e_new**2)) > 0.1  # 2 x 1/8 at best
    assert _noise_z_p(e_ref, e_new, 5000) < 1e-12
    assert _noise_z_p(e_new, e_ref, 5000) > 0.99  # and not the other way round


@pytest.mark.slow
def test_a_slip_jump_that_shows_at_a_few_breakaways_is_named():
    # unseen 171 #2 (independent simulator): a slip jump of 1.58 on ramps through a 1 s V/P lag; the
    # stem rests after slides in one direction only.  Refitted from the slip jump's basin, the
    # baseline fits every block but four within the noise and misses those by up to 150 times it;
    # the slip jump fits them at the noise on the held-out blocks, but four blocks cannot reach the
    # block tests' level.  The noise test sees it (planted truth)
    data, cfg = _unseen("171:1")
    assert reconcile(data, config=replace(cfg, noise_test=False)).effects == []
    r = reconcile(data, config=cfg)
    assert r.effects == ["slip_jump"] and r.final.heldout_rmse < 1.1 * r.noise_floor


def test_a_stribeck_fit_whose_curve_falls_below_the_slow_slides_is_named_as_the_slip_jump_it_is():
    # unseen 177 #1 (independent simulator): a slip jump of 1.52 on random steps.  No slip jump fit
    # passes the first step; the Stribeck candidate does, with v_s 39 µm/s, a tenth of the limit
    # velocity DV and far under the record's slow slides: a Stribeck curve never sampled between
    # F_s and F_c, the slip jump itself.  The slip jump refitted from that fit is judged and named
    # (planted truth; on main before session 39 it was named `stribeck`)
    data, cfg = _unseen("177:0")
    r = reconcile(data, config=cfg)
    assert r.effects == ["slip_jump"]
    assert r.final.heldout_rmse < 1.1 * r.noise_floor
    assert "is not named" in r.steps[0].evidence


@pytest.mark.slow
def test_a_stribeck_curve_no_better_than_the_slip_jump_it_nests_is_not_named():
    # unseen 133 #1: a slip jump of 1.53 on random steps.  Both friction candidates pass; the
    # Stribeck curve (v_s 57 µm/s) wins the step by its cross-fitted gain, but on the same footing
    # (held-out blocks of the fits on the training blocks) the slip jump is 2.0 better by BIC with
    # one parameter fewer.  The simpler, nested model is named, with the planted F_s/F_c
    from tests.bench.accuracy_reconcile import select

    data, cfg = _unseen("133:0")
    ((_, case),) = select("133:0")
    r = reconcile(data, config=cfg)
    assert r.effects == ["slip_jump"]
    p = r.steps[0].params
    assert p["Fs"] / p["Fc"] == pytest.approx(case["hidden"]["slip_jump"][0], rel=0.1)
    assert r.final.heldout_rmse < 1.1 * r.noise_floor


@pytest.mark.slow
def test_a_search_that_ends_above_the_noise_after_a_weak_first_step_is_run_again_with_the_pairs():
    # unseen 123 #25 (independent simulator): a slip jump of 1.51 and a 52 ms dead time on random
    # steps.  In the first step a deadband passes by a hair and leaves most of the excess; the pairs
    # never run and the search ends at about 10 times the noise.  Run again with the pairs competing
    # in the first step, the planted pair is found and fits the record within 1.5 times the noise
    data, cfg = _unseen("123:24")
    first = reconcile(data, config=replace(cfg, retry_pairs=False))
    assert first.final.heldout_rmse >= 2 * first.noise_floor and "slip_jump" not in first.effects
    r = reconcile(data, config=cfg)
    assert set(r.effects) == {"slip_jump", "dead_time"}  # the planted pair
    assert r.final.rmse < 1.5 * r.noise_floor and r.final.heldout_rmse < first.final.heldout_rmse
    assert "run again with the pairs" in r.message and " kept against" in r.message and r.second_search == "kept"


def test_a_cross_fitted_first_step_is_weighed_against_the_current_models_two_folds():
    # unseen x187 #5 (independent simulator, a pair draw): a slip jump of 1.49 and a 39 ms dead time on
    # random steps.  The baseline sits in a wrong basin (bias 4.1 mm against the planted 1.1).  Refitted
    # in a better one, the dead time passes by the cross-fit and leaves most of the excess of the current
    # model's two folds (held out 238 -> 181 µm, noise 14 µm), so it is weak; against the current model's
    # first fold alone (297 µm here, 439 µm in session 41) it was not, and until session 42 the search then
    # ended at 12 times the noise without the second search.  Since the Stribeck search beside an accepted
    # dead time (session 43) the first search reaches the planted pair itself (1.07 times the noise), so
    # the second search is not needed here; the weighing is checked on the step's statistics.
    data, cfg = _unseen("x187:4")
    r = reconcile(data, config=cfg)
    assert set(r.effects) == {"slip_jump", "dead_time"}  # the planted pair
    assert r.final.rmse < 1.5 * r.noise_floor
    n2 = r.noise_floor**2
    weak = [(c, rnd) for rnd in r.rounds for c in rnd if c.effect == "dead_time" and c.passed and c.cross_fitted
            and c.heldout_rmse**2 >= 4 * n2 and c.heldout_rmse**2 - n2 > 0.5 * (c.ref_heldout_rmse**2 - n2)]
    assert weak  # a passing, cross-fitted dead time that leaves most of its reference's excess: weak
    # its reference is the current model's two folds, not the first fold the other candidates of the
    # round are weighed on (against that one the same dead time would not be weak)
    c, rnd = weak[0]
    firsts = {o.ref_heldout_rmse for o in rnd if not o.cross_fitted and not o.replaces}
    assert firsts and all(abs(f - c.ref_heldout_rmse) > 0.1 * c.ref_heldout_rmse for f in firsts)
    assert any(c.heldout_rmse**2 - n2 <= 0.5 * (f**2 - n2) for f in firsts)


@pytest.mark.slow
def test_a_search_that_ends_within_the_noise_is_not_run_again():
    # unseen 129 #1: a slip jump of 1.56 on random steps.  Its first step also leaves most of the
    # excess, but the second step brings the model within the noise; the pairs in the first step
    # would have lost it (a Stribeck + lag pair wins there and ends at 9 times the noise)
    data, cfg = _unseen("129:0")
    r = reconcile(data, config=cfg)
    assert r.effects == ["slip_jump"] and r.final.heldout_rmse < 2 * r.noise_floor
    assert "run again" not in r.message and r.second_search == ""


def test_a_search_whose_training_blocks_showed_too_little_is_run_again_on_the_swapped_blocks():
    # unseen 187 #2 (independent simulator): a slip jump of 1.38 on ramps.  Three of the four blocks
    # with a reversal are held out; the baseline fits the training blocks at the noise (1.0 x) and
    # misses the held-out ones by 10 x, the slip jump fitted on the training blocks comes out at size
    # zero and the search names nothing at 6.5 x the noise on the whole record.  With the halves
    # swapped, the planted slip jump is found and the record fits within the noise
    from tests.bench.accuracy_reconcile import select

    data, cfg = _unseen("187:1")
    ((_, case),) = select("187:1")
    first = reconcile(data, config=replace(cfg, swap_search=False))
    assert first.effects == [] and first.held_out_misfit and first.final.rmse >= 2 * first.noise_floor
    assert first.swap_search == ""
    # where nothing is named, the result says that the misfit lies in the held-out half and not only
    # that the model misses the data (session 44)
    assert "no candidate effect passes the held-out test; the model still misses the data" in first.message
    assert "it fits the training blocks it was fitted on (1.0 × the noise): what it misses lies in the held-out half" in first.message
    r = reconcile(data, config=cfg)
    assert r.effects == ["slip_jump"] and r.swap_search == "kept" and r.as_dict()["swap_search"] == "kept"
    p = r.steps[0].params
    assert p["Fs"] / p["Fc"] == pytest.approx(case["hidden"]["slip_jump"][0], rel=0.1)
    assert r.final.rmse < 1.2 * r.noise_floor
    assert "training and held-out blocks swapped" in r.message and " kept against the first search's" in r.message


def test_a_final_stribeck_curve_that_falls_to_f_c_below_dv_is_named_as_the_slip_jump_it_nests():
    # unseen 169 #28 (independent simulator): a slip jump of 1.40 and a 1.1 mm deadband on PRBS.  The
    # search names the deadband and, beside it, a Stribeck curve whose v_s lies at 0.13 DV: inside the
    # stick band the curve is at F_c already, a jump to the record.  The round's nested test never ran
    # (the curve came in beside an accepted effect); the slip jump it nests fits the held-out blocks
    # as well, and the planted pair is named
    from tests.bench.accuracy_reconcile import select

    data, cfg = _unseen("169:27")
    ((_, case),) = select("169:27")
    before = reconcile(data, config=replace(cfg, nested_slip_jump=False))
    assert before.effects == ["deadband", "stribeck"]
    assert before.final.params["vs"] < before.final.params["dv"]
    r = reconcile(data, config=cfg)
    assert r.effects == ["deadband", "slip_jump"] and "vs" not in r.final.params
    p = r.final.params
    assert p["Fs"] / p["Fc"] == pytest.approx(case["hidden"]["slip_jump"][0], rel=0.1)
    assert "stribeck named slip_jump: its v_s" in r.message
    assert r.final.rmse < 1.2 * r.noise_floor


def test_reported_parameters_map_back_onto_the_fits_parameters():
    import models.reconcile as rc

    v = {"k": 2e5, "fc": 400.0, "dfs": 200.0, "fv": 5e3, "bias": 1e-3, "dv": 1e-4, "nb": 3.0, "vs": 5e-3, "tau": 0.2}
    back = rc._internal(rc._public(v, 1e-4), ["stribeck", "actuator_lag"])
    assert back.keys() == v.keys() and all(back[n] == pytest.approx(v[n], rel=1e-12) for n in v)
    plain = {"k": 2e5, "fc": 400.0, "fv": 5e3, "bias": 1e-3, "dv": 1e-4, "theta": 0.05, "deadband": 1e-3}
    assert rc._internal(rc._public(plain, 1e-4), ["dead_time", "deadband"]) == plain  # F_s = F_c: no dfs


def test_a_final_stribeck_model_that_misses_the_record_is_searched_again_on_the_whole_record():
    # unseen 151 #6 (independent simulator): Stribeck friction (F_s/F_c 1.51, v_s 8.0 mm/s) on ramps.
    # The search names it, but the final model's local refit on the whole record, started from the
    # training fit, stops at 17 times the noise against a baseline at 31 (0.55 of it).  Searched
    # about its own fit on the whole record, the curve comes back near the planted one
    from tests.bench.accuracy_reconcile import select

    data, cfg = _unseen("151:5")
    ((_, case),) = select("151:5")
    valve, (ratio, vs) = case["valve"], case["hidden"]["stribeck"]
    r = reconcile(data, config=cfg)
    assert r.effects == ["stribeck"]
    assert "Stribeck curve searched again on the whole record" in r.message
    assert r.final.rmse <= 0.5 * r.baseline.rmse
    # the reported RMSE is that of the reported simulation (computed here from the samples)
    x_sim = np.concatenate(r.final.x_sim)
    x = np.concatenate([rec.x for rec in r.records])
    assert np.sqrt(np.mean((x - x_sim) ** 2)) == pytest.approx(r.final.rmse, rel=1e-9)
    p = r.final.params
    assert p["k"] == pytest.approx(valve["k"], rel=0.03)
    assert p["Fs"] == pytest.approx(ratio * valve["fc"], rel=0.1)
    assert p["vs"] == pytest.approx(vs, rel=0.2)


def test_the_swapped_search_runs_only_where_the_held_out_half_holds_the_misfit_and_is_kept_if_better(monkeypatch):
    """Unit test of the choice alone (``_search``), the draws replaced by fixed results."""
    import models.reconcile as rc

    def result(effects, rmse, message, held_out_misfit=True):  # the final model's RMSE on the whole record
        steps = tuple(rc.Step(e, {}, rmse, rmse, {}, "", []) for e in effects)
        base = 9.0 if effects else rmse
        return rc.Reconciliation(baseline=rc.Step("baseline", {}, base, base, {}, "", []), steps=steps, rounds=(),
                                 noise_floor=1.0, regime_share={}, regime_samples={}, xcorr={}, records=(),
                                 message=message, held_out_misfit=held_out_misfit)

    def case(first, swapped, **cfg):
        calls = []

        def fake(data, signature, cfg, seed, swap=False):
            calls.append(swap)
            return swapped if swap else first

        monkeypatch.setattr(rc, "_search_draw", fake)
        return rc._search(None, None, ReconcileConfig(**cfg), 8), calls

    high, better, worse = result([], 6.0, "high"), result(["a"], 1.1, "better"), result(["b"], 7.0, "worse")
    assert case(result([], 1.9, "low"), better) == (result([], 1.9, "low"), [False])  # within twice the noise
    plain = result([], 6.0, "plain", held_out_misfit=False)  # the misfit not in the held-out half alone
    assert case(plain, better) == (plain, [False])
    assert case(high, better, swap_search=False) == (high, [False])
    r, calls = case(high, better)
    assert calls == [False, True] and r.effects == ["a"] and r.message.startswith("better")
    assert r.swap_search == "kept" and "a (1.1 × the noise on the whole record) kept against" in r.message
    r, calls = case(high, worse)
    assert calls == [False, True] and r.effects == [] and r.message.startswith("high") and r.swap_search == "not kept"
    assert "b (7.0 × the noise on the whole record) not kept" in r.message
    # either run reports the better baseline of the two (the same model fitted to the same record)
    r, _ = case(high, replace(better, baseline=rc.Step("baseline", {}, 5.0, 5.0, {}, "", [])))
    assert r.baseline.rmse == 5.0 and r.effects == ["a"]
    r, _ = case(high, replace(worse, baseline=rc.Step("baseline", {}, 5.0, 5.0, {}, "", [])))
    assert r.baseline.rmse == 5.0 and r.effects == []


def test_the_run_kept_after_a_second_search_is_the_one_that_fits_the_held_out_blocks_better(monkeypatch):
    """Unit test of the choice alone (``_search_draw``), the searches replaced by fixed results."""
    import models.reconcile as rc

    def result(effects, heldout, message):  # the whole-record RMSE of the final model: its held-out one less 1
        steps = tuple(rc.Step(e, {}, heldout - 1.0, heldout, {}, "", []) for e in effects)
        return rc.Reconciliation(baseline=rc.Step("baseline", {}, 9.0, 9.0, {}, "", []), steps=steps, rounds=(),
                                 noise_floor=1.0, regime_share={}, regime_samples={}, xcorr={}, records=(),
                                 message=message)

    def case(first, weak, second):
        calls = []

        def fake(data, signature, cfg, pool, seed, weak_pairs=False, swap=False):
            calls.append(weak_pairs)
            return (second if weak_pairs else first), weak

        monkeypatch.setattr(rc, "_reconcile", fake)
        return rc._search(None, None, ReconcileConfig(), 8), calls

    # noise 1: "low" ends at 1.9 times the noise on the whole record (2.9 held out), "high" at 5
    low, high, better = result(["a"], 2.9, "low"), result(["a"], 6.0, "high"), result(["b", "c"], 1.2, "better")
    worse = result(["d"], 7.0, "worse")
    assert case(low, True, better) == (low, [False])  # within twice the noise: never again
    assert low.second_search == "" and low.as_dict()["second_search"] == "not run"
    assert case(high, False, better) == (high, [False])  # a first step that was not weak: never again
    r, calls = case(high, True, better)
    assert calls == [False, True] and r.effects == ["b", "c"] and r.message.startswith("better")
    assert r.second_search == "kept" and r.as_dict()["second_search"] == "kept"
    assert "b, c (held-out RMSE 1200000.00 µm, 0.2 × the noise on the whole record) kept" in r.message
    assert "first search's a (held-out RMSE 6000000.00 µm, 5.0 ×" in r.message
    r, calls = case(high, True, worse)
    assert calls == [False, True] and r.effects == ["a"] and r.message.startswith("high") and "not kept" in r.message
    assert r.second_search == "not kept"
    # either run reports the better baseline of the two searches (the same model fitted to the same record)
    low_base = rc.Step("baseline", {}, 5.0, 5.0, {}, "", [])  # the others' baselines read 9
    r, _ = case(replace(high, baseline=low_base, regime_share={"stuck": 1.0}), True, better)
    assert r.effects == ["b", "c"] and r.baseline.rmse == 5.0 and r.regime_share == {"stuck": 1.0}
    r, _ = case(high, True, replace(worse, baseline=low_base))
    assert r.effects == ["a"] and r.baseline.rmse == 5.0


def test_cli_global_search_flag(tmp_path):
    # a clean record fits within the noise: the flag is accepted and no effect is named
    data = tmp_path / "clean.csv"
    assert main(["simulate", "valve", "--test", "isa-steps", "--preset", "low", "--vp-lag", "0", "--seed", "5",
                 "--out", str(data)]) == 0
    js = tmp_path / "out.json"
    assert main(["reconcile", str(data), "--global-search", "--json", str(js)]) == 0
    assert json.loads(js.read_text())["effects"] == []


def test_cli_errors_are_one_line(tmp_path, capsys):
    out = tmp_path / "x.csv"
    assert main(["simulate", "valve", "--test", "sine", "--preset", "low", "--hide", "bogus", "--out", str(out)]) == 2
    assert "unknown effect 'bogus'" in capsys.readouterr().err
    assert main(["reconcile", str(tmp_path / "missing.csv")]) == 2
    assert "cannot open" in capsys.readouterr().err
    assert main(["reconcile", str(tmp_path / "missing.csv"), "--threads", "0"]) == 2
    assert "--threads 0" in capsys.readouterr().err
    assert main(["reconcile", str(tmp_path / "missing.csv"), "--stick-band", "-1"]) == 2
    assert "--stick-band -1" in capsys.readouterr().err
    assert main(["reconcile", str(tmp_path / "missing.csv"), "--split-check", "0"]) == 2
    assert "--split-check 0" in capsys.readouterr().err
    with pytest.raises(ModelConfigError, match="split_check = 0"):
        ReconcileConfig(split_check=0)


def test_dead_time_shift_matches_linear_interpolation():
    p = np.cumsum(np.random.default_rng(3).standard_normal(3000))
    for theta in (0.0004, 0.001, 0.0123, 0.5, 3.5):  # fractions of a sample, whole samples, > record
        ref = np.interp(np.arange(p.size) - theta / 1e-3, np.arange(p.size), p)  # p[0] before the record
        assert np.allclose(actuator_pressure(p, 1e-3, theta=theta), ref, rtol=0, atol=1e-9)


@pytest.mark.slow
def test_hidden_slip_jump_is_named_and_the_gap_shrinks():
    rec = hidden_record(PRESETS["high"].replace(tau_p=0.0), sine(periods=1.2), {"slip_jump": (1.5,)}, seed=3)
    r = reconcile(ValveData(rec.t, rec.p, rec.x, "sine"))
    assert r.effects[:1] == ["slip_jump"]
    assert r.steps[0].params["Fs"] / r.steps[0].params["Fc"] == pytest.approx(1.5, rel=0.15)
    assert r.final.rmse <= 0.5 * r.baseline.rmse


@pytest.mark.slow
def test_the_stribeck_searches_of_a_run_stay_within_their_budget(monkeypatch):
    """Where a slip jump passes, the Stribeck candidate is searched about its fit, each search
    with both stick rules; at most ``_MAX_STRIBECK_SEARCHES`` slip jump fits per fold of the
    cross-fit in one run, so the run's cost stays bounded.  With a budget of 0 no search runs."""
    import models.reconcile as rc

    rec = hidden_record(PRESETS["high"].replace(tau_p=0.0), sine(periods=1.2), {"slip_jump": (1.5,)}, seed=3)
    data = ValveData(rec.t, rec.p, rec.x, "sine")
    calls: list[str] = []
    search = rc._stribeck_search

    def counted(slip, recs, cfg, dv, rule, fold="train"):
        calls.append(fold)
        return search(slip, recs, cfg, dv, rule, fold)

    monkeypatch.setattr(rc, "_stribeck_search", counted)
    r = reconcile(data)
    assert r.effects[:1] == ["slip_jump"]
    assert 1 <= calls.count("train") <= 2 * rc._MAX_STRIBECK_SEARCHES
    assert calls.count("test") <= 2 * rc._MAX_STRIBECK_SEARCHES
    calls.clear()
    monkeypatch.setattr(rc, "_MAX_STRIBECK_SEARCHES", 0)
    reconcile(data)
    assert calls == []


@pytest.mark.slow
def test_a_slip_jump_refit_that_misses_the_held_out_blocks_does_not_replace_the_local_fit():
    # a record of the independent simulator of the accuracy bench (unseen draw 135, record 1):
    # a slip jump F_s = 1.56 F_c on random steps.  The slip jump refitted from the Stribeck
    # search's basin fits the training blocks a little better than the local fit (by 0.14 x the
    # noise power) but misses the held-out blocks at 40 x the noise; it must pass its own held-out
    # test before it replaces the local fit (planted truth: a slip jump, fitting at the noise)
    data, cfg = _unseen("135:0")
    r = reconcile(data, config=cfg)
    assert r.effects[:1] == ["slip_jump"]
    assert r.steps[0].heldout_rmse < 1.5 * r.noise_floor
    assert r.final.rmse <= 0.5 * r.baseline.rmse
    assert 1.2 < r.steps[0].params["Fs"] / r.steps[0].params["Fc"] < 2.0


@pytest.mark.slow
def test_the_second_fold_starts_each_candidate_from_its_first_fold_fit():
    # a record of the independent simulator of the accuracy bench (unseen draw 141, record 25): a
    # slip jump F_s = 1.32 F_c and a dead time of 79 ms on random steps through a 1 s V/P lag.
    # Beside the slip jump, the dead time's fit on the training blocks fits the held-out blocks
    # near the noise; its fit on the held-out blocks from the multi-start alone ended in another
    # basin, the pooled cross-fit failed it, and a lag was named instead.  Started from its first
    # fold's fit, as the current model's second fold is, both planted effects are named
    data, cfg = _unseen("141:24")
    r = reconcile(data, config=cfg)
    assert sorted(r.effects) == ["dead_time", "slip_jump"]
    assert r.final.params["theta_s"] == pytest.approx(0.079, rel=0.2)
    assert r.final.rmse < 1.5 * r.noise_floor


@pytest.mark.slow
def test_stribeck_is_searched_about_the_current_model_when_nothing_passes():
    # a record of the independent simulator of the accuracy bench (unseen draw 131, record 5):
    # Stribeck friction F_s = 1.41 F_c, v_s 8.3 mm/s, on random steps through a 0.3 s V/P lag.
    # No slip jump passes, so the Stribeck search about a slip jump's fit never ran, and the local
    # Stribeck fits from the Karnopp baseline (F_c between the truth's F_c and F_s) failed: nothing
    # was named at 4.4 x the noise.  Searched about the current model, Stribeck is named (planted
    # truth: Stribeck friction, F_s / F_c 1.41)
    data, cfg = _unseen("131:4")
    r = reconcile(data, config=cfg)
    assert r.effects[:1] == ["stribeck"]
    assert r.steps[0].params["Fs"] / r.steps[0].params["Fc"] > 1.15
    assert r.steps[0].params["vs"] == pytest.approx(0.0083, rel=0.5)
    assert r.final.rmse < 0.8 * r.baseline.rmse
    # without the search about the current model, nothing is named on this record
    r0 = reconcile(data, config=replace(cfg, stribeck_base=False))
    assert r0.effects == []


@pytest.mark.slow
def test_a_stick_rule_switch_is_the_current_models_not_a_new_effects():
    # a record of the independent simulator of the accuracy bench (unseen draw 61, record 28): slip
    # jump F_s = 1.53 F_c and a 0.58 mm deadband on PRBS through a 0.3 s V/P lag; no lag hidden.
    # Beside the accepted slip jump, the lag candidate chose the other stick rule and passed with a
    # lag of 10 µs: its whole gain was the rule, which is the current model's (better_basin)
    data, cfg = _unseen("61:27")
    r = reconcile(data, config=cfg)
    assert r.effects[:1] == ["slip_jump"]
    assert "actuator_lag" not in r.effects  # planted truth: no lag
    # the last step reports the model the search stopped at (the stop message's held-out RMSE)
    stop = float(r.message.split("held-out RMSE ")[1].split(" µm")[0])
    assert r.final.heldout_rmse * 1e6 == pytest.approx(stop, abs=0.01)


def test_alternatives_are_every_effect_compatible_with_the_model():
    assert set(_alternatives("actuator_lag", [], "deadband")) == {"dead_time", "slip_jump", "stribeck"}
    assert set(_alternatives("deadband", [], "dead_time")) == {"actuator_lag", "slip_jump", "stribeck"}
    # slip jump and Stribeck friction both set F_s: never together
    assert "stribeck" not in _alternatives("actuator_lag", ["slip_jump"], "deadband")
    assert set(_alternatives("deadband", [], "slip_jump")) == {"actuator_lag", "dead_time"}


@pytest.mark.slow
def test_lag_named_first_is_swapped_for_the_hidden_dead_time_beside_a_deadband():
    # planted truth: dead time 30 ms + deadband 0.5 mm on ISA steps (raw command).  A lag alone fits
    # better than a dead time alone (it absorbs part of the lost motion at reversals) and is named
    # first; with the deadband added, the search must offer the dead time in its place
    rec = hidden_record(PRESETS["high"].replace(tau_p=0.0), isa_steps(hold=60.0 / 19),
                        {"dead_time": (0.03,), "deadband": (0.5e-3,)}, seed=7)
    r = reconcile(ValveData(rec.t, rec.p, rec.x, "pair"))
    db = next(c for rnd in r.rounds[1:] for c in rnd if c.effect == "deadband")
    assert db.replaces == "actuator_lag->dead_time"
    assert db.params["theta_s"] == pytest.approx(0.03, rel=0.2)
    assert db.params["deadband_m"] == pytest.approx(0.5e-3, rel=0.2)
    assert db.heldout_rmse < 1.1 * r.noise_floor
    # with the two-fold cross-fit both planted effects are named (one fold alone: p 0.003 > 0.0025);
    # round 2 may reach that model from either side (the deadband with the lag swapped for the dead
    # time, or the dead time with the lag swapped for the deadband), so the order is not planted
    assert sorted(r.effects) == ["dead_time", "deadband"] and db.cross_fitted


def test_a_first_fold_at_the_noise_is_not_overruled_by_a_second_fold_the_held_out_blocks_do_not_pin_down():
    # unseen 155 #25, planted truth: slip jump F_s = 1.40·F_c + dead time 68.8 ms on random steps.  Beside
    # the slip jump, the dead time fitted on the training blocks predicts the held-out blocks at 1.01 times
    # the noise; fitted on the held-out blocks (the cross-fit's second fold) its F_s ends 6 % lower (F_s - F_c
    # 24 %) and it reads 14 times the noise on the training blocks.  The pooled folds failed it: the slip jump alone was
    # named, 8.4 times the noise left (session 51)
    from tests.bench.accuracy_reconcile import select

    ((_, case),) = select("155:24")
    data, cfg = _unseen("155:24")
    r = reconcile(data, config=cfg)
    assert r.effects == ["slip_jump", "dead_time"]
    assert r.final.params["theta_s"] == pytest.approx(case["hidden"]["dead_time"][0], rel=0.1)
    assert r.final.params["Fs"] / r.final.params["Fc"] == pytest.approx(case["hidden"]["slip_jump"][0], rel=0.1)
    assert r.final.heldout_rmse < 1.1 * r.noise_floor
    # the dead time beside the slip jump is the candidate the first fold decided
    (dt,) = [c for c in r.rounds[-1] if c.effect == "dead_time"]
    assert dt.passed and not dt.cross_fitted and dt.overruled_pooled_rmse > 3 * r.noise_floor
    assert "the first fold decides" in r.steps[-1].evidence


@pytest.mark.slow
def test_the_stick_rule_is_chosen_again_when_a_dead_time_joins_a_slip_jump():
    # planted truth: slip jump F_s = 1.5·F_c + dead time 80 ms on a sine through a 1 s V/P lag.  The
    # slip jump is named first and chose its stick rule without the dead time; held to that rule, a
    # lag was named second (session 12).  The dead time must be fitted with both rules
    rec = hidden_record(PRESETS["high"].replace(tau_p=1.0), sine(periods=1.2),
                        {"slip_jump": (1.5,), "dead_time": (0.08,)}, noise_x=2e-5, noise_p=400.0, seed=147)
    r = reconcile(ValveData(rec.t, rec.p, rec.x, "pair"))
    assert r.effects == ["slip_jump", "dead_time"]
    assert r.final.params["theta_s"] == pytest.approx(0.08, rel=0.2)
    assert r.final.params["Fs"] / r.final.params["Fc"] == pytest.approx(1.5, rel=0.15)
    assert r.final.rmse < 1.1 * r.noise_floor


@pytest.mark.slow
def test_deadband_named_first_is_swapped_for_the_hidden_lag_and_dead_time_on_a_square_wave():
    # planted truth: lag 0.2 s + dead time 80 ms on a square wave through a 1 s V/P lag.  Every
    # edge is a reversal, and a 1.3 mm deadband alone leaves 1.1x the noise: it is named first;
    # with the lag added, the search must offer the dead time in the deadband's place
    rec = hidden_record(PRESETS["low"].replace(tau_p=1.0), square(periods=4.0),
                        {"actuator_lag": (0.2,), "dead_time": (0.08,)}, noise_x=1e-5, noise_p=200.0, seed=152)
    r = reconcile(ValveData(rec.t, rec.p, rec.x, "pair"))
    assert sorted(r.effects) == ["actuator_lag", "dead_time"]
    assert r.final.params["tau_s"] == pytest.approx(0.2, rel=0.15)
    assert r.final.params["theta_s"] == pytest.approx(0.08, rel=0.15)
    assert r.final.rmse < 1.1 * r.noise_floor
    # the swapped step is refitted: its held-out RMSE is that of a fit on the training blocks, near
    # its RMSE over the record, not that of the winner's parameters with the later effect removed
    assert all(s.heldout_rmse < 2 * s.rmse for s in r.steps)
    # round 2 reaches the lag + dead time model from both sides; the other side is the same model,
    # not one the record cannot tell from it
    assert not set(r.steps[-1].indistinguishable_from) & set(r.effects)


def test_cross_fit_scores_every_block_once_by_the_fit_of_the_other_half():
    rec = hidden_record(PRESETS["low"].replace(tau_p=0.0), SHORT, {}, seed=4)
    r = prepare(ValveData(rec.t, rec.p, rec.x, "short"), block_s=0.45)
    train, test = _fold_mask(r, "train"), _fold_mask(r, "test")
    assert not np.any(train & test) and np.all(train | test)
    assert all(np.unique(train[r.block == b]).size == 1 for b in np.unique(r.block))  # whole blocks
    n_blocks = int(r.block.max()) + 1
    assert abs(int(np.unique(r.block[train]).size) - n_blocks / 2) <= 1  # half of them
    # residual 1 on the training blocks, 2 on the held-out ones: each fold sees only its own
    e = np.where(train, 1.0, 2.0)
    a, b = _score([e], [r], "test"), _score([e], [r], "train")
    assert a.mse_h == 4.0 and b.mse_h == 1.0
    pooled = _pool(a, b)
    assert pooled.block_sse.size == n_blocks and pooled.n_h == r.x.size
    assert pooled.mse_h == pytest.approx((4.0 * test.sum() + train.sum()) / r.x.size)


def test_force_balance_at_the_head_of_each_rest_recovers_spring_and_friction_on_ramps():
    """On pressure ramps the stem rests while the pressure keeps moving towards the next
    breakaway, so only the balance read just after each stop (``at="head"``) sees ``F_c``; the
    planted truth (the ``low`` valve with a hidden slip jump) is the reference."""
    params = PRESETS["low"]
    rng = np.random.default_rng(3)
    dt = 1e-3
    knots_t = np.r_[0.0, np.cumsum(rng.uniform(1.0, 5.0, 30))]
    t = dt * np.arange(int(60.0 / dt))
    exc = Excitation("ramps", t, pct_to_pa(np.interp(t, knots_t, rng.uniform(20.0, 70.0, knots_t.size))), dt)
    rec = hidden_record(params, exc, {"slip_jump": (1.6,)}, noise_x=5e-6, noise_p=50.0, seed=3)
    recs = [prepare(ValveData(rec.t, rec.p, rec.x, "ramps"), 0.5, params.sa)]
    head = _initial_baseline(recs, ReconcileConfig(sa=params.sa), at="head")
    assert head["k"] == pytest.approx(params.k, rel=0.15)
    assert head["fc"] == pytest.approx(params.fc, rel=0.25)
    # with the breakaways (eq. 11-12 as written) the same balances also give F_s
    brk = _initial_baseline(recs, ReconcileConfig(sa=params.sa), at="breakaway")
    assert brk["k"] == pytest.approx(params.k, rel=0.15)
    assert brk["fc"] == pytest.approx(params.fc, rel=0.25)
    assert brk["fc"] + brk["dfs"] == pytest.approx(1.6 * params.fc, rel=0.25)
    assert brk["dfs"] > 0.3 * params.fc  # the slip jump is seen (planted: 0.6 F_c)
    # a record without a slip jump gives none (or refuses)
    rec0 = hidden_record(params, exc, {}, noise_x=5e-6, noise_p=50.0, seed=3)
    recs0 = [prepare(ValveData(rec0.t, rec0.p, rec0.x, "ramps"), 0.5, params.sa)]
    try:
        assert _initial_baseline(recs0, ReconcileConfig(sa=params.sa), at="breakaway")["dfs"] < 0.15 * params.fc
    except IdentificationError:
        pass


def _steep_stribeck_ramps(duration: float, knots: int) -> tuple[EffectValve, Prepared]:
    """A steep Stribeck valve (F_s/F_c 1.5, v_s 7 mm/s, F_v 15 kN·s/m, m 2.8 kg) on random ramps
    through a 50 ms V/P lag (it smooths the ramps' corners), simulated with 32 sub-steps; noise
    10 µm / 100 Pa.  Returns the valve and the prepared record."""
    dt = 1e-3
    rng = np.random.default_rng(5)
    knots_t = np.r_[0.0, np.cumsum(rng.uniform(1.0, 5.0, knots))]
    t = dt * np.arange(int(duration / dt))
    p = pct_to_pa(np.interp(t, knots_t, rng.uniform(20.0, 70.0, knots_t.size)))
    valve = EffectValve(k=1.5e5, fc=630.0, fs=945.0, vs=7e-3, fv=1.5e4, m=2.8, sa=0.06, bias=2e-3, dv=1e-6)
    x = simulate_effects(valve, actuator_pressure(p, dt, 0.05, 0.0), dt, substeps=32).x_meas
    noise = np.random.default_rng(6)
    return valve, prepare(ValveData(t, p + 100.0 * noise.standard_normal(t.size),
                                    x + 10e-6 * noise.standard_normal(t.size), "ramps"), 0.5, valve.sa)


def test_sliding_balance_of_the_fast_slides_recovers_coulomb_and_viscous_friction_under_steep_stribeck():
    """With Stribeck friction falling steeply from F_s the balances at rest read about F_s, and
    a baseline with F_s = F_c puts the sliding friction at the record's speeds, F_c + F_v·v, into
    its F_c with F_v near 0.  The slides faster than their median speed, far above v_s, see
    F_c + F_v·v: least squares of both over them (``fast_slides=True``) give back F_c and F_v.
    Planted truth: a steep curve (F_s/F_c 1.5, v_s 7 mm/s, F_v 15 kN·s/m, m 2.8 kg) on ramps,
    simulated with 32 sub-steps."""
    valve, rec = _steep_stribeck_ramps(60.0, 30)
    recs = [rec]
    cfg = ReconcileConfig(sa=valve.sa)
    plain = _initial_baseline(recs, cfg, at="breakaway")
    assert plain["fv"] < 0.3 * valve.fv  # what the balance at rest leaves to F_v: the planted trap
    fast = _initial_baseline(recs, cfg, at="breakaway", fast_slides=True)
    assert fast["k"] == pytest.approx(valve.k, rel=0.15)
    assert fast["fc"] == pytest.approx(valve.fc, rel=0.25)
    assert 0.5 * valve.fv < fast["fv"] < 2.0 * valve.fv
    assert fast["fc"] + fast["dfs"] == pytest.approx(valve.fs, rel=0.25)


def _prbs(n: int, lo: float, hi: float, rng: np.random.Generator) -> np.ndarray:
    """``n`` samples at 1 ms of a two-level pressure (Pa) holding each level 0.5–2.5 s, low first."""
    p = np.empty(n)
    i = s = 0
    while i < n:
        hold = 500 * int(rng.integers(1, 6))
        p[i : i + hold] = hi if s else lo
        i += hold
        s ^= 1
    return p


def test_a_lag_absorbed_in_the_spring_is_started_at_the_balance_spring():
    """A two-level PRBS behind a V/P lag leaves the spring unidentified by the balances at rest (two
    force levels); a baseline may then take a spring a quarter of the truth's and absorb a long
    actuator lag in it.  The lag's grid then also starts at the balance's spring (its force-span
    fallback), and a fit from there finds the planted lag.  Planted truth: k 277 kN/m, F_c 337 N,
    F_v 40 kN·s/m, lag 0.39 s; the current model is the truth's Karnopp part with k/4 (bias moved
    to keep the median position), as a baseline fitted it on an unseen record of this kind."""
    dt = 1e-3
    n = 40_000
    p = _prbs(n, 1.0e5, 1.35e5, np.random.default_rng(11))
    p_vp = actuator_pressure(p, dt, 0.3, 0.0)  # the V/P output is what is recorded
    truth = EffectValve(k=2.77e5, fc=337.0, fv=4.0e4, m=1.8, sa=0.03, bias=1.3e-3, dv=1e-6, tau=0.39)
    x = simulate_effects(truth, p_vp, dt, substeps=8).x_meas
    noise = np.random.default_rng(12)
    recs = [prepare(ValveData(dt * np.arange(n), p_vp + 100.0 * noise.standard_normal(n),
                              x + 8e-6 * noise.standard_normal(n), "prbs"), 0.5, truth.sa)]
    cfg = ReconcileConfig(sa=truth.sa)
    xm = float(np.median(recs[0].x))
    k4 = truth.k / 4
    cur = {"k": k4, "fc": 470.0, "fv": 0.2 * k4, "bias": truth.k / k4 * (xm + truth.bias) - xm, "nb": 0.0}
    dv = 0.01 * recs[0].speed_max
    grid = _grid("actuator_lag", cur, recs, cfg, dv)
    far = [g for g in grid if "k" in g and not 0.5 < g["k"] / k4 < 2.0 and g.get("fc") == cur["fc"]]
    assert far, "no start at the balance's spring"
    fits = [_fit({**cur, **g}, ("k", "fc", "fv", "bias", "tau"), recs, cfg, dv, max_nfev=40) for g in far]
    best = min(fits, key=lambda f: f.sse_train).vals
    assert best["tau"] == pytest.approx(truth.tau, rel=0.2)
    assert best["k"] == pytest.approx(truth.k, rel=0.25)


def _fast_edges(theta: float) -> tuple[ValveData, float]:
    """20 s of raw-command PRBS edges (60 kPa, holds 0.5–2.5 s) on a fast valve (F_v/k 0.12 s,
    m/F_v 0.05 ms), simulated with 32 sub-steps per sample — within 0.7 µm of 256 sub-steps, see
    ``test_substeps_converge_to_the_step_response_of_eq_1`` — with 5 µm / 100 Pa noise."""
    dt, n = 1e-3, 20_000
    rng = np.random.default_rng(3)
    p = _prbs(n, 1.1e5, 1.6e5, rng)
    valve = EffectValve(k=2.0e5, fc=480.0, fv=2.4e4, m=1.2, sa=0.06, bias=1e-3, dv=1e-6, theta=theta)
    x = simulate_effects(valve, p, dt, substeps=32).x_meas
    t = dt * np.arange(n)
    return ValveData(t, p + 100.0 * rng.standard_normal(n), x + 5e-6 * rng.standard_normal(n), "fast"), valve.sa


@pytest.mark.slow
def test_the_one_step_scheme_is_not_named_on_a_continuous_clean_valve_with_fast_edges():
    # planted truth: no effect.  At the true parameters the fitted one-step scheme differs from the
    # continuous response by up to 26 µm (6.5 µm RMS, noise 5 µm) during the 12 mm slides after
    # the edges: its discretisation error must not be named as an effect
    data, sa = _fast_edges(0.0)
    r = reconcile(data, config=ReconcileConfig(sa=sa))
    assert r.effects == []
    assert r.final.rmse < 1.1 * r.noise_floor


@pytest.mark.slow
def test_a_dead_time_of_one_sample_on_the_same_record_is_named():
    # the control of the test above: a real timing effect of one sample period is resolved
    data, sa = _fast_edges(1e-3)
    r = reconcile(data, config=ReconcileConfig(sa=sa))
    assert r.effects[:1] == ["dead_time"]
    assert r.steps[0].params["theta_s"] == pytest.approx(1e-3, rel=0.2)


def test_the_slides_after_command_steps_are_sub_stepped():
    # planted truth: the fast-edge record above, no effect.  At the true parameters the one-step
    # scheme reads well above the 5 µm noise during the slides after the raw steps; with 4
    # sub-steps in the 0.2 s after each step (ReconcileConfig.substeps) the truth is within the noise
    data, sa = _fast_edges(0.0)
    truth = dict(k=2.0e5, fc=480.0, fv=2.4e4, bias=1e-3, nb=3.0)
    rec = prepare(data, 0.5, sa)
    assert 0.05 < rec.fine.mean() < 0.4  # the slides, not the holds

    def ratio(substeps: int) -> float:
        e = _residuals(truth, [rec], ReconcileConfig(sa=sa, m=1.2, substeps=substeps), 1e-6)[0]
        return float(np.sqrt(np.mean(e**2))) / 5e-6

    assert ratio(1) > 1.4
    assert ratio(4) < 1.15
    with pytest.raises(ModelConfigError):
        ReconcileConfig(substeps=0)


def test_smoothing_reports_the_noise_it_leaves_in_each_sample():
    # independent check by Monte Carlo: the std over 30 noise draws of the smoothed pressure, near a
    # step (short windows: most of the noise stays) and on the steady stretch (long windows)
    rng = np.random.default_rng(5)
    n, sig = 6000, 300.0
    base = np.where(np.arange(n) < 3000, 40e3, 70e3)
    _, sd = smooth_pressure(base + sig * rng.standard_normal(n), 1e-3, return_noise=True)
    emp = np.std([smooth_pressure(base + sig * rng.standard_normal(n), 1e-3) for _ in range(30)], axis=0)
    for a, b in ((3000, 3010), (3300, 3500), (4500, 5500)):
        assert np.mean(sd[a:b]) == pytest.approx(np.mean(emp[a:b]), rel=0.35)
    assert np.mean(sd[3000:3010]) > 5 * np.mean(sd[4500:5500])  # wide at the edge, narrow when steady


def test_the_result_does_not_depend_on_the_number_of_fitting_threads():
    # the multi-start fits run on worker processes (ReconcileConfig.threads; the Jacobian columns
    # of a lone fit on threads); each fit is the same computation in any process or thread and the
    # results are taken in the starts' order: 1, 2 and 3 workers give the same result to the bit
    data, sa = _fast_edges(1e-3)
    one, two, three = (reconcile(data, config=ReconcileConfig(sa=sa, threads=n)).as_dict() for n in (1, 2, 3))
    assert one["effects"] and one == two == three
    with pytest.raises(ModelConfigError, match="threads"):
        ReconcileConfig(threads=0)


def test_the_global_search_finds_a_hidden_deadband_from_the_record_alone():
    # planted truth: the low valve with a 0.8 mm deadband on the ISA steps.  The search starts
    # from no model: its ranges are read from the record, and it lands at the truth's deadband
    # and spring with the training blocks fitted near the noise (at the coarse rate, blocks of 4
    # samples: the truth itself reads 1.3 times the noise there)
    params = PRESETS["low"].replace(tau_p=0.0)
    rec = hidden_record(params, SHORT, {"deadband": (0.8e-3,)}, seed=4)
    cfg = ReconcileConfig()
    r = prepare(ValveData(rec.t, rec.p, rec.x, "deadband"), cfg.block_s, cfg.sa)
    dv = 0.01 * r.speed_max
    vals, cost = _global_fit(("deadband",), [r], cfg, dv, {"nb": cfg.stick_band, "dv": dv})
    assert cost < 1.3**2
    assert vals["deadband"] == pytest.approx(0.8e-3, rel=0.2)
    assert vals["k"] == pytest.approx(params.k, rel=0.25)
    with pytest.raises(ModelConfigError, match="global_coarse = 0"):
        ReconcileConfig(global_coarse=0)
    with pytest.raises(ModelConfigError, match="global_excess = -1"):
        ReconcileConfig(global_excess=-1)


@pytest.mark.slow
def test_a_pair_whose_basin_no_local_start_reaches_is_found_by_the_global_search():
    # unseen draw 97, record 25 of the accuracy bench: a slip jump of 1.57 and a 0.11 s dead time
    # on random steps behind a 1 s V/P lag (planted truth).  The local search names the slip jump
    # and a lag in the dead time's place and stops at 1.7 times the noise; the global search
    # (ReconcileConfig.global_search) finds the dead time beside the slip jump (opt-in:
    # `loopwatch reconcile --global-search`).  Until session 20 this was 113 #25, which the local
    # search now finds with the stick band delayed by the dead time.  Checked without the Stribeck
    # search: with it (the default since session 25) the slip jump is named Stribeck on this record,
    # with or without the global search (the dead time is found either way; ACCURACY.md, issue 8,
    # session 25)
    from tests.bench.accuracy_reconcile import make_record, select

    (_, case), = select("97:24")
    assert case["hidden"] == {"slip_jump": (pytest.approx(1.5653, rel=1e-3),), "dead_time": (pytest.approx(0.1114, rel=1e-3),)}
    t, p, x, sa = make_record(case)
    data, cfg = ValveData(t, p, x, "pair"), ReconcileConfig(sa=sa, stribeck_search=False)
    assert "dead_time" not in reconcile(data, config=cfg).effects
    r = reconcile(data, config=replace(cfg, global_search=True))
    assert {"slip_jump", "dead_time"} <= set(r.effects)
    assert r.final.params["theta_s"] == pytest.approx(0.1114, rel=0.2)
    assert r.final.params["Fs"] / r.final.params["Fc"] == pytest.approx(1.5653, rel=0.1)
    assert r.final.rmse < 1.3 * r.noise_floor


def test_the_stick_band_travels_with_the_pressure_through_the_dead_time():
    # the band (nb·S_a·σ of the noise left in the smoothed pressure) belongs to the pressure that
    # acts: delayed by theta with it.  Expected: the kernel run with the band shifted by linear
    # interpolation (as the pressure is, eq. 1 with p(t − θ)); a band burst after each step
    # (where the smoother keeps short windows) makes the two rules differ
    theta = 0.15
    rec = hidden_record(PRESETS["low"].replace(tau_p=0.0), SHORT, {"dead_time": (theta,)}, seed=2)
    r = prepare(ValveData(rec.t, rec.p, rec.x, "short"))
    cfg = ReconcileConfig()
    dv = 0.01 * r.speed_max
    v = rec.valve
    vals = dict(k=v.k, fc=v.fc, fv=v.fv, bias=v.bias, theta=theta, nb=cfg.stick_band, dv=dv)
    idx = np.arange(r.x.size)
    burst = np.zeros(r.x.size)
    for j in np.flatnonzero(np.abs(np.diff(r.p_smooth)) > 1e3):
        burst[j : j + 200] = 1e3  # Pa: a band near F_c for 0.2 s after each edge
    r = replace(r, p_noise=r.p_noise + burst)
    band = cfg.stick_band * r.sa * r.p_noise
    delayed = np.interp(idx - theta / r.dt, idx, band)
    valve = EffectValve(k=v.k, fc=v.fc, fv=v.fv, bias=v.bias, m=cfg.m, sa=cfg.sa, dv=dv, theta=theta)

    def run(b):
        return residual_effects(valve, r.p_smooth, r.dt, r.x, x0_meas=r.x0, rest_meas=r.rest, band=b,
                                substeps=cfg.substeps, fine=r.fine)

    got = _residuals(vals, [r], cfg, dv)[0]
    assert np.max(np.abs(run(band) - run(delayed))) > 5 * r.sigma_x  # the rules differ on this record
    assert np.allclose(got, run(delayed), rtol=0, atol=1e-9)


def test_stribeck_search_about_a_slip_jump_fit_reaches_the_planted_curve():
    """The trap of a Stribeck valve on ramps: a slip jump's fit puts F_c high and F_v near 0, and
    from there the local fit of the Stribeck model stays in that basin.  The search about the
    slip jump's fit (:func:`_stribeck_search`) reaches the planted curve.  Planted truth as in the
    balance test above (F_s/F_c 1.5, v_s 7 mm/s, F_v 15 kN·s/m), 30 s of ramps, 32 sub-steps."""
    valve, rec = _steep_stribeck_ramps(30.0, 15)
    cfg = ReconcileConfig(sa=valve.sa, m=valve.m)
    dv = 0.01 * rec.speed_max
    # the record's V/P lag is an accepted lag here, known: the search and the fits take it as a start
    truth = dict(k=valve.k, fc=valve.fc, dfs=valve.fs - valve.fc, vs=valve.vs, fv=valve.fv, bias=valve.bias, tau=0.05,
                 nb=3.0, dv=dv)

    def train_rms(v):
        return float(np.sqrt(np.mean(_residuals(v, [rec], cfg, dv)[0][rec.train] ** 2)))

    # a slip jump's fit of such a record: F_s about right, F_c 24 % high, no viscous friction
    slip = dict(truth, fc=1.24 * valve.fc, dfs=valve.fs - 1.24 * valve.fc, fv=0.0)
    slip.pop("vs")
    names = ("k", "fc", "fv", "bias", "dfs", "vs", "tau")
    local = _fit({**slip, "vs": rec.speed_typ}, names, [rec], cfg, dv)
    found, _ = _stribeck_search(slip, [rec], cfg, dv, {"nb": 3.0, "dv": dv})
    found = _fit(found, names, [rec], cfg, dv).vals
    assert train_rms(local.vals) > 2.0 * train_rms(truth)  # the trap: the local fit stays in the slip jump's basin
    assert train_rms(found) < 1.3 * train_rms(truth)
    assert found["fc"] == pytest.approx(valve.fc, rel=0.15)
    assert found["fc"] + found["dfs"] == pytest.approx(valve.fs, rel=0.1)


def test_stribeck_search_about_a_slip_jump_fit_also_searches_the_accepted_lag():
    """A lag accepted before the slip jump was fitted beside a slip jump, not beside the Stribeck
    curve; the curve's slides and the lag trade off (unseen 139 #26, Stribeck + lag on ramps: the
    search with the lag held named a slip jump beside the lag at 7.1 × the noise).  The search
    about the slip jump's fit (:func:`_stribeck_search`) also searches an accepted lag, over 0 to
    twice its value, and finds the planted one.  Planted truth: the steep Stribeck valve behind the
    50 ms lag above, the accepted lag 40 % short (30 ms).  (From this start the curve itself is not
    reached at 50 generations: the full-rate refit ends at 1.8 times the truth's training RMS,
    session 42; the search with the lag held at 30 ms cannot move it at all.)"""
    valve, rec = _steep_stribeck_ramps(30.0, 15)
    cfg = ReconcileConfig(sa=valve.sa, m=valve.m)
    dv = 0.01 * rec.speed_max
    truth = dict(k=valve.k, fc=valve.fc, dfs=valve.fs - valve.fc, vs=valve.vs, fv=valve.fv, bias=valve.bias, tau=0.05,
                 nb=3.0, dv=dv)
    slip = dict(truth, fc=1.24 * valve.fc, dfs=valve.fs - 1.24 * valve.fc, fv=0.0, tau=0.03)
    slip.pop("vs")
    found, _ = _stribeck_search(slip, [rec], cfg, dv, {"nb": 3.0, "dv": dv})
    assert 0.0 <= found["tau"] <= 0.06  # within the searched range
    assert found["tau"] == pytest.approx(0.05, rel=0.2)


def _stribeck_lag_record(tag: str):
    """Unseen record ``tag`` with a hidden Stribeck curve and lag, prepared as the workflow does: its configuration,
    the records, DV, the stick rule with the band, the Karnopp fit of the training blocks, the training-block RMSE of
    a model over the noise, and a check that a fit came back to the planted lag, spring, F_s and v_s (within 10 %,
    2 %, 5 % and half)."""
    import models.reconcile as rc
    from tests.bench.accuracy_reconcile import select

    data, cfg = _unseen(tag)
    ((_, case),) = select(tag)
    valve, (ratio, vs), (tau,) = case["valve"], case["hidden"]["stribeck"], case["hidden"]["actuator_lag"]
    rec = rc.prepare(data, 0.5, cfg.sa)
    recs, dv = [rec], 0.01 * rec.speed_max
    rule = {"nb": cfg.stick_band, "dv": dv}
    base = rc._fit({**rc._initial_baseline(recs, cfg), **rule}, rc._BASE, recs, cfg, dv, use="train").vals

    def train_rmse(v):
        e = rc._residuals(v, recs, cfg, dv)[0][rec.train]
        return float(np.sqrt(np.mean(e**2))) / rec.sigma_x

    def planted(fit):
        assert fit["tau"] == pytest.approx(tau, rel=0.1)
        assert fit["k"] == pytest.approx(valve["k"], rel=0.02)
        assert fit["fc"] + fit["dfs"] == pytest.approx(ratio * valve["fc"], rel=0.05)
        assert 0.5 * vs < fit["vs"] < 1.5 * vs

    return cfg, recs, dv, rule, base, train_rmse, planted


def test_a_stribeck_curve_and_a_lag_the_model_lacks_are_found_together_by_the_pair_search():
    # unseen 161 #26 (independent simulator): Stribeck friction (F_s/F_c 1.31, v_s 4.6 mm/s) behind an
    # actuator lag of 0.19 s, on ramps.  From a Karnopp fit, the pair searched together
    # (ReconcileConfig.pair_timing_search) comes back to the planted lag and curve on the training
    # blocks; the same search without the lag cannot fit them
    import models.reconcile as rc

    cfg, recs, dv, rule, base, train_rmse, planted = _stribeck_lag_record("161:25")
    assert train_rmse(base) > 5.0  # the baseline misses the training blocks
    found, _ = rc._stribeck_search(base, recs, cfg, dv, rule, "train", add="actuator_lag", maxiter=cfg.pair_timing_maxiter)
    fit = rc._fit(found, rc._BASE + ("dfs", "vs", "tau"), recs, cfg, dv, use="train").vals
    assert train_rmse(fit) < 1.3
    # the lag, the spring and F_s come back; v_s is loosely held by the training half (4.4 mm/s with
    # OpenBLAS's SkylakeX kernels, 3.0 mm/s with its Haswell ones on the same machine; planted 4.6), and
    # the lag moves with it (0.194 / 0.181 s)
    planted(fit)
    alone, _ = rc._stribeck_search(base, recs, cfg, dv, rule, "train", maxiter=cfg.pair_timing_maxiter)
    assert train_rmse(alone) > 3.0


def test_beside_a_stribeck_curve_fitted_without_its_lag_the_search_finds_the_lag_and_the_curve():
    # unseen 219 #26 (independent simulator): Stribeck friction (F_s/F_c 1.56, v_s 8.8 mm/s) behind an
    # actuator lag of 0.20 s, on ramps.  The Stribeck curve searched about a Karnopp fit without the lag
    # is another curve (v_s 0.4 mm/s with OpenBLAS's Haswell kernels) that misses the training blocks,
    # and a local fit of the lag beside it stays there; the search of the curve and the lag together about
    # it (ReconcileConfig.stribeck_timing_search) comes back to the planted lag and curve
    import models.reconcile as rc

    cfg, recs, dv, rule, base, train_rmse, planted = _stribeck_lag_record("219:25")
    names = rc._BASE + rc._effect_names("stribeck")
    curve = rc._fit(rc._stribeck_search(base, recs, cfg, dv, rule, "train")[0], names, recs, cfg, dv, use="train").vals
    assert train_rmse(curve) > 5.0
    local = rc._fit({**curve, "tau": 0.05}, names + ("tau",), recs, cfg, dv, use="train").vals
    assert train_rmse(local) > 5.0
    found, _ = rc._stribeck_search(curve, recs, cfg, dv, rule, "train", add="actuator_lag", maxiter=cfg.pair_timing_maxiter,
                                   coarse=cfg.stribeck_timing_coarse)  # the search on the record in blocks of 8 samples
    fit = rc._fit(found, names + ("tau",), recs, cfg, dv, use="train").vals
    assert train_rmse(fit) < 2.5  # 1.85 x the noise (SkylakeX kernels); the curve without the lag above 5 x
    planted(fit)
