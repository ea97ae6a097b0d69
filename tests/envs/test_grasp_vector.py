"""PneuNetGraspVectorEnv: N single envs == one vector env of N, the vector API, random streams, bad input."""

from __future__ import annotations

import copy
import dataclasses

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.error import ResetNeeded
from gymnasium.vector import AutoresetMode

import pneunet_env  # noqa: F401  (registers the environment)
from pneunet_env import task
from pneunet_env.config import load_config
from pneunet_env.envs.grasp_vector import PCG64Streams, PneuNetGraspVectorEnv, _seed_words
from pneunet_env.physics._jit import HAVE_NUMBA

# Short episodes and wide object ranges, so that a few hundred steps hold many ends, auto-resets,
# terminations (damage, slip) and time-limit truncations.
SHORT = dict(squeeze_steps=8, hold_steps=8)
VARIED = dict(SHORT, observe_volume=True, object_thickness_mm=[5.0, 15.0], object_curvature_per_m=[2.0, 8.0],
              object_density_kg_m3=[300.0, 1200.0], object_failure_strain=[0.1, 0.5], use_case=None)
CATALOGUE = dict(SHORT, observe_volume=True, use_case="lab_bench")  # every class of the lab bench, both regimes
BACKENDS = ["numba", "numpy"] if HAVE_NUMBA else ["numpy"]
RTOL, ATOL = 1e-10, 1e-12


NAMES: tuple[str, ...] = ()  # the vector env's object_class_names, for comparing its class codes with names


def _assert_same(a, b, where: str) -> None:
    """Equal to 1e-10 (floats; relative, with a 1e-12 floor for round-off-level values), exactly otherwise.

    ``object_class`` is a name in a single env and an integer code in the vector env (with its table of names):
    codes are compared through :data:`NAMES`.
    """
    if "object_class" in where and np.asarray(b).dtype.kind in "iu" and np.asarray(a).dtype.kind in "UO":
        b = np.vectorize(lambda c: task.class_name(NAMES, int(c)), otypes=[object])(np.asarray(b))
        a = np.asarray(a, dtype=object)
        assert a.shape == b.shape and all(x == y for x, y in zip(a.ravel(), b.ravel(), strict=True)), (where, a, b)
        return
    if isinstance(a, dict):
        assert isinstance(b, dict) and set(a) == set(b), (where, set(a) ^ set(b))
        for k in a:
            _assert_same(a[k], b[k], f"{where}[{k!r}]")
        return
    if isinstance(a, tuple):  # (obs, info), a step's 5-tuple
        assert isinstance(b, tuple) and len(a) == len(b), where
        for i, (x, y) in enumerate(zip(a, b, strict=True)):
            _assert_same(x, y, f"{where}[{i}]")
        return
    if a is None or isinstance(a, (str, bool)):
        assert a == b, (where, a, b)
        return
    a, b = np.asarray(a), np.asarray(b)
    assert a.shape == b.shape, (where, a.shape, b.shape)
    if a.dtype == object:
        for i, (x, y) in enumerate(zip(a, b, strict=True)):
            _assert_same(x, y, f"{where}[{i}]")
        return
    assert a.dtype == b.dtype, (where, a.dtype, b.dtype)
    if a.dtype.kind == "f":
        np.testing.assert_allclose(b, a, rtol=RTOL, atol=ATOL, err_msg=where)
    else:
        np.testing.assert_array_equal(b, a, err_msg=where)


# ---- N single envs == one vector env of N ------------------------------------------------------------------


