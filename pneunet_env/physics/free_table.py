"""The free actuator's equilibrium path as a table: a step that touches nothing in one or two energy evaluations.

Where the actuator touches nothing (``kappa~ <= w kappa_obj``), the object's energy is zero and the equilibrium
depends on the pressure alone: the free actuator's path ``(kappa~(p~), e_s(p~))``. :func:`build_free_table`
follows that path once with the continuation (:func:`~pneunet_env.physics.solver.step_state`), from rest to the
env's ``p_max``, and keeps at nodes ``spacing`` apart the state and its tangent ``dx/dp~ = H^{-1} dV/dx`` (the
continuation's own predictor). Between nodes the path is the cubic Hermite interpolant of these: within 2.2e-10 of
the exact path at the default spacing (measured: :func:`interpolate`).

:func:`make_follow_table` builds ``follow_table``, the step along the table: from a free equilibrium on the path to a
pressure where the path is still free, it evaluates the energy at the table's state at the new pressure and, unless
that is already a converged minimum (``|grad| <= gtol``, positive-definite Hessian), polishes it with the solver's
own Newton corrector (:func:`~pneunet_env.physics.solver._make_parts`'s ``descend``, kept within ``max_jump`` of the
table's state). The result is accepted exactly as the continuation's is: converged, positive definite, free. It is
the minimum the continuation reaches (the path is the one it follows), to within the tolerance of both: not bit for
bit. Anything else, and the table is not used: the step is the continuation's.

When the path is used, and why it is the right minimum:

* the table covers the path only as far as it is one plain branch: every node converged, no fold crossed (the
  continuation's ``snapped``), a positive-definite Hessian, ``kappa~`` never decreasing, and loading and unloading
  agreeing (:data:`BRANCH_AGREEMENT`: no hysteresis within the table, even with folds too weak to flag).
  :func:`build_free_table` ends it below the first node that is not, so an actuator whose free path folds has a
  table only below the fold (the branch beyond a fold may reach back below it: unloading from the table's end cannot
  see that branch, so the next condition is what keeps its states off the table);
* the start is a free equilibrium on the path at its pressure (within :data:`ON_PATH`, far tighter than the gap to
  any other branch), and the path at the new pressure is free. Since ``kappa~`` rises along the path, the whole path
  between the two pressures is free: the continuation would follow the table's branch, on which the object's energy
  is zero;
* the polished state is a converged minimum, free, within ``max_jump`` of the table's state.

Only the compiled steps use it (numba: :mod:`pneunet_env.fused`), where :class:`SolverOptions.free_table
<pneunet_env.physics.solver.SolverOptions>` is set (the default).
"""

from __future__ import annotations

import math
import sys
from functools import lru_cache
from typing import NamedTuple

import numpy as np

from pneunet_env.physics import _jit, continuation
from pneunet_env.physics import solver as _solver
from pneunet_env.physics._jit import python_entry
from pneunet_env.physics.continuation import (
    STATUS_INACTIVE,
    STATUS_ROUNDOFF,
    ActuatorNumbers,
    Continuation,
)
from pneunet_env.physics.mechanics import Evaluation

__all__ = ["FreeTable", "SPACING", "EMPTY", "BRANCH_AGREEMENT", "build_free_table", "free_table", "make_follow_table",
           "interpolate", "follow_table"]

SPACING = 5e-4
"""Default pressure spacing of the nodes (``p~``; 0.025 kPa with Table 1's ``mu``). The cubic Hermite interpolant's
error falls as ``spacing^4``: 3.4e-9 at 1e-3, 2.2e-10 at 5e-4 (the largest over the default path, at 20,000
pressures), so that most table states (92 % of 3,000 random free steps) are already converged minima
(``|grad| <= 1e-11``) and the rest take one Newton step. 2,401 nodes to ``p~ = 1.2``: 77 KB, built (loading and
unloading, compiled) in about 3 ms, once per actuator, options and range in a process."""

MAX_NODES = 20_001
"""The most nodes a table holds: ``p~`` up to 10 at the default spacing (8.3 times the default env's ``p~_max = 1.2``;
640 KB, built in about 20 ms). A higher ``p_max`` (a config with a tiny shear modulus ``mu`` makes ``p~_max`` huge)
is tabulated to there; steps above it are the continuation's. Along the Gent-stiffened top of the free path the
continuation converges at every pressure, so without a bound the table would grow with ``p_max``."""

