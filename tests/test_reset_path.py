"""The single env's reset path (issue 36): one object drawn and built in float arithmetic, the same bits as the batch
path, and the lean reset info built from the state's numbers, equal to ``build_info``'s."""

from __future__ import annotations

import dataclasses
import math
import sys

import gymnasium as gym
import numpy as np
import pytest

import pneunet_env
from pneunet_env import task
from pneunet_env import task_objects as to
from pneunet_env.catalogue import class_table
from pneunet_env.config import load_config
from pneunet_env.objects import GraspObject, object_mass_kg

FIELDS = [f.name for f in dataclasses.fields(GraspObject)]
CONFIGS = {"kitchen": {}, "ranges": {"use_case": None}, "lab_bench": {"use_case": "lab_bench"},
           "paper": dict(pneunet_env.PAPER_TASK), "ranges_ring": {"use_case": None, "shape": "ring"},
           "ranges_cylinder": {"use_case": None, "shape": "cylinder", "object_length_mm": 40.0}}
PINS = [None, {"object_stiffness": 0.3}, {"object_curvature_per_m": 35.0, "object_density_kg_m3": 900.0},
        {"object_shear_modulus_kpa": 20.0, "object_thickness_mm": 3.0}, {"object_curvature": 0.2}]


def _bits(x) -> list[int]:
    return np.asarray(x, dtype=float).ravel().view(np.uint64).tolist()


def _assert_one_is_batch(cfg, u: np.ndarray, pins=None) -> None:
    batch = to.object_from_uniforms(u, cfg, pinned=pins, batch=True)
    singles = [to.object_from_uniforms(u[:, i], cfg, pinned=pins) for i in range(u.shape[1])]
    for f in FIELDS:
        one = [getattr(o, f) for o in singles]
        assert all(type(v) is (int if f == "class_id" else float) for v in one), f
        assert _bits(one) == _bits(getattr(batch, f)), f


@pytest.mark.parametrize("name", list(CONFIGS))
def test_one_object_is_the_batchs_element_bit_for_bit(name):
    """The single env's scalar path (floats, one ufunc call for the log-uniforms) against the vector env's arrays,
    field for field, with and without pins: the same bits (and the fields are Python floats, the class an int)."""
    cfg = load_config(**CONFIGS[name])
    u = np.random.default_rng(7).random((task.draw_count(cfg), 3000))
    _assert_one_is_batch(cfg, u)
    for pins in PINS[1:]:
        _assert_one_is_batch(cfg, u[:, :200], pins)


def test_a_cylinder_class_draws_its_length_alike_in_both_paths(monkeypatch):
    """No packaged use case has a cylinder class: one is made here (two kitchen classes turned cylinders), so the
    scalar path's eighth draw (the length) and its cylinder mass meet the batch path's."""
    cfg = load_config()
    tab = class_table(cfg.objects.class_items)
    n = len(tab.names)
    shape = np.array([i % 2 for i in range(n)], dtype=np.int64)
    length = np.array([[0.0 if s == 0 else 50.0 + 10 * i for i, s in enumerate(shape)],
                       [0.0 if s == 0 else 80.0 + 10 * i for i, s in enumerate(shape)]])
    cylinders = dataclasses.replace(tab, shape=shape, length_mm=length)
    monkeypatch.setattr(to, "class_table", lambda items, catalogue=None: cylinders)  # the scalar path's table
    monkeypatch.setattr(type(cfg.objects), "table", property(lambda self: cylinders))  # the batch path's
    to._scalar_table.cache_clear()
    try:
        assert task.draw_count(cfg) == 8
        u = np.random.default_rng(3).random((8, 2000))
        _assert_one_is_batch(cfg, u)
        _assert_one_is_batch(cfg, u[:, :100], {"object_curvature_per_m": 30.0})
        for i in range(50):
            o = to.object_from_uniforms(u[:, i], cfg)
            lo, hi = length[:, o.class_id]
            r = 1e3 / o.curvature_per_m
            want = object_mass_kg("sphere", r, o.density_kg_m3) if shape[o.class_id] == 0 else \
                object_mass_kg("cylinder", r, o.density_kg_m3, length_mm=lo + (hi - lo) * u[7, i])
            assert o.mass_kg == want
    finally:
        to._scalar_table.cache_clear()


