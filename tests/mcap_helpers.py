"""Shared by the recording tests: a small simulated plant recorded through the real monitor.

The plant's samples are the planted truth every recorded window is checked against.  One loop
(:data:`JITTER_LOOP`) is sent as single JSON samples whose time stamps are jittered off the
1 s grid by a planted amount, so the recording must keep the data's own time stamps.
"""

from __future__ import annotations

from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from adapters.mcap_recorder import McapRecorder
from adapters.payloads import BINARY_ENCODING, encode_binary_batch, encode_sample
from pipeline.diagnosis import DiagnosisConfig
from service.commands.simulate_plant import PlantLoop, make_plant
from service.monitor import Alert, AnalysisConfig, LoopConfig, Monitor, MonitorCore

T0 = 1_750_000_000.0
LENGTH, HOP = 512, 128
DURATION = 1400                       # (1400 - 512) // 128 + 1 = 7 windows per loop
N_WINDOWS = (DURATION - LENGTH) // HOP + 1
SIGNALS = ("sp", "mv", "op", "pv")
RAISE_AFTER, CLEAR_AFTER = 2, 2
#: index in the plant of the loop analysed with the paper's method (a non-default config)
PAPER_LOOP = 1
JITTER_LOOP = 2
PAPER_CONFIG = DiagnosisConfig(method="paper", threshold=0.2)


@dataclass
class Recorded:
    dir: Path
    loops: list[PlantLoop]
    times: dict[str, np.ndarray]       # planted sample times of every loop (Unix s)
    alerts: list[Alert]
    monitor_windows: int
    recorder_status: dict


class _Alerts:
    def __init__(self) -> None:
        self.got: list[Alert] = []

    def publish(self, alert: Alert) -> None:
        self.got.append(alert)


def loop_config(loops: list[PlantLoop]):
    paper = loops[PAPER_LOOP].loop_id
    base = dict(sample_time_s=1.0, length=LENGTH, hop=HOP, lateness=16)
    default = LoopConfig(**base)
    special = LoopConfig(**base, analysis=AnalysisConfig(signal="pv", diagnosis=PAPER_CONFIG))
    return lambda loop_id: special if loop_id == paper else default


def planted_times(n: int, *, jitter: bool) -> np.ndarray:
    t = T0 + np.arange(n, dtype=np.float64)
    if jitter:
        t = t + np.random.default_rng(5).uniform(-0.3, 0.3, n).round(3)
    return t


def feed(on_message, loops: list[PlantLoop], times: dict[str, np.ndarray], *, batch: int = 64) -> None:
    """Send the plant in time order: binary batches, the jitter loop as single JSON samples."""
    for k0 in range(0, DURATION, batch):
        for i, lp in enumerate(loops):
            for sig in SIGNALS:
                v = getattr(lp.sim, sig)[k0:k0 + batch]
                key = f"plant/{lp.loop_id}/{sig}"
                if i == JITTER_LOOP:
                    for t, x in zip(times[lp.loop_id][k0:k0 + batch], v):
                        on_message(key, encode_sample(float(t), float(x)), "application/json", None)
                else:
                    p, a = encode_binary_batch(T0 + k0, 1.0, v)
                    on_message(key, p, BINARY_ENCODING, a)


def make_loops(n: int = 6) -> tuple[list[PlantLoop], dict[str, np.ndarray]]:
    loops = make_plant(n, duration_s=float(DURATION))
    times = {lp.loop_id: planted_times(DURATION, jitter=(i == JITTER_LOOP)) for i, lp in enumerate(loops)}
    return loops, times


def record_plant(directory: Path, n_loops: int = 6, **recorder_kw) -> Recorded:
    """Run the real :class:`Monitor` (one analysis thread) with an :class:`McapRecorder` on the plant.

    Chunks are small (about one window each) and so written as they fill: what a cut or failed file
    holds does not depend on how fast this machine feeds the plant relative to ``flush_s`` (on a
    fast machine the whole plant would otherwise land in one chunk written at close)."""
    loops, times = make_loops(n_loops)
    core = MonitorCore(loop_config=loop_config(loops), raise_after=RAISE_AFTER, clear_after=CLEAR_AFTER)
    kw = dict(instance="test", run_config={"alerts": {"raise_after": RAISE_AFTER, "clear_after": CLEAR_AFTER}},
              flush_s=0.2, chunk_size=16_384)
    kw.update(recorder_kw)
    recorder = McapRecorder(directory, **kw)
    alerts = _Alerts()
    monitor = Monitor(core, ThreadPoolExecutor(max_workers=1), alert_sinks=[alerts], window_sinks=[recorder])
    feed(monitor.on_message, loops, times)
    assert monitor.drain(120)
    assert "recording" in monitor.status()["sinks"]
    windows = monitor.windows_done
    monitor.close()                        # closes the recorder: every window queued is written
    return Recorded(Path(directory), loops, times, alerts.got, windows, recorder.status())
