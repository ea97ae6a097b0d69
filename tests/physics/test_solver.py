"""The quasi-static minimiser: accepted states are minima, paths follow branches, the paper's regimes appear."""

from __future__ import annotations

import math

import numpy as np
import pytest

from pneunet_env import ActuatorParams, load_path, solve_equilibrium
from pneunet_env.physics import mechanics
from pneunet_env.physics.solver import ACCEPT_GTOL, Equilibrium

KO = 0.02  # w kappa_obj, the paper's object


def assert_minimum(eq: Equilibrium, params: ActuatorParams) -> None:
    """An accepted state: converged, in the domain, zero gradient and a positive-definite Hessian (re-evaluated)."""
    assert eq.converged, eq.message
    assert all(math.isfinite(v) for v in (eq.curvature, eq.side_strain, eq.energy, eq.contact_force))
    assert bool(mechanics.in_domain(eq.curvature, eq.side_strain, params))
    d = mechanics.energy_grad_hess(eq.curvature, eq.side_strain, eq.pressure, params, eq.object_stiffness,
                                   eq.object_curvature)
    assert np.linalg.norm(d.gradient) <= ACCEPT_GTOL
    assert np.linalg.eigvalsh(d.hessian).min() > 0.0


def test_rest_at_zero_pressure(params):
    eq = solve_equilibrium(0.0, params=params)
    assert eq.state == (0.0, 0.0) and eq.energy == 0.0 and eq.converged


@pytest.mark.parametrize("geometry", [{}, {"chamber_height": 1.3, "side_thickness": 0.3, "top_thickness": 0.7,
                                          "base_thickness": 0.4}])
def test_small_pressure_slope_tends_to_eq17(geometry):
    params = ActuatorParams(**geometry)
    slope = params.small_pressure_slope
    if not geometry:
        assert math.isclose(slope, 4 / (8 * (60 * 0.125 / 9 + 6)), rel_tol=1e-12)  # 0.073171
    errors = [abs(solve_equilibrium(p, params=params).curvature / p - slope) for p in (1e-2, 1e-3, 1e-4)]
    assert errors[0] > errors[1] > errors[2]  # converging as p -> 0 ...
    assert errors[2] < 1e-4 * slope  # ... with an O(p) correction
    assert errors[1] / errors[2] == pytest.approx(10, rel=0.1)


def test_free_actuator_rises_slowly_then_steeply_then_saturates(params):
    ps = np.linspace(0, 1.4, 141)
    path = load_path(ps, 0.0, KO, params)
    k = path.curvature
    slope = np.gradient(k, ps)
    initial = slope[1:5].mean()  # p in (0, 0.05)
    assert initial == pytest.approx(params.small_pressure_slope, rel=0.05)
    assert slope.max() > 8 * initial  # the balloon instability: a steep rise ...
    assert 0.4 < ps[slope.argmax()] < 0.9
    assert slope[-10:].mean() < 0.1 * slope.max()  # ... then Gent stiffening saturates it
    assert 0.45 <= k[120] <= 0.7  # p = 1.2, as on the paper's Fig. 3 axes
    assert not path.snapped.any()  # at J = 20 the free actuator has no fold
    assert np.all(np.diff(k) > 0)


def test_soft_object_traction_saturates(params):
    ps = np.linspace(0, 2.0, 81)
    path = load_path(ps, 1e-5, KO, params)
    F = path.contact_force
    assert F[-1] > 0
    assert (F[-1] - F[40]) / F[-1] < 0.05  # p from 1.0 to 2.0: force control, traction bounded
    assert path.curvature[-1] > 10 * KO  # the actuator curls as if free


def test_stiff_object_curvature_pinned_while_traction_rises(params):
    ps = np.linspace(0, 1.4, 57)
    path = load_path(ps, 1e-2, KO, params)
    contact = path.curvature > KO
    assert contact[-1]
    assert np.all(path.curvature <= 1.02 * KO)  # position control: within 2 % of kappa_obj
    F = path.contact_force[contact]
    assert np.all(np.diff(F) > 0)  # traction rises monotonically with pressure


