"""``SolverOptions.step_control="branch"``: longer continuation sub-steps where both ends lie on one branch. The same
minima, the same folds (``snapped``) and the same branches as the original control (``"jump"``), with fewer
evaluations; the scalar solver and the masked solver (numpy, torch) make the same decisions under it."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest

import pneunet_env  # noqa: F401
from pneunet_env import ActuatorParams, load_path, solve_equilibrium
from pneunet_env.fused import HAVE_FUSED
from pneunet_env.physics import xp
from pneunet_env.physics.masked import solve_masked
from pneunet_env.physics.solver import (
    STEP_CONTROLS,
    SolverOptions,
    evaluate_state,
    hermite_midpoint,
    params_tuple,
    step_state,
)

from .test_solver import KO, assert_minimum


def _walks(control: str, gent: float, n: int = 240, steps: int = 30, seed: int = 3):
    """Random pressure walks from rest (steps up to p~ 0.2 either way, objects from free to k~ = 10): each step's
    state, snapped flag, status and evaluations."""
    rng = np.random.default_rng(seed)
    prm = params_tuple(ActuatorParams(gent_limit=gent))
    opts = SolverOptions(step_control=control).as_tuple()
    kobj = np.where(rng.random(n) < 0.1, 0.0, 10 ** rng.uniform(-3, 1, n))
    ko = rng.uniform(0.01, 0.3, n)
    dp = rng.uniform(-0.2, 0.2, (n, steps))
    out = np.zeros((4, n, steps))
    for w in range(n):
        k = s = p = 0.0
        for i in range(steps):
            p1 = min(max(p + dp[w, i], 0.0), 1.2)
            r = step_state(k, s, p, p1, prm, kobj[w], ko[w], opts)
            if r.status <= 1:
                k, s, p = r.kappa, r.side_strain, p1
            out[:, w, i] = k, s, r.snapped, r.status if r.status > 1 else -r.evaluations
    return out


@pytest.mark.parametrize("gent", [50.0, 20.0])
def test_branch_control_flags_the_same_folds_on_the_same_branches_with_fewer_evaluations(gent):
    jump, branch = _walks("jump", gent), _walks("branch", gent)
    ok = ~((jump[3] > 1).any(axis=1) | (branch[3] > 1).any(axis=1))  # walks where neither failed a solve
    assert ok.mean() > 0.9
    assert jump[2][ok].sum() > (20 if gent == 50.0 else 0)  # folds crossed
    assert np.array_equal(jump[2][ok], branch[2][ok])  # the same snaps, step for step
    assert np.abs(jump[:2, ok] - branch[:2, ok]).max() <= 1e-9  # the same minima: no walk left its branch
    evaluations = [-w[3][ok].sum() for w in (jump, branch)]
    assert evaluations[1] < evaluations[0]


def test_every_state_on_hard_paths_is_a_minimum_under_branch_control():
    options = SolverOptions(step_control="branch")
    cases = [
        (ActuatorParams(), 1e-4, np.linspace(0, 1.2, 25)),  # fold
        (ActuatorParams(), 1e-1, np.linspace(0, 2.0, 11)),  # very stiff
        (ActuatorParams(gent_limit=2.0), 0.0, [0.5, 2.0, 5.0, 20.0]),  # up against the Gent limit
        (ActuatorParams(gent_limit=15.0), 1e-5, [1.2, 0.0, 1.2]),  # big steps both ways
    ]
    for params, kobj, ps in cases:
        path = load_path(ps, kobj, KO, params, options=options)
        reference = load_path(ps, kobj, KO, params, options=SolverOptions(step_control="jump"))
        assert np.array_equal(path.snapped, reference.snapped)
        assert np.abs(path.curvature - reference.curvature).max() <= 1e-9
        for eq in path.equilibria:
            assert_minimum(eq, params)


def test_step_control_is_checked():
    assert SolverOptions(step_control="jump").as_tuple()[-1] == 0
    assert SolverOptions(step_control="branch").as_tuple()[-1] == 1
    assert STEP_CONTROLS == ("jump", "branch")
    for bad in ("Branch", "", None, 1):
        with pytest.raises(ValueError, match="step_control"):
            SolverOptions(step_control=bad)
    with pytest.raises(ValueError, match="step_control"):
        gym.make_vec("PneuNetGrasp-v1", num_envs=2, backend="numpy", step_control="Branch")


@pytest.mark.parametrize("gent", [50.0, 20.0])
def test_the_masked_solver_makes_the_scalar_solvers_decisions_under_branch_control(gent):
    """Random walks batched through the masked solver (numpy; torch runs the same code, checked through the envs in
    tests/envs/test_torch_backend.py): every step's status, snap, work counts and state those of the scalar
    continuation. Long sub-steps, their midpoint tests (accepted and
    rejected), predictors outside the domain and folds all occur."""
    rng = np.random.default_rng(5)
    n, steps = 120, 12
    params = ActuatorParams(gent_limit=gent)
    prm, opts = params_tuple(params), SolverOptions(step_control="branch").as_tuple()
    kobj = np.where(rng.random(n) < 0.1, 0.0, 10 ** rng.uniform(-3, 1, n))
    ko = rng.uniform(0.01, 0.3, n)
    k, s, p = np.zeros(n), np.zeros(n), np.zeros(n)
    snaps = 0
    for _ in range(steps):
        p1 = np.clip(p + rng.uniform(-0.2, 0.2, n), 0.0, 1.2)
        ref = [step_state(k[i], s[i], p[i], p1[i], prm, kobj[i], ko[i], opts) for i in range(n)]
        out = solve_masked(k, s, p, p1, kobj, ko, prm, opts, np.ones(n, bool), xp.NUMPY)
        for name in ("status", "snapped", "evaluations", "substeps", "iterations", "backtracks"):
            assert np.array_equal(out[name], [getattr(r, name) for r in ref]), name
        for name in ("kappa", "side_strain"):
            assert np.abs(out[name] - [getattr(r, name) for r in ref]).max() <= 1e-12, name
        snaps += int(out["snapped"].sum())
        good = out["status"] <= 1
        k, s, p = np.where(good, out["kappa"], k), np.where(good, out["side_strain"], s), np.where(good, p1, p)
    assert snaps > 0


def test_the_numpy_vector_env_steps_like_the_compiled_one_under_branch_control():
    kw = {"num_envs": 6, "step_control": "branch", "free_table": False, "info_level": "full"}
    envs = [gym.make_vec("PneuNetGrasp-v1", backend=b, **kw) for b in ("numpy",) + (("numba",) if HAVE_FUSED else ())]
    for e in envs:
        e.reset(seed=4)
    rng = np.random.default_rng(0)
    for _ in range(30):
        a = rng.uniform(-0.5, 1.5, (6, 1)).astype(np.float32)
        out = [e.step(a) for e in envs]
        assert out[0][4]["solver_converged"].all()
        for other in out[1:]:
            for j in range(4):
                assert np.array_equal(out[0][j], other[j])
            assert np.abs(out[0][4]["curvature_per_m"] - other[4]["curvature_per_m"]).max() <= 1e-9


@pytest.mark.skipif(not HAVE_FUSED, reason="the compiled steps need numba")
def test_the_envs_step_under_branch_control():
    """The single env and the vector env (the compiled steps) take the option: an episode of the best-ramp-like
    ramp into stiff objects, every solve converged, and the single env's states those of the vector env's."""
    n = 8
    kw = {"step_control": "branch", "terminate_on_damage": False, "terminate_on_slip": False}
    vec = gym.make_vec("PneuNetGrasp-v1", num_envs=n, **kw)
    vec.reset(seed=1)
    singles = [gym.make("PneuNetGrasp-v1", **kw) for _ in range(n)]
    for i, e in enumerate(singles):
        e.reset(seed=1 + i)
    a = np.full((n, 1), 0.6, np.float32)
    for _ in range(25):
        _, _, _, _, info = vec.step(a)
        assert info["solver_converged"].all()
        for i, e in enumerate(singles):
            _, _, _, _, si = e.step(a[i])
            assert si["pressure_kpa"] == info["pressure_kpa"][i]
            assert si["curvature_per_m"] == pytest.approx(info["curvature_per_m"][i], abs=1e-9)


def _tangent(eq, prm):
    """``dx/dp = H^-1 dV/dx`` at an equilibrium (the continuation's tangent)."""
    e = evaluate_state(eq.curvature, eq.side_strain, eq.pressure, prm, eq.object_stiffness, eq.object_curvature)
    det = e.h_kk * e.h_ss - e.h_ks * e.h_ks
    return (e.h_ss * e.v_kappa - e.h_ks * e.v_strain) / det, (e.h_kk * e.v_strain - e.h_ks * e.v_kappa) / det


@pytest.mark.parametrize("p0, p1, kobj, ko", [
    (0.3, 0.4, 0.0, 0.2),  # free, below the balloon region
    (0.45, 0.6, 0.0, 0.2),  # free, through it
    (0.8, 1.0, 1.0, 0.05),  # in contact the whole way
    (0.6, 0.7, 5.0, 0.05),  # a stiff object
])
def test_the_hermite_midpoint_is_the_paths_middle(p0, p1, kobj, ko):
    """On a smooth stretch of one branch the cubic Hermite midpoint of two equilibria (with their tangents) lies far
    closer to the equilibrium halfway than their chord's middle: what lets the branch test tell one branch from two
    (a wrong sign or a wrong tangent puts it farther than the chord)."""
    prm = params_tuple(ActuatorParams())
    a = solve_equilibrium(p0, kobj, ko)
    b = solve_equilibrium(p1, kobj, ko, initial=a)
    m = solve_equilibrium(0.5 * (p0 + p1), kobj, ko, initial=a)
    assert a.in_contact == b.in_contact == m.in_contact
    mid = hermite_midpoint(a.curvature, a.side_strain, *_tangent(a, prm), b.curvature, b.side_strain,
                           *_tangent(b, prm), p1 - p0)
    chord = 0.5 * (a.curvature + b.curvature), 0.5 * (a.side_strain + b.side_strain)

    def error(x):
        return max(abs(x[0] - m.curvature), abs(x[1] - m.side_strain))

    assert error(mid) < 0.25 * error(chord)


@pytest.mark.parametrize("gent, kobj, ko, p0, p1, k, s", [
    # found by review: without the midpoint test, "branch" crossed these folds without flagging them
    (20.0, 8.057607705812616e-06, 0.01508693307462388, 0.0, 0.738169340904125, 0.0, 0.0),
    (15.0, 0.0001488449087008495, 0.03338056237411515, 0.654404448722596, 0.6024689428611705, 0.17516495866864812,
     0.8976607460272517),
])
def test_a_long_step_across_a_fold_is_flagged_under_branch_control(gent, kobj, ko, p0, p1, k, s):
    prm = params_tuple(ActuatorParams(gent_limit=gent))
    jump, branch = (step_state(k, s, p0, p1, prm, kobj, ko, SolverOptions(step_control=c).as_tuple())
                    for c in STEP_CONTROLS)
    assert jump.snapped and branch.snapped and branch.status <= 1
    assert abs(jump.kappa - branch.kappa) <= 1e-9 and abs(jump.side_strain - branch.side_strain) <= 1e-9
