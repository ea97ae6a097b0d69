"""numba's disk cache keeps one entry per compiled function, not one per process (issue 37, item 5).

Before: every process that drew objects added a ``streams._make_draw.<locals>.draw-*.nbc`` file (about 35 KB) and an
entry to its index, because numba keys a closure's cache entry by the pickled closure, and the draw's closure held
compiled functions, which pickle differently in every process. Without ``NUMBA_CACHE_DIR`` the files land in the
installed package's ``__pycache__``, and grow without end.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

from pneunet_env.physics._jit import HAVE_NUMBA

ROOT = Path(__file__).resolve().parents[1]

# One process's use of every disk-cached function of the package (the single and vector envs on the numba backend,
# fused and not, serial and parallel; the solver's and the free table's entries Python calls); it prints, for each
# cached dispatcher it finds in the package's modules, its cache hits and misses in this process.
_SCRIPT = r"""
import json, sys
import numpy as np
from numba.core.caching import NullCache
from numba.core.registry import CPUDispatcher
from pneunet_env.envs.grasp import PneuNetGraspEnv
from pneunet_env.envs.grasp_vector import PneuNetGraspVectorEnv
from pneunet_env.physics import free_table as ft, solver
from pneunet_env.physics.solver import DEFAULT_OPTIONS, params_tuple

env = PneuNetGraspEnv()
env.reset(seed=1)
for _ in range(4):
    env.step(np.array([0.5], np.float32))
env.close()
for kw in ({}, {"parallel": True}, {"fused": False}, {"fused": False, "parallel": True}):
    v = PneuNetGraspVectorEnv(num_envs=2, backend="numba", **kw)
    v.reset(seed=2)
    for _ in range(4):
        v.step(np.full((2, 1), 0.5, np.float32))
    v.close()
prm, opts = params_tuple(None), DEFAULT_OPTIONS.as_tuple()
ev0 = solver.evaluate_state(0.0, 0.0, 0.0, prm, 1e-4, 0.02)
solver.step_state_from(0.0, 0.0, 0.0, 0.5, prm, 1e-4, 0.02, opts, ev0)
solver.minimise_state((0.1, 0.0), 0.5, None, 1e-4, 0.02)
table = ft.free_table(prm, opts, 1.2)
ft.interpolate(table.nodes, table.spacing, 0.5)
ft.follow_table(0.0, 0.0, 0.0, 0.5, prm, 0.0, 1.0, opts, table.nodes, table.spacing)

stats = {}
for name, module in list(sys.modules.items()):
    if name.split(".")[0] != "pneunet_env":
        continue
    for attr, value in vars(module).items():
        d = getattr(value, "plain", value)  # (a python_entry's compiled function)
        if isinstance(d, CPUDispatcher) and not isinstance(d._cache, NullCache):
            key = f"{d.py_func.__module__}.{d.py_func.__qualname__} ({name}.{attr})"
            stats[key] = [sum(d.stats.cache_hits.values()), sum(d.stats.cache_misses.values())]
print(json.dumps(stats))
"""


def _cache_files(folder: Path) -> dict[str, int]:
    """The cache's files (relative paths) and their sizes in bytes."""
    return {str(p.relative_to(folder)): p.stat().st_size for p in folder.rglob("*") if p.is_file()}


@pytest.mark.slow  # the first process compiles every cached function (about 30 s on 2 cores)
@pytest.mark.skipif(not HAVE_NUMBA, reason="needs numba")
def test_three_processes_leave_one_cache_entry_per_compiled_function(tmp_path):
    cache = tmp_path / "numba"
    env = {**os.environ, "NUMBA_CACHE_DIR": str(cache)}
    env.pop("PNEUNET_DISABLE_NUMBA", None)
    runs = []
    for _ in range(3):
        proc = subprocess.run([sys.executable, "-c", _SCRIPT], capture_output=True, text=True, env=env, cwd=tmp_path,
                              timeout=600)
        assert proc.returncode == 0, proc.stderr[-3000:]
        runs.append((json.loads(proc.stdout.strip().splitlines()[-1]), _cache_files(cache)))
    (first, files), later = runs[0], runs[1:]
    assert len(first) >= 13, first  # the step's, the solver's, the table's and the draw's dispatchers were found
    unused = [k for k, (hits, misses) in first.items() if hits + misses == 0]
    assert not unused, f"cached functions the script does not call (add them): {unused}"
    assert len([f for f in files if f.endswith(".nbi")]) == len({k.split(" ")[0] for k in first}), files
    for stats, after in later:
        missed = {k: v for k, v in stats.items() if v[1] or not v[0]}
        assert not missed, f"compiled again in a later process instead of loaded (hits, misses): {missed}"
        assert after == files  # no new file, and no index grown
