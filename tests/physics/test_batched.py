"""The batched solver gives the scalar solver's answers, env by env, on both back-ends."""

from __future__ import annotations

import math

import numpy as np
import pytest

from pneunet_env import ActuatorParams, SolverOptions, solve_equilibrium
from pneunet_env.physics import batched as B
from pneunet_env.physics import mechanics
from pneunet_env.physics._jit import HAVE_NUMBA
from pneunet_env.physics.solver import (
    ACCEPT_GTOL,
    DEFAULT_OPTIONS,
    STATUS_INACTIVE,
    STATUS_MESSAGES,
    Equilibrium,
    params_tuple,
    step_state,
)

KO = 0.02
BACKENDS = ["numpy"] + (["numba"] if HAVE_NUMBA else [])


def scalar_reference(k, s, p0, p1, kobj, ko, params=None, options=DEFAULT_OPTIONS):
    """``step_state`` env by env: rows of (k, s, U, |g|, lmin, iters, substeps, snapped, status, dV, evaluations,
    backtracks)."""
    prm, opts = params_tuple(params), options.as_tuple()
    n = len(k)
    kobj, ko, p0, p1 = (np.broadcast_to(np.asarray(a, float), (n,)) for a in (kobj, ko, p0, p1))
    return np.array([step_state(k[i], s[i], p0[i], p1[i], prm, kobj[i], ko[i], opts) for i in range(n)], dtype=float)


def equilibria(p, kobj, ko=KO, params=None):
    """Equilibria loaded quasi-statically from rest to ``p`` (batched, checked against the scalar API below)."""
    n = len(p)
    r = B.solve_batch(np.zeros(n), np.zeros(n), 0.0, p, kobj, ko, params)
    assert r.converged.all()
    return r.curvature, r.side_strain


def assert_matches(result: Equilibrium, ref: np.ndarray, tol: float = 1e-10) -> None:
    assert np.max(np.abs(result.curvature - ref[:, 0])) <= tol
    assert np.max(np.abs(result.side_strain - ref[:, 1])) <= tol
    assert np.max(np.abs(result.energy - ref[:, 2])) <= tol
    assert np.array_equal(result.snapped, ref[:, 7].astype(bool))
    assert np.array_equal(result.status, ref[:, 8].astype(int))
    assert np.array_equal(result.converged, ref[:, 8] <= 1)
    assert np.max(np.abs(result.volume_change - ref[:, 9])) <= tol
    # Iteration counts follow the same control flow; a knife-edge branch may flip on a last-bit difference
    # between numpy's and libm's elementary functions, so allow a few envs to differ there.
    assert np.mean(result.iterations == ref[:, 5]) >= 0.98
    assert np.mean(result.substeps == ref[:, 6]) >= 0.98
    assert np.mean(result.evaluations == ref[:, 10]) >= 0.98  # the work counters, counted the same way
    assert np.mean(result.backtracks == ref[:, 11]) >= 0.98


@pytest.fixture(scope="module")
def random_steps():
    """Random env-like steps from equilibria: loading and unloading, free to very stiff objects, clipping at 0."""
    rng = np.random.default_rng(1234)
    n = 300
    kobj = np.where(rng.random(n) < 0.2, 0.0, 10.0 ** rng.uniform(-6.0, -1.0, n))
    ko = rng.uniform(0.01, 0.06, n)
    p0 = rng.uniform(0.0, 1.3, n)
    k, s = equilibria(p0, kobj, ko)
    p1 = np.clip(p0 + rng.uniform(-0.15, 0.15, n), 0.0, 1.5)
    p1[:20] = 0.0  # unloading to rest
    p1[20:30] = p0[20:30]  # no pressure change
    return k, s, p0, p1, kobj, ko


CONTROLS = [SolverOptions(step_control="jump"), SolverOptions(step_control="branch")]


@pytest.mark.parametrize("options", CONTROLS, ids=lambda o: o.step_control)
@pytest.mark.parametrize("backend", BACKENDS)
def test_random_steps_match_scalar(random_steps, backend, options):
    k, s, p0, p1, kobj, ko = random_steps
    ref = scalar_reference(k, s, p0, p1, kobj, ko, options=options)
    r = B.solve_batch(k, s, p0, p1, kobj, ko, options=options, backend=backend)
    assert_matches(r, ref)
    assert r.converged.all()
    assert np.all(r.gradient_norm <= ACCEPT_GTOL) and np.all(r.min_eigenvalue > 0.0)


