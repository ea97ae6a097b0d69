"""The fused numba step is :func:`pneunet_env.task.step`, bit for bit (every field of the returned Step), with the
free table off (``solver.free_table: false``); with it on (the default), within the solver's tolerance
(``tests/physics/test_free_table.py``)."""

from __future__ import annotations

import dataclasses

import gymnasium as gym
import numpy as np
import pytest

import pneunet_env  # noqa: F401
from pneunet_env import task
from pneunet_env.fused import HAVE_FUSED, fused_step, new_cache

pytestmark = pytest.mark.skipif(not HAVE_FUSED, reason="the fused step needs numba")


def _fields(record, prefix=""):
    items = (record._asdict().items() if hasattr(record, "_asdict")
             else ((f.name, getattr(record, f.name)) for f in dataclasses.fields(record)))
    out = {}
    for name, v in items:
        if hasattr(v, "_asdict") or dataclasses.is_dataclass(v):
            out.update(_fields(v, f"{prefix}{name}."))
        else:
            out[prefix + name] = np.asarray(v)
    return out


@pytest.mark.parametrize("env_id,overrides", [
    ("PneuNetGrasp-v1", {}),
    pytest.param("PneuNetGrasp-Paper-v0", {"observe_volume": True}, marks=pytest.mark.slow),
])
def test_fused_step_equals_the_array_step(env_id, overrides):
    n = 256
    env = gym.make_vec(env_id, num_envs=n, backend="numba", fused=False, free_table=False, **overrides).unwrapped
    env.reset(seed=4)
    state, params = env.state, env._params
    rng = np.random.default_rng(0)
    failed_or_ended = 0
    for t in range(30):
        a = rng.uniform(-1.5, 2.5, n)  # clipped actions, loading and unloading
        ref = task.step(state, a, params, env._contact)
        got = fused_step(state, a, params, parallel=bool(t % 2))
        f_ref, f_got = _fields(ref), _fields(got)
        assert f_ref.keys() == f_got.keys()
        for key, v in f_ref.items():
            w = f_got[key]
            assert v.dtype == w.dtype and v.shape == w.shape, key
            assert np.array_equal(v, w, equal_nan=v.dtype.kind == "f"), key
        failed_or_ended += int(np.sum(ref.terminated | ref.truncated))
        state = ref.state
    assert failed_or_ended > 0


def test_fused_is_the_numba_default_and_checked():
    assert gym.make_vec("PneuNetGrasp-v1", num_envs=2, backend="numba").unwrapped.fused
    assert not gym.make_vec("PneuNetGrasp-v1", num_envs=2, backend="numpy").unwrapped.fused
    with pytest.raises(ValueError, match="fused"):
        gym.make_vec("PneuNetGrasp-v1", num_envs=2, backend="numpy", fused=True)
    with pytest.raises(ValueError, match="fused"):
        gym.make_vec("PneuNetGrasp-v1", num_envs=2, backend="numba", fused="yes")


@pytest.mark.parametrize("mode", ["SameStep", pytest.param("NextStep", marks=pytest.mark.slow)])
def test_fused_env_with_its_evaluation_cache_equals_the_array_step_env(mode):
    """The numba env (fused, with the cache of each env's last evaluation) against the array step, through autoresets
    and a masked reset: every observation, reward, flag and info value equal, bit for bit, but the work: the fused
    step makes one energy evaluation fewer wherever its cache held the start's."""
    n = 64
    envs = [gym.make_vec("PneuNetGrasp-v1", num_envs=n, backend="numba", fused=f, autoreset_mode=mode,
                         info_level="full", free_table=False) for f in (True, False)]
    outs = [e.reset(seed=2) for e in envs]
    rng = np.random.default_rng(1)
    ended = cached = 0
    for t in range(130):
        a = rng.uniform(-1.0, 2.0, (n, 1)).astype(np.float32)
        if t == 60:  # a masked reset in the middle
            mask = rng.random(n) < 0.3
            outs = [e.reset(options={"reset_mask": mask}) for e in envs]
            assert np.array_equal(outs[0][0], outs[1][0])
        outs = [e.step(a) for e in envs]
        for x, y in zip(outs[0][:4], outs[1][:4], strict=True):
            assert np.array_equal(x, y)
        for key, v in outs[0][4].items():
            if key in ("final_obs", "final_info", "solver_evaluations"):
                continue
            assert np.array_equal(v, outs[1][4][key], equal_nan=v.dtype.kind == "f"), key
        saved = outs[1][4]["solver_evaluations"] - outs[0][4]["solver_evaluations"]
        assert set(np.unique(saved)) <= {0, 1}
        cached += int(saved.sum())
        ended += int(np.sum(outs[0][2] | outs[0][3]))
    assert ended > n // 2
    assert cached > n * 50  # the cache was in use