@pytest.mark.slow  # a few seconds: the quick loop stays under a minute
@pytest.mark.parametrize("backend", BACKENDS)
def test_vector_env_equals_n_single_envs_with_auto_resets(backend):
    """The brief's check, written out: N gym.make envs seeded s+i, each reset when its episode ends."""
    n, steps, seed = 6, 150, 21
    kw = dict(VARIED, free_table=backend != "numpy")  # numpy's array step has no free table: the singles neither
    singles = [gym.make("PneuNetGrasp-v1", max_episode_steps=16, **kw) for _ in range(n)]
    vec = PneuNetGraspVectorEnv(n, max_episode_steps=16, backend=backend, **kw)
    actions = np.random.default_rng(0).uniform(-1.3, 1.3, (steps, n, 1)).astype(np.float32)

    obs, info = vec.reset(seed=seed)
    for i, env in enumerate(singles):
        o, inf = env.reset(seed=seed + i)
        _assert_same(o, obs[i], f"reset obs {i}")
        for k, v in inf.items():
            assert info[f"_{k}"][i]
            _assert_same(np.asarray(v), info[k][i], f"reset info {i} {k}")
    ends = terminations = 0
    for t in range(steps):
        obs, rew, term, trunc, info = vec.step(actions[t])
        for i, env in enumerate(singles):
            o, r, te, tr, inf = env.step(actions[t, i])
            assert (te, tr) == (term[i], trunc[i]), (t, i)
            _assert_same(np.float64(r), rew[i], f"t={t} reward {i}")
            if te or tr:
                ends += 1
                terminations += te
                # the ended step: Gymnasium's final_obs / final_info
                assert info["_final_obs"][i] and info["_final_info"][i]
                _assert_same(o, info["final_obs"][i], f"t={t} final obs {i}")
                for k, v in inf.items():
                    _assert_same(np.asarray(v), info["final_info"][k][i], f"t={t} final info {i} {k}")
                o, inf = env.reset()  # the single env's own stream draws the next object
            else:
                assert not info.get("_final_obs", np.zeros(n, bool))[i]
            _assert_same(o, obs[i], f"t={t} obs {i}")
            for k, v in inf.items():
                _assert_same(np.asarray(v), info[k][i], f"t={t} info {i} {k}")
    assert ends >= 3 * n and terminations >= 5  # the run did exercise ends, resets and terminations


@pytest.mark.parametrize("objects", ["ranges", "catalogue"])
@pytest.mark.parametrize("mode", [AutoresetMode.SAME_STEP, AutoresetMode.NEXT_STEP])
@pytest.mark.parametrize("backend", [  # with numba, the numpy fallback's four cases (7 s) run with the slow tests
    pytest.param(b, marks=pytest.mark.slow) if b == "numpy" and HAVE_NUMBA else b for b in BACKENDS])
def test_vector_env_is_the_sync_vector_env_of_single_envs(backend, mode, objects):
    """Step for step, Gymnasium's SyncVectorEnv of single envs in the same autoreset mode, every key of the vector
    info included, through many episode ends; objects from ranges and from the catalogue."""
    global NAMES
    n, steps = 5, 120
    kw = dict(VARIED if objects == "ranges" else CATALOGUE, max_episode_steps=16,
              free_table=backend != "numpy")  # numpy's array step has no free table: the singles neither
    ref = gym.make_vec("PneuNetGrasp-v1", num_envs=n, vectorization_mode="sync",
                       vector_kwargs={"autoreset_mode": mode}, **kw)
    extra = {} if mode is AutoresetMode.SAME_STEP else {"autoreset_mode": mode}
    vec = gym.make_vec("PneuNetGrasp-v1", num_envs=n, backend=backend, **kw, **extra)
    assert isinstance(vec.unwrapped, PneuNetGraspVectorEnv)
    NAMES = vec.unwrapped.object_class_names
    assert vec.metadata["autoreset_mode"] is mode
    actions = np.random.default_rng(1).uniform(-1.3, 1.3, (steps, n, 1)).astype(np.float32)
    _assert_same(ref.reset(seed=3), vec.reset(seed=3), "reset")
    for t in range(steps):
        got, want = vec.step(actions[t]), ref.step(actions[t])
        for name, a, b in zip(("obs", "reward", "terminated", "truncated", "info"), want, got, strict=True):
            _assert_same(a, b, f"t={t} {name}")
    ref.close()
    vec.close()


@pytest.mark.slow  # 4 s: a run at scale; the README's test command runs it
def test_default_config_run_converges_and_matches_singles_at_scale():
    """64 envs at the default config over 250 steps (two and a half episodes): every solve converged."""
    n, steps = 64, 250
    vec = gym.make_vec("PneuNetGrasp-v1", num_envs=n, info_level="full")
    singles = [gym.make("PneuNetGrasp-v1") for _ in range(n)]
    actions = np.random.default_rng(2).uniform(-1.0, 1.0, (steps, n, 1)).astype(np.float32)
    obs, _ = vec.reset(seed=100)
    for i, env in enumerate(singles):
        env.reset(seed=100 + i)
    for t in range(steps):
        obs, rew, term, trunc, info = vec.step(actions[t])
        assert info["solver_converged"].all() and (info["gradient_norm"] <= 1e-10).all()
        assert np.all(np.isfinite(obs)) and np.all(np.isfinite(rew))
        assert vec.observation_space.contains(obs)
        for i, env in enumerate(singles):
            o, r, te, tr, _ = env.step(actions[t, i])
            if te or tr:
                o, _ = env.reset()
            np.testing.assert_allclose(obs[i], o, rtol=RTOL, atol=ATOL)
            assert r == pytest.approx(rew[i], rel=RTOL, abs=ATOL) and (te, tr) == (term[i], trunc[i])


