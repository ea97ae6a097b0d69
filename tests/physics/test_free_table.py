"""The free actuator's table (:mod:`pneunet_env.physics.free_table`): the path it holds, the steps it takes (converged
minima, the continuation's to within its tolerance), the steps it declines, and the envs that use it."""

from __future__ import annotations

import math

import gymnasium as gym
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import pneunet_env  # noqa: F401
from pneunet_env import task
from pneunet_env.config import load_config
from pneunet_env.physics import free_table as ft
from pneunet_env.physics._jit import HAVE_NUMBA
from pneunet_env.physics.params import ActuatorParams
from pneunet_env.physics.solver import (
    DEFAULT_OPTIONS,
    STATUS_INACTIVE,
    STATUS_ROUNDOFF,
    SolverOptions,
    params_tuple,
    step_state,
)

PRM = params_tuple(None)
OPTS = DEFAULT_OPTIONS.as_tuple()
TIGHT = SolverOptions(gtol=1e-14).as_tuple()
P_MAX = 1.2  # the default env's p~_max (60 kPa / 50 kPa)


@pytest.fixture(scope="module")
def table():
    return ft.free_table(PRM, OPTS, P_MAX)


def _on_path(table, p):
    """The continuation's state at ``p`` (from the node below it, to the default tolerance)."""
    j = int(p / table.spacing)
    r = step_state(table.nodes[j, 0], table.nodes[j, 1], j * table.spacing, p, PRM, 0.0, 1.0, OPTS)
    return r.kappa, r.side_strain


def test_the_table_is_the_free_path_to_p_max(table):
    """Table 1's actuator: a plain branch all the way (no fold, loading and unloading agree); between nodes the
    Hermite interpolant is within 1e-9 of the exact path (a solve to |grad| <= 1e-14)."""
    assert table.nodes.shape == (2401, 4) and table.pressure_max >= P_MAX and not table.nodes.flags.writeable
    assert table.nodes[0, 0] == 0.0 and table.nodes[0, 1] == 0.0
    assert np.all(np.diff(table.nodes[:, 0]) > 0.0)
    rng = np.random.default_rng(0)
    worst = 0.0
    for p in rng.uniform(0.0, P_MAX, 400):
        j = int(p / table.spacing)
        exact = step_state(table.nodes[j, 0], table.nodes[j, 1], j * table.spacing, p, PRM, 0.0, 1.0, TIGHT)
        k, s = ft.interpolate(table.nodes, table.spacing, p)
        worst = max(worst, abs(k - exact.kappa), abs(s - exact.side_strain))
    assert worst <= 1e-9, worst


def _free_cases(rng, n):
    for _ in range(n):
        p0 = float(rng.uniform(0.0, P_MAX))
        p1 = float(np.clip(p0 + rng.uniform(-0.1, 0.1), 0.0, P_MAX)) if rng.random() < 0.9 else 0.0
        yield p0, p1, float(10.0 ** rng.uniform(-6, -1)), 2.0  # an object the free path never reaches


def test_a_free_step_along_the_table_is_the_continuations_minimum(table):
    """Every step the table takes ends at a converged minimum (|grad| <= gtol, positive-definite Hessian), free,
    within 1e-10 of the continuation's answer, with 1 or 2 energy evaluations (the continuation: 2 to 20)."""
    rng = np.random.default_rng(1)
    evals, ref_evals = [], []
    for p0, p1, kobj, ko in _free_cases(rng, 500):
        k, s = _on_path(table, p0)
        r = ft.follow_table(k, s, p0, p1, PRM, kobj, ko, OPTS, table.nodes, table.spacing)
        ref = step_state(k, s, p0, p1, PRM, kobj, ko, OPTS)
        assert r.status != STATUS_INACTIVE
        assert 0 <= r.status <= STATUS_ROUNDOFF and r.gradient_norm <= OPTS[0] and r.min_eigenvalue > 0.0
        assert 0.0 <= r.kappa < ko and r.substeps == 1 and not r.snapped
        assert max(abs(r.kappa - ref.kappa), abs(r.side_strain - ref.side_strain)) <= 1e-10
        assert r.evaluation.ok and r.volume_change == r.evaluation.volume_change
        assert abs(r.energy - ref.energy) <= 1e-12
        evals.append(r.evaluations)
        ref_evals.append(ref.evaluations)
    assert set(evals) <= {1, 2} and np.mean(evals) < 1.5
    assert np.mean(ref_evals) > 3 * np.mean(evals)


