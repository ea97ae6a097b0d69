"""The task's pure functions: thresholds, pressure update, rules, reward; scalars and arrays agree."""

from __future__ import annotations

import dataclasses
import math
import re

import numpy as np
import pytest

from pneunet_env import PAPER_TASK, task
from pneunet_env.config import EnvConfig, TaskConfig, load_config
from pneunet_env.objects import GraspObject, stiffness_per_modulus
from pneunet_env.physics._jit import HAVE_NUMBA
from pneunet_env.physics.solver import Equilibrium
from pneunet_env.physics.units import PAPER_MODULUS_PER_STIFFNESS_PA, object_stiffness_from_material
from pneunet_env.physics.xp import NUMPY

CFG = load_config(**PAPER_TASK)  # ranges and the crush-fraction rule: the paper's task
TP = task.TaskParams.from_config(CFG)  # one env: Python scalars
TP_NP = task.TaskParams.from_config(CFG, NUMPY)  # a batch: numpy arrays


# ---- the object -------------------------------------------------------------------------------------


def test_object_stiffness_is_eq_3_2():
    obj = GraspObject.from_material(15.0, 10.0, 4.0)
    assert obj.stiffness == object_stiffness_from_material(15.0, 10.0, 4.0)
    assert obj.curvature == pytest.approx(0.02)
    assert obj.thickness == pytest.approx(2.0)
    # eq. 3.3: mu_obj ~ 1.47e7 k~ Pa at the paper's object
    assert 1e3 * obj.shear_modulus_kpa / obj.stiffness == pytest.approx(PAPER_MODULUS_PER_STIFFNESS_PA)
    assert PAPER_MODULUS_PER_STIFFNESS_PA == pytest.approx(1.47e7, rel=0.01)


def test_object_from_stiffness_keeps_k_exactly_and_inverts_eq_3_2():
    obj = GraspObject.from_stiffness(1e-4, 10.0, 4.0)
    assert obj.stiffness == 1e-4
    assert obj.shear_modulus_kpa * stiffness_per_modulus(10.0, 4.0) == pytest.approx(1e-4, rel=1e-14)


def test_object_batch_equals_scalars():
    mus = np.array([0.2, 3.0, 400.0])
    hs = np.array([5.0, 10.0, 20.0])
    batch = GraspObject.from_material(mus, hs, 4.0, 1000.0, 0.3)
    for i in range(3):
        one = GraspObject.from_material(mus[i], hs[i], 4.0, 1000.0, 0.3)
        assert batch.stiffness[i] == one.stiffness
        assert batch.thickness[i] == one.thickness
        assert batch.curvature[i] == one.curvature


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        (dict(shear_modulus_kpa=-1.0, thickness_mm=10.0, curvature_per_m=4.0), "shear_modulus_kpa"),
        (dict(shear_modulus_kpa=1.0, thickness_mm=300.0, curvature_per_m=4.0), "thickness"),
        (dict(shear_modulus_kpa=1.0, thickness_mm=10.0, curvature_per_m=4.0, density_kg_m3=0.0), "density"),
        (dict(shear_modulus_kpa=1.0, thickness_mm=10.0, curvature_per_m=4.0, failure_strain=np.nan), "failure"),
        (dict(shear_modulus_kpa=1.0, thickness_mm=1.0, curvature_per_m=700.0), "pi"),
    ],
)
def test_invalid_objects_are_named(kwargs, match):
    with pytest.raises(ValueError, match=match):
        GraspObject.from_material(**kwargs)


def test_thresholds_in_physical_units():
    obj = GraspObject.from_material(10.0, 10.0, 4.0, density_kg_m3=1000.0, failure_strain=0.3)
    thr = task.object_thresholds(obj, TP._replace(hold_rule="slab"))
    mu = CFG.actuator.shear_modulus_kpa
    assert thr.failure_traction * mu == pytest.approx(3 * 0.3 * 10.0)  # kPa: eps_f E_obj
    assert thr.crush_indentation * CFG.actuator.width_mm == pytest.approx(10.0)  # mm: H
    # the slab rule (PneuNetGrasp-v1): rho g H / (2 mu_f) = 1000 * 9.81 * 0.01 / (2 * 0.5) Pa = 98.1 Pa
    assert thr.grip_traction * mu * 1e3 == pytest.approx(98.1)