def test_intermediate_object_snaps_through_with_hysteresis(params):
    up = np.linspace(0, 1.2, 121)
    ps = np.concatenate([up, up[-2::-1]])
    path = load_path(ps, 1e-4, KO, params)
    n = len(up)
    k_up, k_down = path.curvature[:n], path.curvature[n - 1:][::-1]
    snaps_up = np.flatnonzero(path.snapped[:n])
    snaps_down = np.flatnonzero(path.snapped[n:])
    assert len(snaps_up) == 1 and len(snaps_down) == 1  # one fold each way
    window = np.abs(k_up - k_down) > 0.1
    assert window.sum() >= 3  # loading and unloading differ over a pressure window
    p_window = up[window]
    assert p_window.min() >= 0.5 and p_window.max() <= 0.8
    assert np.all(path.converged)


@pytest.mark.parametrize("kobj", [0.0, 1e-5, 1e-4, 1e-3, 1e-1])
def test_path_independence_coarse_vs_fine(params, kobj):
    coarse = load_path([0.4, 0.8, 1.2], kobj, KO, params)
    fine = load_path(np.linspace(0, 1.2, 1201), kobj, KO, params)
    assert abs(coarse.curvature[-1] - fine.curvature[-1]) <= 1e-8
    assert abs(coarse.side_strain[-1] - fine.side_strain[-1]) <= 1e-8
    single = solve_equilibrium(1.2, kobj, KO, params)
    assert abs(single.curvature - fine.curvature[-1]) <= 1e-8


def test_unloading_returns_to_rest(params):
    path = load_path([0.0, 0.6, 1.2, 0.6, 0.0], 1e-3, KO, params)
    assert abs(path.curvature[-1]) < 1e-12 and abs(path.side_strain[-1]) < 1e-12
    assert path.curvature[1] == pytest.approx(path.curvature[3], abs=1e-10)


def test_every_state_on_hard_paths_is_a_minimum():
    cases = [
        (ActuatorParams(), 1e-4, np.linspace(0, 1.2, 25)),  # fold
        (ActuatorParams(), 1e-1, np.linspace(0, 2.0, 11)),  # very stiff: Hessian condition ~1e5
        (ActuatorParams(gent_limit=2.0), 0.0, [0.5, 2.0, 5.0, 20.0]),  # up against the Gent limit
        (ActuatorParams(gent_limit=15.0), 1e-5, [1.2, 0.0, 1.2]),  # big steps both ways
        (ActuatorParams(top_thickness=0.25, side_thickness=0.25), 0.0, np.linspace(0, 1.2, 7)),  # thin walls
    ]
    for params, kobj, ps in cases:
        path = load_path(ps, kobj, KO, params)
        for eq in path.equilibria:
            assert_minimum(eq, params)


def test_fold_reports_snapped_and_big_step_lands_on_same_branch(params):
    before = solve_equilibrium(0.6, 1e-4, KO, params)
    assert before.curvature < 0.03 and not before.snapped
    after = solve_equilibrium(0.8, 1e-4, KO, params, initial=before)
    assert after.snapped and after.curvature > 0.3
    direct = solve_equilibrium(0.8, 1e-4, KO, params)
    assert direct.snapped
    assert after.curvature == pytest.approx(direct.curvature, abs=1e-10)


def test_initial_pair_with_and_without_pressure(params):
    eq = solve_equilibrium(0.5, 1e-3, KO, params)
    cont = solve_equilibrium(0.6, 1e-3, KO, params, initial=eq.state, initial_pressure=0.5)
    desc = solve_equilibrium(0.6, 1e-3, KO, params, initial=eq.state)
    ref = solve_equilibrium(0.6, 1e-3, KO, params)
    for e in (cont, desc):
        assert e.curvature == pytest.approx(ref.curvature, abs=1e-12)
        assert_minimum(e, params)


@pytest.mark.parametrize(
    "kwargs, name",
    [
        ({"pressure": float("nan")}, "pressure"),
        ({"pressure": -0.1}, "pressure"),
        ({"pressure": float("inf")}, "pressure"),
        ({"pressure": 0.5, "object_stiffness": -1e-3}, "object_stiffness"),
        ({"pressure": 0.5, "object_stiffness": float("nan")}, "object_stiffness"),
        ({"pressure": 0.5, "object_curvature": 0.0}, "object_curvature"),
        ({"pressure": 0.5, "object_curvature": 4.0}, "object_curvature"),
        ({"pressure": 0.5, "initial": (float("nan"), 0.0)}, "initial curvature"),
        ({"pressure": 0.5, "initial": (-1.0, 0.0)}, "outside the domain"),
        ({"pressure": 0.5, "initial": "abc"}, "initial"),
    ],
)
def test_bad_solver_input_raises_naming_it(kwargs, name):
    with pytest.raises(ValueError, match=name):
        solve_equilibrium(**kwargs)


