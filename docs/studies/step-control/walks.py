"""Random pressure walks with the scalar continuation: each step's state, snapped flag, status and evaluations.

``python walks.py OUT.npz MAX_JUMP [GENT_LIMIT]``; the environment's ``STEP`` (largest pressure step, ``p~``), ``KLO``
and ``KHI`` (``log10`` of the objects' ``k~`` range; one walk in ten is free) set the walks, ``STEP_CONTROL`` the
solver's ``step_control`` (``jump``, this script's default and the package's until 0.12, or ``branch``).
"""

import os
import sys
import time

import numpy as np

from pneunet_env.physics.params import ActuatorParams
from pneunet_env.physics.solver import SolverOptions, params_tuple, step_state

out, max_jump = sys.argv[1], float(sys.argv[2])
gent = float(sys.argv[3]) if len(sys.argv) > 3 else None
W, S = 3600, 60
rng = np.random.default_rng(11)
prm = params_tuple(ActuatorParams() if gent is None else ActuatorParams(gent_limit=gent))
opts = SolverOptions(max_jump=max_jump, step_control=os.environ.get("STEP_CONTROL", "jump")).as_tuple()
k_range = float(os.environ.get("KLO", "-4")), float(os.environ.get("KHI", "-1"))
kobj = np.where(rng.random(W) < 0.1, 0.0, 10 ** rng.uniform(*k_range, W))
ko = rng.uniform(0.01, 0.3, W)
steps = rng.uniform(-1, 1, (W, S)) * float(os.environ.get("STEP", "0.06"))
K, Sx, P = np.zeros((W, S)), np.zeros((W, S)), np.zeros((W, S))
snap, status, evals = np.zeros((W, S), bool), np.zeros((W, S), int), np.zeros((W, S), int)
t = time.time()
for w in range(W):
    k = s = p = 0.0
    for i in range(S):
        p1 = min(max(p + steps[w, i], 0.0), 1.2)
        r = step_state(k, s, p, p1, prm, kobj[w], ko[w], opts)
        if r.status <= 1:
            k, s, p = r.kappa, r.side_strain, p1
        K[w, i], Sx[w, i], snap[w, i], status[w, i], evals[w, i], P[w, i] = (
            k, s, r.snapped, r.status, r.evaluations, p)
print(out, f"{time.time() - t:.1f} s; failed {int((status > 1).sum())}; snapped {int(snap.sum())}; "
      f"evaluations per solve {evals.mean():.2f}")
np.savez(out, K=K, S=Sx, snap=snap, status=status, evals=evals, P=P)
