"""Independent high-precision check: the solver agrees with an mpmath Newton at 30 digits on the same energy."""

from __future__ import annotations

import pytest

from pneunet_env import ActuatorParams, solve_equilibrium
from pneunet_env.physics.reference import reference_path
from pneunet_env.physics.solver import SolverOptions

mpmath = pytest.importorskip("mpmath")
from pneunet_env.physics.reference import reference_minimum  # noqa: E402


@pytest.mark.parametrize(
    "p, kobj, J",
    [
        (0.05, 0.0, 20.0),
        (0.3, 0.0, 20.0),
        (0.6, 0.0, 20.0),  # balloon region
        (1.2, 0.0, 15.0),
        (1.2, 1e-5, 20.0),  # force control
        (0.6, 1e-4, 20.0),  # held branch, approaching the fold
        (0.8, 1e-4, 20.0),  # after the snap-through
        (1.4, 1e-2, 20.0),  # position control
        (1.0, 1e-1, 20.0),  # very stiff object
        (5.0, 0.0, 2.0),  # against the Gent limit
    ],
)
@pytest.mark.parametrize("control", ["jump", "branch"])
def test_solver_matches_30_digit_reference(p, kobj, J, control):
    params = ActuatorParams(gent_limit=J)
    eq = solve_equilibrium(p, kobj, 0.02, params, options=SolverOptions(step_control=control))
    k, s = reference_minimum(p, kobj, 0.02, params, eq.state, digits=30)
    assert abs(eq.curvature - k) <= 1e-9 * abs(k)
    assert abs(eq.side_strain - s) <= 1e-9 * abs(s)


@pytest.mark.parametrize("control", ["jump", "branch"])
def test_near_the_fold_on_both_branches(control):
    """Loading and unloading a k~ = 1e-4 object near its folds, checked point by point at 30 digits (each step
    control: the snap and the unloading branch are the same)."""
    params = ActuatorParams()
    up = [0.6, 0.65, 0.68]
    down = [0.68, 0.65, 0.62]
    eq = today = None
    options = SolverOptions(step_control=control)
    for p in up + [0.75] + down:
        eq = solve_equilibrium(p, 1e-4, 0.02, params, initial=eq, options=options)
        today = solve_equilibrium(p, 1e-4, 0.02, params, initial=today)
        assert eq.snapped == today.snapped
        k, s = reference_minimum(p, 1e-4, 0.02, params, eq.state, digits=30)
        assert abs(eq.curvature - k) <= 1e-9 * abs(k)
        assert abs(eq.side_strain - s) <= 1e-9 * abs(s)


def test_reference_at_zero_pressure_is_rest():
    assert reference_minimum(0.0, 1e-3, 0.02, ActuatorParams(), (1e-3, 1e-3)) == (0.0, 0.0)


def test_reference_path_polishes_every_point():
    ks, ss = reference_path([0.2, 0.5, 0.8], 1e-3, 0.02, ActuatorParams(), digits=30, refine=5)
    assert len(ks) == 3 and all(0.0 < k < 0.03 for k in ks)


def _catalogue_extremes():
    """Each in-model catalogue class at its stiffest corner (largest k~: top modulus, smallest radius, thickest
    layer) and at its softest, as ``(k~, w kappa_obj)``: the default task's hardest and easiest contacts."""
    from pneunet_env.catalogue import load_catalogue
    from pneunet_env.physics.contact import winkler_stiffness

    out = []
    for cls in load_catalogue().values():
        if not cls.in_annulus_model:
            continue
        for mu, r, h in ((cls.shear_modulus_kpa[1], cls.radius_mm[0], cls.thickness_mm[1]),
                         (cls.shear_modulus_kpa[0], cls.radius_mm[1], cls.thickness_mm[0])):
            out.append((cls.name, winkler_stiffness(mu, h, 1e3 / r, 5.0, 50.0), 5.0 / r))
    return out


@pytest.mark.parametrize("name, kobj, c", _catalogue_extremes(), ids=lambda v: v if isinstance(v, str) else "")
def test_catalogue_extremes_converge_and_match_30_digits(name, kobj, c):
    """The catalogue's stiffest (k~ up to about 55) and softest objects: loading to 60 kPa in the env's 3 kPa steps
    and back, every state converged (zero gradient, positive-definite Hessian), the end states at 30 digits."""
    import numpy as np

    from pneunet_env import load_path
    from pneunet_env.physics.solver import ACCEPT_GTOL

    params = ActuatorParams()
    ps = np.r_[np.arange(0.06, 1.2001, 0.06), np.arange(1.14, -1e-9, -0.06).clip(0.0)]
    path = load_path(ps, kobj, c, params)
    assert path.converged.all(), name
    assert max(e.gradient_norm for e in path.equilibria) <= ACCEPT_GTOL
    assert min(e.min_eigenvalue for e in path.equilibria) > 0.0
    top = path.equilibria[19]  # p~ = 1.2
    k, s = reference_minimum(1.2, kobj, c, params, top.state, digits=30)
    assert abs(top.curvature - k) <= 1e-9 * abs(k) and abs(top.side_strain - s) <= 1e-9 * abs(s)


def test_the_energy_kernel_matches_the_30_digit_energy_and_gradient():
    """The compiled kernel (written with reciprocals and one ``tan``) against the independent mpmath energy and its
    derivatives at 30 digits, at states of the env's range (free, touching, near the series switch, high strain):
    round-off only."""
    import math

    import numpy as np

    from pneunet_env.physics import solver
    from pneunet_env.physics.reference import reference_energy

    mp = mpmath.mp
    params = ActuatorParams()
    prm = solver.params_tuple(params)
    rng = np.random.default_rng(11)
    points = [(0.0, 0.0, 0.0, 0.0, 0.02), (0.0999, 0.05, 0.3, 0.0, 0.02), (0.1001, 0.05, 0.3, 1e-3, 0.02)]
    points += [(float(rng.uniform(0.0, 1.0)), float(rng.uniform(0.0, 0.5)), float(rng.uniform(0.0, 1.2)),
                float(rng.choice([0.0, 10.0 ** rng.uniform(-5, -1)])), float(rng.uniform(0.01, 0.5)))
               for _ in range(12)]
    checked = 0
    with mp.workdps(40):
        for k, s, p, kobj, ko in points:
            ev = solver.evaluate_state(k, s, p, prm, kobj, ko)
            assert ev.ok
            f = lambda a, b, p=p, kobj=kobj, ko=ko: reference_energy(mp, a, b, p, params, kobj, ko)  # noqa: E731
            x = [mp.mpf(k), mp.mpf(s)]
            u = f(*x)
            assert abs(ev.energy - float(u)) <= 1e-14 * max(1.0, abs(float(u))), (k, s, p)
            if k < 1e-3 or abs(k - ko) < 1e-3:  # the edge k = 0; the contact's kink at k = ko
                continue
            checked += 1
            for got, order in ((ev.g_kappa, (1, 0)), (ev.g_strain, (0, 1)), (ev.h_kk, (2, 0)), (ev.h_ks, (1, 1)),
                               (ev.h_ss, (0, 2))):
                want = float(mp.diff(f, x, order))
                assert math.isclose(got, want, rel_tol=1e-12, abs_tol=1e-12), (k, s, p, order, got, want)
    assert checked >= 12 and any(k > ko and kobj > 0.0 for k, _, _, kobj, ko in points)
