"""Probe (issue 8, pairs): a hidden pair fitted on the whole record, then cross-fitted from that fit.

For each chosen record with two hidden effects, the pair's model (the workflow's kernel, both
effects free) is fitted on the *whole* record from the joint force-balance starts
(``models.reconcile._joint_starts``: short fits, the two best refined), and refitted locally on
each fold from that fit.  Printed, in multiples of the measurement noise: the planted truth as the
workflow simulates it, the whole-record fit (its spring and Coulomb friction against the truth's),
and each fold's fit on its own blocks and on the other fold's.  A pair the workflow misses but
whose whole-record fit reaches the noise and holds on both folds is one the search could find by
fitting on the whole record first; a fold fit that reaches the noise on its blocks and not on the
other's is split-limited (ACCURACY.md, issue 8, session 34).

Not a test and not in the default run.  Usage (independent records by tag, as in
``tests.bench.accuracy_reconcile``)::

    .venv/bin/python -m tests.bench.probe_pair_whole 121:25 123:24 163:25
"""

from __future__ import annotations

import sys

import numpy as np

from models import reconcile as rc
from models.identification import ValveData
from models.reconcile import ReconcileConfig

from .accuracy_reconcile import make_record, select, truth_values


def probe(tag: str, case: dict) -> str:
    t, p, x, sa = make_record(case)
    cfg = ReconcileConfig(sa=sa)
    truth, _ = truth_values(case, cfg)
    data = ValveData(t, p, x, "case")
    rec = rc.prepare(data, rc._block_seconds(data, cfg), cfg.sa)  # the workflow's blocks
    recs, dv = [rec], 0.01 * rec.speed_max
    truth["dv"] = dv

    def ratio(v: dict[str, float], mask: np.ndarray) -> float:
        e = rc._residuals(v, recs, cfg, dv)[0]
        return float(np.sqrt(np.mean(e[mask] ** 2)) / rec.sigma_x)

    effects = tuple(case["hidden"])
    free = rc._BASE + sum((rc._effect_names(e) for e in effects), ())
    starts = rc._joint_starts(effects, recs, cfg, rc._stick_rules(cfg, dv))
    shorts = [rc._fit(s, free, recs, cfg, dv, use="all", max_nfev=rc._SHORT_NFEV, stride_s=0.016) for s in starts]
    best = [shorts[i].vals for i in np.argsort([f.sse_train for f in shorts])[:2]]
    whole = min((rc._fit(v, free, recs, cfg, dv, use="all") for v in best), key=lambda f: f.sse_train).vals
    tr, al = rec.train, np.ones(rec.x.size, bool)
    f_tr = rc._fit(whole, free, recs, cfg, dv, use="train").vals
    f_te = rc._fit(whole, free, recs, cfg, dv, use="test").vals
    return (f"{tag} {case['exc']} {'+'.join(effects)}: truth {ratio(truth, al):.2f} | whole-record fit "
            f"{ratio(whole, al):.2f} (k/k_true {whole['k'] / truth['k']:.3f}, F_c/F_c,true {whole['fc'] / truth['fc']:.3f})"
            f" | from it, training fit {ratio(f_tr, tr):.2f} own / {ratio(f_tr, ~tr):.2f} held out, held-out fit "
            f"{ratio(f_te, ~tr):.2f} own / {ratio(f_te, tr):.2f} held out (x noise)")


if __name__ == "__main__":
    for spec in sys.argv[1:]:
        for tag, case in select(spec):
            if case["kind"] == "pair":
                print(probe(tag, case), flush=True)