# ---- random streams ----------------------------------------------------------------------------------------


@pytest.mark.parametrize("path", ["compiled", "arrays"])
@pytest.mark.parametrize("seed", [0, 1, 12345, 2**32 - 3, 2**63 + 7, 2**100 + 2**64 - 2])
def test_streams_are_numpys_pcg64_bit_for_bit(seed, path, monkeypatch):
    """Both draws (numba's compiled pass, and the array operations without numba) are numpy's PCG64."""
    from pneunet_env.envs import streams as streams_module

    if path == "arrays":
        monkeypatch.setattr(streams_module, "_draw", None)
    elif streams_module._draw is None:
        pytest.skip("needs numba")
    n = 5
    streams = PCG64Streams(n)
    streams.seed(np.arange(n), _seed_words(seed, n))
    draws = streams.random(np.arange(n), 12)
    for i in range(n):
        ref = np.random.Generator(np.random.PCG64(np.random.SeedSequence(seed + i)))
        assert np.array_equal(draws[:, i], ref.random(12)), i
    # a subset advances alone; generator() is a copy at the current position
    more = streams.random(np.array([3]), 4)
    ref3 = np.random.Generator(np.random.PCG64(np.random.SeedSequence(seed + 3)))
    assert np.array_equal(more[:, 0], ref3.random(16)[12:])
    g = streams.generator(1)
    assert np.array_equal(g.random(3), streams.random(np.array([1]), 3)[:, 0])


def test_sub_env_streams_are_the_single_envs_np_random():
    vec = PneuNetGraspVectorEnv(3)
    vec.reset(seed=7)
    for i in range(3):
        single = gym.make("PneuNetGrasp-v1")
        single.reset(seed=7 + i)
        assert np.array_equal(vec.sub_env_generator(i).random(8), single.unwrapped.np_random.random(8))


def test_seeding_rules():
    vec = PneuNetGraspVectorEnv(4)
    a = vec.reset(seed=5)[1]["object_stiffness"]
    b = vec.reset(seed=[5, 6, 7, 8])[1]["object_stiffness"]
    assert np.array_equal(a, b)
    c = vec.reset()[1]["object_stiffness"]  # continues the streams: new objects
    assert not np.any(c == a)
    d = vec.reset(seed=[5, None, 7, None])[1]["object_stiffness"]  # None: that stream goes on
    assert d[0] == a[0] and d[2] == a[2] and d[1] != a[1]
    e = PneuNetGraspVectorEnv(4).reset()[1]["object_stiffness"]  # unseeded: random, but valid
    assert np.all(np.isfinite(e))
    for bad, match in [(-1, "seed"), ([1, 2], "num_envs"), ([1, 2, "x", 4], r"seed\[2\]"), (2**128, "seed")]:
        with pytest.raises(ValueError, match=match):
            PneuNetGraspVectorEnv(4).reset(seed=bad)
    with pytest.raises(ValueError, match="first seeding"):
        PneuNetGraspVectorEnv(2).reset(seed=[1, None])


# ---- the Gymnasium vector API ------------------------------------------------------------------------------


def test_make_vec_uses_the_native_env_with_the_registered_time_limit(recwarn):
    env = gym.make_vec("PneuNetGrasp-v1", num_envs=3)
    assert isinstance(env, PneuNetGraspVectorEnv) and env.num_envs == 3
    assert env.max_episode_steps == 100
    assert env.metadata["autoreset_mode"] is AutoresetMode.SAME_STEP
    assert not [w for w in recwarn if "autoreset" in str(w.message).lower()]
    env2 = gym.make_vec("PneuNetGrasp-v1", num_envs=2, observe_volume=True, hold_steps=10, max_episode_steps=60)
    assert env2.config.task.hold_steps == 10 and env2.max_episode_steps == 60
    assert env2.single_observation_space.shape == (2,)


