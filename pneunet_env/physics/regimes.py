"""The paper's two regimes, for any object: force-controlled (the object yields) or position-controlled (it blocks).

The seed paper names them on its 250 mm ring: on a soft object the actuator curls on, with a bounded traction (force
control); on a stiff one its curvature stays at the object's (position control). A hand-scale object is smaller
and its contact stiffer for the same material (eq. 3.2), so a threshold on ``k~`` alone does not carry over. The
regime is read off the mechanics instead, at the pressure ``p~`` (the env's maximum by default), loaded from rest:

    phi = (kappa_free(p) - kappa(p)) / (kappa_free(p) - kappa_obj)

the fraction of the free actuator's curvature beyond the object's surface that the object blocks. ``phi`` near 0:
the object yields (force control); near 1: the curvature stays at the object's (position control). An object is
**force-controlled** when ``phi < 1/2`` and **position-controlled** otherwise. On the paper's ring this reproduces
its boundaries: ``phi`` jumps from 0.002 at ``k~ = 4.47e-4`` to 0.995 at ``k~ = 1.12e-3`` (the fold between them;
README statement 10), so ``1/2`` falls inside the paper's own transition. An object that the free actuator cannot
reach (``kappa_obj >= kappa_free(p)``, an object smaller than about 9.4 mm in radius at the default actuator) is
**unreachable**.
"""

from __future__ import annotations

import numpy as np

from pneunet_env.physics.batched import solve_batch
from pneunet_env.physics.params import ActuatorParams
from pneunet_env.physics.solver import DEFAULT_OPTIONS, SolverOptions

__all__ = ["REGIMES", "FORCE", "POSITION", "UNREACHABLE", "blocked_fraction", "regime"]

FORCE, POSITION, UNREACHABLE = 0, 1, 2
REGIMES = ("force-controlled", "position-controlled", "unreachable")
"""Regime names by code."""


def blocked_fraction(object_stiffness, object_curvature, pressure: float = 1.2, params: ActuatorParams | None = None,
                     options: SolverOptions = DEFAULT_OPTIONS) -> np.ndarray:
    """``phi`` (see the module docstring) for each object, loaded from rest to ``pressure``; NaN where unreachable.

    Args:
        object_stiffness: ``k~`` per object (array-like).
        object_curvature: ``w kappa_obj`` per object.
        pressure: ``p~`` (1.2 = the env's default 60 kPa).
    """
    k = np.atleast_1d(np.asarray(object_stiffness, dtype=float))
    c = np.broadcast_to(np.asarray(object_curvature, dtype=float), k.shape)
    n = k.size
    free = solve_batch(np.zeros(1), np.zeros(1), 0.0, pressure, 0.0, 0.02, params, options).curvature[0]
    eq = solve_batch(np.zeros(n), np.zeros(n), 0.0, pressure, k.ravel(), c.ravel(), params, options)
    with np.errstate(divide="ignore", invalid="ignore"):
        phi = (free - eq.curvature) / (free - c.ravel())
    return np.where(c.ravel() < free, phi, np.nan).reshape(k.shape)


def regime(object_stiffness, object_curvature, pressure: float = 1.2, params: ActuatorParams | None = None,
           options: SolverOptions = DEFAULT_OPTIONS) -> np.ndarray:
    """The regime code of each object (:data:`FORCE`, :data:`POSITION` or :data:`UNREACHABLE`; names in
    :data:`REGIMES`)."""
    phi = blocked_fraction(object_stiffness, object_curvature, pressure, params, options)
    return np.where(np.isnan(phi), UNREACHABLE, np.where(phi < 0.5, FORCE, POSITION)).astype(np.int64)
