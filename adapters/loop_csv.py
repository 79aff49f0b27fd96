"""Loop records as CSV: columns ``t`` (s), ``pv``, ``op``, optional ``sp``, ``mv``, ``mode``.

An empty cell is a missing sample.  Time must be finite and strictly increasing; the sample
time is the median spacing of ``t``, and samples are placed on that regular grid (a sample
whose time falls between grid points goes to the nearest one; grid points with no sample are
missing).  A row stamped with the same time as the previous row is dropped (the first is kept)
and counted in ``n_duplicates``; time going backwards is an error.  ``mode`` is 1 for automatic, anything else for manual / cascade-open.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from .csv_table import read_table
from .errors import DataFileError

__all__ = ["LoopData", "read_loop_csv", "MIN_SAMPLES"]

#: a record shorter than this cannot hold even one analysable window
MIN_SAMPLES = 32


@dataclass(frozen=True)
class LoopData:
    """One loop's record on a regular time grid (NaN = missing sample)."""

    source: str
    t: np.ndarray
    sample_time_s: float
    pv: np.ndarray
    op: np.ndarray
    sp: np.ndarray | None = None
    mv: np.ndarray | None = None
    mode: np.ndarray | None = None
    n_raw: int = 0
    n_duplicates: int = 0

    def __len__(self) -> int:
        return self.t.size


def read_loop_csv(path: str | Path) -> LoopData:
    """Read and validate a loop record; raise :class:`DataFileError` naming the problem."""
    cols = read_table(path, required=("t", "pv", "op"), optional=("sp", "mv", "mode"))
    t = cols["t"]
    if t.size < MIN_SAMPLES:
        raise DataFileError(f"{path}: {t.size} samples, too short (at least {MIN_SAMPLES} needed)")
    bad = np.flatnonzero(~np.isfinite(t))
    if bad.size:
        raise DataFileError(f"{path}, line {bad[0] + 2}: time 't' is missing or not finite")
    # a row with the same time as the previous one (a historian artefact: in the shared plant
    # data a sample is stamped with its predecessor's time every 300 s) is dropped and counted;
    # its grid point is then a missing sample
    same = np.diff(t) == 0
    n_dup = int(same.sum())
    if n_dup:
        keep = np.r_[True, ~same]
        cols = {c: v[keep] for c, v in cols.items()}
        t = cols["t"]
    step = np.diff(t)
    bad = np.flatnonzero(step <= 0)
    if bad.size:
        i = bad[0] + 1
        raise DataFileError(
            f"{path}: time is not increasing (t={t[i]:g} after t={t[i - 1]:g}, data row {i + 1 + n_dup})"
        )
    dt = float(np.median(step))
    idx = np.rint((t - t[0]) / dt).astype(np.int64)
    if np.any(np.diff(idx) == 0):
        i = int(np.flatnonzero(np.diff(idx) == 0)[0]) + 1
        raise DataFileError(
            f"{path}, data row {i + 1}: two samples within one sample time ({dt:g} s) of each other; "
            "the record is not on a regular grid"
        )
    n = int(idx[-1]) + 1
    if n > 50 * t.size:
        raise DataFileError(f"{path}: time gaps make the grid {n} samples long for {t.size} rows")

    def grid(v: np.ndarray) -> np.ndarray:
        out = np.full(n, np.nan)
        out[idx] = v
        return out

    return LoopData(
        source=str(path),
        t=t[0] + dt * np.arange(n),
        sample_time_s=dt,
        pv=grid(cols["pv"]),
        op=grid(cols["op"]),
        sp=grid(cols["sp"]) if "sp" in cols else None,
        mv=grid(cols["mv"]) if "mv" in cols else None,
        mode=grid(cols["mode"]) if "mode" in cols else None,
        n_raw=int(t.size),
        n_duplicates=n_dup,
    )