def test_spaces_and_returned_types():
    n = 4
    env = PneuNetGraspVectorEnv(n)
    assert env.single_action_space == gym.spaces.Box(-1.0, 1.0, (1,), np.float32)
    assert env.action_space == gym.spaces.Box(-1.0, 1.0, (n, 1), np.float32)
    assert env.single_observation_space == gym.spaces.Box(0.0, 1.0, (1,), np.float32)
    assert env.observation_space == gym.spaces.Box(0.0, 1.0, (n, 1), np.float32)
    obs, info = env.reset(seed=0)
    assert obs.shape == (n, 1) and obs.dtype == np.float32 and env.observation_space.contains(obs)
    single_keys = set(gym.make("PneuNetGrasp-v1").reset(seed=0)[1])
    assert {k for k in info if not k.startswith("_")} == single_keys
    for k in single_keys:
        assert info[k].shape == (n,) and info[f"_{k}"].dtype == bool and info[f"_{k}"].all(), k
    env.action_space.seed(0)
    obs, rew, term, trunc, info = env.step(env.action_space.sample())
    assert obs.shape == (n, 1) and env.observation_space.contains(obs)
    assert rew.shape == (n,) and rew.dtype == np.float64
    assert term.shape == trunc.shape == (n,) and term.dtype == trunc.dtype == bool
    assert "final_obs" not in info  # only on steps where an episode ends
    env.step(np.zeros(n, np.float32))  # (N,) actions are accepted too
    env.close()


def test_same_seed_same_trajectory_and_fresh_arrays():
    n = 3
    env = PneuNetGraspVectorEnv(n, **SHORT)
    actions = np.random.default_rng(5).uniform(-1, 1, (40, n, 1)).astype(np.float32)

    def run():
        out = [env.reset(seed=9)]
        out += [env.step(a) for a in actions]
        return out

    a, b = run(), run()
    for x, y in zip(a, b, strict=True):
        for u, v in zip(x, y, strict=True):
            _assert_same(u, v, "rerun")
    # nothing returned shares memory with the env's state or with another step's output
    o1, *_, i1 = env.step(actions[0])
    o2, *_, i2 = env.step(actions[1])
    assert not np.shares_memory(o1, o2)
    s = env.state
    state = [*s.eq, *s.thresholds, *s.task, s.command, env._obs]
    state += [getattr(s.obj, f.name) for f in dataclasses.fields(s.obj)]
    for k, v in i1.items():
        if isinstance(v, np.ndarray) and v.dtype != object:
            assert not np.shares_memory(v, i2[k]), k
            assert not any(np.shares_memory(v, s) for s in state if isinstance(s, np.ndarray)), k
    keep = env.equilibria
    i2["curvature_per_m"][:] = 123.0  # a caller mutating the info does not touch the env
    o2[:] = -5.0
    np.testing.assert_array_equal(env.equilibria.curvature, keep.curvature)


def test_autoreset_same_step_contract():
    n = 4
    env = PneuNetGraspVectorEnv(n, **SHORT)  # episodes end at step 16 at the latest
    obs, _ = env.reset(seed=0)
    actions = np.full((n, 1), 0.3, np.float32)
    for step in range(1, 17):
        obs, rew, term, trunc, info = env.step(actions)
        t, done = step, term | trunc
        if done.any():
            break
    assert done.any()
    assert np.array_equal(info["_final_obs"], done) and np.array_equal(info["_final_info"], done)
    fi = info["final_info"]
    assert np.array_equal(fi["_is_success"], done) and fi["is_success"].dtype == bool
    for i in np.flatnonzero(done):
        assert info["step"][i] == 0 and obs[i, 0] == 0.0  # already reset: the next episode's first observation
        assert fi["step"][i] == t and info["final_obs"][i].shape == (1,)
    for i in np.flatnonzero(~done):
        assert info["final_obs"][i] is None and not fi["_step"][i]


def test_reset_mask_and_per_env_pins():
    n = 4
    env = PneuNetGraspVectorEnv(n)
    obs, info = env.reset(seed=1, options={"object_stiffness": np.array([1e-5, 1e-4, 1e-3, 1e-2])})
    np.testing.assert_array_equal(info["object_stiffness"], [1e-5, 1e-4, 1e-3, 1e-2])
    for _ in range(5):
        obs, *_ = env.step(np.ones((n, 1), np.float32))
    before = env.equilibria
    mask = np.array([True, False, True, False])
    obs2, info2 = env.reset(options={"reset_mask": mask, "object_stiffness": 0.05})
    np.testing.assert_array_equal(info2["_pressure_kpa"], mask)
    assert np.all(obs2[mask] == 0.0) and np.array_equal(obs2[~mask], obs[~mask])
    after = env.equilibria
    np.testing.assert_array_equal(after.pressure[~mask], before.pressure[~mask])
    assert np.all(after.pressure[mask] == 0.0)
    np.testing.assert_array_equal(env.objects.stiffness, [0.05, 1e-4, 0.05, 1e-2])