def _numpy_calls(fn) -> set[str]:
    """The numpy functions written in Python that ``fn`` calls (``sys.setprofile``): reductions, broadcasting,
    ``np.vectorize``, ``errstate`` and the like."""
    seen: set[str] = set()

    def prof(frame, event, arg):
        if event == "call" and "/numpy/" in frame.f_code.co_filename.replace("\\", "/"):
            seen.add(frame.f_code.co_name)

    sys.setprofile(prof)
    try:
        fn()
    finally:
        sys.setprofile(None)
    return seen


@pytest.mark.parametrize("name", ["kitchen", "ranges", "ranges_ring"])
def test_one_objects_draw_calls_no_numpy_function_written_in_python(name):
    """A reset's object (the draw, the checks, eq. 3.2, the mass) takes no numpy call but the generator's draw and one
    ``power``: before the scalar path it took about 30 (``np.any``/``np.all`` on scalars, ``broadcast_to``,
    ``errstate``, ``np.vectorize``'s wrapper), most of a 270 us reset."""
    cfg = load_config(**CONFIGS[name])
    rng = np.random.default_rng(0)
    task.sample_object(rng, cfg)  # the class table's cache filled
    assert _numpy_calls(lambda: task.sample_object(rng, cfg)) == set()
    assert _numpy_calls(lambda: GraspObject.from_material(10.0, 5.0, 40.0, 1000.0, 0.3)) == set()
    obj = task.sample_object(rng, cfg)
    assert _numpy_calls(lambda: task.object_thresholds(obj, task.TaskParams.from_config(cfg))) == set()
    assert _numpy_calls(lambda: task.warn_if_beyond_convergence(obj)) == set()


def test_from_material_on_floats_is_its_array_path():
    """``from_material``'s scalar path (Python numbers) and its array path (1-element arrays): the same bits, and the
    same checks: a bad property is named by both."""
    rng = np.random.default_rng(5)
    for _ in range(500):
        args = (rng.uniform(0.1, 1e3), rng.uniform(1.0, 10.0), rng.uniform(20.0, 90.0), rng.uniform(500, 1500),
                rng.uniform(0.05, 0.6))
        one = GraspObject.from_material(*args)
        arr = GraspObject.from_material(*(np.array([a]) for a in args))
        # built without the dataclass's __init__: the same object, its fields in their order, still frozen
        assert one == GraspObject(**dataclasses.asdict(one)) and list(vars(one)) == FIELDS
        with pytest.raises(dataclasses.FrozenInstanceError):
            one.stiffness = 1.0
        for f in FIELDS:
            assert type(getattr(one, f)) is (int if f == "class_id" else float)
            assert _bits(getattr(one, f)) == _bits(getattr(arr, f)), f
    one = GraspObject.from_material(10, 5, 40, mass_kg=0.02)  # ints are numbers too; a given mass is kept
    assert (one.shear_modulus_kpa, one.mass_kg) == (10.0, 0.02) and type(one.thickness_mm) is float
    bad = [(dict(density_kg_m3=-1.0), "density_kg_m3"), (dict(failure_strain=math.nan), "failure_strain"),
           (dict(mass_kg=0.0), "mass_kg"), (dict(curvature_per_m=700.0, thickness_mm=1.0), "w kappa_obj >= pi"),
           (dict(thickness_mm=30.0), "not below its outer radius"), (dict(shear_modulus_kpa=-1.0), "shear_modulus"),
           (dict(shear_modulus_kpa=1e308, failure_strain=10.0), "not a finite number")]
    for change, match in bad:
        kwargs = {"shear_modulus_kpa": 10.0, "thickness_mm": 5.0, "curvature_per_m": 40.0, **change}
        for make in (lambda v: v, lambda v: np.array([v])):
            with pytest.raises(ValueError, match=match):
                GraspObject.from_material(**{k: make(v) for k, v in kwargs.items()})


def test_the_mass_of_one_object_is_the_arrays():
    rng = np.random.default_rng(2)
    r, rho, h, length = (rng.uniform(lo, hi, 300) for lo, hi in ((5, 200), (200, 2000), (0.5, 4), (10, 300)))
    for code, name in enumerate(("sphere", "cylinder", "ring")):
        arr = object_mass_kg(np.full(300, code), r, rho, h, length)
        assert _bits([object_mass_kg(name, *v) for v in zip(r.tolist(), rho.tolist(), h.tolist(),
                                                            length.tolist(), strict=True)]) == _bits(arr)
        assert _bits([object_mass_kg(code, *v) for v in zip(r, rho, h, length, strict=True)]) == _bits(arr)
    with pytest.raises(ValueError):
        object_mass_kg("cube", 10.0, 1000.0)


