"""The envs reproduce the reference run recorded before the refactor of issue 22: bit for bit on the machine that
recorded it, to round-off (:data:`reference_run.REL_TOL`, exact for everything but floats) on any other.

``tests/data/reference_run.npz`` was recorded by ``tests/reference_run.py`` from commit 8ab6920: seeded episodes
through autoresets of the single env, the vector env (numba fused and array step, numpy, torch on the CPU; SAME_STEP,
NEXT_STEP and a masked reset; unconverged solves) and the rigid env, with every state field and every key of the full
info. Any change of a number beyond round-off, a NaN's place, a dtype, a flag, a count or a value's type fails here,
naming the entry; and two runs in one process must agree bit for bit.

Re-recorded since, each time for a documented change only (issue 23, ``docs/performance-solver.md``):

* the solver's work counters (``Equilibrium.evaluations``/``backtracks``, ``info["solver_evaluations"]``/
  ``["solver_backtracks"]``): entries added, every earlier entry unchanged bit for bit;
* the energy kernel written with reciprocals and one ``tan``: states within 1.1e-15 (curvature 3.3e-16, side strain
  1.1e-15), energies 5.3e-15, gradient norms 1.5e-14 (all still below 1e-11); every reward, flag, count, status and
  string unchanged;
* the single env's step as one compiled call (``pneunet_env.fused.SingleStep``, with the vector env's evaluation
  cache): its work counters (one evaluation fewer a step, none where the pressure held at a converged minimum), and
  the type of the peak force (``TaskState.peak_force``, ``info["peak_contact_force_kpa"]``), a Python float on every
  step where it was an ``np.float64`` until the first contact; every number unchanged bit for bit.

Added since, with every earlier entry unchanged bit for bit:

* the free actuator's table (``solver.free_table``, the default since 0.10): the compiled steps' scenarios above run
  without it (``CONTINUATION``), and ``single_free_table`` and ``vector_numba_free_table`` repeat ``single`` and
  ``vector_numba`` with it. Against those, the states differ by at most 6.2e-12 (curvature 1.3e-12, side strain
  6.2e-12, energy 1.3e-15, gradient norms 9.1e-12, all still below 1e-11), the work counters differ, and every
  observation, reward, flag, status and string is the same.
* the solver's step control ``"branch"`` (``solver.step_control``, the default since 0.12): every scenario above runs
  with ``"jump"`` (``JUMP``), and the ``*_branch`` ones with the defaults. Against their ``"jump"`` twins
  (``single_free_table``, ``single_paper_volume``, ``vector_numba_free_table``, ``vector_numpy``; the ring's twin runs
  without the free table too, and against the ring run with the table under ``"jump"`` the differences are the same
  figures) every observation, reward, flag, status, snap and string is the same; the states differ by at most 1.6e-13
  (single) and 8.0e-12 (the paper's ring: indentation), energies' Hessians' smallest eigenvalues by 3.6e-11, the
  volume changes in mm^3 by 1.9e-9; the work counters differ. ``vector_numba_array_branch`` has no twin: under its
  small sub-step budget the longer sub-steps converge where ``"jump"`` spent the budget, so its episodes differ.
"""

from __future__ import annotations

import importlib.util
import warnings
from pathlib import Path

import numpy as np
import pytest

HERE = Path(__file__).parent
_spec = importlib.util.spec_from_file_location("reference_run", HERE / "reference_run.py")
reference_run = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(reference_run)

HAS_TORCH = importlib.util.find_spec("torch") is not None


@pytest.fixture(scope="module")
def expected() -> dict[str, np.ndarray]:
    return reference_run.load(HERE / "data" / "reference_run.npz")


SLOW = ("vector_numpy", "vector_torch")
"""The array back-ends' masked solver takes seconds for these few steps: run with ``-m slow``."""


@pytest.mark.parametrize("scenario", [pytest.param(s, marks=pytest.mark.slow) if s in SLOW else s
                                      for s in reference_run.SCENARIOS])