NODE_SUBSTEPS = 16
"""The sub-step budget of the continuation from one node to the next while tabulating (the solver's
``max_substeps`` for these calls, if lower): a node that needs more ends the table there. On Table 1's actuator and
the designs tried every node took 1 sub-step (4 near a fold); a path that needs more over ``dp~ = 5e-4`` is too steep
for a table to help, and a degenerate actuator (the fuzz test's ``mu = 1e-12`` kPa: 37,000 evaluations a node) is
not tabulated for minutes."""

NODE_FIELDS = ("kappa", "side_strain", "dkappa_dp", "dside_strain_dp")
"""The columns of :attr:`FreeTable.nodes`."""


class FreeTable(NamedTuple):
    """The free actuator's path at ``p~ = j * spacing``, ``j = 0 .. M - 1`` (dimensionless).

    Attributes:
        nodes: ``(M, 4)`` float64: ``kappa~``, ``e_s`` and their derivatives in ``p~`` at each node
            (:data:`NODE_FIELDS`); ``M = 0`` for no table.
        spacing: the nodes' pressure spacing ``dp~``.
    """

    nodes: np.ndarray
    spacing: float

    def __eq__(self, other: object) -> bool:
        """Equal nodes (element by element) and spacing."""
        return isinstance(other, FreeTable) and self.spacing == other.spacing and np.array_equal(self.nodes,
                                                                                                   other.nodes)

    def __ne__(self, other: object) -> bool:
        return not self == other

    __hash__ = None  # type: ignore[assignment]  (its array is not hashable)

    @property
    def pressure_max(self) -> float:
        """The highest pressure the table covers (``-inf`` for an empty one)."""
        return (len(self.nodes) - 1) * self.spacing if len(self.nodes) >= 2 else -math.inf


EMPTY = FreeTable(np.zeros((0, len(NODE_FIELDS))), SPACING)
"""No table (every step is the continuation's). Read-only, as :func:`free_table`'s are: numba types a read-only array
apart, so both kinds would compile the loops twice."""
EMPTY.nodes.setflags(write=False)

BRANCH_AGREEMENT = 1e-8
"""Loading and unloading must agree to within this at every node of a table (``max(|d kappa~|, |d e_s|)``). The
same branch, followed both ways, agrees to the continuation's own accuracy (about 1e-11: 6.9e-12 on Table 1's
actuator); two stable branches differ by their separation (a fold's jump)."""

ON_PATH = 1e-7
"""A start is on the table's path if it lies within this of it (``max(|d kappa~|, |d e_s|)``). A converged state lies
within about 1e-9 of the exact path (``gtol`` over the Hessian's smallest eigenvalue) and the table within 2.2e-10;
another stable branch lies a fold's jump away. (The continuation's own test of one branch, ``max_jump = 0.02``, would
let a state on a coexisting upper branch, such as one reached across a fold and unloaded, be moved onto the path.)"""

_FREE_CURVATURE = 1.0
"""The object curvature passed to the kernel while tabulating: with ``k~_obj = 0`` the object's energy is zero
whatever it is (any value inside the kernel's domain)."""


def build_free_table(prm: ActuatorNumbers, opts: tuple, pressure_max: float, spacing: float = SPACING) -> FreeTable:
    """The free actuator's path from rest to ``pressure_max``, as far as it is one plain branch (see the module).

    It is followed with the continuation from node to node, loading, over at most :data:`MAX_NODES` nodes; it ends at
    the first node that is not converged (within :data:`NODE_SUBSTEPS` sub-steps), is reached across a fold
    (``snapped``), has a Hessian that is not positive definite or a lower ``kappa~`` than the node before. Then it is
    followed back, unloading from its last node, and it ends below the first node (from rest)
    where the two disagree by more than :data:`BRANCH_AGREEMENT`: where they differ, the path has two stable branches
    (a hysteresis loop, whose folds may be too weak to flag), and a table would pick one of them for the
    continuation.

    Args:
        prm: :func:`~pneunet_env.physics.solver.params_tuple` of the actuator.
        opts: :meth:`SolverOptions.as_tuple <pneunet_env.physics.solver.SolverOptions.as_tuple>`.
        pressure_max: the highest pressure ``p~`` needed (the env's ``p_max``).
        spacing: the nodes' spacing in ``p~`` (> 0).
    """
    if not (isinstance(spacing, float) and 0.0 < spacing <= 0.1):
        raise ValueError(f"spacing must be a float in (0, 0.1], got {spacing!r}")
    if not (isinstance(pressure_max, float) and math.isfinite(pressure_max) and pressure_max > 0.0):
        raise ValueError(f"pressure_max must be a finite float > 0, got {pressure_max!r}")
    m = min(int(math.ceil(min(pressure_max / spacing, MAX_NODES) - 1e-9)) + 1, MAX_NODES)
    while m < MAX_NODES and (m - 1) * spacing < pressure_max:  # the last node at or above p_max, not an ulp below
        m += 1
    # SolverOptions.as_tuple(): max_substeps bounded; the step control today's (the tabulated path is short sub-steps
    # anyway: the nodes are 5e-4 apart)
    opts = tuple(opts[:7]) + (min(int(opts[7]), NODE_SUBSTEPS), 0)
    nodes = np.empty((m, len(NODE_FIELDS)))
    end = _tabulate(prm, opts, spacing, BRANCH_AGREEMENT, nodes)
    if end < 2:
        return EMPTY
    return FreeTable(nodes[:end].copy(), spacing)