def test_sample_object_is_deterministic_and_within_ranges():
    cfg = load_config(object_thickness_mm=[5.0, 15.0], object_density_kg_m3=[30.0, 1100.0], **PAPER_TASK)
    a = task.sample_object(np.random.default_rng(3), cfg)
    b = task.sample_object(np.random.default_rng(3), cfg)
    assert a == b
    batch = task.sample_object(np.random.default_rng(4), cfg, size=500)
    for name, field in [("object_shear_modulus_kpa", "shear_modulus_kpa"), ("object_thickness_mm", "thickness_mm"),
                        ("object_density_kg_m3", "density_kg_m3")]:
        lo, hi = getattr(cfg.objects, name)
        v = getattr(batch, field)
        assert v.shape == (500,) and np.all(v >= lo) and np.all(v <= hi)
    # log-uniform modulus: about half the draws below the geometric mean
    gm = math.sqrt(cfg.objects.object_shear_modulus_kpa[0] * cfg.objects.object_shear_modulus_kpa[1])
    assert 0.4 < np.mean(batch.shear_modulus_kpa < gm) < 0.6


def test_fixed_ranges_give_exactly_the_value():
    obj = task.sample_object(np.random.default_rng(0), CFG)
    assert (obj.thickness_mm, obj.curvature_per_m, obj.density_kg_m3, obj.failure_strain) == (10.0, 4.0, 1000.0, 0.3)


def test_pins_override_without_changing_the_other_draws():
    cfg = load_config(object_thickness_mm=[5.0, 15.0], **PAPER_TASK)
    free = task.sample_object(np.random.default_rng(7), cfg)
    pinned = task.sample_object(np.random.default_rng(7), cfg, pinned={"object_shear_modulus_kpa": 2.0})
    assert pinned.shear_modulus_kpa == 2.0 and pinned.thickness_mm == free.thickness_mm
    k = task.sample_object(np.random.default_rng(7), cfg, pinned={"object_stiffness": 1e-3, "object_curvature": 0.03})
    assert k.stiffness == 1e-3 and k.curvature == pytest.approx(0.03) and k.thickness_mm == free.thickness_mm
    none = task.sample_object(np.random.default_rng(7), cfg, pinned={"object_stiffness": None})
    assert none == free


@pytest.mark.parametrize(
    ("pins", "match"),
    [
        ({"stiffness": 1e-3}, "unknown reset option"),
        ({"object_stiffness": 1e-3, "object_shear_modulus_kpa": 1.0}, "conflict"),
        ({"object_curvature": 0.02, "object_curvature_per_m": 4.0}, "conflict"),
        ({"object_stiffness": -1.0}, "object_stiffness"),
        ({"object_stiffness": float("nan")}, "object_stiffness"),
        ({"object_thickness_mm": "x"}, "object_thickness_mm"),
        ({"object_thickness_mm": 500.0}, "thickness"),
        # finite, but the failure stress 3 eps_f mu_obj (or k~) overflows: refused, not an object that never breaks
        ({"object_shear_modulus_kpa": 1e10, "object_failure_strain": 1e300}, "object_failure_strain=1e\\+300.* not a "
         "finite number"),
        ({"object_shear_modulus_kpa": 1e308}, "object_shear_modulus_kpa=1e\\+308.* not a finite number"),
    ],
)
def test_bad_pins_are_named(pins, match):
    with pytest.raises(ValueError, match=match):
        task.sample_object(np.random.default_rng(0), CFG, pinned=pins)


@pytest.mark.parametrize("pins", [{"object_shear_modulus_kpa": 1e10, "object_failure_strain": 1e300},
                                  {"object_shear_modulus_kpa": 1e308}, {"object_stiffness": 1e306}])