def test_gymnasium_vector_wrappers_handle_it():
    n = 3
    env = gym.wrappers.vector.RecordEpisodeStatistics(PneuNetGraspVectorEnv(n, **SHORT))
    env.reset(seed=0)
    returns = np.zeros(n)
    seen = 0
    for _ in range(40):
        _, rew, term, trunc, info = env.step(np.full((n, 1), 0.5, np.float32))
        returns += rew
        if "episode" in info:
            for i in np.flatnonzero(info["_episode"]):
                assert info["episode"]["r"][i] == pytest.approx(returns[i])
                returns[i] = 0.0
                seen += 1
    assert seen >= n


def test_render_rgb_array_matches_the_single_env():
    env = PneuNetGraspVectorEnv(2, render_mode="rgb_array")
    single = gym.make("PneuNetGrasp-v1", render_mode="rgb_array")
    env.reset(seed=4)
    single.reset(seed=5)  # sub-env 1
    for _ in range(12):
        env.step(np.ones((2, 1), np.float32))
        single.step(np.ones(1, np.float32))
    frames = env.render()
    assert len(frames) == 2 and frames[1].shape == (360, 480, 3) and frames[1].dtype == np.uint8
    np.testing.assert_array_equal(frames[1], single.render())
    with pytest.warns(UserWarning, match="render mode"):
        assert PneuNetGraspVectorEnv(1).render() is None  # no render mode: a warning, no frame


def test_equilibrium_of_a_sub_env_is_the_single_envs():
    env = PneuNetGraspVectorEnv(2)
    single = gym.make("PneuNetGrasp-v1")
    env.reset(seed=0, options={"object_stiffness": 1e-3})
    single.reset(seed=1, options={"object_stiffness": 1e-3})
    for _ in range(10):
        env.step(np.ones((2, 1), np.float32))
        single.step(np.ones(1, np.float32))
    a, b = env.equilibrium(1), single.unwrapped.equilibrium
    for f in a._fields:
        va, vb = getattr(a, f), getattr(b, f)
        assert type(va) is type(vb), f
        if f == "evaluations":  # a compiled step's cache held the start's evaluation: one fewer
            assert vb - va == int(env.fused) - int(single.unwrapped._single is not None)
            continue
        assert va == pytest.approx(vb, rel=RTOL, abs=ATOL), f
    assert 0 < env.state_nbytes() / env.num_envs <= 1024


# ---- bad input ---------------------------------------------------------------------------------------------


@pytest.mark.parametrize(("actions", "match"), [
    (np.array([[0.1], [np.nan], [0.2]]), r"actions\[1\].*nan"),
    (np.array([0.1, 0.2, np.inf]), r"actions\[2\].*inf"),
    (np.zeros((3, 2)), r"shape \(3, 2\)"),
    (np.zeros(4), r"shape \(4,\)"),
    ("abc", "real numbers"),
])
def test_bad_actions_raise_naming_the_value(actions, match):
    env = PneuNetGraspVectorEnv(3)
    env.reset(seed=0)
    with pytest.raises((ValueError, TypeError), match=match):
        env.step(actions)
    for bad, error in [(np.array([["1"]] * 3), TypeError), (np.full((3, 1), 1j), TypeError), (None, TypeError),
                       (np.ones((3, 1), bool), TypeError), ([[10**400]] * 3, ValueError)]:
        with pytest.raises(error, match="actions"):
            env.step(bad)


def test_bad_arguments_raise():
    with pytest.raises(ResetNeeded, match="reset"):
        PneuNetGraspVectorEnv(2).step(np.zeros((2, 1)))
    for kwargs, match in [(dict(num_envs=0), "num_envs"), (dict(num_envs=2.5), "num_envs"),
                          (dict(backend="cuda"), "backend"), (dict(render_mode="human"), "render_mode"),
                          (dict(max_episode_steps=0), "max_episode_steps"), (dict(stiffnes=1.0), "stiffnes")]:
        with pytest.raises(ValueError, match=match):
            PneuNetGraspVectorEnv(**{"num_envs": 2, **kwargs})
    env = PneuNetGraspVectorEnv(2)
    for options, match in [({"stiffness": 1.0}, "unknown reset option"),
                           ({"object_stiffness": -1.0}, "object_stiffness"),
                           ({"object_stiffness": [1e-3, 1e-3, 1e-3]}, "object_stiffness"),
                           ({"reset_mask": [True, False]}, "reset_mask"), ("x", "options")]:
        with pytest.raises(ValueError, match=match):
            env.reset(seed=0, options=options)
    with pytest.raises(ValueError, match="first reset"):
        PneuNetGraspVectorEnv(2).reset(options={"reset_mask": np.array([True, False])})