def _make_tabulate(stamp: int):
    def tabulate(prm, opts, spacing, agreement, nodes):
        # build_free_table's two passes, compiled (the solver's own continuation and kernel); fills nodes' rows and
        # returns how many of them the table keeps
        if stamp < 0:  # the stamp keys the disk cache (see _jit.njit_cached)
            raise AssertionError
        k = s = 0.0
        rows = 0
        for j in range(nodes.shape[0]):
            p = j * spacing
            if j > 0:
                r = _solver._follow_ev(k, s, (j - 1) * spacing, p, prm, 0.0, _FREE_CURVATURE, opts)
                if r.status > STATUS_ROUNDOFF or r.snapped or r.kappa < k:
                    break  # not converged, a fold, or kappa~ falling: the table ends at the last plain node
                k, s = r.kappa, r.side_strain
            e = _solver._evaluate(k, s, p, prm, 0.0, _FREE_CURVATURE)
            positive, tk, ts = _solver.hessian_solve(e, e.v_kappa, e.v_strain)  # the tangent dx/dp
            if not (e.ok and positive):
                break
            nodes[j, 0], nodes[j, 1], nodes[j, 2], nodes[j, 3] = k, s, tk, ts
            rows = j + 1
        end = rows
        if rows > 0:  # unloading starts from the last node kept (loading may have stopped past it)
            k, s = nodes[rows - 1, 0], nodes[rows - 1, 1]
        for j in range(rows - 2, -1, -1):  # unloading, from the last node
            r = _solver._follow_ev(k, s, (j + 1) * spacing, j * spacing, prm, 0.0, _FREE_CURVATURE, opts)
            if r.status > STATUS_ROUNDOFF:
                end = 0  # the nodes below cannot be checked: no table
                break
            k, s = r.kappa, r.side_strain
            if max(abs(k - nodes[j, 0]), abs(s - nodes[j, 1])) > agreement:
                end = j  # two branches at this node: the table ends below it
        return end

    return tabulate


@lru_cache(maxsize=16)
def free_table(prm: ActuatorNumbers, opts: tuple, pressure_max: float) -> FreeTable:
    """:func:`build_free_table` at the default spacing, built once per actuator, options and range in a process (the
    envs share it; its array is read-only)."""
    table = build_free_table(prm, opts, float(pressure_max))
    table.nodes.setflags(write=False)
    return table


