"""Karnopp valve (models/karnopp.py) and bench excitations (models/valve_tests.py).

Expected values come from the spec paper (Romano & Garcia) or from the physics of eq. (1)-(2);
invariants are checked on every step of simulated records.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from models.errors import ModelConfigError
from models.karnopp import (
    PRESETS,
    TABLE1,
    KarnoppParams,
    KarnoppValve,
    ValveState,
    karnopp_friction,
    karnopp_step,
    pct_to_pa,
    preset,
    rest_state,
    simulate,
)
from models.valve_tests import ISA_STEPS_PCT, bench_record, excitation, isa_steps, sine, square, triangle

H = 1e-3


# --------------------------------------------------------------------------- parameters


def test_presets_are_the_papers_valve_and_table1():
    # section 4: Fisher ET, Sa = 0.0445 m^2, 28.575 mm travel, m = 1.6 kg; Table 1 model 1
    for name, fc, fv in (("low", 152.7, 4865.0), ("high", 606.0, 4.48e4)):
        p = PRESETS[name]
        assert (p.sa, p.m, p.k) == (0.0445, 1.6, 2.05e5)
        assert (p.fc, p.fs, p.fv) == (fc, fc, fv)
        assert p.x_max - p.x_min == pytest.approx(28.575e-3)
        assert p.bias == 1.13e-3  # eq. (16)
        assert TABLE1[(name, "model 1")]["fc"] == fc
    assert pct_to_pa(0.0) == 41.74e3 and pct_to_pa(100.0) == pytest.approx(206.84e3)


@pytest.mark.parametrize(
    "changes, word",
    [({"m": 0.0}, "m"), ({"k": -1.0}, "k"), ({"fc": 200.0, "fs": 100.0}, "fs"), ({"fv": -1.0}, "fv"),
     ({"dv": math.nan}, "dv"), ({"x_min": 0.02, "x_max": 0.01}, "x_min"), ({"sa": 0.0}, "sa")],
)
def test_bad_parameters_are_refused_with_the_name(changes, word):
    with pytest.raises(ModelConfigError, match=word):
        KarnoppParams(**changes)


def test_replace_refuses_unknown_fields_and_preset_slip_jump():
    with pytest.raises(ModelConfigError, match="Fc"):
        PRESETS["low"].replace(Fc=1.0)
    assert preset("low", fs_ratio=1.3).fs == pytest.approx(1.3 * 152.7)
    with pytest.raises(ModelConfigError):
        preset("medium")
    with pytest.raises(ModelConfigError):
        preset("low", fs_ratio=0.9)


def test_friction_law_eq2_three_branches():
    p = KarnoppParams(fc=100.0, fs=150.0, fv=1000.0, dv=1e-3)
    assert karnopp_friction(0.01, 0.0, p) == pytest.approx(-100.0 - 10.0)  # slip
    assert karnopp_friction(-0.01, 0.0, p) == pytest.approx(100.0 + 10.0)
    assert karnopp_friction(0.0, 120.0, p) == -120.0  # stick: cancels the net force
    assert karnopp_friction(5e-4, -149.0, p) == 149.0
    assert karnopp_friction(0.0, 200.0, p) == -150.0  # breakaway: saturated at Fs
    assert karnopp_friction(0.0, -200.0, p) == 150.0


# --------------------------------------------------------------------------- invariants


@pytest.fixture(scope="module")
def sine_runs():
    """The paper's sine validation input through both presets, with a slip-jump variant."""
    out = {}
    for name, params in (("low", PRESETS["low"]), ("high", PRESETS["high"]),
                         ("jump", PRESETS["low"].replace(fs=1.3 * 152.7))):
        exc = sine(periods=1.0)
        out[name] = simulate(params, exc.p_cmd, exc.dt)
    return out


@pytest.mark.parametrize("name", ["low", "high", "jump"])
def test_no_motion_while_net_force_within_fs(sine_runs, name):
    r = sine_runs[name]
    p = r.params
    rest_before = r.v[:-1] == 0.0
    f_net = p.sa * r.p[1:] - p.k * r.x[:-1]
    held = rest_before & (np.abs(f_net) <= p.fs)
    assert held.sum() > 1000  # the record has long stuck intervals
    np.testing.assert_array_equal(r.x[1:][held], r.x[:-1][held])  # exactly, not approximately
    assert np.all(r.v[1:][held] == 0.0)
    # and it does break away when the net force exceeds Fs
    breaks = rest_before & (np.abs(f_net) > p.fs)
    assert breaks.any()
    moved = np.sign(r.x[1:][breaks] - r.x[:-1][breaks])
    np.testing.assert_array_equal(moved, np.sign(f_net[breaks]))


