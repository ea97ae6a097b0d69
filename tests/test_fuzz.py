"""Fuzz: every input either works (finite results, an honest convergence flag) or raises ValueError/TypeError that
names it, within a short time; and long seeded random walks never leave a step unconverged.

The examples are derandomized (the same every run, so CI is reproducible). The default run is a quick profile (a few
dozen examples each); the ``slow`` tests run the same properties for
minutes (``python -m pytest -m slow tests/test_fuzz.py``).
"""

from __future__ import annotations

import math
import time

import gymnasium as gym
import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

import pneunet_env  # noqa: F401  (registers the environments)
from pneunet_env.config import FLAT_KEYS, load_config
from pneunet_env.envs.grasp import PneuNetGraspEnv
from pneunet_env.physics._jit import HAVE_NUMBA

QUICK = settings(max_examples=40, deadline=None, derandomize=True, suppress_health_check=[HealthCheck.too_slow])
LONG = settings(max_examples=1500, deadline=None, derandomize=True, suppress_health_check=[HealthCheck.too_slow])
TIME_LIMIT_S = 20.0  # no input may take longer than this to work or to be refused

# Anything a user might pass: numbers of every size and sign, special floats, wrong types.
ANY_VALUE = st.one_of(
    st.floats(allow_nan=True, allow_infinity=True, width=64),
    st.integers(min_value=-(10**30), max_value=10**30),
    st.booleans(),
    st.none(),
    st.text(max_size=8),
    st.lists(st.floats(allow_nan=True, allow_infinity=True), max_size=3),
    st.sampled_from([1e-15, 1e-12, 1e300, -0.0, 1.5, 2**63, 10**400, float("nan")]),
)
KEYS = sorted(FLAT_KEYS)


def _names_it(exc: Exception, *names: str) -> bool:
    msg = str(exc)
    return any(n in msg for n in names)


def _one_config(key: str, value) -> None:
    t0 = time.perf_counter()
    try:
        cfg = load_config(**{key: value})
    except (ValueError, TypeError) as exc:
        section, field = FLAT_KEYS[key]
        assert _names_it(exc, key, field), (key, value, exc)
        return
    finally:
        assert time.perf_counter() - t0 < TIME_LIMIT_S
    # accepted: an episode runs, finite, with an honest flag
    env = PneuNetGraspEnv(config=cfg)
    obs, _ = env.reset(seed=0)
    for _ in range(5):
        obs, reward, terminated, truncated, info = env.step(np.array([1.0], np.float32))
        assert np.all(np.isfinite(obs)) and math.isfinite(reward)
        eq = env.equilibrium
        if info["solver_converged"]:
            assert eq.gradient_norm <= 1e-10 and eq.min_eigenvalue > 0.0
        if terminated or truncated:
            break
    assert time.perf_counter() - t0 < TIME_LIMIT_S, (key, value)


@QUICK
@given(key=st.sampled_from(KEYS), value=ANY_VALUE)
def test_config_values_work_or_are_named(key, value):
    _one_config(key, value)


@pytest.mark.slow
@LONG
@given(key=st.sampled_from(KEYS), value=ANY_VALUE)
def test_config_values_work_or_are_named_long(key, value):
    _one_config(key, value)


ACTIONS = st.one_of(
    ANY_VALUE,
    st.lists(st.floats(allow_nan=True, allow_infinity=True, width=32), min_size=0, max_size=3).map(np.array),
    st.complex_numbers(max_magnitude=2.0).map(lambda z: np.array([z])),
    st.sampled_from([np.array(["1"]), np.array([[0.5]]), {"a": 1}, object()]),
)


def _one_action(action) -> None:
    env = PneuNetGraspEnv()
    env.reset(seed=1)
    t0 = time.perf_counter()
    try:
        obs, reward, *_ = env.step(action)
    except (ValueError, TypeError) as exc:
        assert "action" in str(exc), (action, exc)
    else:
        assert np.all(np.isfinite(obs)) and math.isfinite(reward)
        env.step(np.array([0.0], np.float32))  # the env is still usable
    assert time.perf_counter() - t0 < TIME_LIMIT_S


@QUICK
@given(action=ACTIONS)
def test_actions_work_or_are_named(action):
    _one_action(action)


@pytest.mark.slow
@LONG
@given(action=ACTIONS)
def test_actions_work_or_are_named_long(action):
    _one_action(action)


PIN_KEYS = ("object_stiffness", "object_shear_modulus_kpa", "object_curvature", "object_curvature_per_m",
            "object_thickness_mm", "object_density_kg_m3", "object_failure_strain")
OPTIONS = st.one_of(
    st.none(),
    st.dictionaries(st.sampled_from(PIN_KEYS + ("bogus", "reset_mask")), ANY_VALUE, max_size=3),
    ANY_VALUE,
)