# ---- the shared task functions on arrays ---------------------------------------------------------------------


def test_batch_objects_equal_single_objects_without_a_loop(monkeypatch):
    cfg = load_config(**VARIED)
    u = np.random.default_rng(3).random((task.draw_count(cfg), 200))
    cases = [(None, [task.object_from_uniforms(u[:, i], cfg) for i in range(200)]),
             ({"object_stiffness": 1e-3},
              [task.sample_object(_Fixed(u[:, i]), cfg, pinned={"object_stiffness": 1e-3}) for i in range(200)])]
    # the batch path must not fall back on the per-object (np.vectorize) eq. 3.2
    import pneunet_env.objects as objects

    def boom(*a, **k):
        raise AssertionError("a Python loop over objects")

    monkeypatch.setattr(objects, "_k_from_mu", boom)
    monkeypatch.setattr(objects, "_mu_from_k", boom)
    for pins, ref in cases:
        batch = task.object_from_uniforms(u, cfg, pinned=pins)
        for f in batch.__dataclass_fields__:
            np.testing.assert_allclose(getattr(batch, f), [getattr(o, f) for o in ref], rtol=1e-14, err_msg=f)
            if pins is None:  # drawn, not pinned: the same ufuncs, so the same bits (the vector env's promise)
                np.testing.assert_array_equal(getattr(batch, f), [getattr(o, f) for o in ref], err_msg=f)


@pytest.mark.parametrize("overrides", [{}, VARIED], ids=["catalogue", "ranges"])
def test_drawn_objects_are_single_objects_bit_for_bit(overrides):
    """4,000 draws, one by one and as a batch: every field the same to the last bit (log-uniform draws through
    numpy's ``power`` ufunc in both, eq. 3.2's square as ``q * q`` in both)."""
    cfg = load_config(**overrides)
    u = np.random.default_rng(8).random((task.draw_count(cfg), 4000))
    batch = task.object_from_uniforms(u, cfg)
    singles = [task.object_from_uniforms(u[:, i], cfg) for i in range(u.shape[1])]
    for f in batch.__dataclass_fields__:
        np.testing.assert_array_equal(getattr(batch, f), [getattr(o, f) for o in singles], err_msg=f)
    with pytest.raises(ValueError, match="curvature_per_m"):
        task.object_from_uniforms(u, cfg, pinned={"object_curvature_per_m": np.where(np.arange(200) == 7, -1.0, 4.0)})


class _Fixed:
    """A generator stand-in that returns given uniforms (to feed sample_object)."""

    def __init__(self, u):
        self.u = u

    def random(self, shape):
        return self.u.reshape(shape)


def test_autoreset_mode_is_checked_and_named():
    assert PneuNetGraspVectorEnv(2, autoreset_mode="NextStep").autoreset_mode is AutoresetMode.NEXT_STEP
    assert PneuNetGraspVectorEnv(2, autoreset_mode="next_step").metadata["autoreset_mode"] is AutoresetMode.NEXT_STEP
    assert PneuNetGraspVectorEnv.metadata["autoreset_mode"] is AutoresetMode.SAME_STEP  # the class default is kept
    with pytest.raises(ValueError, match="autoreset_mode"):
        PneuNetGraspVectorEnv(2, autoreset_mode=AutoresetMode.DISABLED)


def test_info_keys_build_only_what_is_asked():
    from pneunet_env import task

    full = gym.make_vec("PneuNetGrasp-v1", num_envs=4, info_level="full")
    full.reset(seed=0)
    info = full.step(np.zeros((4, 1)))[4]
    assert {k for k in info if not k.startswith("_")} == set(task.FULL_KEYS)
    some = gym.make_vec("PneuNetGrasp-v1", num_envs=4, info_keys=("pressure_kpa", "held"))
    _, info = some.reset(seed=0)
    assert set(info) == {"pressure_kpa", "_pressure_kpa", "held", "_held"}
    none = gym.make_vec("PneuNetGrasp-v1", num_envs=4, info_keys=())
    _, info = none.reset(seed=0)
    assert info == {}
    for _ in range(none.unwrapped.config.episode_steps):
        obs, _, term, trunc, info = none.step(np.ones((4, 1)))
    assert set(info) == {"final_obs", "_final_obs", "final_info", "_final_info"} and "is_success" in info["final_info"]
    with pytest.raises(ValueError, match="not keys"):
        gym.make_vec("PneuNetGrasp-v1", num_envs=2, info_keys=("nope",))
    with pytest.raises(ValueError, match="sequence"):
        gym.make_vec("PneuNetGrasp-v1", num_envs=2, info_keys="pressure_kpa")