@pytest.mark.parametrize("options", CONTROLS, ids=lambda o: o.step_control)
@pytest.mark.parametrize("backend", BACKENDS)
def test_folds_snap_like_scalar(backend, options):
    """k~ = 1e-4 folds near p~ = 0.68 on loading and snaps back near 0.6-0.7 on unloading (hysteresis)."""
    kobj = np.array([1e-4, 1e-4, 3e-5, 1e-4, 1e-4, 2e-4])
    before = np.array([0.60, 0.66, 0.55, 0.60, 0.20, 0.60])
    after = np.array([0.80, 0.70, 0.75, 0.62, 1.20, 0.90])
    k, s = equilibria(before, kobj)
    ref = scalar_reference(k, s, before, after, kobj, KO, options=options)
    r = B.solve_batch(k, s, before, after, kobj, KO, options=options, backend=backend)
    assert_matches(r, ref)
    assert r.snapped[[0, 1, 4]].all() and not r.snapped[3]
    # Unload the snapped states: they snap back.
    down = np.full(6, 0.3)
    ref2 = scalar_reference(r.curvature, r.side_strain, after, down, kobj, KO, options=options)
    r2 = B.solve_batch(r.curvature, r.side_strain, after, down, kobj, KO, options=options, backend=backend)
    assert_matches(r2, ref2)
    assert r2.snapped[[0, 1, 4]].all()
    # And the batched answer is the public API's.
    eq = solve_equilibrium(0.8, 1e-4, KO, initial=(k[0], s[0]), initial_pressure=0.6)
    assert eq.snapped and abs(eq.curvature - r.curvature[0]) <= 1e-10


@pytest.mark.parametrize("backend", BACKENDS)
def test_contact_onset_and_stiff_objects(backend):
    """Steps across kappa~ = kappa_obj (the energy's second derivative jumps) and into very stiff contact."""
    kobj = np.repeat([1e-5, 1e-3, 1e-2, 1e-1], 4)
    p0 = np.tile([0.2, 0.25, 0.27, 0.3], 4)  # free curvature reaches kappa_obj = 0.02 near p~ = 0.27
    p1 = p0 + np.tile([0.05, 0.02, -0.03, 0.4], 4)
    k, s = equilibria(p0, kobj)
    ref = scalar_reference(k, s, p0, p1, kobj, KO)
    r = B.solve_batch(k, s, p0, p1, kobj, KO, backend=backend)
    assert_matches(r, ref)
    assert (r.curvature > KO).any() and (k < KO).any()


@pytest.mark.parametrize("backend", BACKENDS)
def test_near_the_gent_limit(backend):
    params = ActuatorParams(gent_limit=2.0)
    p0 = np.array([0.5, 2.0, 5.0, 10.0])
    p1 = np.array([2.0, 5.0, 20.0, 40.0])
    k, s = equilibria(p0, 0.0, KO, params)
    ref = scalar_reference(k, s, p0, p1, 0.0, KO, params)
    r = B.solve_batch(k, s, p0, p1, 0.0, KO, params, backend=backend)
    assert_matches(r, ref)
    # The walls stiffen against the limit I1 - 3 < J: the states stay in the domain.
    assert np.all(mechanics.in_domain(r.curvature, r.side_strain, params))
    assert r.converged.all()


@pytest.mark.parametrize("backend", BACKENDS)
def test_cold_starts_and_options(backend):
    """Starts that are not equilibria (polished first) and non-default tolerances."""
    options = SolverOptions(max_step=0.02, max_jump=0.05, corrector_max_iter=8)
    k = np.array([0.0, 0.1, 0.3, 0.05])
    s = np.array([0.0, 0.3, 0.5, 1.0])
    p0 = np.array([0.0, 0.3, 0.7, 0.9])
    p1 = np.array([0.5, 0.6, 0.2, 1.1])
    kobj = np.array([0.0, 1e-4, 1e-3, 1e-2])
    ref = scalar_reference(k, s, p0, p1, kobj, KO, options=options)
    r = B.solve_batch(k, s, p0, p1, kobj, KO, options=options, backend=backend)
    assert_matches(r, ref)


