"""Property tests (hypothesis): over valid actuators, pressures and objects, every solve is a finite minimum."""

from __future__ import annotations

import math

import numpy as np
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from pneunet_env import ActuatorParams, load_path, solve_equilibrium
from pneunet_env.physics import mechanics
from pneunet_env.physics.solver import ACCEPT_GTOL


@st.composite
def actuators(draw):
    d = draw(st.floats(0.5, 2.0))
    hb = draw(st.floats(0.1, min(0.9, 2 * d - 0.25)))
    hm = draw(st.floats(0.1, min(0.9, 2 * d - hb - 0.05)))
    return ActuatorParams(
        chamber_height=d,
        base_thickness=hb,
        side_thickness=draw(st.floats(0.1, 0.9)),
        top_thickness=hm,
        base_modulus=draw(st.floats(5.0, 500.0)),
        poisson_ratio=draw(st.floats(-0.5, 0.5)),
        gent_limit=draw(st.floats(1.0, 60.0)),
    )


# Objects up to k~ = 0.3 with w kappa_obj >= 0.01: the contact stiffness k~/kappa_obj^4 stays below 3e7, where
# |grad| <= 1e-10 is attainable in double precision (one ulp of kappa moves the gradient by H * ulp ~ 5e-11).
# test_solver.py checks what happens beyond that.
stiffness = st.one_of(st.just(0.0), st.floats(-7.0, -0.5).map(lambda e: 10.0**e))
pressure = st.floats(0.0, 2.0)
curvature = st.floats(0.01, 0.2)


def _is_minimum(eq, params) -> bool:
    d = mechanics.energy_grad_hess(eq.curvature, eq.side_strain, eq.pressure, params, eq.object_stiffness,
                                   eq.object_curvature)
    return (
        eq.converged
        and bool(mechanics.in_domain(eq.curvature, eq.side_strain, params))
        and np.isfinite(d.energy)
        and np.linalg.norm(d.gradient) <= ACCEPT_GTOL
        and np.linalg.eigvalsh(d.hessian).min() > 0.0
    )


@settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(params=actuators(), p=pressure, kobj=stiffness, ko=curvature)
def test_any_solve_is_a_finite_minimum(params, p, kobj, ko):
    eq = solve_equilibrium(p, kobj, ko, params)
    assert all(math.isfinite(v) for v in (eq.curvature, eq.side_strain, eq.energy, eq.contact_force))
    assert _is_minimum(eq, params)


@settings(max_examples=25, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(params=actuators(), ps=st.lists(pressure, min_size=2, max_size=6), kobj=stiffness, ko=curvature)
def test_any_path_stays_on_minima(params, ps, kobj, ko):
    path = load_path(ps, kobj, ko, params)
    for eq in path.equilibria:
        assert _is_minimum(eq, params)