def test_load_path_rejects_bad_pressures():
    with pytest.raises(ValueError, match=r"pressures\[1\]"):
        load_path([0.1, float("nan")])
    with pytest.raises(ValueError, match=r"pressures\[0\]"):
        load_path([-1.0])


def test_free_actuator_has_no_contact_or_indentation(params):
    eq = solve_equilibrium(1.0, 0.0, KO, params)
    assert eq.curvature > KO
    assert not eq.in_contact and eq.indentation == 0.0 and eq.contact_force == 0.0


def test_round_off_floor_beyond_double_precision_is_reported_not_hidden():
    """k~/kappa_obj^4 ~ 3e8: one ulp of kappa moves the gradient by ~5e-10, so |grad| <= 1e-10 is unreachable.

    The solver must not call that converged: it reports it (and the state is still finite, in the domain,
    a descent from rest, with a positive-definite Hessian).
    """
    params = ActuatorParams(base_modulus=5.0, poisson_ratio=0.0, gent_limit=1.0)
    eq = solve_equilibrium(1.0, 1.0, 2.0**-7, params)
    d = mechanics.energy_grad_hess(eq.curvature, eq.side_strain, 1.0, params, 1.0, 2.0**-7)
    assert np.isfinite(d.energy) and np.linalg.eigvalsh(d.hessian).min() > 0
    assert eq.converged == (eq.gradient_norm <= ACCEPT_GTOL)
    if not eq.converged:
        assert eq.message != "converged"
    assert abs(eq.curvature - 2.0**-7) < 1e-9  # pinned at the kink of contact onset, as it should be


# ---- options that could hang, and the sub-step budget ----------------------------------------------------------


@pytest.mark.parametrize(("field", "value"), [
    ("max_jump", 1e-15), ("max_step", 1e-12), ("min_step", 1e-15), ("gtol", 1e-9), ("gtol", 0.0),
    ("max_iter", 1.5), ("max_iter", 1e300), ("max_iter", True), ("corrector_max_iter", 0), ("eig_floor", 0.5),
    ("max_substeps", 0), ("max_substeps", 10**9), ("max_jump", float("nan")), ("max_step", "0.1"),
])
def test_options_out_of_their_bounds_raise_naming_the_field(field, value):
    from pneunet_env.physics.solver import SolverOptions

    with pytest.raises(ValueError, match=field):
        SolverOptions(**{field: value})


def test_a_spent_substep_budget_is_flagged_never_hangs():
    import time

    from pneunet_env.physics import batched
    from pneunet_env.physics.solver import STATUS_BUDGET, SolverOptions

    opts = SolverOptions(max_jump=1e-5, max_step=1e-6, min_step=1e-12, max_substeps=50)
    t0 = time.perf_counter()
    eq = solve_equilibrium(0.6, 1e-4, 0.02, options=opts)
    assert time.perf_counter() - t0 < 10.0
    assert not eq.converged and eq.status == STATUS_BUDGET and "budget" in eq.message
    assert np.isfinite(eq.curvature) and np.isfinite(eq.energy)
    backends = ["numpy"] + (["numba"] if batched.HAVE_NUMBA else [])
    for backend in backends:  # the masked array form counts the same attempts and stops at the same place
        r = batched.solve_batch([0.0, 0.0], [0.0, 0.0], 0.0, [0.6, 1e-6], 1e-4, 0.02, options=opts, backend=backend)
        assert list(r.status) == [STATUS_BUDGET, 0] and list(r.converged) == [False, True], backend
        assert r.curvature[0] == pytest.approx(eq.curvature, abs=1e-12) and r.substeps[0] == eq.substeps


def test_the_default_budget_is_far_above_what_env_steps_take():
    from pneunet_env.physics.solver import DEFAULT_OPTIONS

    path = load_path(np.linspace(0.0, 1.2, 21), 1e-4)  # env-sized steps, through the fold
    assert path.converged.all() and max(e.substeps for e in path.equilibria) * 100 < DEFAULT_OPTIONS.max_substeps


