"""``loopwatch simulate plant --loops N --speed X``: publish a simulated plant over zenoh.

A mixed plant of the paper's closed loops (:data:`models.loop.CASES`): stiction (two models),
tuning, disturbance, deadband and healthy loops, assigned in turn; the truth of every loop is
printed at the start.  Samples go to ``{prefix}/{loop_id}/{signal}`` for ``sp, mv, op, pv`` in
one of the payload formats of :mod:`adapters.payloads` (``single``: one JSON sample per message;
``json`` / ``binary``: batches of ``--batch`` samples), paced at ``--speed`` times real time.
Sample times are ``t0 + k * Ts`` with ``t0`` the wall clock at start unless ``--t0`` is given.
"""

from __future__ import annotations

import argparse
import json
import math
import threading
import time
from dataclasses import dataclass

import numpy as np

from adapters.payloads import BINARY_ENCODING, encode_binary_batch, encode_json_batch, encode_sample
from models.loop import LoopSimResult, scenario_for_case, simulate_loop

from ..errors import UsageError

__all__ = ["PLANT_MIX", "PlantLoop", "make_plant", "PlantPublisher", "expects_alert"]

#: cases of the mixed plant, assigned in turn (the pipeline gets all of them right without noise)
PLANT_MIX = ("stiction-datadriven", "tuning", "disturbance", "healthy", "stiction-lugre", "deadband")
_TAGS = ("FIC", "LIC", "TIC", "PIC")
#: published signals, in this order within a tick (op and pv last: they pace the monitor's windows)
PUBLISHED = ("sp", "mv", "op", "pv")


def expects_alert(truth: str) -> bool:
    """Whether a loop of this truth should raise a stiction alert."""
    return truth == "stiction"


@dataclass(frozen=True)
class PlantLoop:
    """One simulated loop: its id, the case it was simulated from, the truth, and the record."""

    loop_id: str
    case: str
    truth: str
    sim: LoopSimResult


