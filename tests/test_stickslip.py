"""Stick-slip without a limit cycle: the Hammerstein (stiction + linear) test of OP -> PV,
against hand computations and planted loops (models.loop)."""

import numpy as np
import pytest
from scipy.signal import lfilter

from models.loop import FOPDT, LoopScenario, PIController, SetpointStep, Sinusoid, simulate_loop
from models.valves import ChoudhuryStiction, ChoudhuryStictionSpec, KarnoppLoopSpec
from pipeline.diagnosis import diagnose_window
from pipeline.hammerstein import _time_constants, hammerstein_fit, reversal_stem, stiction_stem, stiction_test
from pipeline.stickslip import stick_slip_episodes


def test_stiction_stem_by_hand():
    """He et al. (2007): stuck while |op - x| <= fs, then x = op - sign * fd."""
    op = np.array([0.0, 0.5, 1.0, 1.2, 1.4, 1.8, 1.0, 0.0])
    x = stiction_stem(op, np.array([1.0, 0.0]), np.array([0.5, 0.0]))
    np.testing.assert_allclose(x[0], [0, 0, 0, 0.7, 0.7, 1.3, 1.3, 0.5])
    np.testing.assert_allclose(x[1], op)  # no friction: the stem is the OP
    # a net force at the start: the stem sits 0.8 below the OP and breaks away sooner
    x = stiction_stem(op, np.array([1.0]), np.array([0.5]), np.array([0.8]))
    np.testing.assert_allclose(x[0], [-0.8, 0.0, 0.0, 0.7, 0.7, 1.3, 1.3, 0.5])


def test_reversal_stem_by_hand():
    """Choudhury, Thornhill & Shah (2005), Fig. 7, S = 1, J = 0.5: stuck until the OP has moved
    more than S from the reversal point, then y = x - d (S - J) / 2."""
    op = np.array([0.0, 0.5, 1.2, 1.5, 1.3, 1.0, 0.2, 0.0])
    y = reversal_stem(op, np.array([1.0]), np.array([0.5]))[0]
    np.testing.assert_allclose(y, [0, 0, 0.95, 1.25, 1.25, 1.25, 0.45, 0.25])
    # the count restarts at each reversal: a ramp of 0.1 per sample with +-0.15 of alternating
    # noise travels 5 S and the stem holds; the force-balance stem (He et al. 2007) moves
    op = 0.1 * np.arange(51) + 0.15 * (-1.0) ** np.arange(51)
    assert np.ptp(reversal_stem(op, np.array([1.0]), np.array([0.5]))[0]) == 0
    assert np.ptp(stiction_stem(op, np.array([0.75]), np.array([0.25]))[0]) > 3
    # held 3 below the OP at the start: the first slip (OP 1.2 > S from its start) is 3.95
    y = reversal_stem(np.array([0.0, 0.5, 1.2, 1.5]), np.array([1.0]), np.array([0.5]), np.array([3.0]))[0]
    np.testing.assert_allclose(y, [-3.0, -3.0, 0.95, 1.25])


def test_reversal_stem_is_the_simulators_two_parameter_valve():
    """The pipeline's kernel and models.valves.ChoudhuryStiction (the loop simulator's valve, an
    independent implementation of the same flow chart) agree on random OPs with pauses."""
    rng = np.random.default_rng(11)
    for _ in range(50):
        op = np.cumsum(rng.standard_normal(300)) * rng.uniform(0.1, 2.0)
        pause = rng.random(300) < 0.2
        for k in np.flatnonzero(pause[1:]) + 1:
            op[k] = op[k - 1]
        S = rng.uniform(0.0, 3.0)
        J = rng.uniform(0.0, 2.0) * S
        valve = ChoudhuryStiction(S, J)
        expected = [valve.update(o, 1.0) for o in op]
        np.testing.assert_allclose(reversal_stem(op, np.array([S]), np.array([J]))[0], expected)


