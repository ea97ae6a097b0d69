"""``python compare.py REF.npz RUN.npz...``: each run's walks against the reference's (``walks.py``), over the walks
in which neither had a failed solve: folds the reference flags and the run does not, folds flagged wrongly, walks
that left the reference's branch (a state more than 1e-6 away), the largest state difference elsewhere, and the
evaluations per solve."""

import sys

import numpy as np

ref = np.load(sys.argv[1])
for f in sys.argv[2:]:
    c = np.load(f)
    ok = ~((ref["status"] > 1).any(axis=1) | (c["status"] > 1).any(axis=1))
    missed = int((ref["snap"] & ~c["snap"])[ok].sum())
    wrong = int((~ref["snap"] & c["snap"])[ok].sum())
    ds, dk = np.abs(c["S"] - ref["S"]), np.abs(c["K"] - ref["K"])
    off = (ds.max(axis=1) > 1e-6) | (dk.max(axis=1) > 1e-6)
    d = max(ds[ok & ~off].max(initial=0.0), dk[ok & ~off].max(initial=0.0))
    print(f, f"walks without a failure {ok.sum()}/{ok.size}; there: reference folds {int(ref['snap'][ok].sum())}, "
          f"missed {missed}, flagged wrongly {wrong}, off the reference's branch {int((off & ok).sum())}, "
          f"largest state difference elsewhere {d:.1e}; evaluations per solve {c['evals'][ok].mean():.2f} "
          f"(reference {ref['evals'][ok].mean():.2f})")
