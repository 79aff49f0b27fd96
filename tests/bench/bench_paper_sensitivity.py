"""How the paper-method figures of Table 3 move with the choices the paper leaves open.

Prints (for ACCURACY.md): TDNL per case for set-point step times 1, 10 and 50 s and for three
EMD stop rules; and case (c) analysed in 1000 s segments, with the amplitude of the barely
stable loop mode in each.
"""

import dataclasses

import numpy as np
import pytest
from scipy import signal

from models.loop import CASES, SetpointStep, simulate_loop
from pipeline.diagnosis import DiagnosisConfig, diagnose_window
from pipeline.emd import EMDConfig

CASE_NAMES = ("tuning", "disturbance", "tuning+disturbance", "stiction-datadriven", "stiction-lugre")
RULES = {
    "4 sifts x 3 IMFs (default)": EMDConfig(),
    "10 sifts x 4 IMFs": EMDConfig(sifts=10, max_imfs=4),
    "PyEMD default rule": EMDConfig(sifts=0, max_imfs=-1),
}


def _pv(name: str, step_s: float) -> np.ndarray:
    sc = dataclasses.replace(CASES[name], setpoint_steps=(SetpointStep(step_s, 5.0),))
    return simulate_loop(sc, seed=0).pv


@pytest.mark.bench
def test_table3_sensitivity():
    print("\nTable 3 TDNL (verdict) by set-point step time and EMD stop rule")
    for rule, emd_config in RULES.items():
        cfg = DiagnosisConfig(method="paper", emd=emd_config)
        for step in (1.0, 10.0, 50.0):
            cells = []
            for name in CASE_NAMES:
                d = diagnose_window(_pv(name, step), fs=1.0, config=cfg)
                cells.append(f"{d.tdnl:.3f} ({d.verdict[:3]})")
            print(f"  {rule:27s} step {step:4.0f} s | " + " | ".join(cells))
    print("columns: " + ", ".join(CASE_NAMES))

    pv = _pv("tuning+disturbance", 1.0)
    b, a = signal.butter(2, [0.03 / 0.5, 0.06 / 0.5], "band")  # around the 0.27 rad/s loop mode
    mode = signal.filtfilt(b, a, pv)
    print("\nCase (c) by 1000 s segment: loop-mode amplitude, verdict, TDNL, DNL per kept IMF")
    for start in range(0, 4000, 1000):
        seg = slice(start, start + 1000)
        d = diagnose_window(pv[seg], fs=1.0, config=DiagnosisConfig(method="paper"))
        amp = np.sqrt(2) * np.std(mode[seg])
        print(f"  {start:4d}-{start + 1000:4d} s  mode amplitude {amp:5.2f}  {d.verdict:9s} TDNL {d.tdnl:.3f}  DNL {np.round(d.dnl, 3)}")