WORK = ("solve.evaluations", "state.eq.evaluations")
"""The one thing the fused step with a cache does differently: fewer energy evaluations."""


def _assert_steps_equal(ref, got, skip=()):
    f_ref, f_got = _fields(ref), _fields(got)
    assert f_ref.keys() == f_got.keys()
    for key, v in f_ref.items():
        if key in skip:
            continue
        w = f_got[key]
        assert v.dtype == w.dtype and v.shape == w.shape, key
        assert np.array_equal(v, w, equal_nan=v.dtype.kind == "f"), key


def test_an_unchanged_pressure_skips_the_solve_only_at_a_converged_minimum():
    """Where the pressure does not change and the start is a converged minimum, the fused step skips the solve; the
    result is the array step's, bit for bit. A start nudged off its minimum (its gradient above the tolerance) is
    solved, as the array step solves it."""
    n = 256
    env = gym.make_vec("PneuNetGrasp-v1", num_envs=n, backend="numba", fused=False, free_table=False).unwrapped
    env.reset(seed=3)
    state, params, contact = env.state, env._params, env._contact
    rng = np.random.default_rng(3)
    for _ in range(20):  # into contact, some envs at the pressure ceiling
        state = task.step(state, rng.uniform(0.5, 2.0, n), params, contact).state
    cache = new_cache(n)
    a = rng.uniform(-1.0, 1.0, n)
    ref = task.step(state, a, params, contact)
    got = fused_step(state, a, params, cache=cache)  # fills the cache
    _assert_steps_equal(ref, got, skip=WORK)
    zero = np.zeros(n)
    ref = task.step(ref.state, zero, params, contact)
    got = fused_step(got.state, zero, params, cache=cache)  # every pressure unchanged, the cache valid
    _assert_steps_equal(ref, got, skip=WORK)
    assert np.all(got.solve.evaluations == 0) and np.all(ref.solve.evaluations == 1)
    assert np.all(ref.solve.iterations == 0) and ref.solve.in_contact.any()
    eq = ref.state.eq
    nudged = ref.state._replace(eq=eq._replace(curvature=eq.curvature * (1.0 + 1e-9)))
    ref = task.step(nudged, zero, params, contact)
    got = fused_step(nudged, zero, params, cache=new_cache(n))
    _assert_steps_equal(ref, got)
    assert np.mean(ref.solve.iterations > 0) > 0.5


COUNTERS = ("evaluations", "iterations", "substeps", "backtracks")
"""The solve's work counters: the compiled steps start from the cached evaluation (and skip a solve at an unchanged
pressure from a converged minimum), so these differ; every other number is the same."""


def _kind(v):
    return float if type(v) in (float, np.float64) else type(v)


@pytest.mark.parametrize("overrides", [{}, {"observe_volume": True},
                                       {"max_substeps": 3, "max_pressure_step_kpa": 20.0}])
def test_the_single_envs_compiled_step_is_task_step(overrides):
    """``SingleStep`` (the single env's step as one compiled call) against :func:`pneunet_env.task.step` with the
    scalar Newton contact: the observation (values and dtype), reward, flags, the solve, the new state and the rules'
    outcome, equal number for number and of the same kind, over random actions (clipped ones, zeros that hold the
    pressure), with unconverged solves in the third case (a tiny sub-step budget)."""
    from pneunet_env.config import load_config
    from pneunet_env.fused import SingleStep

    config = load_config(None, free_table=False, **overrides)
    params = task.EnvParams.from_config(config)
    assert params.free_table is None
    rng = np.random.default_rng(1)
    single = SingleStep(params)
    failures = steps = 0
    while steps < 300:
        a_state = b_state = task.reset_state(task.sample_object(rng, config), params, task.newton_contact)
        for _ in range(config.episode_steps):
            a = float(rng.uniform(-1.3, 1.3)) if rng.random() < 0.7 else 0.0
            ra, rb = task.step(a_state, a, params, task.newton_contact), single(b_state, a)
            assert ra.obs.dtype == rb.obs.dtype and np.array_equal(ra.obs, rb.obs)
            for name in ("reward", "terminated", "truncated", "action_clipped", "solver_failed", "outcome"):
                assert getattr(ra, name) == getattr(rb, name), name
            for rec_a, rec_b in [(ra.solve, rb.solve), (ra.state.eq, rb.state.eq), (ra.state.task, rb.state.task)]:
                for f in rec_a._fields:
                    va, vb = getattr(rec_a, f), getattr(rec_b, f)
                    assert _kind(va) is _kind(vb) and (f in COUNTERS or va == vb), (f, va, vb)
            assert ra.state.command == rb.state.command and ra.state.obj is rb.state.obj
            failures += bool(ra.solver_failed)
            steps += 1
            a_state, b_state = ra.state, rb.state
            if ra.terminated or ra.truncated:
                break
    assert (failures > 0) == ("max_substeps" in overrides)