def test_a_table_step_is_within_1e9_of_the_30_digit_reference(table):
    """Steps along the table (one with the object present, untouched) against the independent mpmath equilibrium."""
    pytest.importorskip("mpmath")
    from pneunet_env.physics.params import ActuatorParams
    from pneunet_env.physics.reference import reference_minimum

    for p0, p1 in [(0.0, 0.03), (0.3, 0.36), (0.55, 0.58), (0.62, 0.6), (1.1, 1.2), (0.7, 0.0)]:
        k, s = _on_path(table, p0) if p0 > 0.0 else (0.0, 0.0)
        r = ft.follow_table(k, s, p0, p1, PRM, 1e-3, 2.0, OPTS, table.nodes, table.spacing)
        assert r.status != STATUS_INACTIVE, (p0, p1)
        ref = reference_minimum(p1, 1e-3, 2.0, ActuatorParams(), (r.kappa, r.side_strain))
        assert max(abs(r.kappa - ref[0]), abs(r.side_strain - ref[1])) <= 1e-9, (p1, r.kappa - ref[0])


def test_the_table_declines_what_is_not_a_free_step_on_its_branch(table):
    """No step is taken from contact, into contact, from off the branch, beyond the table or with no table: status
    STATUS_INACTIVE, with no work done."""
    k, s = _on_path(table, 0.6)
    nodes, h = table.nodes, table.spacing
    cases = {
        "start in contact": (k, s, 0.6, 0.62, 1e-3, k * 0.99),
        "the path touches by p1": (k, s, 0.6, 0.66, 1e-3, ft.interpolate(nodes, h, 0.65)[0]),
        "off the branch": (k + 2 * OPTS[5], s, 0.6, 0.62, 1e-3, 2.0),
        "off the path, within max_jump": (k, s + 1e-5, 0.6, 0.62, 1e-3, 2.0),  # a branch close by is still another
        "beyond the table": (k, s, 0.6, P_MAX + 0.01, 1e-3, 2.0),
    }
    for name, (k0, s0, p0, p1, kobj, ko) in cases.items():
        r = ft.follow_table(k0, s0, p0, p1, PRM, kobj, ko, OPTS, nodes, h)
        assert r.status == STATUS_INACTIVE and r.evaluations == 0, name
    r = ft.follow_table(k, s, 0.6, 0.62, PRM, 1e-3, 2.0, OPTS, ft.EMPTY.nodes, ft.EMPTY.spacing)
    assert r.status == STATUS_INACTIVE and r.evaluations == 0


@settings(max_examples=60, deadline=None)
@given(p0=st.floats(0.0, P_MAX), dp=st.floats(-0.2, 0.2), kobj=st.floats(0.0, 0.1), ko=st.floats(0.01, 1.0))
def test_whatever_the_object_a_taken_step_is_a_free_converged_minimum(p0, dp, kobj, ko):
    """Over random starts on the path, pressure steps and objects (some touched along the way): a step the table takes
    is a converged, free minimum within 1e-10 of the continuation's; the others are left to the continuation."""
    table = ft.free_table(PRM, OPTS, P_MAX)
    p1 = min(max(p0 + dp, 0.0), P_MAX)
    k, s = _on_path(table, p0)
    r = ft.follow_table(k, s, p0, p1, PRM, kobj, ko, OPTS, table.nodes, table.spacing)
    if r.status == STATUS_INACTIVE:
        return
    ref = step_state(k, s, p0, p1, PRM, kobj, ko, OPTS)
    assert r.status <= STATUS_ROUNDOFF and r.gradient_norm <= OPTS[0] and r.min_eigenvalue > 0.0 and r.kappa < ko
    assert max(abs(r.kappa - ref.kappa), abs(r.side_strain - ref.side_strain)) <= 1e-10
    assert not ref.snapped and ref.kappa < ko


def test_a_free_path_that_folds_is_tabulated_only_below_its_fold():
    """A Gent limit of 50 makes the free actuator snap through (the top wall's balloon instability) near p~ = 0.54:
    the table ends there, and the continuation from its end snaps."""
    prm = params_tuple(ActuatorParams(gent_limit=50.0))
    t = ft.build_free_table(prm, OPTS, 1.2)
    assert 0.3 < t.pressure_max < 0.6
    top = t.nodes[-1]
    r = step_state(top[0], top[1], t.pressure_max, t.pressure_max + 0.01, prm, 0.0, 1.0, OPTS)
    assert r.snapped and r.kappa - top[0] > OPTS[5]
    assert ft.build_free_table(PRM, OPTS, 1.2) == ft.free_table(PRM, OPTS, P_MAX)