@pytest.mark.parametrize("backend", BACKENDS)
def test_inactive_envs_are_left_alone(random_steps, backend):
    k, s, p0, p1, kobj, ko = (a[:40] for a in random_steps)
    active = np.arange(40) % 3 != 0
    r = B.solve_batch(k, s, p0, p1, kobj, ko, active=active, backend=backend)
    full = B.solve_batch(k, s, p0, p1, kobj, ko, backend=backend)
    for field in Equilibrium._fields:
        a, b = getattr(r, field)[active], getattr(full, field)[active]
        assert np.array_equal(a, b, equal_nan=a.dtype.kind == "f"), field
    off = ~active
    assert np.array_equal(r.curvature[off], k[off]) and np.array_equal(r.side_strain[off], s[off])
    assert np.all(r.status[off] == STATUS_INACTIVE) and not r.converged[off].any()
    assert np.all(r.iterations[off] == 0) and np.isnan(r.energy[off]).all()
    assert STATUS_MESSAGES[STATUS_INACTIVE] == "not solved (inactive)"
    assert list(r.message[off]) == [STATUS_MESSAGES[STATUS_INACTIVE]] * int(off.sum())
    none = B.solve_batch(k, s, p0, p1, kobj, ko, active=np.zeros(40, bool), backend=backend)
    assert np.all(none.status == STATUS_INACTIVE)


@pytest.mark.parametrize("backend", BACKENDS)
def test_broadcasting_and_fresh_arrays(backend):
    k, s = equilibria(np.array([0.4]), 1e-3)
    r = B.solve_batch(k[0], s[0], 0.4, [0.41, 0.45, 0.5], 1e-3, backend=backend)
    assert r.curvature.shape == (3,)
    for i, p in enumerate([0.41, 0.45, 0.5]):
        eq = solve_equilibrium(p, 1e-3, KO, initial=(float(k[0]), float(s[0])), initial_pressure=0.4)
        assert abs(eq.curvature - r.curvature[i]) <= 1e-10 and abs(eq.volume_change - r.volume_change[i]) <= 1e-10
    r2 = B.solve_batch(k[0], s[0], 0.4, [0.41, 0.45, 0.5], 1e-3, backend=backend)
    assert all(not np.shares_memory(getattr(r, f), getattr(r2, f)) for f in Equilibrium._fields)
    scalar = B.solve_batch(0.0, 0.0, 0.0, 0.3, backend=backend)
    assert scalar.curvature.shape == (1,)
    unchecked = B.solve_batch(k[0], s[0], 0.4, [0.41, 0.45, 0.5], 1e-3, backend=backend, validate=False)
    assert np.array_equal(unchecked.curvature, r.curvature)
    with pytest.raises(ValueError, match="outside the domain"):  # a NaN start is caught even unvalidated
        B.solve_batch(float("nan"), 0.0, 0.0, 0.3, backend=backend, validate=False)


@pytest.mark.slow  # a few seconds: the quick loop stays under a minute
def test_backends_agree_on_a_long_random_walk():
    """Episodes of env-like random pressure steps, all envs advanced together on both back-ends."""
    rng = np.random.default_rng(7)
    n, steps = 64, 40
    kobj = 10.0 ** rng.uniform(-5.0, -1.0, n)
    state = {b: (np.zeros(n), np.zeros(n)) for b in BACKENDS}
    p = np.zeros(n)
    for _ in range(steps):
        p_new = np.clip(p + rng.uniform(-0.06, 0.1, n), 0.0, 1.2)
        out = {}
        for b in BACKENDS:
            out[b] = B.solve_batch(*state[b], p, p_new, kobj, KO, backend=b)
            assert out[b].converged.all()
            state[b] = (out[b].curvature, out[b].side_strain)
        if len(BACKENDS) == 2:
            assert np.max(np.abs(out["numpy"].curvature - out["numba"].curvature)) <= 1e-10
            assert np.array_equal(out["numpy"].snapped, out["numba"].snapped)
        p = p_new


@pytest.mark.skipif(not HAVE_NUMBA, reason="needs numba")
def test_parallel_and_serial_loops_agree(random_steps):
    k, s, p0, p1, kobj, ko = random_steps
    args = (k, s, p0, p1, kobj, ko, params_tuple(None), DEFAULT_OPTIONS.as_tuple(), np.ones(len(k), bool))
    a = B.solve_batch_numba(*args, parallel=False)
    b = B.solve_batch_numba(*args, parallel=True)
    for field in Equilibrium._fields:
        assert np.array_equal(getattr(a, field), getattr(b, field)), field


def test_step_state_is_the_public_api():
    eq0 = solve_equilibrium(0.5, 1e-4)
    eq1 = solve_equilibrium(0.52, 1e-4, initial=eq0)
    r = step_state(eq0.curvature, eq0.side_strain, 0.5, 0.52, params_tuple(None), 1e-4, KO, DEFAULT_OPTIONS.as_tuple())
    assert (r[0], r[1], r[2], r[5], r[6], r[7]) == (eq1.curvature, eq1.side_strain, eq1.energy, eq1.iterations,
                                                    eq1.substeps, eq1.snapped)
    assert math.isclose(r[9], float(mechanics.volume_change(r[0], r[1], ActuatorParams())), abs_tol=1e-13)
    assert params_tuple(ActuatorParams(gent_limit=15.0)) == ActuatorParams(gent_limit=15.0).as_tuple()