def test_stuck_stem_holds_exactly_under_a_wobbling_pressure():
    p = PRESETS["high"].replace(tau_p=0.0)
    p0 = pct_to_pa(50.0)
    valve = KarnoppValve(p, p0=p0)
    x0 = valve.x_meas
    amp = 0.99 * p.fs / p.sa  # never reaches Fs
    xs = [valve.update(p0 + amp * math.sin(0.37 * i), H) for i in range(5000)]
    assert set(xs) == {x0}


@pytest.mark.parametrize("name", ["low", "high", "jump"])
def test_force_balance_holds_on_every_sliding_step(sine_runs, name):
    r = sine_runs[name]
    p = r.params
    v0, v1 = r.v[:-1], r.v[1:]
    slide = (np.abs(v0) >= p.dv) & (np.sign(v1) == np.sign(v0)) & (v1 != 0)
    assert slide.sum() > 10000
    lhs = p.m * (v1 - v0) / H
    rhs = p.sa * r.p[1:] - p.k * r.x[1:] - p.fc * np.sign(v0) - p.fv * v1  # eq. (1) with eq. (2), 1st line
    np.testing.assert_allclose(lhs[slide], rhs[slide], atol=1e-6 * p.sa * r.p.max())


def test_energy_balance_while_sliding():
    # A sustained slide: work of the actuator = kinetic + spring energy + friction dissipation
    # (+ the non-negative numerical dissipation of the implicit step, which must stay small).
    p = PRESETS["low"].replace(tau_p=0.0, x_min=-math.inf, x_max=math.inf)
    n = 3000
    state = rest_state(pct_to_pa(20.0), p)
    ramp = pct_to_pa(20.0) + p.fs / p.sa * 1.5 + np.linspace(0, 40e3, n)
    r = simulate(p, ramp, H, initial=state)
    assert np.all(np.abs(r.v) >= p.dv)  # breaks away at once and never sticks again
    x = np.concatenate(([state.x], r.x))
    v = np.concatenate(([0.0], r.v))
    f = np.concatenate(([p.sa * state.p], p.sa * r.p))
    dx = np.diff(x)
    w_ext = float(np.sum(f[1:] * dx))
    # friction of eq. (2) on each step: breakaway (Fs) from rest, then Coulomb + viscous
    fric = np.where(np.abs(v[:-1]) < p.dv, p.fs * np.sign(v[1:]), p.fc * np.sign(v[1:]) + p.fv * v[1:])
    d_fric = float(np.sum(fric * dx))
    d_kin = 0.5 * p.m * (v[-1] ** 2 - v[0] ** 2)
    d_pot = 0.5 * p.k * (x[-1] ** 2 - x[0] ** 2)
    d_num = 0.5 * p.m * float(np.sum(np.diff(v) ** 2)) + 0.5 * p.k * float(np.sum(dx**2))
    assert w_ext == pytest.approx(d_kin + d_pot + d_fric + d_num, rel=1e-9)
    assert 0 <= d_num < 1e-3 * w_ext


def test_slow_ramp_slides_at_the_quasi_static_speed():
    # eq. (1)-(2) in steady slip under dF/dt = r: v = r / k, and F - k x = Fc + Fv v
    p = PRESETS["high"].replace(tau_p=0.0, x_min=-math.inf, x_max=math.inf)
    r_n = 300.0  # N/s
    t = np.arange(0, 8.0, H)
    p_cmd = pct_to_pa(20.0) + r_n * t / p.sa
    res = simulate(p, p_cmd, H)
    tail = slice(-1000, None)
    assert np.mean(res.v[tail]) == pytest.approx(r_n / p.k, rel=1e-3)
    f_net = p.sa * res.p[tail] - p.k * res.x[tail]
    assert np.mean(f_net) == pytest.approx(p.fc + p.fv * r_n / p.k, rel=1e-3)


def test_slip_jump_after_breakaway():
    # Fs > Fc under a slow force ramp r: the stuck stem breaks away when F - kx reaches Fs
    # (eq. 2, 3rd line), then jumps until F - kx settles at the sliding value Fc + Fv*r/k.
    p = PRESETS["low"].replace(fs=1.3 * 152.7, tau_p=0.0)
    r_n = 300.0
    p0 = pct_to_pa(30.0)
    t = np.arange(0, 2.0, H)
    res = simulate(p, p0 + r_n * t / p.sa, H, initial=rest_state(p0, p))
    f_net = p.sa * res.p - p.k * res.x
    i_b = int(np.argmax(res.x != res.x[0]))
    assert f_net[i_b - 1] <= p.fs < f_net[i_b - 1] + r_n * H * 1.01  # breakaway exactly at Fs
    assert np.max(f_net) == pytest.approx(p.fs, abs=3 * r_n * H)  # a step or two in the DV band
    assert f_net[i_b + 300] == pytest.approx(p.fc + p.fv * r_n / p.k, rel=0.01)
    jump = (res.x[i_b + 300] - res.x[i_b - 1]) - r_n * 0.3 / p.k
    assert jump == pytest.approx((p.fs - p.fc - p.fv * r_n / p.k) / p.k, rel=0.05)