def test_a_huge_pressure_range_is_tabulated_only_to_max_nodes():
    """A config with a tiny shear modulus makes ``p~_max`` huge; the Gent-stiffened free path converges at every
    pressure, so the table is bounded (the fuzz test found a build that grew with ``p_max``)."""
    t = ft.build_free_table(PRM, OPTS, 6e13)
    assert len(t.nodes) == ft.MAX_NODES and t.pressure_max == pytest.approx((ft.MAX_NODES - 1) * ft.SPACING)
    k, s = t.nodes[-1, :2]
    r = ft.follow_table(k, s, t.pressure_max, t.pressure_max * 2, PRM, 0.0, 2.0, OPTS, t.nodes, t.spacing)
    assert r.status == STATUS_INACTIVE  # above the table: the continuation's


def test_the_table_reaches_p_max_even_when_the_spacing_does_not_divide_it():
    """10.8 kPa over 50 kPa is 0.21600000000000003: the last node is at or above it, not an ulp below (steps at the
    ceiling would otherwise all fall back on the continuation)."""
    p_max = 10.8 / 50.0
    t = ft.build_free_table(PRM, OPTS, p_max)
    assert t.pressure_max >= p_max and len(t.nodes) == 434
    k, s = t.nodes[-2, :2]
    r = ft.follow_table(k, s, (len(t.nodes) - 2) * t.spacing, p_max, PRM, 0.0, 2.0, OPTS, t.nodes, t.spacing)
    assert r.status != STATUS_INACTIVE


def test_bad_arguments_and_the_option():
    with pytest.raises(ValueError, match="spacing"):
        ft.build_free_table(PRM, OPTS, 1.2, spacing=0)
    with pytest.raises(ValueError, match="pressure_max"):
        ft.build_free_table(PRM, OPTS, math.nan)
    with pytest.raises(ValueError, match="free_table"):
        SolverOptions(free_table="yes")
    with pytest.raises((TypeError, ValueError), match="free_table"):
        load_config(None, free_table="yes")
    assert task.EnvParams.from_config(load_config(None, free_table=False)).free_table is None
    assert SolverOptions(free_table=False).as_tuple() == OPTS


@pytest.mark.skipif(not HAVE_NUMBA, reason="the table is used by the compiled steps (numba)")
@pytest.mark.parametrize("policy", ["random", "ramp"])
def test_the_vector_env_with_the_table_is_the_env_without_it(policy):
    """The fused vector env with the table (the default) against the same env without it, over two episodes with
    autoresets: every observation, reward, flag and status the same, the states within 1e-9, every solve a converged
    minimum, and fewer energy evaluations."""
    n = 96
    envs = [gym.make_vec("PneuNetGrasp-v1", num_envs=n, info_level="full", free_table=f) for f in (True, False)]
    obs = [e.reset(seed=7)[0] for e in envs]
    rng = np.random.default_rng(7)
    evals = [0, 0]
    for t in range(200):
        if policy == "random":
            a = rng.uniform(-1.2, 1.2, (n, 1))
        else:  # up in steps of random size, then held (a blind grasp)
            a = np.where(obs[0] < 0.6, rng.uniform(0.2, 1.0, (n, 1)), 0.0)
        outs = [e.step(a) for e in envs]
        (o0, r0, te0, tr0, i0), (o1, r1, te1, tr1, i1) = outs
        for x, y in ((o0, o1), (r0, r1), (te0, te1), (tr0, tr1)):
            assert np.array_equal(x, y), t
        for key, v in i0.items():
            if key in ("final_obs", "final_info"):
                continue
            w = i1[key]
            if v.dtype.kind == "f" and key not in ("pressure", "pressure_kpa", "object_stiffness"):
                assert np.allclose(v, w, rtol=0.0, atol=1e-9 * max(1.0, float(np.max(np.abs(w)))), equal_nan=True), \
                    key
            elif key not in ("solver_evaluations", "solver_iterations", "solver_substeps", "solver_backtracks"):
                assert np.array_equal(v, w), key
        assert np.all(i0["gradient_norm"] <= 1e-11) and np.all(i0["min_eigenvalue"] > 0.0)
        evals[0] += int(i0["solver_evaluations"].sum())
        evals[1] += int(i1["solver_evaluations"].sum())
        obs = [o0, o1]
    assert evals[0] < 0.7 * evals[1], evals


@pytest.mark.skipif(not HAVE_NUMBA, reason="the table is used by the compiled steps (numba)")
def test_the_single_env_uses_the_table():
    envs = [gym.make("PneuNetGrasp-v1", info_level="full", free_table=f) for f in (True, False)]
    for e in envs:
        e.reset(seed=3)
    for _ in range(10):
        (o0, r0, *_, i0), (o1, r1, *_, i1) = (e.step(np.ones(1, np.float32)) for e in envs)
        assert np.array_equal(o0, o1) and r0 == r1 and not i0["in_contact"]
        assert abs(i0["curvature"] - i1["curvature"]) <= 1e-10
        assert i0["solver_evaluations"] <= 2 < i1["solver_evaluations"]