def test_a_batch_refuses_what_one_object_refuses(pins):
    # the vector env's objects (a batch) get the same overflow check as the single env's
    with pytest.raises(ValueError, match="not a finite number|must be finite"):
        task.sample_object(np.random.default_rng(0), CFG, pinned=pins)
    with pytest.raises(ValueError, match="not a finite number"):
        task.sample_object(np.random.default_rng(0), CFG, size=3, pinned=pins)


# ---- action -> pressure ---------------------------------------------------------------------------------


def test_update_pressure_scales_clips_and_reports():
    p, c = task.update_pressure(0.5, 0.5, TP)
    assert p == pytest.approx(0.5 + 0.5 * TP.pressure_step) and not c
    p, c = task.update_pressure(0.5, 3.0, TP)
    assert p == pytest.approx(0.5 + TP.pressure_step) and c
    p, c = task.update_pressure(0.01, -1.0, TP)
    assert p == 0.0 and not c
    p, c = task.update_pressure(TP.pressure_max, 1.0, TP)
    assert p == TP.pressure_max and not c


@pytest.mark.parametrize("bad", [float("nan"), float("inf"), -float("inf"), "a"])
def test_update_pressure_raises_on_non_finite(bad):
    with pytest.raises(ValueError, match="action"):
        task.update_pressure(0.0, bad, TP)


def test_update_pressure_batch_equals_scalars():
    rng = np.random.default_rng(0)
    p = rng.uniform(0, TP.pressure_max, 200)
    a = rng.uniform(-2, 2, 200)
    pb, cb = task.update_pressure(p, a, TP_NP)
    for i in range(200):
        ps, cs = task.update_pressure(p[i], a[i], TP)
        assert pb[i] == ps and cb[i] == cs
    with pytest.raises(ValueError, match="finite"):
        task.update_pressure(p, np.where(np.arange(200) == 7, np.nan, a), TP_NP)


# ---- rules and reward ------------------------------------------------------------------------------------

THR = task.Thresholds(failure_traction=0.5, crush_indentation=2.0, grip_traction=2e-3)


def _run(forces, indentations=None, params=TP, failed=None):
    """Apply transition along a sequence of (F, delta); return the outcomes."""
    st = task.initial_state()
    outs = []
    for i, F in enumerate(forces):
        d = 0.0 if indentations is None else indentations[i]
        out = task.transition(st, task.Touch(F, d, F > 0 or d > 0), THR, bool(failed and failed[i]), params)
        st = out.state
        outs.append(out)
        if out.terminated or out.truncated:
            break
    return outs


def test_a_held_grasp_earns_the_hold_reward_and_the_success_bonus():
    outs = _run([5e-3] * TP.episode_steps)
    assert len(outs) == TP.episode_steps
    assert not any(o.terminated for o in outs)
    assert outs[-1].truncated and outs[-1].success
    assert [o.in_hold for o in outs] == [t >= TP.squeeze_steps for t in range(TP.episode_steps)]
    total = sum(o.reward for o in outs)
    assert total == pytest.approx(TP.hold_steps * TP.reward_hold + TP.reward_success)


def test_damage_is_penalised_and_terminates():
    outs = _run([1e-3, 1e-2, 0.6, 1e-2])  # overstressed on the third step
    assert len(outs) == 3 and outs[-1].terminated and not outs[-1].truncated
    assert outs[-1].overstressed and outs[-1].damage_event and outs[-1].state.damaged
    assert outs[-1].reward == -TP.penalty_damage and not outs[-1].success
    outs = _run([1e-3, 1e-2], indentations=[1.0, 2.5])  # crushed through
    assert outs[-1].crushed and outs[-1].terminated and outs[-1].reward == -TP.penalty_damage


def test_indentation_without_contact_is_not_damage():
    st = task.initial_state()
    out = task.transition(st, task.Touch(0.0, 10.0, False), THR, False, TP)
    assert not out.crushed and not out.terminated