@pytest.mark.parametrize("c", [0.02, 0.1, 0.25, 0.5, 1.0])
def test_solves_converge_up_to_the_measured_contact_ratio(c):
    """The bound the envs warn above (contact.CONVERGED_CONTACT_RATIO): loading and unloading in env-sized steps."""
    from pneunet_env.physics.contact import CONVERGED_CONTACT_RATIO

    k = CONVERGED_CONTACT_RATIO * c**4
    ps = np.r_[np.linspace(0.0, 1.2, 21), np.linspace(1.2, 0.0, 21)]
    path = load_path(ps, k, c)
    assert path.converged.all()
    for eq in path.equilibria:
        assert eq.gradient_norm <= ACCEPT_GTOL and eq.min_eigenvalue > 0.0


def test_the_envs_warn_beyond_the_measured_contact_ratio():
    import gymnasium as gym

    env = gym.make("PneuNetGrasp-Paper-v0")
    with pytest.warns(UserWarning, match="measured to converge"):
        env.reset(seed=0, options={"object_stiffness": 10.0})  # 10 / 0.02^4 = 6e7
    vec = gym.make_vec("PneuNetGrasp-Paper-v0", num_envs=2)
    with pytest.warns(UserWarning, match="measured to converge"):
        vec.reset(seed=0, options={"object_stiffness": np.array([1e-3, 10.0])})


def _counting_solver():
    """A pure-Python instance of the solver over a kernel that counts its calls (the compiled one counts itself)."""
    from pneunet_env.physics import solver
    from pneunet_env.physics.xp import identity, scalar_max, scalar_where

    terms = mechanics.make_terms(math.log, math.tan, scalar_where, scalar_max, abs)[1]
    calls = [0]

    def counted(*args):
        calls[0] += 1
        return terms(*args)

    return solver._make_parts(counted, jit=identity), calls


def test_the_work_counters_count_the_kernel_calls():
    """``evaluations`` is the number of energy kernel calls a solve made (counted independently, on a pure-Python
    instance of the same solver), from the continuation, the cached start and the descent alike; ``backtracks``
    counts rejected line-search trials, so loading from rest (where the first Newton steps overshoot) has some."""
    from pneunet_env.physics.solver import DEFAULT_OPTIONS, params_tuple, step_state, step_state_from

    (evaluate, minimise, follow_ev, follow_from, _), calls = _counting_solver()
    prm, opts = params_tuple(None), DEFAULT_OPTIONS.as_tuple()
    rng = np.random.default_rng(5)
    cases = [(0.0, 0.0, 0.0, 0.9, 0.0, 0.02), (0.0, 0.0, 0.0, 0.70, 1e-4, 0.02)]  # from rest; across the fold
    for _ in range(25):
        kobj = float(rng.choice([0.0, 10.0 ** rng.uniform(-5, -1)]))
        p0 = float(rng.uniform(0.0, 1.2))
        eq = solve_equilibrium(p0, kobj, 0.02)
        cases.append((eq.curvature, eq.side_strain, p0, float(np.clip(p0 + rng.uniform(-0.1, 0.1), 0, 1.2)), kobj,
                      0.02))
    backtracks = 0
    for k, s, p0, p1, kobj, ko in cases:
        calls[0] = 0
        ref = follow_ev(k, s, p0, p1, prm, kobj, ko, opts)
        n = calls[0]
        r = step_state(k, s, p0, p1, prm, kobj, ko, opts)
        # the same control flow (numba's and Python's libm may differ in a last bit, never here in a decision)
        assert (r.iterations, r.substeps, r.status, r.evaluations, r.backtracks) == \
            (ref.iterations, ref.substeps, ref.status, n, ref.backtracks), (k, s, p0, p1, kobj)
        assert abs(r.kappa - ref.kappa) <= 1e-12
        ev0 = evaluate(k, s, p0, prm, kobj, ko)
        calls[0] = 0
        follow_from(k, s, p0, p1, prm, kobj, ko, opts, ev0)
        assert step_state_from(k, s, p0, p1, prm, kobj, ko, opts, ev0).evaluations == calls[0] == n - 1
        calls[0] = 0
        m = minimise(k, s, p1, prm, kobj, ko, 1e-11, 200, 1e-10)
        assert m.evaluations == calls[0]
        backtracks += r.backtracks
        assert r.evaluations >= r.iterations + 1 + r.substeps  # a start, a trial per iteration, a start per sub-step
    assert backtracks > 0
    eq = solve_equilibrium(0.9)
    assert (eq.evaluations, eq.backtracks) == tuple(step_state(0.0, 0.0, 0.0, 0.9, prm, 0.0, 0.02, opts)[-2:])
    assert solve_equilibrium(0.5, initial=(eq.curvature, eq.side_strain)).evaluations > 0