def test_a_cpu_tensor_action_steps_the_numpy_backends():
    """A CPU torch tensor is real numbers to the numpy and numba backends, as numpy takes it (not a crash)."""
    torch = pytest.importorskip("torch")
    for backend in ["numpy"] + (["numba"] if HAVE_NUMBA else []):
        env = gym.make_vec("PneuNetGrasp-v1", num_envs=4, backend=backend)
        env.reset(seed=0)
        ref = gym.make_vec("PneuNetGrasp-v1", num_envs=4, backend=backend)
        ref.reset(seed=0)
        obs, *_ = env.step(torch.full((4, 1), 0.5))
        assert isinstance(obs, np.ndarray) and np.array_equal(obs, ref.step(np.full((4, 1), 0.5))[0])
        with pytest.raises(ValueError, match=r"actions\[2\]"):
            env.step(torch.tensor([[0.1], [0.2], [float("nan")], [0.0]]))


def _bits_differ(x, y, where: str, out: list[str], names: tuple[str, ...] = ()) -> None:
    """Append to ``out`` where ``x`` (ours) and ``y`` (the sync env's) differ in any bit (dicts walked key by key;
    our ``object_class`` codes read through our table of class ``names``)."""
    if isinstance(x, dict):
        for k in sorted(set(x) | set(y)):
            if k not in x or k not in y:
                out.append(f"{where}[{k!r}]: only in {'ours' if k in x else 'the sync env'}")
            else:
                _bits_differ(x[k], y[k], f"{where}[{k!r}]", out, names)
        return
    a, b = np.asarray(x), np.asarray(y)
    if "object_class'" in where and a.dtype.kind in "iu":
        a = np.array([task.class_name(names, int(c)) for c in a.ravel()], dtype=object).reshape(a.shape)
    if a.dtype.kind == "f" and b.dtype.kind == "f":
        if a.shape != b.shape or a.astype(float).tobytes() != b.astype(float).tobytes():
            out.append(f"{where}: {a!r} != {b!r}"[:300])
    elif a.dtype == object or b.dtype == object:
        if len(a.ravel()) != len(b.ravel()):
            out.append(f"{where}: lengths differ")
        for i, (p, q) in enumerate(zip(a.ravel(), b.ravel(), strict=False)):
            if p is None or q is None:
                if (p is None) != (q is None):
                    out.append(f"{where}[{i}]: {p!r} != {q!r}")
            else:
                _bits_differ(p, q, f"{where}[{i}]", out, names)
    elif not np.array_equal(a, b):
        out.append(f"{where}: {a!r} != {b!r}"[:300])


@pytest.mark.skipif(not HAVE_NUMBA, reason="the compiled step: without numba the vector env's array step is tested "
                                           "to round-off")
@pytest.mark.parametrize("mode", [AutoresetMode.NEXT_STEP, AutoresetMode.SAME_STEP])
def test_vector_env_is_n_single_envs_bit_for_bit(mode):
    """On one install the (numba) vector env gives the bits of N single envs, objects included, through autoresets.

    The single and the vector env draw each object through the same ufuncs (``task_objects._log_uniform``: never a
    scalar ``**``, whose libm ``pow`` differs from numpy's AVX-512 ``power`` in the last bit of ~4 % of draws) and
    step through the same compiled loop, so nothing may differ, not even a last bit, on any machine.
    """
    n, steps = 16, 120
    ours = gym.make_vec("PneuNetGrasp-v1", num_envs=n, info_level="full", autoreset_mode=mode)
    sync = gym.make_vec("PneuNetGrasp-v1", num_envs=n, info_level="full", vectorization_mode="sync",
                        vector_kwargs={"autoreset_mode": mode})
    actions = np.random.default_rng(5).uniform(-1.0, 1.0, (steps, n, 1)).astype(np.float32)
    bad: list[str] = []
    names = ours.unwrapped.object_class_names
    try:
        a, b = ours.reset(seed=40), sync.reset(seed=40)
        _bits_differ(a[0], b[0], "reset obs", bad, names)
        _bits_differ(a[1], b[1], "reset info", bad, names)
        ends = 0
        for t in range(steps):
            ra, rb = ours.step(actions[t]), sync.step(actions[t])
            for name, x, y in zip(("obs", "reward", "terminated", "truncated", "info"), ra, rb, strict=True):
                _bits_differ(x, y, f"step {t} {name}", bad, names)
            ends += int(np.sum(ra[2] | ra[3]))
            if len(bad) > 20:
                break
    finally:
        ours.close()
        sync.close()
    assert not bad, f"{len(bad)} differences:\n" + "\n".join(bad[:20])
    assert ends >= n, f"only {ends} episodes ended: the run must go through autoresets"