def test_slip_only_counts_in_the_hold_phase():
    outs = _run([1e-3] * TP.episode_steps)  # below the grip traction throughout
    assert not any(o.slipping for o in outs[:-1])
    assert len(outs) == TP.squeeze_steps + 1
    last = outs[-1]
    assert last.in_hold and last.slipping and last.drop_event and last.terminated
    assert last.reward == -TP.penalty_slip
    assert sum(o.reward for o in outs) == -TP.penalty_slip


def test_without_termination_events_are_penalised_once_and_success_is_lost():
    params = TP._replace(terminate_on_damage=False, terminate_on_slip=False)
    forces = [1e-2] * 10 + [0.6] + [1e-2] * (TP.squeeze_steps - 11) + [1e-3] * TP.hold_steps
    outs = _run(forces, params=params)
    assert len(outs) == TP.episode_steps and outs[-1].truncated and not outs[-1].success
    rewards = np.array([o.reward for o in outs])
    assert rewards.sum() == pytest.approx(-TP.penalty_damage - TP.penalty_slip)
    assert sum(o.damage_event for o in outs) == 1 and sum(o.drop_event for o in outs) == 1
    assert all(o.state.damaged for o in outs[10:])


def test_a_failed_solve_truncates_without_success():
    outs = _run([5e-3] * 5, failed=[False, False, True, False, False])
    assert len(outs) == 3 and outs[-1].truncated and not outs[-1].terminated and not outs[-1].success


def test_transition_batch_equals_scalars():
    rng = np.random.default_rng(1)
    n = 300
    F = 10 ** rng.uniform(-5, 0, n)
    d = rng.uniform(0, 3, n)
    contact = rng.random(n) < 0.8
    failed = rng.random(n) < 0.05
    thr = task.Thresholds(10 ** rng.uniform(-2, 0, n), rng.uniform(0.5, 3, n), 10 ** rng.uniform(-4, -2, n))
    st = task.TaskState(rng.integers(0, TP.episode_steps, n), rng.random(n) < 0.1, rng.random(n) < 0.1,
                        rng.uniform(0, 1e-2, n))
    batch = task.transition(st, task.Touch(F, d, contact), thr, failed, TP_NP)
    for i in range(n):
        one = task.transition(
            task.TaskState(int(st.step[i]), bool(st.damaged[i]), bool(st.dropped[i]), float(st.peak_force[i])),
            task.Touch(float(F[i]), float(d[i]), bool(contact[i])),
            task.Thresholds(*(float(x[i]) for x in thr)), bool(failed[i]), TP,
        )
        for name in task.Outcome._fields:
            if name == "state":
                for a, b in zip(batch.state, one.state, strict=True):
                    assert a[i] == b
            else:
                assert getattr(batch, name)[i] == getattr(one, name), name


def test_observation_shapes_and_freshness():
    o = task.observation(0.6, 3.0, TP)
    assert o.shape == (1,) and o.dtype == np.float32 and o[0] == pytest.approx(0.5)
    o2 = task.observation(np.array([0.6, 1.2]), np.array([3.0, 6.0]), TP_NP, volume_scale=6.0)
    assert o2.shape == (2, 2) and o2.dtype == np.float32
    np.testing.assert_allclose(o2, [[0.5, 0.5], [1.0, 1.0]])
    assert task.observation(0.6, 3.0, TP) is not o