@pytest.mark.parametrize(
    "kwargs, name",
    [
        ({"kappa": [0.0, float("nan")]}, r"kappa\[1\]"),
        ({"side_strain": float("inf")}, "side_strain"),
        ({"p0": [0.0, -0.1]}, r"p0\[1\]"),
        ({"p1": [float("nan"), 0.1]}, r"p1\[0\]"),
        ({"object_stiffness": [1e-3, -1e-3]}, r"object_stiffness\[1\]"),
        ({"object_curvature": 0.0}, "object_curvature"),
        ({"object_curvature": [0.02, 3.5]}, r"object_curvature\[1\]"),
        ({"kappa": [0.0, -0.5]}, r"outside the domain.*|kappa\[1\]"),
        ({"side_strain": [0.0, -1.5]}, "outside the domain"),
        ({"kappa": [[0.0]]}, "one-dimensional"),
        ({"kappa": "abc"}, "kappa"),
        ({"p1": [0.1, 0.2, 0.3]}, "broadcast"),
        ({"active": [1, 0]}, "boolean"),
        ({"active": np.ones(3, bool)}, "shape"),
        ({"backend": "cuda"}, "backend"),
    ],
)
def test_bad_input_raises_naming_it(kwargs, name):
    args = {"kappa": [0.0, 0.0], "side_strain": [0.0, 0.0], "p0": 0.0, "p1": 0.1, "object_stiffness": 0.0,
            "object_curvature": KO}
    args.update(kwargs)
    with pytest.raises(ValueError, match=name):
        B.solve_batch(**args)


_FORK_AFTER_PARALLEL = """
import os, sys, threading, numpy as np
from pneunet_env.physics import batched
n = 2048
args = (np.zeros(n), np.zeros(n), 0.0, np.linspace(0.0, 1.2, n), 1e-3)
r = batched.solve_batch(*args, parallel=True, backend="numba")
# two threads at once: the parallel loop is serialised, never aborted
out = []
ts = [threading.Thread(target=lambda: out.append(batched.solve_batch(*args, parallel=True, backend="numba")))
      for _ in range(2)]
[t.start() for t in ts]; [t.join() for t in ts]
assert len(out) == 2 and all(np.array_equal(o.curvature, r.curvature) for o in out)
pid = os.fork()
if pid == 0:
    r2 = batched.solve_batch(*args, parallel=True, backend="numba")
    os._exit(0 if np.array_equal(r.curvature, r2.curvature) else 3)
_, status = os.waitpid(pid, 0)
sys.exit(os.waitstatus_to_exitcode(status))
"""


@pytest.mark.slow  # 3 s: forks a process; the README's test command runs it
@pytest.mark.skipif(not HAVE_NUMBA, reason="needs numba")
def test_fork_after_the_parallel_loop_survives():
    """AsyncVectorEnv and multiprocessing fork on Linux: a child forked after a parallel solve must live (GNU OpenMP
    kills it), and two threads solving at once must not abort."""
    import os
    import subprocess
    import sys

    env = {k: v for k, v in os.environ.items() if k != "NUMBA_THREADING_LAYER"}
    res = subprocess.run([sys.executable, "-c", _FORK_AFTER_PARALLEL], capture_output=True, text=True, timeout=300,
                         env=env)
    assert res.returncode == 0, res.stderr[-2000:]


def test_threads_are_chosen_by_n_and_can_be_set():
    from pneunet_env.physics.batched import ENVS_PER_THREAD, check_threads, threads_for

    assert threads_for(1) == 1 and threads_for(ENVS_PER_THREAD) == 1
    assert threads_for(10**9) >= 1
    for bad in (0, -1, 2.5, True, "2", 10**6):
        with pytest.raises(ValueError, match="threads"):
            check_threads(bad)
    check_threads(None)
    check_threads(1)
    if HAVE_NUMBA:
        from pneunet_env.physics.batched import solve_batch

        p1 = np.linspace(0.0, 1.2, 2048)
        one = solve_batch(0.0, 0.0, 0.0, p1, 1e-3, 0.1, backend="numba", threads=1)
        auto = solve_batch(0.0, 0.0, 0.0, p1, 1e-3, 0.1, backend="numba", parallel=True)
        assert np.array_equal(one.curvature, auto.curvature) and one.converged.all()
