"""Valve bench / positioner records as CSV: columns ``t`` (s), ``p`` (Pa, the pressure that
drives the actuator) and ``x`` (m, measured stem position).

Read with :func:`adapters.csv_table.read_table`; every problem is a :class:`DataFileError`
naming the file, the line and the column.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from models.identification import ValveData

from .csv_table import read_table, write_table
from .errors import DataFileError

__all__ = ["COLUMNS", "read_valve_csv", "write_valve_csv"]

COLUMNS = ("t", "p", "x")
_MEANING = {"t": "time (s)", "p": "actuator pressure (Pa)", "x": "stem position (m)"}


def read_valve_csv(path: str | Path) -> ValveData:
    """Read and validate a valve record.

    Raises
    ------
    DataFileError
        a column missing, an empty or non-numeric cell (NaN), fewer than two rows, or time that
        is not strictly increasing.
    """
    cols = read_table(path, required=COLUMNS)
    n = cols["t"].size
    if n < 2:
        raise DataFileError(f"{path}: {n} data row(s); a valve record needs at least two samples of t, p, x")
    for c in COLUMNS:
        bad = np.flatnonzero(~np.isfinite(cols[c]))
        if bad.size:
            raise DataFileError(
                f"{path}, line {bad[0] + 2}, column {c!r}: {_MEANING[c]} is missing or not finite "
                f"({bad.size} such row(s) in all); the identification needs a gap-free record"
            )
    step = np.diff(cols["t"])
    bad = np.flatnonzero(step <= 0)
    if bad.size:
        i = int(bad[0]) + 1
        raise DataFileError(
            f"{path}, line {i + 2}: time is not strictly increasing (t={cols['t'][i]:g} after t={cols['t'][i - 1]:g})"
        )
    return ValveData(t=cols["t"], p=cols["p"], x=cols["x"], name=Path(path).name)


def write_valve_csv(path: str | Path, t: np.ndarray, p: np.ndarray, x: np.ndarray) -> None:
    """Write ``t, p, x`` (s, Pa, m) as CSV."""
    write_table(path, {"t": t, "p": p, "x": x})