def make_plant(n: int, *, duration_s: float, noise: float = 0.0, seed: int = 0,
               mix: tuple[str, ...] = PLANT_MIX, distinct_seeds: int = 4) -> list[PlantLoop]:
    """``n`` loops cycling through ``mix``; loops of the same case and ``seed % distinct_seeds``
    share one simulated record (keeps a plant of thousands of loops cheap)."""
    if n < 1:
        raise UsageError(f"--loops {n}: need at least one loop")
    cache: dict[tuple[str, int], LoopSimResult] = {}
    loops = []
    for i in range(n):
        case = mix[i % len(mix)]
        s = seed + (i // len(mix)) % max(1, distinct_seeds)
        sim = cache.get((case, s))
        if sim is None:
            sim = cache[(case, s)] = simulate_loop(scenario_for_case(case, noise_std=noise, duration_s=duration_s),
                                                   seed=s)
        loops.append(PlantLoop(f"area{i // 10 + 1}/{_TAGS[i % len(_TAGS)]}{100 + i}", case, sim.truth, sim))
    return loops


class PlantPublisher:
    """Publishes the records of ``loops`` on ``session``, paced at ``speed`` times real time.

    Parameters
    ----------
    session : an open zenoh session.
    loops : from :func:`make_plant`.
    prefix : key prefix.
    fmt : ``single``, ``json`` or ``binary``.
    batch : samples per message for the batch formats.
    speed : data seconds per wall second; ``math.inf`` publishes as fast as possible.
    t0 : Unix time of sample 0.
    """

    def __init__(self, session, loops: list[PlantLoop], *, prefix: str = "plant", fmt: str = "binary",
                 batch: int = 16, speed: float = 1.0, t0: float | None = None) -> None:
        import zenoh

        if fmt not in ("single", "json", "binary"):
            raise UsageError(f"--format {fmt!r} must be single, json or binary")
        if batch < 1 or not speed > 0:
            raise UsageError(f"--batch {batch} must be >= 1 and --speed {speed} > 0")
        self._z = zenoh
        self.session, self.loops, self.prefix = session, loops, prefix.rstrip("/")
        self.fmt, self.batch, self.speed = fmt, (1 if fmt == "single" else batch), speed
        self.t0 = float(round(time.time()) if t0 is None else t0)
        self.sent_samples = 0
        self.sent_messages = 0
        self.stop_event = threading.Event()

    def _put(self, key: str, ts: float, t_first: float, v: np.ndarray) -> None:
        z = self._z
        if self.fmt == "single":
            for j, x in enumerate(v):
                self.session.put(key, encode_sample(t_first + j * ts, x), encoding=z.Encoding.APPLICATION_JSON,
                                 congestion_control=z.CongestionControl.BLOCK)
                self.sent_messages += 1
        elif self.fmt == "json":
            self.session.put(key, encode_json_batch(t_first, ts, v), encoding=z.Encoding.APPLICATION_JSON,
                             congestion_control=z.CongestionControl.BLOCK)
            self.sent_messages += 1
        else:
            payload, att = encode_binary_batch(t_first, ts, v)
            self.session.put(key, payload, encoding=z.Encoding(BINARY_ENCODING), attachment=att,
                             congestion_control=z.CongestionControl.BLOCK)
            self.sent_messages += 1
        self.sent_samples += int(v.size)

    def run(self) -> None:
        """Publish every record from start to end (or until :attr:`stop_event` is set)."""
        n = min(lp.sim.t.size for lp in self.loops)
        ts = float(self.loops[0].sim.t[1] - self.loops[0].sim.t[0])
        start = time.monotonic()
        for k0 in range(0, n, self.batch):
            k1 = min(n, k0 + self.batch)
            if math.isfinite(self.speed):   # a batch goes out once its last sample is due
                delay = start + (k1 - 1) * ts / self.speed - time.monotonic()
                if delay > 0 and self.stop_event.wait(delay):
                    return
            if self.stop_event.is_set():
                return
            for lp in self.loops:
                for sig in PUBLISHED:
                    self._put(f"{self.prefix}/{lp.loop_id}/{sig}", ts, self.t0 + k0 * ts,
                              getattr(lp.sim, sig)[k0:k1])


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--loops", type=int, default=12, metavar="N", help="number of loops (default 12)")
    p.add_argument("--speed", type=float, default=1.0, metavar="X", help="times real time (default 1)")
    p.add_argument("--duration", type=float, default=4000.0, metavar="S", help="plant seconds to publish (default 4000)")
    p.add_argument("--format", dest="fmt", choices=["single", "json", "binary"], default="binary",
                   help="payload format (default binary batches)")
    p.add_argument("--batch", type=int, default=16, help="samples per message for json/binary (default 16)")
    p.add_argument("--noise", type=float, default=0.0, metavar="STD", help="PV measurement noise std (default 0)")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--t0", type=float, default=None, help="Unix time of the first sample (default: now)")
    p.add_argument("--prefix", default="plant", help="key prefix (default plant)")
    p.add_argument("--connect", action="append", default=None, metavar="ENDPOINT",
                   help="zenoh endpoint to connect to (default tcp/127.0.0.1:7447, the monitor's default)")
    p.add_argument("--mode", choices=["peer", "client"], default="peer", help="zenoh mode (client: via a router)")


def run(args: argparse.Namespace) -> int:
    from adapters.zenoh_session import open_session

    if not (math.isfinite(args.duration) and args.duration >= 2):
        raise UsageError(f"--duration {args.duration}: must be >= 2 s")
    loops = make_plant(args.loops, duration_s=float(args.duration), noise=args.noise, seed=args.seed)
    print(json.dumps({"plant": [{"loop": lp.loop_id, "case": lp.case, "truth": lp.truth,
                                 "expect_alert": expects_alert(lp.truth)} for lp in loops]}, indent=1))
    session = open_session(args.mode, connect=args.connect or ["tcp/127.0.0.1:7447"])
    try:
        pub = PlantPublisher(session, loops, prefix=args.prefix, fmt=args.fmt, batch=args.batch,
                             speed=args.speed, t0=args.t0)
        t = time.monotonic()
        pub.run()
        print(f"published {pub.sent_samples} samples in {pub.sent_messages} messages "
              f"in {time.monotonic() - t:.1f} s")
    finally:
        session.close()
    return 0