def test_the_single_env_steps_with_the_compiled_call():
    env = gym.make("PneuNetGrasp-v1").unwrapped
    assert env._single is not None
    env.reset(seed=0)
    for _ in range(3):
        env.step(np.ones(1, np.float32))
    state = env.state  # built from the packed state the compiled call left (no record was built by the steps)
    assert env._single._state is state and state.task.step == 3
    assert env.state is state  # built once


def _record_path(env):
    """``env`` stepping through the records (``_step_state`` and :func:`pneunet_env.task.build_info`), the fast
    path off."""
    env.unwrapped._step_fast = lambda state, action: None
    return env


def _assert_same_record(a, b, where):
    assert type(a) is type(b), where
    for f in a._fields:
        va, vb = getattr(a, f), getattr(b, f)
        if hasattr(va, "_fields"):
            _assert_same_record(va, vb, f"{where}.{f}")
        else:
            assert type(va) is type(vb) and (va == vb or (va != va and vb != vb)), (where, f, va, vb)


@pytest.mark.parametrize("overrides", [
    {},
    {"free_table": False},
    {"observe_volume": True, "max_pressure_step_kpa": 8.0},
    {"max_substeps": 3, "max_pressure_step_kpa": 20.0},  # unconverged solves: the state kept, truncation
    pytest.param({"terminate_on_damage": False, "terminate_on_slip": False}, marks=pytest.mark.slow),
])
def test_the_single_envs_fast_step_equals_its_record_path(overrides):
    """The lean step that builds no records (``SingleStep.step_lean``, :func:`pneunet_env.info.lean_info`) against
    the same env stepping through records and :func:`pneunet_env.task.build_info`: every observation, reward, flag and
    info (keys in order, values and types), and the state built afterwards (every field, of the same type), step for
    step over random, clipped and zero actions, with the state read mid-episode on one env only."""
    fast = gym.make("PneuNetGrasp-v1", **overrides)
    slow = _record_path(gym.make("PneuNetGrasp-v1", **overrides))
    rng = np.random.default_rng(5)
    steps = failures = 0
    for episode in range(8):
        fa, fb = fast.reset(seed=episode), slow.reset(seed=episode)
        assert np.array_equal(fa[0], fb[0]) and fa[1] == fb[1]
        done = False
        while not done:
            a = np.array([rng.uniform(-1.4, 1.4) if rng.random() < 0.7 else 0.0], np.float32)
            ra, rb = fast.step(a), slow.step(a)
            assert ra[0].dtype == rb[0].dtype and ra[0].shape == rb[0].shape and np.array_equal(ra[0], rb[0])
            assert ra[1:4] == rb[1:4] and [type(v) for v in ra[1:4]] == [type(v) for v in rb[1:4]]
            assert list(ra[4]) == list(rb[4]), "the info's keys, in order"
            for k, v in rb[4].items():
                assert type(ra[4][k]) is type(v) and ra[4][k] == v, (k, ra[4][k], v)
            if rng.random() < 0.3 or ra[2] or ra[3]:  # read the state mid-episode (the next step goes on from it)
                _assert_same_record(fast.unwrapped.state, slow.unwrapped.state, "state")
            failures += ra[4]["solver_failed"]
            steps += 1
            done = ra[2] or ra[3]
    assert steps > (80 if "max_substeps" in overrides else 250)
    assert (failures > 0) == ("max_substeps" in overrides)


def test_the_single_envs_fast_step_survives_a_copy_and_a_pickle():
    """A copy (``copy.copy`` of the env, ``copy.deepcopy``) or a pickle taken between fast steps carries the packed
    state: each goes on as the original does, and stepping one moves no other."""
    import copy
    import pickle

    env = gym.make("PneuNetGrasp-v1")
    env.reset(seed=3)
    for _ in range(20):
        env.step(np.full(1, 0.8, np.float32))
    copies = [copy.copy(env.unwrapped), copy.deepcopy(env), pickle.loads(pickle.dumps(env))]
    for _ in range(15):
        a = np.full(1, 0.4, np.float32)
        r = env.step(a)
        for c in copies:
            rc = c.step(a)
            assert np.array_equal(r[0], rc[0]) and r[1:4] == rc[1:4] and r[4] == rc[4]
    for c in copies:
        _assert_same_record(env.unwrapped.state, c.unwrapped.state, "state")