@pytest.mark.parametrize("name", ["kitchen", "ranges", "paper"])
def test_the_lean_reset_info_is_build_infos(name):
    """The reset info the env builds from the state's numbers: ``build_info``'s keys in its order, its values of its
    types, over many objects, pinned ones included."""
    env = gym.make("PneuNetGrasp-v1", **CONFIGS[name]).unwrapped
    for seed in range(120):
        options = PINS[seed % len(PINS)]
        _, info = env.reset(seed=seed, options=options)
        ref = task.build_info(env.state, env._params.task, None, "lean", env._static_info)
        assert list(info) == list(ref)
        for k, v in ref.items():
            assert type(info[k]) is type(v), k
            assert info[k] == v if isinstance(v, str) else _bits(info[k]) == _bits(v), k
    env.close()


def test_the_solve_at_rest_touches_no_object_so_the_env_solves_it_once():
    """``reset_state``'s solve (from rest at zero pressure to zero pressure) gives the same numbers for every object,
    from none (``k~ = 0``) to the stiffest and from the flattest arc to the most curved: the env keeps the first and
    builds each reset's record from it, the same state as ``task.reset_state`` with the Newton contact."""
    from pneunet_env.physics.solver import step_state

    env = gym.make("PneuNetGrasp-v1").unwrapped
    p = env._params
    rest = step_state(0.0, 0.0, 0.0, 0.0, p.actuator, 1.0, 0.2, p.solver)
    for k in (0.0, 1e-9, 1e-3, 1.0, 1e3, 1e9):
        for c in (1e-6, 1e-3, 0.05, 0.5, 2.0, 3.14):
            assert step_state(0.0, 0.0, 0.0, 0.0, p.actuator, k, c, p.solver) == rest, (k, c)
    for seed in range(100):
        env.reset(seed=seed, options=PINS[seed % len(PINS)])
        want = task.reset_state(env.state.obj, p, task.newton_contact)
        assert _bits(list(env.state.eq)) == _bits(list(want.eq)) and env.state.thresholds == want.thresholds
        assert env.state.task == want.task and env.state.command == want.command
    assert env._rest == rest
    # a contact asked for anything but the rest is the Newton contact itself
    obj = env.state.obj
    assert env._rest_contact(0.0, 0.0, 0.0, 0.3, obj, p) == task.newton_contact(0.0, 0.0, 0.0, 0.3, obj, p)
    env.close()


@pytest.mark.parametrize("name", ["kitchen", "ranges", "paper", "ranges_cylinder"])
def test_one_objects_info_is_object_infos(name):
    """``object_info_one`` (written out, for a single env's reset) against the table's ``object_info``: the same keys
    in the same order, the same values of the same types, over many objects, pinned ones included."""
    cfg = load_config(**CONFIGS[name])
    tp = task.TaskParams.from_config(cfg)
    rng = np.random.default_rng(11)
    for i in range(200):
        obj = task.sample_object(rng, cfg, pinned=PINS[i % len(PINS)])
        th = task.object_thresholds(obj, tp)
        one, ref = pneunet_env.info.object_info_one(obj, th, tp), task.object_info(obj, th, tp)
        assert list(one) == list(ref) == list(task.OBJECT_KEYS)
        for k, v in ref.items():
            assert type(one[k]) is type(v) and _bits(one[k]) == _bits(v), k


class _ReferenceEnv(pneunet_env.PneuNetGraspEnv):
    """The reset by the pure functions alone: ``task.reset_state`` with the Newton contact (the solve at rest solved at
    every reset, not kept), the object's constants from the info table (``task.object_info``)."""

    def _reset_state(self, obj):
        return task.reset_state(obj, self._params, task.newton_contact)

    def _after_reset(self, obj, options):
        super()._after_reset(obj, options)
        name = self._static_info["object_class"]
        self._static_info = {**task.object_info(obj, self._state.thresholds, self._params.task), "object_class": name}


def _types_and_bits(x):
    if isinstance(x, tuple):  # records: field for field
        return tuple(_types_and_bits(v) for v in x)
    if isinstance(x, (float, int, bool, np.floating)):
        return type(x), _bits(x)
    return type(x), x


