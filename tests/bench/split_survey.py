"""Which records of the reconcile bench the balanced split (``ReconcileConfig.balanced_split``,
:func:`models.reconcile.balanced_split`) gives other training blocks than the one seeded draw.

``python -m tests.bench.split_survey survey OUT.json.gz [--workers N]``: for every record of the
numbered draws that ``reconcile_lines`` counts (singles below 1.8 × the noise skipped: they count in
no line), the regimes each block holds, as one bit mask per block (bit ``k``: ``REGIMES[k]``);
about 3.5 CPU-seconds a record (the record is simulated again), 25 min on 2 cores.

``python -m tests.bench.split_survey changed SURVEY.json.gz``: the tags whose split the balanced
rule changes, pairs first, then singles, then clean records, on one line (the arguments of
``accuracy_reconcile``; run those with ``LOOPWATCH_RECONCILE_BALANCED=1``).
``results/split_survey1088_s53.json.gz`` is the survey of session 53.
"""

from __future__ import annotations

import argparse
import json
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

import numpy as np

from models import reconcile as rc
from models.errors import ModelError
from models.identification import ValveData

from .accuracy_reconcile import _open, make_record, select
from .reconcile_lines import MAIN, NUMBERED, group, load

_ORDER = {"pair": 0, "single": 1, "clean": 2}


def counted() -> dict[str, dict]:
    """The stored records of the numbered draws, by tag, that a line can count."""
    recs = {}
    for path in MAIN:
        recs.update({r["tag"]: r for r in load(Path(path))})
    return {t: r for t, r in recs.items() if group(t) == NUMBERED and r["kind"] in _ORDER
            and not (r["kind"] == "single" and r["base"] < 1.8 * r["noise"])}


def held_masks(tag: str) -> list[int] | str:
    """Bit mask of the regimes each block of the record holds, as the workflow blocks it; the
    error message where the record is refused."""
    try:
        (_, case), = select(tag)
        t, p, x, sa = make_record(case)
        data = ValveData(t, p, x, "case")
        r = rc.prepare(data, rc._block_seconds(data, rc.ReconcileConfig(sa=sa)), sa)
    except ModelError as exc:
        return repr(exc)[:200]
    m = np.zeros(int(r.block[-1]) + 1, int)
    np.bitwise_or.at(m, r.block, 1 << r.labels)
    return m.tolist()


def changed(survey: dict[str, list[int] | str], kinds: dict[str, str]) -> list[str]:
    """Tags whose balanced split differs from the first draw, pairs first."""
    out = []
    for tag, m in survey.items():
        if isinstance(m, str) or tag not in kinds:
            continue
        held = (np.asarray(m)[:, None] >> np.arange(len(rc.REGIMES))) & 1
        if not np.array_equal(rc.balanced_split(held.astype(bool), rc._SPLIT_SEED),
                              rc._first_draw(len(m), rc._SPLIT_SEED)):
            out.append(tag)
    return sorted(out, key=lambda t: _ORDER[kinds[t]])


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("what", choices=("survey", "changed"))
    ap.add_argument("path")
    ap.add_argument("--workers", type=int, default=2)
    a = ap.parse_args(argv)
    recs = counted()
    if a.what == "survey":
        tags = sorted(recs, key=lambda t: _ORDER[recs[t]["kind"]])
        with ProcessPoolExecutor(a.workers) as pool:
            survey = dict(zip(tags, pool.map(held_masks, tags, chunksize=4)))
        with _open(a.path, "w") as fh:
            json.dump(survey, fh, separators=(",", ":"))
        return
    with _open(a.path, "r") as fh:
        tags = changed(json.load(fh), {t: r["kind"] for t, r in recs.items()})
    print(" ".join(tags))


if __name__ == "__main__":
    main()
