"""The acceptance lines of issue 8 from stored results, without running ``reconcile``.

ACCURACY.md quotes these lines after every change; until session 43 they were computed by scratch
scripts outside the repository.  The results of ``accuracy_reconcile --json`` are stored in
``tests/bench/results``; :data:`MAIN` holds every record of the hidden-effect suite (numbered
draws 119-185, the own suite, the pair draws x187-x197) as main names them after session 43, then
the fresh draws 187 and 189 as session 44 ran them, then the 230 records session 44's refit in the
backward elimination can change, as it names them, then the fresh draws 191 and 193 as session 46
ran them (main at 25b88f9), then the fresh draws 195 and 197 as session 48 ran them (main at
657fc88), then the fresh draws 199 and 201 as session 49 ran them (main at 2b5effc), then the 179
records session 51 re-ran after the first fold at the noise decides the cross-fit (every single and pair
above the noise whose final model read 1.5 times the noise or more held out, and 32 others), then the
fresh draws 203 and 205 as session 51 ran them (main at 0c5b6d5), then the 22 records on which
session 54's search on the swapped blocks can run (``ReconcileConfig.swap_search``: every stored
record whose search stopped with nothing passing, a model fitting its training blocks and not the
held-out ones, and the whole record at twice the noise or more), as it names them, then the fresh
draws 207, 209, 211 and 213 as session 54 ran them (main at 1e73fad, with OPENBLAS_CORETYPE=SkylakeX),
then the 47 records session 54's nested slip jump at the end of the search can change
(``ReconcileConfig.nested_slip_jump``: a final Stribeck curve with v_s below DV, in the kept run or
named in the message of a run not kept), as it names them, then the fresh draws 215 and 217 as
session 54 ran them on its final code (main at 5814426, OPENBLAS_CORETYPE=SkylakeX), then the 62
records on which session 55's search of the final Stribeck model on the whole record can run
(``ReconcileConfig.final_search``: a final model with a Stribeck curve at twice the noise or more on the
whole record), as it names them (OPENBLAS_CORETYPE=SkylakeX), then the fresh draws 219 and 221 as session 55
ran them on its final code (main at ed6b802, OPENBLAS_CORETYPE=SkylakeX), then the 56 records on which
session 56's search of the Stribeck + lag / dead time pairs can run (``ReconcileConfig.pair_timing_search``:
no single passing the first step with the model at twice the noise or more held out; found by a probe of
every stored record with two effects or more or a swapped search, and by the held-out error of those naming
none), as it names them (OPENBLAS_CORETYPE=SkylakeX), then the fresh draws 223 and 225 as session 57 ran them
(main at 83f6a66, on an Intel Xeon whose own OpenBLAS kernel is SkylakeX), then the 43 records on which session
57's search of the lag beside an accepted Stribeck curve changed the result in a broader first form or was aimed at
(``ReconcileConfig.stribeck_timing_search``), as it names them (SkylakeX), then the fresh draws 227 and 229 as
session 58 ran them (main at 1feec9c with a log of each better-basin refit added and nothing else changed; Xeon,
SkylakeX), then 183 #26 re-run on main at 1feec9c (its stored result was older than the code), then the fresh
draws 231 and 233 as session 60 ran them (main at a5c031d; Xeon, SkylakeX), and
:data:`TRUTHS` each record's truth ratio (``accuracy_reconcile --truth``: the planted truth simulated
by the workflow from the smoothed recorded pressure, RMSE over the position noise).
Files given on the command line replace the records of the same tags, in order: the lines of a
branch from the records it re-ran.

Lines, per group of records (numbered draws, own suite, x-draws):

* singles named first, where the baseline misses by twice the noise or more (the issue's "effect
  clearly above the noise"); and where the effect is visible (``visible``: the truth without
  it, refitted, misses the training blocks by twice the noise or more);
* clean records naming none;
* pairs with both effects found: all, both visible, and both visible against the truth's own
  error (each effect's absence costs twice the truth's RMSE or more: the truth reads several times
  the noise where the smoothed pressure's noise moves a Stribeck valve's slips, ACCURACY.md
  issue 8 session 43, so twice the noise is not yet visible there);
* final RMSE at most half the baseline's (baseline at twice the noise or more), and the same where
  the truth itself reads at most half the baseline (reachable by a fit within the model family).

Run: ``.venv/bin/python -m tests.bench.reconcile_lines [RESULTS.json[.gz] ...]``
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

from .accuracy_reconcile import _open, clear, shown

RESULTS = Path(__file__).parent / "results"
MAIN = (RESULTS / "reconcile_main_s43.json.gz", RESULTS / "reconcile_187-189_s44.json.gz",
        RESULTS / "reconcile_refit230_s44.json.gz", RESULTS / "reconcile_191-193_s46.json.gz",
        RESULTS / "reconcile_195-197_s48.json.gz", RESULTS / "reconcile_199-201_s49.json.gz",
        RESULTS / "reconcile_firstfold179_s51.json.gz", RESULTS / "reconcile_203-205_s51.json.gz",
        RESULTS / "reconcile_swap22_s54.json.gz", RESULTS / "reconcile_207-209_s54.json.gz",
        RESULTS / "reconcile_211-213_s54.json.gz", RESULTS / "reconcile_nested47_s54.json.gz",
        RESULTS / "reconcile_215-217_s54.json.gz", RESULTS / "reconcile_final62_s55.json.gz",
        RESULTS / "reconcile_219-221_s55.json.gz", RESULTS / "reconcile_pairtiming56_s56.json.gz",
        RESULTS / "reconcile_223-225_s57.json.gz", RESULTS / "reconcile_stribecktiming43_s57.json.gz",
        RESULTS / "reconcile_227-229_s58.json.gz", RESULTS / "reconcile_rerun183_s58.json.gz",
        RESULTS / "reconcile_231-233_s60.json.gz")
TRUTHS = (RESULTS / "truth_119-185_s40.json.gz", RESULTS / "truth_x187-197_s42.json.gz",
          RESULTS / "truth_187-189_s44.json.gz", RESULTS / "truth_191-193_s46.json.gz",
          RESULTS / "truth_195-197_s48.json.gz", RESULTS / "truth_199-201_s49.json.gz",
          RESULTS / "truth_203-205_s51.json.gz", RESULTS / "truth_207-209_s54.json.gz",
          RESULTS / "truth_211-213_s54.json.gz", RESULTS / "truth_215-217_s54.json.gz",
          RESULTS / "truth_219-221_s55.json.gz", RESULTS / "truth_223-225_s57.json.gz",
          RESULTS / "truth_227-229_s58.json.gz", RESULTS / "truth_231-233_s60.json.gz")
NUMBERED = "numbered draws 119-233"


def load(path: Path) -> list | dict:
    with _open(str(path), "r") as fh:
        return json.load(fh)


def truth_ratios(stored: list | dict) -> dict[str, float]:
    """``{tag: truth ratio}`` of a stored truth file: the ``accuracy_reconcile --truth --json`` list
    of records as written, or the ``{tag: ratio}`` dict the files of sessions 40-49 hold (converted
    by hand from that list)."""
    return dict(stored) if isinstance(stored, dict) else {r["tag"]: r["truth"] for r in stored}


def group(tag: str) -> str:
    head = tag.split(":")[0]
    return "own suite" if head == "own" else "x-draws (pairs)" if head.startswith("x") else NUMBERED


def _share(ok: list[bool]) -> str:
    return f"{sum(ok)}/{len(ok)} = {100 * sum(ok) / len(ok):.1f} %" if ok else "0/0"


def lines(records: list[dict], truth: dict[str, float]) -> list[str]:
    """The lines (module docstring) of one group of result records."""
    out = []
    singles = [r for r in records if r["kind"] == "single"]
    if singles:
        above = [r for r in singles if clear(r)]  # NaN (a refused record) is not above
        vis = [r for r in singles if shown(r)]
        first = [r["effects"][:1] == list(r["hidden"]) for r in above]
        out.append(f"singles named first, baseline >= 2 x noise: {_share(first)}; visible: "
                   f"{_share([r['effects'][:1] == list(r['hidden']) for r in vis])}")
    clean = [r for r in records if r["kind"] == "clean"]
    if clean:
        out.append(f"clean, none named: {_share([not r['effects'] for r in clean])}")
    pairs = [r for r in records if r["kind"] == "pair"]
    if pairs:
        def found(r: dict) -> bool:
            return set(r["hidden"]) <= set(r["effects"])

        vis = [r for r in pairs if shown(r)]
        rel = [r for r in vis if r["tag"] in truth and min(r["visible"].values()) >= 2 * truth[r["tag"]]]
        out.append(f"pairs, both found: {_share([found(r) for r in pairs])}; both visible (>= 2 x noise): "
                   f"{_share([found(r) for r in vis])}; both visible against the truth (each >= 2 x the truth's RMSE): "
                   f"{_share([found(r) for r in rel])}")
    hid = [r for r in records if r["kind"] in ("single", "pair") and clear(r)]
    if hid:
        half = [r["final"] <= 0.5 * r["base"] for r in hid]
        reach = [r for r in hid if r["tag"] in truth and truth[r["tag"]] * r["noise"] <= 0.5 * r["base"]]
        out.append(f"final <= 0.5 x baseline: {_share(half)}; where the truth reads <= 0.5 x baseline: "
                   f"{_share([r['final'] <= 0.5 * r['base'] for r in reach])} (not counted: {len(hid) - len(reach)} "
                   "records whose truth reads more or has no stored ratio)")
    return out


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("results", nargs="*", help="accuracy_reconcile --json files replacing records of main by tag")
    a = ap.parse_args(argv)
    recs = {}
    for path in (*MAIN, *a.results):
        recs.update({r["tag"]: r for r in load(Path(path))})
    truth: dict[str, float] = {}
    for path in TRUTHS:
        truth.update(truth_ratios(load(path)))
    for name in (NUMBERED, "own suite", "x-draws (pairs)"):
        sel = [r for r in recs.values() if group(r["tag"]) == name]
        print(f"== {name}: {len(sel)} records")
        for line in lines(sel, truth):
            print("  " + line)


if __name__ == "__main__":
    main()
