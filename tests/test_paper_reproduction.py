"""Reproduction of Aftab, Hovd, Huang & Sivalingam (2016), Tables 2 and 3, with the paper method.

The paper leaves open the EMD stop rule, the IF estimator, the end handling and (for Table 3) the
timing of the set-point step that provides the "transient effects" of §4.  Our choices are in the
docstrings of ``pipeline.dnl``, ``pipeline.frequency`` and ``pipeline.emd``; the step is placed
at t = 1 s, the default step time of Simulink's Step block (the paper's Fig. 3 is a Simulink-
style diagram).  ACCURACY.md records the numbers and how they move with these choices.
Run with ``-s`` to see paper vs. ours.
"""

import dataclasses

import numpy as np
import pytest

from models.loop import CASES, SetpointStep, simulate_loop
from pipeline.diagnosis import DiagnosisConfig, diagnose_window
from pipeline.dnl import imf_dnl, tdnl
from pipeline.emd import EMDConfig, emd

PAPER_TABLE2 = {  # signal: (DNL IMF1, DNL IMF2, TDNL), Aftab et al. 2016, Table 2
    "x": (0.04, 0.04, 0.04),
    "x+0.25x^2": (0.21, 0.05, 0.13),
    "x+x^2": (0.29, 0.47, 0.37),
}

PAPER_TABLE3 = {  # case: (TDNL, verdict), Aftab et al. 2016, Table 3 and §4.1-4.4
    "tuning": (0.057, "linear"),
    "disturbance": (0.023, "linear"),
    "tuning+disturbance": (0.024, "linear"),
    "stiction-datadriven": (1.6, "nonlinear"),
    "stiction-lugre": (1.38, "nonlinear"),
}


def example_one(n: int = 1000) -> dict[str, np.ndarray]:
    """Eq. 9: x(k) = sin(2 pi 0.05 k) + sin(2 pi 0.1 k), y = x + a x^2 (k in samples, 1 Hz)."""
    k = np.arange(n, dtype=float)
    x = np.sin(2 * np.pi * 0.05 * k) + np.sin(2 * np.pi * 0.1 * k)
    return {"x": x, "x+0.25x^2": x + 0.25 * x**2, "x+x^2": x + x**2}


def table2_row(y: np.ndarray, config: EMDConfig) -> tuple[float, float, float]:
    """Two IMFs as in the paper's Example I, their DNL (eq. 11) and the TDNL (eq. 12)."""
    imfs, _ = emd(y - y.mean(), config=dataclasses.replace(config, max_imfs=2))
    d = np.array([imf_dnl(c, fs=1.0).dnl for c in imfs[:2]])
    return float(d[0]), float(d[1]), tdnl(d, imfs[:2])


@pytest.mark.parametrize("emd_config", [EMDConfig(), EMDConfig(sifts=0, max_imfs=-1)], ids=["bounded", "pyemd-default"])
def test_table2_example_one(emd_config, capsys):
    ours = {name: table2_row(y, emd_config) for name, y in example_one().items()}
    with capsys.disabled():
        print(f"\nTable 2 ({emd_config}):  signal | paper DNL1 DNL2 TDNL | ours DNL1 DNL2 TDNL")
        for name, row in ours.items():
            p = PAPER_TABLE2[name]
            print(f"  {name:10s} | {p[0]:.2f} {p[1]:.2f} {p[2]:.2f} | {row[0]:.3f} {row[1]:.3f} {row[2]:.3f}")
    # the paper's findings: the undistorted signal is linear, the strongly distorted one is
    # non-linear, and (with our bounded EMD) the TDNL grows with the distortion; PyEMD's default
    # stop rule gives 0.175 vs 0.176 for the two distorted signals, too close to assert an order
    assert ours["x"][2] < 0.1
    assert ours["x+x^2"][2] > 0.1
    if emd_config.sifts:
        assert ours["x"][2] < ours["x+0.25x^2"][2] < ours["x+x^2"][2]


def paper_scenario(name: str):
    """A Table 3 case as in §4, the set-point step at t = 1 s (see the module docstring)."""
    return dataclasses.replace(CASES[name], setpoint_steps=(SetpointStep(1.0, 5.0),))


@pytest.fixture(scope="module")
def table3():
    out = {}
    for name in PAPER_TABLE3:
        sim = simulate_loop(paper_scenario(name), seed=0)
        out[name] = diagnose_window(sim.pv, fs=1.0, config=DiagnosisConfig(method="paper"))
    return out


def test_table3_prints_paper_vs_ours(table3, capsys):
    with capsys.disabled():
        print("\nTable 3 (noise-free, paper method):  case | paper TDNL verdict | ours DNL(IMFs) TDNL verdict")
        for name, d in table3.items():
            p = PAPER_TABLE3[name]
            dnl = " & ".join(f"{v:.3f}" for v in d.dnl)
            print(f"  {name:20s} | {p[0]:5.3f} {p[1]:9s} | {dnl} (IMF {d.imfs_kept}) {d.tdnl:.3f} {d.verdict}")
    assert all(d.gate is not None and d.gate.oscillating for d in table3.values())


@pytest.mark.parametrize("case", ["tuning", "disturbance", "stiction-datadriven", "stiction-lugre"])
def test_table3_verdicts_match_the_paper(table3, case):
    assert table3[case].verdict == PAPER_TABLE3[case][1], table3[case].reason


def test_table3_linear_cases_well_below_and_stiction_well_above_threshold(table3):
    """Beyond the verdict: the margins the paper reports (linear <= 0.06, stiction >= 1.38) are
    not reproduced in size (see ACCURACY.md), but each side stays clear of the 0.1 threshold."""
    for case in ("tuning", "disturbance"):
        assert table3[case].tdnl < 0.05
    for case in ("stiction-datadriven", "stiction-lugre"):
        assert table3[case].tdnl > 0.25