def test_the_single_step_calls_the_dispatchers_own_compiled_function():
    """The single step calls its compiled function's entry point directly (no typing of its ten arguments on every
    call): it must be the dispatcher's own overload for the types of the step's own arrays, in a new env and after a
    copy and a pickle (whose arrays may differ in type: an unpickled table is writable), and a step through it must
    be the dispatcher's step, bit for bit. A numba whose dispatcher no longer gives its overload's entry point fails
    here, not slowly elsewhere."""
    import copy
    import pickle

    import numba

    def args(s, a=0.3):
        return (s._x, a, s._params, s._table, s._c, s._valid, s._f, s._n, s._b, s._obs_rows)

    env = gym.make("PneuNetGrasp-v1").unwrapped
    env.reset(seed=4)
    env.step(np.full(1, 0.5, np.float32))
    unpickled = pickle.loads(pickle.dumps(env))
    assert unpickled._single._table.flags.writeable != env._single._table.flags.writeable  # another type, asked again
    fresh = gym.make("PneuNetGrasp-v1").unwrapped
    assert fresh._single._entry == fresh._single._first_call  # made, not stepped: nothing compiled for it yet
    for s in (env._single, copy.copy(env)._single, unpickled._single):
        s._advance(0.3)  # (a copy's and an unpickled env's first step finds their entry point)
        sig = tuple(numba.typeof(v) for v in args(s))
        assert s._entry is s._call.get_overload(sig)
        twin = copy.copy(s)
        s._advance(0.3)
        twin._call(*args(twin))  # the dispatcher, typing every argument
        for name in ("_x", "_f", "_n", "_b", "_obs"):
            assert np.array_equal(getattr(s, name), getattr(twin, name)), name


def test_lean_info_is_the_tables_lean_rows():
    """:func:`pneunet_env.info.lean_info` gives :data:`pneunet_env.info.LEAN_KEYS`, in order: a lean row added to the
    table and not to it fails here."""
    from pneunet_env.info import LEAN_KEYS, lean_info

    info = lean_info(0.5, 0.1, 0.2, 0.01, True, 3, *([False] * 11), 50.0, 10.0)
    assert tuple(info) == LEAN_KEYS
    assert info["indentation_mm"] == 0.01 * 10.0
    assert lean_info(0.5, 0.1, 0.2, 0.01, False, 3, *([False] * 11), 50.0, 10.0)["indentation_mm"] == 0.0


def test_a_ctrl_c_as_the_compiled_call_returns_leaves_the_env_consistent():
    """A ``KeyboardInterrupt`` is raised as the compiled call returns (CPython handles a signal then). The step is then
    not taken, as far as the env is concerned: its state is the one before, and the next step goes on from that
    state, not from the packed one the call had already moved."""
    env = gym.make("PneuNetGrasp-v1").unwrapped
    env.reset(seed=2)
    a = np.full(1, 0.7, np.float32)
    for _ in range(5):
        env.step(a)
    single = env._single
    call = single._entry

    def interrupted(*args):
        call(*args)
        raise KeyboardInterrupt

    single._entry = interrupted
    before = env.state
    with pytest.raises(KeyboardInterrupt):
        env.step(a)
    single._entry = call
    assert env.state is before
    _, _, _, _, info = env.step(a)
    assert info["step"] == before.task.step + 1
    assert env.state.eq.pressure == pytest.approx(before.eq.pressure + 0.7 * 3.0 / 50.0)


def test_a_subclass_with_its_own_info_takes_the_record_path():
    """The lean step builds its info itself: a subclass that overrides ``_info`` (or ``_step_state``) is stepped
    through the records, so that its override is called."""
    from pneunet_env.envs.grasp import PneuNetGraspEnv

    class Tagged(PneuNetGraspEnv):
        def _info(self, res):
            info = super()._info(res)
            info["tag"] = True
            return info

    env = Tagged()
    env.reset(seed=0)
    assert env.step(np.ones(1, np.float32))[4]["tag"] is True
    plain = PneuNetGraspEnv()
    plain.reset(seed=0)
    assert "tag" not in plain.step(np.ones(1, np.float32))[4] and plain._own_step
