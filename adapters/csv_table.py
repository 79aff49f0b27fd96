"""Numeric CSV tables: header row, one float column per name, empty cell = missing (NaN).

This is the file format shared by every CSV port (loop records, valve bench records).
Errors name the file, the line and the column, and never carry a traceback to the user.
"""

from __future__ import annotations

import csv
import math
from collections.abc import Mapping, Sequence
from pathlib import Path

import numpy as np

from .errors import DataFileError

__all__ = ["read_table", "write_table"]


def read_table(
    path: str | Path,
    *,
    required: Sequence[str],
    optional: Sequence[str] = (),
) -> dict[str, np.ndarray]:
    """Read the named numeric columns of a CSV file.

    Parameters
    ----------
    path : path of the CSV file; the first row is the header.
    required : columns that must be present.
    optional : columns returned when present (absent ones are left out of the result).

    Returns
    -------
    dict mapping column name to a float64 array; empty cells are NaN.

    Raises
    ------
    DataFileError
        file missing or unreadable, no header, a required column missing, a row with the wrong
        number of cells, or a cell that is not a number.
    """
    path = Path(path)
    try:
        fh = path.open(newline="", encoding="utf-8-sig")
    except OSError as exc:
        raise DataFileError(f"{path}: cannot open ({exc.strerror or exc})") from None
    with fh:
        reader = csv.reader(fh)
        try:
            header = next(reader, None)
        except (csv.Error, UnicodeDecodeError) as exc:
            raise DataFileError(f"{path}: not a readable CSV file ({exc})") from None
        if not header:
            raise DataFileError(f"{path}: empty file, expected a header row with {', '.join(required)}")
        names = [h.strip() for h in header]
        missing = [c for c in required if c not in names]
        if missing:
            raise DataFileError(
                f"{path}: missing column(s) {', '.join(missing)}; the header has {', '.join(names) or 'nothing'}"
            )
        wanted = [c for c in (*required, *optional) if c in names]
        index = {c: names.index(c) for c in wanted}
        cols: dict[str, list[float]] = {c: [] for c in wanted}
        width = len(names)
        try:
            for row in reader:
                if not row or (len(row) == 1 and not row[0].strip()):
                    continue  # blank line
                if len(row) != width:
                    raise DataFileError(
                        f"{path}, line {reader.line_num}: {len(row)} cells where the header has {width}"
                    )
                for c, i in index.items():
                    cell = row[i].strip()
                    if not cell:
                        cols[c].append(math.nan)
                        continue
                    try:
                        cols[c].append(float(cell))
                    except ValueError:
                        raise DataFileError(
                            f"{path}, line {reader.line_num}, column {c!r}: {cell[:40]!r} is not a number"
                        ) from None
        except (csv.Error, UnicodeDecodeError) as exc:
            raise DataFileError(f"{path}, line {reader.line_num}: not readable as CSV ({exc})") from None
    return {c: np.asarray(v, dtype=np.float64) for c, v in cols.items()}


def write_table(path: str | Path, columns: Mapping[str, np.ndarray], *, fmt: str = "%.12g") -> None:
    """Write equal-length numeric columns as CSV (header row first; NaN is written as an empty cell)."""
    names = list(columns)
    arrays = [np.asarray(columns[n], dtype=np.float64) for n in names]
    lengths = {a.shape for a in arrays}
    if len(lengths) != 1 or arrays[0].ndim != 1:
        raise DataFileError(f"{path}: columns must be 1-D and of equal length, got shapes {sorted(lengths)}")
    data = np.column_stack(arrays).reshape(-1, len(names))
    text = np.char.mod(fmt, data).astype(object)
    text[np.isnan(data)] = ""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    with path.open("w", newline="", encoding="utf-8") as fh:
        fh.write(",".join(names) + "\n")
        for row in text:
            fh.write(",".join(row) + "\n")