def _one_reset(options) -> None:
    env = PneuNetGraspEnv()
    t0 = time.perf_counter()
    try:
        obs, info = env.reset(seed=2, options=options)
    except (ValueError, TypeError) as exc:
        assert "option" in str(exc) or any(k in str(exc) for k in PIN_KEYS), (options, exc)
    else:
        assert np.all(np.isfinite(obs))
        for _ in range(3):
            obs, reward, terminated, truncated, info = env.step(np.array([1.0], np.float32))
            assert np.all(np.isfinite(obs)) and math.isfinite(reward)
            if terminated or truncated:
                break
    assert time.perf_counter() - t0 < TIME_LIMIT_S


@QUICK
@given(options=OPTIONS)
def test_reset_options_work_or_are_named(options):
    _one_reset(options)


@pytest.mark.slow
@LONG
@given(options=OPTIONS)
def test_reset_options_work_or_are_named_long(options):
    _one_reset(options)


# ---- seeded random walks: no step left unconverged -----------------------------------------------------------

WALK_CONFIGS = [
    {},
    dict(object_thickness_mm=[5.0, 15.0], object_curvature_per_m=[2.0, 8.0]),
    dict(object_shear_modulus_kpa=[0.01, 20000.0], object_curvature_per_m=[2.0, 12.0], object_thickness_mm=[2.0, 20.0]),
    dict(max_pressure_step_kpa=20.0),  # big pressure steps
]


def _walk(cfg: dict, n: int, steps: int, seed: int, backend: str) -> tuple[int, int]:
    env = gym.make_vec("PneuNetGrasp-v1", num_envs=n, backend=backend, **cfg)
    env.reset(seed=seed)
    rng = np.random.default_rng(seed)
    failed = 0
    for _ in range(steps):
        obs, reward, _, _, info = env.step(rng.uniform(-1.0, 1.0, (n, 1)).astype(np.float32))
        assert np.all(np.isfinite(obs)) and np.all(np.isfinite(reward))
        failed += int(info["solver_failed"].sum())
        eq = env.unwrapped.state.eq
        assert np.all(eq.gradient_norm[eq.converged] <= 1e-10) and np.all(eq.min_eigenvalue[eq.converged] > 0.0)
    env.close()
    return failed, n * steps


@pytest.mark.parametrize("cfg", WALK_CONFIGS, ids=["default", "sizes", "wide", "big-steps"])
def test_seeded_random_walks_converge(cfg):
    backend = "numba" if HAVE_NUMBA else "numpy"
    failed, total = _walk(cfg, 512, 60, 3, backend)
    assert failed == 0, f"{failed} of {total} steps unconverged"


@pytest.mark.slow
@pytest.mark.parametrize("cfg", WALK_CONFIGS, ids=["default", "sizes", "wide", "big-steps"])
def test_seeded_random_walks_converge_long(cfg):
    """About 2.5 M steps per configuration (10 M in all): every step converges, on both back-ends' shared path."""
    backend = "numba" if HAVE_NUMBA else "numpy"
    failed, total = _walk(cfg, 16384, 150, 11, backend)
    assert failed == 0, f"{failed} of {total} steps unconverged"


_TORCH_DTYPES = ("float32", "float64", "float16", "int64", "int32", "uint8", "bool", "complex64")


@QUICK
@given(shape=st.sampled_from([(4, 1), (4,), (3, 1), (4, 2), (), (1, 4), (0,)]),
       dtype=st.sampled_from(_TORCH_DTYPES),
       value=st.one_of(st.floats(allow_nan=True, allow_infinity=True, width=32), st.integers(-5, 5)))
def test_torch_backend_actions_either_step_or_raise_a_clear_error(shape, dtype, value):
    """Any tensor handed to the torch backend's step: it steps (finite, real, right shape), or it raises a
    ValueError/TypeError that names the problem; the env stays usable."""
    torch = pytest.importorskip("torch")
    env = _torch_env()
    dt = getattr(torch, dtype)
    try:
        a = torch.full(shape, value).to(dt)
    except (RuntimeError, OverflowError, TypeError):
        return
    try:
        obs, reward, *_ = env.step(a)
    except (ValueError, TypeError) as exc:
        assert any(w in str(exc) for w in ("actions", "shape", "dtype", "finite")), exc
    else:
        assert obs.shape == (4, 1) and bool(torch.isfinite(obs).all()) and reward.dtype == torch.float64
    obs, *_ = env.step(torch.zeros(4, 1))  # still usable
    assert bool(torch.isfinite(obs).all())


_TORCH_ENV: list = []


def _torch_env():
    if not _TORCH_ENV:
        env = gym.make_vec("PneuNetGrasp-v1", num_envs=4, backend="torch")
        env.reset(seed=0)
        _TORCH_ENV.append(env)
    return _TORCH_ENV[0]


@pytest.mark.parametrize("kwargs", [
    {"backend": "torch", "compile": "yes"}, {"backend": "torch", "device": 3.5}, {"backend": "torch", "device": "tpu"},
    {"backend": "numpy", "compile": True}, {"backend": "torch", "num_threads": 2}, {"backend": "jax"},
    {"info_keys": ["pressure_kpa", 3]}, {"num_threads": "two"}, {"fused": 1},
])
def test_backend_arguments_are_checked(kwargs):
    pytest.importorskip("torch")
    with pytest.raises(ValueError):
        gym.make_vec("PneuNetGrasp-v1", num_envs=2, **kwargs)
