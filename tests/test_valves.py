"""Valve blocks against their defining behaviour (Choudhury et al. 2005; Olsson 1996; backlash).

Expected values come from the models' definitions and from mechanics, never from running the
code under test.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.integrate import solve_ivp

from models.errors import ModelConfigError
from models.valves import (
    Backlash,
    BacklashSpec,
    ChoudhuryStiction,
    ChoudhuryStictionSpec,
    LinearValve,
    LinearValveSpec,
    LuGreParams,
    LuGreSpec,
    LuGreValve,
    lugre_force_gain_for_stick_band,
    lugre_rhs,
    lugre_steady_friction,
    make_valve,
)

DT = 0.1


def _drive(valve, ops):
    return np.array([valve.update(float(o), DT) for o in ops])


def _ramp(a, b, step=0.01):
    n = int(round(abs(b - a) / step))
    return np.linspace(a, b, n + 1)[1:]


# ---------------------------------------------------------------- Choudhury two-parameter model


def test_choudhury_stuck_inside_stick_band_from_rest():
    v = ChoudhuryStiction(S=7.0, J=5.0)
    assert v.update(0.0, DT) == 0.0
    mv = _drive(v, _ramp(0.0, 6.99))
    assert np.all(mv == 0.0)  # OP has not crossed deadband + stickband S: no movement
    mv = _drive(v, _ramp(6.99, 7.2))
    # First sample beyond S: MV = OP - (S - J)/2 (moving branch of the flow chart).
    moved = np.nonzero(mv != 0.0)[0]
    first = moved[0]
    op_first = _ramp(6.99, 7.2)[first]
    assert op_first > 7.0 and op_first - 7.0 <= 0.0101
    assert mv[first] == pytest.approx(op_first - 1.0)


def test_choudhury_reversal_needs_S_and_slips_by_J():
    S, J = 7.0, 5.0
    v = ChoudhuryStiction(S, J)
    v.update(0.0, DT)
    up = _drive(v, _ramp(0.0, 20.0))
    assert up[-1] == pytest.approx(20.0 - (S - J) / 2)  # sliding: MV lags OP by (S - J)/2
    down_ops = _ramp(20.0, 10.0)
    down = _drive(v, down_ops)
    stuck = down_ops >= 20.0 - S
    assert np.all(down[stuck] == up[-1])  # stuck until the OP has travelled S back
    first = np.nonzero(~stuck)[0][0]
    jump = up[-1] - down[first]
    overshoot = (20.0 - S) - down_ops[first]  # how far the sample went past the threshold
    assert jump == pytest.approx(J + overshoot, abs=1e-9)
    assert 0.0 < overshoot <= 0.0101
    # afterwards it slides again with the lag on the other side
    assert down[-1] == pytest.approx(10.0 + (S - J) / 2)


def test_choudhury_reversal_inside_band_resets_stick_point():
    # Flow chart: every reversal stores a new x_ss; the valve then needs S from there.
    S, J = 4.0, 2.0
    v = ChoudhuryStiction(S, J)
    v.update(0.0, DT)
    _drive(v, _ramp(0.0, 10.0))
    y0 = 10.0 - (S - J) / 2
    mv = _drive(v, _ramp(10.0, 7.0))  # back 3 < S: stuck
    assert np.all(mv == y0)
    ops = _ramp(7.0, 10.9)  # up again 3.9 < S from the new reversal point 7
    mv = _drive(v, ops)
    assert np.all(mv == y0)
    mv = _drive(v, [11.05])  # 4.05 > S from 7: moves, MV = OP - (S-J)/2
    assert mv[0] == pytest.approx(11.05 - 1.0)


def test_choudhury_stop_in_same_direction_needs_only_J():
    S, J = 7.0, 3.0
    v = ChoudhuryStiction(S, J)
    v.update(0.0, DT)
    _drive(v, _ramp(0.0, 20.0))
    y_stop = 20.0 - (S - J) / 2
    held = _drive(v, [20.0] * 5)  # OP stops: valve sticks
    assert np.all(held == y_stop)
    ops = _ramp(20.0, 24.0)
    mv = _drive(v, ops)
    stuck = ops - 20.0 <= J
    assert np.all(mv[stuck] == y_stop)
    first = np.nonzero(~stuck)[0][0]
    assert mv[first] == pytest.approx(ops[first] - (S - J) / 2)
    assert mv[first] - y_stop == pytest.approx(J + (ops[first] - 20.0 - J), abs=1e-12)


def test_choudhury_pause_then_reverse_needs_S():
    S, J = 7.0, 3.0
    v = ChoudhuryStiction(S, J)
    v.update(0.0, DT)
    _drive(v, _ramp(0.0, 20.0))
    _drive(v, [20.0] * 3)
    ops = _ramp(20.0, 12.0)
    mv = _drive(v, ops)
    stuck = 20.0 - ops <= S
    assert np.all(mv[stuck] == 20.0 - (S - J) / 2)
    assert mv[~stuck][0] == pytest.approx(ops[~stuck][0] + (S - J) / 2)


def test_choudhury_J0_is_backlash_of_width_S_for_large_sine():
    S = 4.0
    t = np.arange(0.0, 200.0, DT)
    ops = 10.0 * np.sin(2 * np.pi * t / 50.0)
    ch = ChoudhuryStiction(S, 0.0)
    mv = _drive(ch, ops)
    # Classic backlash written out: after the first breakaway MV = OP - S/2 going up,
    # OP + S/2 going down, and holds for S of OP travel after each extremum.
    expected = np.empty_like(ops)
    y = ops[0]
    started = False
    for i, x in enumerate(ops):
        if not started:
            if x > S:  # from rest the model needs S (as after a reversal)
                started = True
                y = x - S / 2
            expected[i] = y if started else ops[0]
            continue
        if x - y > S / 2:
            y = x - S / 2
        elif x - y < -S / 2:
            y = x + S / 2
        expected[i] = y
    np.testing.assert_allclose(mv, expected, atol=1e-12)


def test_choudhury_reset_restores_behaviour():
    v = ChoudhuryStiction(3.0, 1.0)
    ops = 5 * np.sin(np.arange(300) * 0.05)
    a = _drive(v, ops)
    v.reset()
    b = _drive(v, ops)
    np.testing.assert_array_equal(a, b)


# --------------------------------------------------------------------------------------- backlash


def test_backlash_holds_within_gap_after_reversal():
    w = 2.0
    v = Backlash(w)
    v.update(0.0, DT)
    up = _drive(v, _ramp(0.0, 10.0))
    assert up[-1] == pytest.approx(10.0 - w / 2)
    ops = _ramp(10.0, 8.0 + 1e-6)  # back by less than the full gap
    mv = _drive(v, ops)
    assert np.all(mv == up[-1])
    mv = _drive(v, [7.5])
    assert mv[0] == pytest.approx(7.5 + w / 2)


@settings(max_examples=60, deadline=None)
@given(
    width=st.floats(0.0, 5.0),
    steps=st.lists(st.floats(-1.0, 1.0), min_size=1, max_size=200),
)
def test_backlash_invariants(width, steps):
    v = Backlash(width)
    x = 0.0
    y = v.update(x, DT)
    for s in steps:
        x_new = x + s
        y_new = v.update(x_new, DT)
        assert abs(x_new - y_new) <= width / 2 + 1e-9  # stem never further than half the gap
        if y_new != y:  # it only moves when pushed, in the direction of the push
            assert abs(abs(x_new - y_new) - width / 2) < 1e-9
            assert np.sign(y_new - y) == np.sign(x_new - x)
        x, y = x_new, y_new


# ----------------------------------------------------------------------------------------- LuGre


def test_lugre_stuck_below_static_friction_then_breaks_away():
    p = LuGreParams()
    v = LuGreValve(p, force_gain=1.0)  # op is the applied force
    # Ramp the force slowly to 0.95 Fs and hold: a frictionless stem would go to x = F/k = 0.95.
    for f in np.linspace(0.0, 0.95 * p.fs, 201)[1:]:
        v.update(f, DT)
    for _ in range(500):
        v.update(0.95 * p.fs, DT)
    assert abs(v.x) < 2e-3  # only pre-sliding bristle deflection ~ F / sigma0 = 1e-4
    assert abs(v.v) < 1e-6
    # Above Fs it breaks away and settles where the spring takes the load.
    for f in np.linspace(0.95, 1.05, 101)[1:]:
        v.update(f * p.fs, DT)
    for _ in range(300):
        v.update(1.05 * p.fs, DT)
    assert v.x > 0.3


def test_lugre_breakaway_force_is_fs_for_slow_ramp():
    p = LuGreParams(spring=0.0)  # free stem: moves as soon as friction cannot hold it
    v = LuGreValve(p, force_gain=1.0)
    rate = 0.01  # force units per second, slow compared with the bristle dynamics
    f = 0.0
    while abs(v.v) < p.vs and f < 2.0:
        f += rate * DT
        v.update(f, DT)
    assert f == pytest.approx(p.fs, rel=0.03)


@pytest.mark.parametrize("force", [2.0, 3.5])
def test_lugre_steady_sliding_friction_is_coulomb_plus_viscous(force):
    p = LuGreParams(spring=0.0)
    v = LuGreValve(p, force_gain=1.0)
    v.update(force, DT)
    for _ in range(400):
        v.update(force, DT)
    v_term = (force - p.fc) / p.fv  # F = Fc + Fv v at speeds far above the Stribeck velocity
    assert v.v == pytest.approx(v_term, rel=1e-3)
    assert v.friction == pytest.approx(p.fc + p.fv * v_term, rel=1e-3)


def test_lugre_steady_friction_curve():
    p = LuGreParams()
    assert lugre_steady_friction(0.0, p) == 0.0
    assert lugre_steady_friction(1e-9, p) == pytest.approx(p.fs)  # static level at v -> 0+
    assert lugre_steady_friction(-10.0, p) == pytest.approx(-(p.fc + 10 * p.fv))
    assert lugre_steady_friction(p.vs, p) == pytest.approx(p.fc + (p.fs - p.fc) * math.exp(-1) + p.fv * p.vs)


def test_lugre_rhs_equilibria_and_free_sliding():
    p = LuGreParams()
    # Stuck at rest: bristles carry the net force, nothing moves.
    f, x = 0.7, 0.2
    z = (f - p.spring * x) / p.sigma0
    np.testing.assert_allclose(lugre_rhs(0.0, np.array([x, 0.0, z]), f, p), 0.0, atol=1e-12)
    # Steady sliding: z = g(v) sign(v) so dz/dt = 0 and friction = Stribeck curve.
    vv = 0.03
    g = (p.fc + (p.fs - p.fc) * math.exp(-((vv / p.vs) ** 2))) / p.sigma0
    d = lugre_rhs(0.0, np.array([0.0, vv, g]), 0.0, LuGreParams(spring=0.0))
    assert d[0] == vv and abs(d[2]) < 1e-15
    assert -d[1] == pytest.approx(lugre_steady_friction(vv, p))
    # Independent stiff integrator on the pure RHS: a free stem reaches (F - Fc) / Fv.
    pf = LuGreParams(spring=0.0)
    sol = solve_ivp(lambda t, s: lugre_rhs(t, s, 3.5, pf), (0.0, 40.0), [0.0, 0.0, 0.0],
                    method="Radau", rtol=1e-8, atol=1e-10)
    assert sol.y[1, -1] == pytest.approx((3.5 - pf.fc) / pf.fv, rel=1e-3)


def test_lugre_slip_jump_between_coulomb_bounds():
    # Released at Fs against kinetic friction ~Fc with light viscous damping, the stem of a
    # mass-spring travels between (Fs - Fc)/k (overdamped) and 2 (Fs - Fc)/k (undamped);
    # with zeta = Fv / (2 sqrt(k m)) = 0.15 the first stop is at
    # (Fs - Fc)/k * (1 + exp(-pi zeta / sqrt(1 - zeta^2))) ~ 0.81.
    p = LuGreParams()
    v = LuGreValve(p, force_gain=1.0)
    xs = []
    f = 0.0
    while f < 1.3:
        f += 0.01 * DT
        v.update(f, DT)
        xs.append(v.x)
    xs = np.array(xs)
    dx = np.diff(xs)
    start = int(np.argmax(dx > 1e-3))  # breakaway
    stop = start + int(np.argmax(dx[start:] < 1e-4))  # first stop after it
    jump = xs[stop] - xs[start]
    zeta = p.fv / (2 * math.sqrt(p.spring * p.mass))
    theory = (p.fs - p.fc) / p.spring * (1 + math.exp(-math.pi * zeta / math.sqrt(1 - zeta**2)))
    assert (p.fs - p.fc) / p.spring < jump < 2 * (p.fs - p.fc) / p.spring
    assert jump == pytest.approx(theory, rel=0.15)  # Stribeck + rate effects shift it slightly


def test_lugre_position_in_op_units_is_identity_without_friction_load():
    # Very slow motion far above the stick band: MV tracks OP minus friction/gain.
    gain = lugre_force_gain_for_stick_band(7.0)
    assert gain == pytest.approx((1.0 + 0.5) / 7.0)
    v = LuGreValve(LuGreParams(), gain)
    ops = np.concatenate([np.linspace(0, 40, 4001), np.full(2000, 40.0)])
    mv = _drive(v, ops)
    # At rest the spring force k x balances gain*OP minus a friction between -Fs and +Fs.
    assert abs(mv[-1] - 40.0) <= 1.0 / gain + 1e-9


def test_lugre_coarse_stuck_steps_do_not_change_the_trajectory():
    t = np.arange(0.0, 300.0, DT)
    ops = 12.0 * np.sin(2 * np.pi * t / 60.0) + 3.0 * np.sin(2 * np.pi * t / 17.0)
    fine = _drive(LuGreValve(LuGreParams(), 3 / 14, coarse_when_stuck=False), ops)
    fast = _drive(LuGreValve(LuGreParams(), 3 / 14, coarse_when_stuck=True), ops)
    assert np.max(np.abs(fast - fine)) < 0.01 * np.ptp(fine)


# ------------------------------------------------------------------------- specs and validation


def test_make_valve_builds_each_kind():
    assert isinstance(make_valve(None), LinearValve)
    assert isinstance(make_valve(LinearValveSpec()), LinearValve)
    assert isinstance(make_valve(ChoudhuryStictionSpec(7, 5)), ChoudhuryStiction)
    assert isinstance(make_valve(LuGreSpec()), LuGreValve)
    assert isinstance(make_valve(BacklashSpec(2.0)), Backlash)
    assert LinearValve().update(3.25, DT) == 3.25


@pytest.mark.parametrize(
    "build, word",
    [
        (lambda: ChoudhuryStiction(-1.0, 0.0), "S"),
        (lambda: ChoudhuryStictionSpec(7.0, float("nan")), "J"),
        (lambda: Backlash(-0.5), "width"),
        (lambda: LuGreParams(fs=0.4, fc=0.5), "fs"),
        (lambda: LuGreParams(sigma0=0.0), "sigma0"),
        (lambda: LuGreParams(vs=-1.0), "vs"),
        (lambda: LuGreValve(LuGreParams(), force_gain=0.0), "force_gain"),
        (lambda: LuGreSpec(LuGreParams(spring=0.0)), "spring"),
        (lambda: make_valve("sticky"), "valve spec"),
    ],
)
def test_bad_valve_parameters_are_named(build, word):
    with pytest.raises(ModelConfigError, match=word):
        build()