def test_hammerstein_fit_recovers_a_planted_first_order_lag_with_dead_time():
    rng = np.random.default_rng(0)
    n, D = 600, 40
    op = np.cumsum(rng.standard_normal(n))
    a = _time_constants(n)[5]
    pv = 3.0 + 2.0 * lfilter([1 - a], [1, -a], np.r_[np.zeros(7), op[:-7]] - op[0]) + 0.01 * rng.standard_normal(n)
    fit = hammerstein_fit(pv, np.vstack([op, np.roll(op, 50)]), max_dead_time=D)
    assert fit.dead_time[0] == 7 and fit.pole[0] == pytest.approx(a)
    assert fit.gain[0] == pytest.approx(2.0, rel=0.01)
    assert fit.sse[0] < 1e-3 * fit.sse[1]


def test_a_lag_0_fit_explains_the_controllers_reaction_to_noise_from_lag_1_nothing():
    """Valve stuck throughout: the PV is its set point plus measurement noise ``nu``, the OP a
    slow wander minus the controller's P-action on ``nu`` at the same sample.  At lag 0 a linear
    model of PV from OP "explains" the noise (gain ``-1/kc``), a correlation no valve causes;
    from one sample on (the PV cannot answer the OP computed from it) it explains nothing."""
    rng = np.random.default_rng(3)
    n = 751
    nu = 0.3 * rng.standard_normal(n)
    op = 0.1 * np.sin(2 * np.pi * np.arange(n) / 300.0) - 0.8 * nu
    pv = 5.0 + nu
    ss = float(np.sum((pv[75:] - pv[75:].mean()) ** 2))
    fit0 = hammerstein_fit(pv, op[None, :], max_dead_time=75, poles=np.array([0.0]))
    assert fit0.dead_time[0] == 0 and fit0.sse[0] < 0.2 * ss
    fit1 = hammerstein_fit(pv, op[None, :], max_dead_time=75, min_dead_time=1, poles=np.array([0.0]))
    assert fit1.dead_time[0] >= 1 and fit1.sse[0] > 0.95 * ss


@pytest.mark.parametrize("seed", [0, 1])
def test_sticking_valve_found_despite_the_controllers_reaction_to_noise(seed):
    """A PI ramp (0.005 per sample) plus P-action on the measurement noise (kc = 1) through a
    He et al. (2007) stem (fs 1.5, fd 0.75); the PV answers the stem one sample later.  The
    test allows dead times from one sample, so the linear model cannot fit the noise reaction
    at lag 0 (with lag 0 allowed, these windows read as linear)."""
    rng = np.random.default_rng(seed)
    n = 751
    nu = 0.3 * rng.standard_normal(n)
    op = 0.005 * np.arange(n) - nu
    stem = stiction_stem(op, np.array([1.5]), np.array([0.75]))[0]
    pv = 1.5 * np.r_[stem[0], stem[:-1]] + nu
    assert not stiction_test(pv, op, min_dead_time=0).sticking
    t = stiction_test(pv, op)
    assert t is not None and t.sticking and t.slips >= 2, t


def slow_loop(valve, seed: int, *, n: int = 751):
    """Slow PI on a FOPDT flow-like plant, set-point steps, measurement and load noise:
    the last ``n`` samples (pv, op, sp)."""
    plant = FOPDT(1.5, 10.0, 3.0)
    steps = (SetpointStep(0.0, 50.0), SetpointStep(900.0, 55.0), SetpointStep(1200.0, 51.0))
    sc = LoopScenario(plant=plant, controller=PIController(0.1, 0.01), setpoint_steps=steps, valve=valve,
                      measurement_noise_std=0.1, load_noise_std=0.05, duration_s=1502.0)
    sim = simulate_loop(sc, seed=seed)
    return sim.pv[-n:], sim.op[-n:], sim.sp[-n:]


@pytest.mark.parametrize("seed", [1, 2])
def test_sticking_valve_found_and_linear_valve_not(seed):
    pv, op, sp = slow_loop(KarnoppLoopSpec(fc=1.5, fs=3.0), seed)
    t = stiction_test(pv, op)
    assert t is not None and t.sticking, t
    found = stick_slip_episodes(pv, op, sp)
    assert found.episodes >= 1 and "does not follow the OP" in found.reason
    d = diagnose_window(pv, fs=1.0, op=op, sp=sp)
    assert d.verdict == "not_oscillating" and d.stick_slip.episodes >= 1, d.reason
    pv, op, sp = slow_loop(None, seed)
    t = stiction_test(pv, op)
    assert t is not None and not t.sticking, t
    assert diagnose_window(pv, fs=1.0, op=op, sp=sp).stick_slip.episodes == 0