def test_reference_run(scenario, expected):
    """The recorded run, to :data:`reference_run.REL_TOL` on any machine; and bit for bit run after run here.

    Floats are compared to a tolerance because the recording's last bits belong to the machine it was made on (an
    AVX-512 CPU draws ~4 % of its log-uniform objects one bit apart: numpy's ``power`` kernel is picked by SIMD
    level). Integers, flags, strings, types and NaN places must be exact everywhere.
    """
    if scenario == "vector_torch" and not HAS_TORCH:
        pytest.skip("torch is not installed")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # objects beyond the solver's measured convergence: expected here
        got = reference_run.record([scenario])
        again = reference_run.record([scenario])
    mine = {k: v for k, v in expected.items() if k.startswith(scenario + "/")}
    assert mine, f"no reference entries for {scenario}"
    bad = reference_run.mismatches(mine, got, tolerance=True)
    assert not bad, f"{len(bad)} entries differ from the reference run:\n" + "\n".join(bad[:20])
    same = reference_run.mismatches(got, again)
    assert not same, f"{len(same)} entries differ between two runs in one process:\n" + "\n".join(same[:20])


def test_mismatches_sees_one_bit_and_a_moved_nan():
    """The comparison itself: a last-bit change, a NaN moved, a dtype change and a missing key are all caught."""
    a = {"x": np.array([1.0, np.nan, 3.0]), "y": np.array([1, 2]), "z": np.array(["a"])}
    assert reference_run.mismatches(a, {k: v.copy() for k, v in a.items()}) == []
    for key, changed in (("x", np.array([np.nextafter(1.0, 2.0), np.nan, 3.0])), ("x", np.array([1.0, 2.0, np.nan])),
                         ("x", np.array([1.0, np.nan, -3.0])), ("y", np.array([1.0, 2.0])), ("z", np.array(["b"]))):
        assert reference_run.mismatches(a, {**a, key: changed}), (key, changed)
    assert reference_run.mismatches(a, {"x": a["x"], "y": a["y"]}) == ["z: missing"]
    packed = reference_run.unpack(reference_run.pack(a))
    assert reference_run.mismatches(a, packed) == []


def test_tolerance_takes_round_off_and_nothing_more():
    """Across machines: a few ulps pass; a 1e-9 change, a moved NaN or infinity, a flipped flag or a changed count
    fail; a residual (``gradient_norm``) is judged absolutely, to a tenth of the solver's ``gtol``."""
    x = np.array([1.0, np.nan, 3.0e3, 0.0, np.inf, 1e-20])
    a = {"s/step/info.x": x, "s/step/info.flag": np.array([True, False]), "s/step/info.n": np.array([3, 4]),
         "s/step/info.gradient_norm": np.array([3e-12, 4e-16])}

    def check(key, changed):
        return reference_run.mismatches(a, {**a, key: changed}, tolerance=True)

    ulps = np.array([np.nextafter(np.nextafter(1.0, 2.0), 2.0), np.nan, 3.0e3 * (1 + 4e-16), 0.0, np.inf, 1e-20])
    assert check("s/step/info.x", ulps) == []
    assert check("s/step/info.x", x * np.where(np.arange(6) == 5, 1.0 + 1e-6, 1.0)) == []  # 1e-26: round-off of 3e3
    assert check("s/step/info.gradient_norm", np.array([2.5e-12, 9e-13])) == []
    for key, changed in (("s/step/info.x", x * (1 + 1e-9)), ("s/step/info.x", np.where(np.isnan(x), 2.0, x)),
                         ("s/step/info.x", np.where(np.isinf(x), 1e300, x)), ("s/step/info.x", -x),
                         ("s/step/info.flag", np.array([False, False])), ("s/step/info.n", np.array([3, 5])),
                         ("s/step/info.gradient_norm", np.array([3e-12, 2e-12]))):
        assert check(key, changed), (key, changed)