def test_hard_stops_and_vp_lag():
    p = PRESETS["low"]
    res = simulate(p, np.full(20000, 300e3), H, initial=rest_state(pct_to_pa(50.0), p))
    assert res.x.max() == p.x_max and np.all(res.x <= p.x_max)
    res = simulate(p, np.full(20000, 0.0), H, initial=rest_state(pct_to_pa(50.0), p))
    assert res.x.min() == p.x_min and np.all(res.x >= p.x_min)
    # first-order V/P lag, exact for a held command
    p0 = pct_to_pa(50.0)
    res = simulate(p, np.full(3000, p0 + 10e3), H, initial=ValveState(rest_state(p0, p).x, 0.0, p0))
    t = H * np.arange(1, 3001)
    np.testing.assert_allclose(res.p, p0 + 10e3 * (1 - np.exp(-t / p.tau_p)), rtol=1e-12)


def test_stepping_object_equals_batch_simulation_and_resets():
    p = PRESETS["high"]
    exc = isa_steps(hold=1.0)
    batch = simulate(p, exc.p_cmd, exc.dt, initial=rest_state(exc.p_cmd[0], p))
    valve = KarnoppValve(p, p0=float(exc.p_cmd[0]))
    stream = np.array([valve.update(u, exc.dt) for u in exc.p_cmd])
    np.testing.assert_array_equal(stream, batch.x_meas)
    valve.reset()
    assert valve.state == rest_state(float(exc.p_cmd[0]), p)
    assert 0.0 <= valve.travel_fraction <= 1.0
    with pytest.raises(ModelConfigError):
        valve.update(float("nan"), H)
    with pytest.raises(ModelConfigError):
        valve.update(100e3, 0.0)


def test_step_is_pure():
    p = PRESETS["low"]
    s = rest_state(pct_to_pa(40.0), p)
    a = karnopp_step(s, pct_to_pa(80.0), H, p)
    b = karnopp_step(s, pct_to_pa(80.0), H, p)
    assert a == b and s == rest_state(pct_to_pa(40.0), p)


# --------------------------------------------------------------------------- excitations


def test_excitations_follow_the_paper():
    sq = square()
    assert sq.dt == 1e-3
    assert set(np.round(sq.p_cmd, 6)) == {round(pct_to_pa(15.0), 6), round(pct_to_pa(75.0), 6)}
    switches = np.flatnonzero(np.diff(sq.p_cmd)) + 1
    assert np.allclose(np.diff(sq.t[switches]), 5.2, atol=2e-3)  # 10.4 s period
    sn = sine()
    assert sn.p_cmd.min() == pytest.approx(63.95e3, abs=1.0) and sn.p_cmd.max() == pytest.approx(160.44e3, abs=1.0)
    tr = triangle()
    assert tr.p_cmd.min() == pytest.approx(pct_to_pa(15.0)) and tr.p_cmd.max() == pytest.approx(pct_to_pa(75.0), rel=1e-4)
    isa = isa_steps()
    steps = np.abs(np.diff(isa.p_cmd))
    steps = steps[steps > 0] / (206.84e3 - 41.74e3) * 100
    sizes = sorted(set(np.round(steps, 6)))
    expected = sorted({round(a / 2, 6) for a in ISA_STEPS_PCT[:1]} | {round(a, 6) for a in ISA_STEPS_PCT}
                      | {round((a + b) / 2, 6) for a, b in zip(ISA_STEPS_PCT, ISA_STEPS_PCT[1:])})
    assert sizes == expected
    with pytest.raises(ModelConfigError):
        excitation("ramp")


def test_bench_record_noise_is_seeded_and_sized():
    p = PRESETS["low"]
    a = bench_record(p, "square", seed=4, noise_x=1e-5, noise_p=200.0)
    b = bench_record(p, "square", seed=4, noise_x=1e-5, noise_p=200.0)
    np.testing.assert_array_equal(a.x, b.x)
    assert np.std(a.x - a.truth.x_meas) == pytest.approx(1e-5, rel=0.05)
    assert np.std(a.p - a.truth.p) == pytest.approx(200.0, rel=0.05)
    # the paper's excitations stay inside the travel of the preset
    assert not np.any((a.truth.x == p.x_min) | (a.truth.x == p.x_max))