def reversal_loop(valve, seed: int, *, n: int = 751):
    """Slow PI (P-action on measurement noise 0.3: the OP reverses at about a third of its
    samples) on the FOPDT of :func:`slow_loop`, set point moved up, down and up again: the
    last ``n`` samples (pv, op, sp, stem)."""
    steps = (SetpointStep(0.0, 50.0), SetpointStep(900.0, 56.0), SetpointStep(1150.0, 50.0), SetpointStep(1350.0, 55.0))
    sc = LoopScenario(plant=FOPDT(1.5, 10.0, 3.0), controller=PIController(0.15, 0.01), setpoint_steps=steps,
                      valve=valve, measurement_noise_std=0.3, load_noise_std=0.05, duration_s=1502.0)
    sim = simulate_loop(sc, seed=seed)
    return sim.pv[-n:], sim.op[-n:], sim.sp[-n:], sim.mv[-n:]


@pytest.mark.parametrize("seed, rule", [(1, "reversal rule"), (2, None), (5, "reversal rule")])
def test_reversal_rule_valve_behind_a_noisy_pi_found_and_linear_valve_not(seed, rule):
    """Planted two-parameter valve (Choudhury et al. 2005, S = 3, J = 1.5) whose count restarts
    at every OP reversal: found, on seeds 1 and 5 by the reversal-rule stem (the planted model;
    on seed 2 a force-balance deadband fits the PV better); the same loop with a linear valve:
    no stick-slip."""
    pv, op, sp, stem = reversal_loop(ChoudhuryStictionSpec(S=3.0, J=1.5), seed)
    assert np.count_nonzero(np.diff(stem)) > 10  # the planted stem slips in the window
    t = stiction_test(pv, op)
    assert t is not None and t.sticking and t.rule == (rule or t.rule), t
    assert stick_slip_episodes(pv, op, sp).episodes >= 1
    pv, op, sp, _ = reversal_loop(None, seed)
    t = stiction_test(pv, op)
    assert t is not None and not t.sticking, t
    assert stick_slip_episodes(pv, op, sp).episodes == 0


def test_no_stick_slip_when_an_integrating_pv_turns_round():
    """Level-like PV (integral of OP - balance): while the OP ramps through the balance the
    PV is momentarily steady, then moves on; a linear (integrating) response, no stiction."""
    rng = np.random.default_rng(5)
    n = 750
    op = np.linspace(-3.0, 3.0, n) + 0.01 * rng.standard_normal(n)
    pv = np.cumsum(op) * 0.02 + 0.05 * rng.standard_normal(n)
    found = stick_slip_episodes(pv, op)
    assert found is None or found.episodes == 0, found


def test_long_windows_are_averaged_down_and_flat_signals_give_nothing():
    pv, op, sp = slow_loop(KarnoppLoopSpec(fc=1.5, fs=3.0), 1)
    found = stick_slip_episodes(np.repeat(pv, 4), np.repeat(op, 4), np.repeat(sp, 4))  # 3004 samples at 4x the rate
    assert found.episodes >= 1
    assert stick_slip_episodes(np.ones(500), op[:500]) is None


@pytest.mark.parametrize("seed", [1, 2])
def test_a_compensated_disturbance_is_no_stick_slip(seed):
    """Healthy valve, well-tuned PI cancelling a wandering load (three sinusoids at the PV):
    no stick-slip should be reported.  (A deadband model of OP -> PV fits such a window better
    than the linear one -- the OP is correlated with the load it cancels -- but the OP is no
    PI ramp while that stem is held.)"""
    plant = FOPDT(1.5, 10.0, 3.0)
    loads = tuple(Sinusoid(1.0, 2 * np.pi / p, ph) for p, ph in ((80.0, 0.3), (200.0, 2.0), (500.0, 4.0)))
    steps = (SetpointStep(0.0, 50.0), SetpointStep(1000.0, 55.0))
    sc = LoopScenario(plant=plant, controller=PIController(1.11, 0.111), setpoint_steps=steps, disturbances=loads,
                      measurement_noise_std=0.1, load_noise_std=0.05, duration_s=1502.0)
    sim = simulate_loop(sc, seed=seed)
    found = stick_slip_episodes(sim.pv[-751:], sim.op[-751:], sim.sp[-751:])
    assert found is None or found.episodes == 0, found