@pytest.mark.parametrize("level", task.INFO_LEVELS)
def test_build_info_batch_equals_scalars(level):
    rng = np.random.default_rng(2)
    n = 20
    obj = GraspObject.from_material(rng.uniform(0.1, 100, n), 10.0, 4.0)
    eq = Equilibrium(
        pressure=rng.uniform(0, 1.2, n), curvature=rng.uniform(0, 0.5, n), side_strain=rng.uniform(0, 0.5, n),
        top_strain=rng.uniform(0, 0.5, n), contact_force=rng.uniform(0, 1e-2, n), indentation=rng.uniform(0, 3, n),
        in_contact=rng.random(n) < 0.5, volume_change=rng.uniform(0, 10, n), energy=rng.uniform(-1, 0, n),
        gradient_norm=rng.uniform(0, 1e-12, n), min_eigenvalue=rng.uniform(1, 2, n), converged=np.ones(n, bool),
        iterations=rng.integers(0, 10, n), substeps=rng.integers(0, 10, n), snapped=rng.random(n) < 0.5,
        status=np.zeros(n, np.int64), object_stiffness=obj.stiffness, object_curvature=obj.curvature,
        evaluations=rng.integers(0, 10, n), backtracks=rng.integers(0, 3, n),
    )
    thr = task.object_thresholds(obj, TP)
    state = task.EnvState(eq.pressure, eq, obj, thr, task.initial_state(NUMPY, eq.pressure))
    info = task.build_info(state, TP_NP, None, level)
    for i in range(n):
        eqi = Equilibrium(*(v[i].item() for v in eq))
        obji = GraspObject.from_material(obj.shear_modulus_kpa[i], 10.0, 4.0)
        thri = task.object_thresholds(obji, TP)
        one = task.build_info(task.EnvState(eqi.pressure, eqi, obji, thri, task.initial_state()), TP, None, level)
        assert set(one) == set(info)
        for key, value in one.items():
            assert np.ravel(info[key])[i if np.ndim(info[key]) else 0] == pytest.approx(value), key
    assert np.all(info["indentation_mm"][~eq.in_contact] == 0.0)


# ---- one array path, records, a new reward term ------------------------------------------------------------------


def test_the_step_has_one_path_on_every_namespace():
    """No function of the step tests the type of its input: the namespace is the params' (``TaskParams.ops``)."""
    import inspect

    from pneunet_env import actions, info

    forbidden = (r"\bis_torch\b", r"\bops_for\b", r"np\.ndarray", r"np\.ndim", r"np\.bool_", r"(?<!\.)\bto_host\(")
    sources = {"task": inspect.getsource(task), "info": inspect.getsource(info),
               "update_pressure": inspect.getsource(actions.update_pressure)}
    for name, src in sources.items():
        assert not [w for w in forbidden if re.search(w, src)], name
    assert task.EnvParams.from_config(CFG).ops.name == "scalar"
    assert task.EnvParams.from_config(CFG, NUMPY).task.ops is NUMPY


def test_task_params_hold_every_field_of_the_task_section():
    """Every config field reaches the params (and the rules) by name; the damage rule is the config's."""
    for f in dataclasses.fields(TaskConfig):
        assert getattr(TP, f.name) == getattr(CFG.task, f.name), f.name
    assert task.TaskParams.from_config(EnvConfig()).damage_rule == TaskConfig().damage_rule
    assert TP.episode_steps == CFG.task.squeeze_steps + CFG.task.hold_steps


@dataclasses.dataclass(frozen=True)
class _TaskWithContactBonus(TaskConfig):
    """The config's task section with one more field: a test-only reward term."""

    reward_contact: float = 0.25


_BONUS_LINE = "        reward = reward + params.reward_contact * number(eq.in_contact)\n"


def _make_rules_with_contact_bonus():
    """:func:`pneunet_env.task.make_rules` with one line more: its source, edited as a developer would edit it."""
    import inspect

    src = inspect.getsource(task.make_rules)
    anchor = "        return Outcome("
    assert src.count(anchor) == 1
    namespace = dict(vars(task))
    exec(compile(src.replace(anchor, _BONUS_LINE + anchor), "<make_rules with a contact bonus>", "exec"), namespace)
    return namespace["make_rules"]


def _bonus_configs():
    base = dict(squeeze_steps=4, hold_steps=4, max_pressure_step_kpa=20.0)
    return EnvConfig(task=TaskConfig(**base)), EnvConfig(task=_TaskWithContactBonus(**base))


def _rollouts(make_env, cfg, n_steps=12):
    env = make_env(cfg)
    env.reset(seed=5)
    rng = np.random.default_rng(5)
    out = []
    for _ in range(n_steps):
        a = rng.uniform(-0.3, 1.2, env.action_space.shape).astype(np.float32)
        obs, reward, terminated, truncated, info = env.step(a)
        out.append((np.asarray(obs), np.asarray(reward, float), np.asarray(info["in_contact"]),
                    np.asarray(terminated | truncated)))
        if not np.ndim(terminated) and (terminated or truncated):
            env.reset()
    return out