@pytest.mark.parametrize("name", ["kitchen", "ranges", "paper", "lab_bench", "ranges_ring"])
@pytest.mark.parametrize("volume", [False, True])
def test_the_reset_is_the_pure_functions(name, volume):
    """The single env's reset (its hooks: the solve at rest kept, the object's constants from ``object_info_one``, the
    task state at reset one shared record) against the pure functions (``task.reset_state`` with the Newton contact,
    the info table): the same observation, info, state (every field of every record, its type and its bits) and
    frame label, over seeds and pins; and the episodes that follow alike."""
    kwargs = dict(CONFIGS[name], observe_volume=volume)
    env = gym.make("PneuNetGrasp-v1", **kwargs).unwrapped
    ref = _ReferenceEnv(**kwargs)
    for seed in range(60):
        options = PINS[seed % len(PINS)]
        (o1, i1), (o2, i2) = env.reset(seed=seed, options=options), ref.reset(seed=seed, options=options)
        assert o1.dtype == o2.dtype == np.float32 and _bits(o1) == _bits(o2)
        assert list(i1) == list(i2) and all(_types_and_bits(i1[k]) == _types_and_bits(i2[k]) for k in i1)
        s1, s2 = env.state, ref.state
        assert s1.obj == s2.obj and _types_and_bits(s1.command) == _types_and_bits(s2.command)
        for r1, r2 in ((s1.eq, s2.eq), (s1.thresholds, s2.thresholds), (s1.task, s2.task)):
            assert _types_and_bits(r1) == _types_and_bits(r2)
        assert env._render_name == ref._render_name and list(env._static_info) == list(ref._static_info)
        assert all(_types_and_bits(v) == _types_and_bits(ref._static_info[k]) for k, v in env._static_info.items())
        o1[...] = 0.5  # the observation is the caller's: the next reset's is not changed by it
        for a in (0.7, 0.3, -0.2):
            r1, r2 = env.step(a), ref.step(a)
            assert _bits(r1[0]) == _bits(r2[0]) and r1[1:4] == r2[1:4]
    assert _bits(env.reset(seed=0)[0]) == _bits(ref.reset(seed=0)[0])
    env.close()
    ref.close()


def test_an_env_with_its_own_rest_contact_is_asked_at_every_reset():
    """``_rest_contact`` is a hook of the reset (``_reset_state`` asks it): a subclass's own is asked at every
    reset."""
    calls = []

    class Counting(pneunet_env.PneuNetGraspEnv):
        def _rest_contact(self, *args):
            calls.append(1)
            return super()._rest_contact(*args)

    env = Counting()
    env.reset(seed=0)
    env.reset(seed=1)
    assert len(calls) == 2


def test_the_env_runs_under_numbas_own_disable_jit(tmp_path):
    """``NUMBA_DISABLE_JIT=1`` (numba's switch: ``njit`` gives the Python function back) leaves the env working: the
    single step calls that function, as it calls the compiled one otherwise."""
    import subprocess

    code = ("import gymnasium as gym, numpy as np, pneunet_env\n"
            "env = gym.make('PneuNetGrasp-v1', use_case=None)\n"
            "obs, _ = env.reset(seed=0)\n"
            "obs, *_ = env.step(np.ones(1, np.float32))\n"
            "print(float(obs[0]))\n")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=300,
                         env={**__import__("os").environ, "NUMBA_DISABLE_JIT": "1"}, cwd=tmp_path)
    assert out.returncode == 0, out.stderr[-2000:]
    assert float(out.stdout.split()[-1]) == pytest.approx(3.0 / 60.0, rel=1e-6)


def test_the_task_state_at_reset_of_one_env_is_full_likes():
    """One env's task state at reset is one shared record: the values, and the types, that ``SCALAR.full_like`` gives
    (an int, two bools, a float), as for every other namespace."""
    from pneunet_env.physics.xp import SCALAR

    want = task.TaskState(SCALAR.full_like(None, 0, "int"), SCALAR.full_like(None, False, "bool"),
                          SCALAR.full_like(None, False, "bool"), SCALAR.full_like(None, 0.0, "float"))
    got = task.initial_state()
    assert got is task.initial_state(SCALAR, 1.0)
    assert _types_and_bits(got) == _types_and_bits(want)