def test_ramp_share_of_the_op_while_the_stem_is_held():
    """Straight lines between set-point changes within the holds: 1 for PI ramps, ~0 for a
    wandering OP, 0 when the stem is never held."""
    from pipeline.stickslip import _ramp_share

    n = 800
    t = np.arange(n, dtype=float)
    stem = np.zeros(n)  # held throughout
    assert _ramp_share(0.01 * t, stem) == pytest.approx(1.0)
    # back and forth: 4 periods of a sine; the best line leaves almost all of its variance
    assert _ramp_share(np.sin(2 * np.pi * 4 * t / n), stem) < 0.05
    # a ramp reversed with a kick at a set-point change is two PI ramps; with the set point
    # unchanged it is not: one line through a symmetric triangle explains none of it
    tri = np.where(t < 400, 0.01 * t, 4.0 - 0.01 * (t - 400) + 0.5)
    sp = np.where(t < 400, 50.0, 48.0)
    assert _ramp_share(tri, stem, sp) == pytest.approx(1.0)
    tri = np.where(t < 400, 0.01 * t, 8.0 - 0.01 * t)
    assert _ramp_share(tri, stem) < 0.05
    # a set point that keeps moving (a cascade's) earns no breaks: a wandering OP stays unexplained
    sp = 50.0 + np.round(np.sin(2 * np.pi * 3 * t / n), 2)
    assert _ramp_share(np.sin(2 * np.pi * 4 * t / n), stem, sp) < 0.05
    assert _ramp_share(0.01 * t, t) == 0.0  # never held
    # two holds: a ramp each, a slip between (pooled)
    stem = np.where(t < 500, 0.0, 1.0)
    assert _ramp_share(np.where(t < 500, 0.01 * t, 10.0 - 0.01 * t), stem) == pytest.approx(1.0)


def test_setpoint_moves_group_clicks_and_skip_a_wandering_set_point():
    from pipeline.stickslip import _setpoint_moves

    sp = np.r_[np.zeros(10), np.ones(2), 2 * np.ones(20), 3 + np.arange(30.0), 40 * np.ones(10)]
    # two clicks 2 samples apart are one move (both break); the 30-sample ramp is no step
    np.testing.assert_array_equal(_setpoint_moves(sp, 5), [10, 12])
    assert _setpoint_moves(np.full(9, 3.0), 3).size == 0


@pytest.mark.xfail(strict=True, reason="known defect (issue 3, session 5): in block-averaged windows a linear "
                   "loop with a noisy OP reads as stick-slip; at the window's own sampling it does not")
@pytest.mark.parametrize("seed", [100, 101])
def test_linear_loop_with_a_noisy_op_on_a_block_averaged_window_is_no_stick_slip(seed):
    """A linear valve one sample behind the OP; the OP a slow triangle (straight ramps) minus the
    controller's P-action on the PV's measurement noise.  On 751 samples (own sampling) no
    stick-slip; on 4096 samples, averaged over blocks of 6 before the test, the block means of
    the OP still carry the same-block reaction to the PV's noise, which a deadband stem filters
    out, and the stiction model wins (4-5 slips found on these seeds)."""
    rng = np.random.default_rng(seed)
    n = 4096
    nu = 0.3 * rng.standard_normal(n)
    op = 0.004 * np.abs(((np.arange(n) + 500) % 2000) - 1000) - nu
    pv = 1.5 * np.r_[op[0], op[:-1]] + nu
    assert stick_slip_episodes(pv[:751], op[:751]).episodes == 0
    assert stick_slip_episodes(pv, op).episodes == 0
