"""The object's contact law, written once: eq. 3.1 (Winkler traction) and eq. 3.2 (the annulus's stiffness).

The object is an incompressible annular sector of outer curvature ``kappa_obj`` and thickness ``H`` on a
Winkler foundation. Where the actuator's base curls past the object's surface (``kappa > kappa_obj``) and
there is an object (``k~_obj > 0``), it indents it by

    delta~ = w (1/kappa_obj - 1/kappa) = (kappa~ - kappa~_obj) / (kappa~ kappa~_obj)      (units of w)

and the traction is ``F~ = k~_obj delta~`` (eq. 3.1, in units of ``mu``). The foundation's stiffness follows
from the annulus's mechanics (eq. 3.2):

    k_obj = 2 mu_obj kappa_obj [(1 - H kappa_obj)^-2 - 1],      k~ = k_obj w / mu.

The formulas are written once, in :func:`make_contact` against ``maximum``/``where`` (like
:func:`pneunet_env.physics.mechanics.make_terms`) and in :func:`winkler_stiffness` as plain arithmetic, so the
energy kernel, the solver, the task and the rigid jaw all use the same expressions, on floats (compiled by
numba or not) and on numpy arrays alike.
"""

from __future__ import annotations

import numpy as np

from pneunet_env.physics.xp import identity, scalar_max, scalar_where

__all__ = ["make_contact", "indentation", "contact", "scalar_indentation", "scalar_contact", "winkler_stiffness",
           "CONVERGED_CONTACT_RATIO", "contact_ratio"]

CONVERGED_CONTACT_RATIO = 2e6
"""The largest contact stiffness ratio ``k~ / (w kappa_obj)^4`` at which every solve was measured to converge
(``|grad| <= 1e-10``, positive-definite Hessian): loading to ``p~ = 1.2`` and unloading in env-sized steps, at
``w kappa_obj`` = 0.02, 0.1, 0.25, 0.5 and 1 (``tests/physics/test_solver.py`` re-checks it). Past it the contact's
Hessian ``k~/kappa_obj^4`` times the spacing of doubles near ``kappa_obj`` exceeds the gradient tolerance at some
curvatures (first at 3e6, for ``w kappa_obj = 0.5``): the solver then reports ``converged=False`` honestly, and the
environments warn when they draw such an object."""


def contact_ratio(object_stiffness, object_curvature):
    """``k~ / (w kappa_obj)^4``, the contact stiffness over the bending scale (:data:`CONVERGED_CONTACT_RATIO`)."""
    return object_stiffness / object_curvature**4


def make_contact(maximum, where, jit=identity):
    """Build ``(indentation, contact)`` from elementary operations (numpy ufuncs, or scalar ones).

    * ``indentation(kappa~, w kappa_obj) -> delta~``: the geometric overlap, 0 out of contact;
    * ``contact(kappa~, k~_obj, w kappa_obj) -> (delta~, F~, in_contact)``: eq. 3.1, with ``in_contact`` where
      ``kappa~ > w kappa_obj`` and ``k~_obj > 0`` (no object, no indentation).
    """

    @jit
    def indentation(k, ko):
        return maximum(k - ko, 0.0) / (maximum(k, ko) * ko)

    @jit
    def contact(k, kobj, ko):
        touching = (k > ko) & (kobj > 0.0)
        delta = where(touching, indentation(k, ko), 0.0)
        return delta, kobj * delta, touching

    return indentation, contact


indentation, _np_contact = make_contact(np.maximum, np.where)
scalar_indentation, scalar_contact = make_contact(scalar_max, scalar_where)
"""``scalar_contact``: :func:`contact` on Python floats (what one environment uses: no ufunc calls)."""


def contact(kappa, object_stiffness, object_curvature):
    """``(delta~, F~, in_contact)`` of eq. 3.1 for arrays (or scalars, as 0-d arrays); see :func:`make_contact`."""
    return _np_contact(np.asarray(kappa, dtype=float), np.asarray(object_stiffness, dtype=float), object_curvature)


def winkler_stiffness(shear_modulus_kpa, thickness_mm, curvature_per_m, width_mm, scale_modulus_kpa):
    """Eq. 3.2: the dimensionless Winkler stiffness ``k~ = k_obj w / mu`` of an annulus (floats or arrays).

    Args:
        shear_modulus_kpa: the object's ``mu_obj`` (kPa).
        thickness_mm: its thickness ``H`` (mm), ``0 < H kappa_obj < 1`` (not checked here).
        curvature_per_m: its outer curvature ``kappa_obj`` (1/m).
        width_mm, scale_modulus_kpa: the model's scales ``w`` (mm) and ``mu`` (kPa).
    """
    H = thickness_mm * 1e-3
    q = 1.0 - H * curvature_per_m
    factor = 1.0 / (q * q) - 1.0  # q * q, not q ** 2: a float's ** (libm pow) and an array's (a square) may differ
    k_obj_kpa_per_m = 2.0 * shear_modulus_kpa * curvature_per_m * factor
    return k_obj_kpa_per_m * 1e-3 * width_mm / scale_modulus_kpa