def test_seeded_partial_resets_reseed_only_the_envs_they_reset_as_sync_vector_env_does():
    """``reset(seed=s, options={"reset_mask": m})`` seeds sub-env i with s + i only where m is true; the others keep
    their streams, so their next objects are SyncVectorEnv's (a regression: every stream used to be re-seeded)."""
    from gymnasium.vector import SyncVectorEnv

    n = 4
    ours = gym.make_vec("PneuNetGrasp-v1", num_envs=n)
    sync = SyncVectorEnv([lambda: gym.make("PneuNetGrasp-v1") for _ in range(n)])

    def stiffness(info, mask):
        return np.where(mask, np.asarray(info["object_stiffness"], float), np.nan)

    try:
        for seed, mask in ((0, None), (7, [True, False, False, False]), (None, [False, True, True, False]),
                           ([11, 12, 13, 14], [False, False, True, True]), (None, [True, True, True, True])):
            options = None if mask is None else {"reset_mask": np.array(mask)}
            m = np.ones(n, bool) if mask is None else np.array(mask)
            _, a = ours.reset(seed=seed, options=options)
            _, b = sync.reset(seed=seed, options=None if options is None else dict(options))
            np.testing.assert_array_equal(stiffness(a, m), stiffness(b, m), err_msg=f"seed={seed}, mask={mask}")
    finally:
        ours.close()
        sync.close()


@pytest.mark.parametrize("mode", ["SameStep", "NextStep"])
def test_the_in_place_autoreset_never_changes_a_state_handed_out(mode):
    """The autoreset writes the reset sub-envs into the step's fresh arrays; the arrays an earlier state holds (the
    objects and thresholds carry over from step to step) are copied first, so a state a caller kept never changes."""
    n = 8
    env = PneuNetGraspVectorEnv(n, autoreset_mode=mode, **SHORT)
    env.reset(seed=4)
    rng = np.random.default_rng(4)
    resets = 0
    for _ in range(40):
        kept = env.state
        values = [np.copy(a) for a in task.leaves(kept)]
        *_, term, trunc, _ = env.step(rng.uniform(0.0, 1.5, (n, 1)).astype(np.float32))
        resets += int(np.sum(term | trunc))
        for a, v in zip(task.leaves(kept), values, strict=True):
            assert np.array_equal(a, v, equal_nan=v.dtype.kind == "f")
        now = {id(a) for a in task.leaves(env.state)}
        assert len(now) == len(task.leaves(env.state))  # no array held twice
    assert resets >= n


@pytest.mark.parametrize("mode", ["SameStep", "NextStep"])
def test_a_state_handed_out_is_never_changed_and_one_kept_inside_is_reset_in_place(mode):
    """``env.state`` is a snapshot: later steps and their autoresets never write into its arrays (the first autoreset
    after it copies the arrays it still shares). A state nobody was handed is reset in place: the objects' arrays it
    shares with the state before are written, not copied (a copy is a pass over every env's object)."""
    n = 6
    env = PneuNetGraspVectorEnv(n, autoreset_mode=mode, **SHORT)
    env.reset(seed=3)
    rng = np.random.default_rng(3)
    snapshots = [env.state]  # handed out: the next autoreset must copy
    before = [[np.array(a, copy=True) for a in task.leaves(snapshots[0])]]
    in_place = copied = 0
    protected = True
    for t in range(80):
        inner = env._state.obj.stiffness  # the env's own array (read without handing the state out)
        env.step(rng.uniform(0.0, 1.5, (n, 1)).astype(np.float32))
        if np.any(env._state.task.step == 0):  # an autoreset in this step (a sub-env back at step 0)
            same = env._state.obj.stiffness is inner
            assert same != protected, (t, protected)  # copied after a snapshot, written in place otherwise
            in_place += same
            copied += not same
            protected = False
        if t == 40:  # a second snapshot, mid-run
            snapshots.append(env.state)
            before.append([np.array(a, copy=True) for a in task.leaves(snapshots[1])])
            protected = True
    for snap, values in zip(snapshots, before, strict=True):
        for a, b in zip(task.leaves(snap), values, strict=True):
            np.testing.assert_array_equal(a, b)
    assert copied == 2 and in_place > 5, (copied, in_place)
    env.state  # noqa: B018  (hands the state out)
    assert env._handed_out is env._state and copy.deepcopy(env)._handed_out is None  # the copy's is held by no one