def _assert_only_the_reward_moved(plain, bonus, weight):
    touched = 0
    for (o0, r0, c0, d0), (o1, r1, c1, d1) in zip(plain, bonus, strict=True):
        assert np.array_equal(o0, o1) and np.array_equal(c0, c1) and np.array_equal(d0, d1)
        np.testing.assert_array_equal(r1, r0 + weight * c0)
        touched += int(np.sum(c0))
    assert touched > 0  # the term was in play


@pytest.mark.parametrize("kind", ["single", "vector"])
def test_a_new_reward_term_is_a_config_field_and_a_line_in_rules(kind, monkeypatch):
    """Adding a reward term: a field of the task section (here a subclass stands in for a new ``TaskConfig`` field)
    and one line in ``rules`` (inserted in ``make_rules``' source). Nothing else is edited, and the envs' rewards carry
    the term, on one env (Python scalars) and on a batch (numpy arrays: the array step, around numba's batched solve
    when numba is installed)."""
    import gymnasium as gym

    from pneunet_env.envs.grasp_vector import PneuNetGraspVectorEnv

    def make(cfg):
        if kind == "single":  # task.step on Python scalars (the compiled single step: the slow test below)
            env = gym.make("PneuNetGrasp-v1", config=cfg)
            env.unwrapped._single = None
            return env
        return PneuNetGraspVectorEnv(3, config=cfg, backend="numba" if HAVE_NUMBA else "numpy", fused=False,
                                     autoreset_mode="NextStep")

    plain_cfg, bonus_cfg = _bonus_configs()
    plain = _rollouts(make, plain_cfg)
    monkeypatch.setattr(task, "make_rules", _make_rules_with_contact_bonus())
    monkeypatch.setattr(task, "_RULES", {})  # rules_for builds the rules again, from the edited make_rules
    with pytest.raises(AttributeError, match="reward_contact"):  # the line needs the field ...
        _rollouts(make, plain_cfg, 1)
    bonus = _rollouts(make, bonus_cfg)  # ... and with it, nothing else
    assert task.TaskParams.from_config(bonus_cfg).reward_contact == 0.25
    _assert_only_the_reward_moved(plain, bonus, 0.25)


@pytest.mark.slow
@pytest.mark.skipif(not HAVE_NUMBA, reason="the fused step needs numba")
def test_a_new_reward_term_reaches_the_fused_numba_step(monkeypatch):
    """The same edit, on the fused numba step and the single env's compiled step: compiled again (numba reads the
    rules when it compiles)."""
    import gymnasium as gym
    import numba

    from pneunet_env import fused
    from pneunet_env.envs.grasp_vector import PneuNetGraspVectorEnv
    from pneunet_env.physics import xp

    def vector(cfg):
        return PneuNetGraspVectorEnv(3, config=cfg, backend="numba", parallel=False, autoreset_mode="NextStep")

    def single(cfg):
        env = gym.make("PneuNetGrasp-v1", config=cfg)
        assert env.unwrapped._single is not None
        return env

    plain_cfg, bonus_cfg = _bonus_configs()
    plain = {make: _rollouts(make, plain_cfg) for make in (vector, single)}
    make_rules = _make_rules_with_contact_bonus()
    monkeypatch.setattr(fused, "_rules", make_rules(numba.njit(fused._flag_value), numba.njit(xp.scalar_max),
                                                    jit=numba.njit))
    monkeypatch.setattr(fused, "_loop_serial", numba.njit(fused._make_loop(0, 0)))
    monkeypatch.setattr(fused, "_SINGLES", {})  # the bonus config's params type: its single step compiled anew
    for make in (vector, single):
        _assert_only_the_reward_moved(plain[make], _rollouts(make, bonus_cfg), 0.25)