def make_follow_table(evaluate, descend, jit):
    """``(interpolate, follow_table)`` over the solver's ``evaluate`` and ``descend``
    (:func:`~pneunet_env.physics.solver._make_parts`), compiled by ``jit``.

    * ``interpolate(nodes, spacing, p) -> (kappa~, e_s)``: the table's path at ``p`` (cubic Hermite; ``p`` within
      the table);
    * ``follow_table(k, s, p0, p1, prm, kobj, ko, opts, nodes, spacing) -> Continuation``: the step from the free
      equilibrium ``(k, s)`` at ``p0`` to ``p1`` along the table (see the module), with ``substeps = 1``; where the
      table cannot take it, status :data:`~pneunet_env.physics.solver.STATUS_INACTIVE` with the work it spent
      (``evaluations``, ``backtracks``), and the caller runs the continuation.
    """

    @jit
    def interpolate(nodes, spacing, p):
        x = p / spacing
        j = min(int(x), nodes.shape[0] - 2)
        t = x - j
        t2 = t * t
        t3 = t2 * t
        h00 = 2.0 * t3 - 3.0 * t2 + 1.0
        h01 = 3.0 * t2 - 2.0 * t3
        h10 = (t3 - 2.0 * t2 + t) * spacing
        h11 = (t3 - t2) * spacing
        k = h00 * nodes[j, 0] + h01 * nodes[j + 1, 0] + h10 * nodes[j, 2] + h11 * nodes[j + 1, 2]
        s = h00 * nodes[j, 1] + h01 * nodes[j + 1, 1] + h10 * nodes[j, 3] + h11 * nodes[j + 1, 3]
        return k, s

    @jit
    def not_taken(k, s, evaluations, backtracks):
        nan = math.nan
        return Continuation(k, s, nan, nan, nan, 0, 0, False, STATUS_INACTIVE, nan, evaluations, backtracks,
                            Evaluation(False, nan, nan, nan, nan, nan, nan, nan, nan, nan))

    @jit
    def follow_table(k, s, p0, p1, prm, kobj, ko, opts, nodes, spacing):
        gtol, _, corr_iter, _, _, max_jump, eig_floor, _, _ = opts
        top = (nodes.shape[0] - 1) * spacing
        if nodes.shape[0] < 2 or not (k < ko and p0 <= top and p1 <= top):
            return not_taken(k, s, 0, 0)
        k0, s0 = interpolate(nodes, spacing, p0)
        if max(abs(k - k0), abs(s - s0)) > ON_PATH:
            return not_taken(k, s, 0, 0)  # not on the table's path
        k1, s1 = interpolate(nodes, spacing, p1)
        k1 = max(k1, 0.0)  # the domain's edge, as the descent projects (the rest state lies on it)
        if not k1 < ko:
            return not_taken(k, s, 0, 0)  # the path touches the object by p1
        ev = evaluate(k1, s1, p1, prm, kobj, ko)
        r = descend(k1, s1, p1, prm, kobj, ko, gtol, corr_iter, eig_floor, ev, k1, s1, max_jump)
        moved = max(abs(r.kappa - k1), abs(r.side_strain - s1))
        if r.status <= STATUS_ROUNDOFF and r.kappa < ko and moved <= max_jump:
            return Continuation(r.kappa, r.side_strain, r.energy, r.gradient_norm, r.min_eigenvalue, r.iterations, 1,
                                False, r.status, r.evaluation.volume_change, 1 + r.evaluations, r.backtracks,
                                r.evaluation)
        return not_taken(k, s, 1 + r.evaluations, r.backtracks)

    return interpolate, follow_table


_interpolate, _follow_table = make_follow_table(_solver._evaluate, _solver._descend, _jit.njit)
# the compiled pair the envs' compiled step calls (plain Python without numba); Python calls the entries below


def _make_entries(stamp: int):
    def plain_interpolate(nodes, spacing, p):
        if stamp < 0:  # the stamp keys the disk cache (see _jit.njit_cached)
            raise AssertionError
        return _interpolate(nodes, spacing, p)

    def plain_follow_table(k, s, p0, p1, prm, kobj, ko, opts, nodes, spacing):
        if stamp < 0:
            raise AssertionError
        r = _follow_table(k, s, p0, p1, prm, kobj, ko, opts, nodes, spacing)
        return _solver._solve_numbers(r) + (_solver._evaluation_numbers(r.evaluation),)

    return {"interpolate": plain_interpolate, "follow_table": plain_follow_table}


_ENTRY_SOURCES = (_solver.mechanics, _solver.contact, _solver.xp, _jit, continuation, _solver, sys.modules[__name__])
_tabulate = _jit.njit_cached(_make_tabulate, _ENTRY_SOURCES)

interpolate = _jit.njit_cached(lambda stamp: _make_entries(stamp)["interpolate"], _ENTRY_SOURCES)
"""``interpolate(nodes, spacing, p) -> (kappa~, e_s)``: the table's path at ``p`` (cubic Hermite), from Python."""
follow_table = python_entry(_jit.njit_cached(lambda stamp: _make_entries(stamp)["follow_table"], _ENTRY_SOURCES),
                            Continuation, {"evaluation": Evaluation})
"""``follow_table(kappa~, e_s, p0, p1, prm, k~_obj, w kappa_obj, opts, nodes, spacing) -> Continuation``: a step
along the table (see :func:`make_follow_table`), from Python."""
