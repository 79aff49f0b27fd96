"""Shared by the rerun tests: feed a simulated plant through the monitor core into a window sink
(exactly what the live monitor and ``loopwatch replay`` do), and read an ``.rrd`` back with
rerun's own reader."""

from __future__ import annotations

from collections import defaultdict
from dataclasses import dataclass, field

import numpy as np
import pyarrow as pa

from adapters.payloads import BINARY_ENCODING, encode_binary_batch
from service.monitor import LoopConfig, MonitorCore, analyze_window

T0 = 1_750_000_000.0
W, HOP = 1024, 256


@dataclass
class Fed:
    windows: list = field(default_factory=list)      # (WindowSamples, WindowResult, Alert | None)

    def alerts(self):
        return [a for _, _, a in self.windows if a is not None]


def feed_plant(sink, loops, *, batch: int = 32, raise_after: int = 2) -> Fed:
    """Publish every loop's SP, OP, PV in binary batches into a :class:`MonitorCore`, analyse each
    closed window and hand ``(window, result, alert)`` to ``sink.on_window`` in order."""
    core = MonitorCore(loop_config=lambda _id: LoopConfig(sample_time_s=1.0, length=W, hop=HOP),
                       raise_after=raise_after, clear_after=2, clock=lambda: 0.0)
    fed = Fed()
    for lp in loops:
        n = lp.sim.pv.size
        for k in range(0, n, batch):
            for sig in ("sp", "op", "pv"):
                p, a = encode_binary_batch(T0 + k, 1.0, getattr(lp.sim, sig)[k:k + batch])
                for w in core.ingest(f"plant/{lp.loop_id}/{sig}", p, BINARY_ENCODING, a):
                    r = analyze_window(w)
                    alert = core.apply(w, r)
                    sink.on_window(w.loop_id, w, r, alert)
                    fed.windows.append((w, r, alert))
    return fed


@dataclass
class Entity:
    times: list = field(default_factory=list)    # seconds (float) on the "time" timeline
    values: list = field(default_factory=list)   # one entry per row (list of scalars, or text)
    static_rows: int = 0


def read_rrd(path) -> dict[str, Entity]:
    """Every entity of the recording in ``path``: its ``time`` stamps and values, in row order."""
    from rerun.chunk import RrdReader

    out: dict[str, Entity] = defaultdict(Entity)
    reader = RrdReader(str(path))
    for ch in reader.stream():
        e = out[ch.entity_path]
        if ch.is_static:
            e.static_rows += ch.num_rows
            continue
        rb = ch.to_record_batch()
        names = rb.schema.names
        if "time" not in names:
            continue
        t = rb.column("time").cast(pa.int64()).to_numpy() / 1e9
        col = next((c for c in ("Scalars:scalars", "TextLog:text", "TextDocument:text", "LineStrips2D:strips")
                    if c in names), None)
        if col is None:
            continue
        e.times.extend(t.tolist())
        e.values.extend(rb.column(col).to_pylist())
    return dict(out)


def scalars(e: Entity, column: int | None = 0) -> tuple[np.ndarray, np.ndarray]:
    """(times, values) of a scalar entity, sorted by time; ``column=None``: every series."""
    t = np.asarray(e.times)
    v = np.array([row if column is None else row[column] for row in e.values], dtype=float)
    order = np.argsort(t, kind="stable")
    return t[order], v[order]
