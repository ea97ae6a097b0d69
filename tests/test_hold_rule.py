"""The hold rule (``hold_rule: weight``): the object's weight in 3D against friction on the fingers, checked against
hand calculations, in the env and in the thresholds; its parameters' bad values; the v0 ids' slab rule."""

from __future__ import annotations

import math

import gymnasium as gym
import numpy as np
import pytest

import pneunet_env  # noqa: F401  (registers the ids)
from pneunet_env import PAPER_TASK, load_config, task
from pneunet_env.catalogue import _object_class
from pneunet_env.objects import GraspObject, object_mass_kg

RANGES = {"use_case": None, "class_weights": None}
G = 9.81


def _grip_pa(mass_g, contact_mm, width_mm=10.0, faces=2, mu_f=0.5):
    """The traction (Pa) at which friction on ``faces`` fingers carries the weight: m g / (faces mu_f L_c b)."""
    return mass_g * 1e-3 * G / (faces * mu_f * contact_mm * 1e-3 * width_mm * 1e-3)


# Three objects, by hand (docs/env.md, "The hold rule"): the masses and contact lengths written out.
LIGHT = dict(radius_mm=15.0, density=1000.0, mass_g=4 / 3 * math.pi * 1.5 ** 3, contact_mm=math.pi * 15.0)  # 14.14 g
HEAVY = dict(radius_mm=40.0, density=850.0, mass_g=4 / 3 * math.pi * 4.0 ** 3 * 0.85, contact_mm=90.0)  # 227.9 g


@pytest.mark.parametrize("case, expected_pa", [(LIGHT, 294.3), (HEAVY, 2483.8)])
def test_the_grip_traction_is_the_hand_calculation(case, expected_pa):
    assert _grip_pa(case["mass_g"], case["contact_mm"]) == pytest.approx(expected_pa, rel=1e-4)
    cfg = load_config(**RANGES)
    obj = GraspObject.from_material(10.0, 5.0, 1e3 / case["radius_mm"], density_kg_m3=case["density"])
    assert obj.mass_kg * 1e3 == pytest.approx(case["mass_g"], rel=1e-12)
    params = task.TaskParams.from_config(cfg)
    assert task.contact_length_mm(obj, params) == pytest.approx(case["contact_mm"], rel=1e-12)
    grip_kpa = task.object_thresholds(obj, params).grip_traction * cfg.actuator.shear_modulus_kpa
    assert grip_kpa * 1e3 == pytest.approx(expected_pa, rel=1e-4)


def test_the_papers_ring_weighs_an_annulus_as_tall_as_the_finger():
    env = gym.make("PneuNetGrasp-v1", **{**PAPER_TASK, "hold_rule": "weight"})
    _, info = env.reset(seed=0)
    ring_g = math.pi * (25.0 ** 2 - 24.0 ** 2) * 1.0 * 1.0  # cm: R 25, R - H 24, height b = 1 cm, 1 g/cm^3
    assert info["object_mass_g"] == pytest.approx(ring_g, rel=1e-12)  # 153.9 g
    assert info["contact_length_mm"] == 90.0
    assert info["grip_traction_kpa"] * 1e3 == pytest.approx(_grip_pa(ring_g, 90.0), rel=1e-12)


def test_a_soft_object_slips_exactly_where_friction_cannot_carry_its_weight():
    """Every hold-phase step of a ramp on a heavy, soft object: ``slipping`` is the hand calculation's
    ``2 mu_f F L_c b < m g`` on the info's own numbers; a soft one (its traction saturates) slips at full pressure."""
    env = gym.make("PneuNetGrasp-v1", info_level="full", terminate_on_slip=False, terminate_on_damage=False, **RANGES)
    _, info = env.reset(seed=1, options={"object_shear_modulus_kpa": 0.5, "object_curvature_per_m": 25.0,
                                         "object_thickness_mm": 10.0, "object_density_kg_m3": 1000.0})
    weight_n = info["object_mass_g"] * 1e-3 * G
    assert info["object_mass_g"] == pytest.approx(4 / 3 * math.pi * 4.0 ** 3, rel=1e-12)  # a 40 mm ball of water
    seen = 0
    for _ in range(env.unwrapped.config.episode_steps):
        _, _, _, truncated, info = env.step(np.array([1.0], np.float32))
        if info["in_hold"]:
            force_n = 2 * 0.5 * info["contact_force_kpa"] * 1e3 * info["contact_length_mm"] * 1e-3 * 10e-3
            assert info["grip_force_n"] == pytest.approx(force_n, rel=1e-12)
            assert info["slipping"] == (force_n < weight_n)
            seen += 1
        if truncated:
            break
    assert seen == env.unwrapped.config.task.hold_steps
    assert info["slipping"] and info["grip_force_n"] < 0.5 * weight_n  # the force-controlled regime cannot lift it


def test_mass_by_shape():
    assert object_mass_kg("sphere", 10.0, 1000.0) == pytest.approx(4 / 3 * math.pi * 1e-6 * 1000.0)
    assert object_mass_kg("cylinder", 10.0, 1000.0, length_mm=50.0) == pytest.approx(math.pi * 1e-4 * 0.05 * 1000.0)
    assert object_mass_kg("ring", 10.0, 1000.0, 2.0, 50.0) == pytest.approx(math.pi * (1e-4 - 0.64e-4) * 0.05 * 1e3)
    codes = np.array([0, 1, 2])
    assert np.allclose(object_mass_kg(codes, 10.0, 1000.0, 2.0, 50.0),
                       [object_mass_kg(s, 10.0, 1000.0, 2.0, 50.0) for s in ("sphere", "cylinder", "ring")])


def test_the_v0_ids_keep_the_slab_rule_and_v1_carries_the_weight():
    for v0, v1 in [("PneuNetGrasp-v0", "PneuNetGrasp-v1"), ("RigidGrasp-v0", "RigidGrasp-v1")]:
        with pytest.warns(DeprecationWarning, match="out of date"):
            old = gym.make(v0)
        _, i0 = old.reset(seed=3)
        _, i1 = gym.make(v1).reset(seed=3)
        assert i0["object_shear_modulus_kpa"] == i1["object_shear_modulus_kpa"]  # the same object
        slab_pa = i0["object_density_kg_m3"] * G * i0["object_thickness_mm"] * 1e-3 / (2 * 0.5)
        assert i0["grip_traction_kpa"] * 1e3 == pytest.approx(slab_pa, rel=1e-12)
        assert i1["grip_traction_kpa"] * 1e3 == pytest.approx(
            _grip_pa(i1["object_mass_g"], i1["contact_length_mm"]), rel=1e-12)


@pytest.mark.parametrize("overrides, match", [
    (dict(hold_rule="weights"), "'hold_rule' must be one of"),
    (dict(hold_rule=1), "'hold_rule'"),
    (dict(length_mm=0.0), "length_mm"),
    (dict(length_mm=float("nan")), "length_mm"),
    (dict(shape="cube", **RANGES), "'shape' must be one of"),
    (dict(object_length_mm=-1.0, shape="cylinder", **RANGES), "'object_length_mm' must be a finite number > 0"),
    (dict(object_length_mm=float("inf"), shape="ring", **RANGES), "'object_length_mm'"),
    (dict(object_length_mm=20.0, **RANGES), "a sphere has none"),
    (dict(object_length_mm="long", shape="ring", **RANGES), "object_length_mm"),
])
def test_bad_hold_rule_values_are_named(overrides, match):
    with pytest.raises((ValueError, TypeError), match=match):
        load_config(**overrides)


def test_a_cylinder_class_needs_its_length_and_a_sphere_has_none():
    entry = {"description": "d", "youngs_modulus_kpa": [1, 2], "density_kg_m3": [900, 1000],
             "failure_strain": [0.1, 0.2], "failure_stress_kpa": [1, 2], "radius_mm": [10, 20],
             "thickness_mm": [2, 4], "in_annulus_model": True, "reason": "r", "sources": ["s"]}
    assert _object_class("ball", entry).shape == "sphere"
    with pytest.raises(ValueError, match="'length_mm' is missing"):
        _object_class("roll", {**entry, "shape": "cylinder"})
    assert _object_class("roll", {**entry, "shape": "cylinder", "length_mm": [50, 80]}).length_mm == (50.0, 80.0)
    with pytest.raises(ValueError, match="'length_mm' belongs to a cylinder"):
        _object_class("ball", {**entry, "length_mm": [50, 80]})
    with pytest.raises(ValueError, match="'shape' must be 'sphere' or 'cylinder'"):
        _object_class("cube", {**entry, "shape": "block"})


def test_no_pressure_lifts_the_papers_ring_by_its_weight_so_the_paper_task_keeps_the_slab_rule():
    """The finding behind ``PAPER_TASK``'s ``hold_rule: slab``: under the weight rule the oracle finds no pressure up
    to ``p_max`` that holds the 250 mm ring, however stiff (the grip ratio stays below 0.2); the paper's task keeps
    its id and the slab rule, under which the stiff rings are held."""
    from agents.policies.oracle import plan_target

    assert PAPER_TASK["shape"] == "ring" and PAPER_TASK["hold_rule"] == "slab"
    for rule, held in (("weight", False), ("slab", True)):
        cfg = load_config(**{**PAPER_TASK, "hold_rule": rule})
        obj = task.sample_object(np.random.default_rng(0), cfg, pinned={"object_stiffness": 0.05})
        thr = task.object_thresholds(obj, task.TaskParams.from_config(cfg))
        plan = plan_target(0.05, obj.curvature, thr.failure_traction, thr.crush_indentation, thr.grip_traction, cfg)
        assert plan["feasible"] is held
        if not held:
            assert plan["grip_ratio"] < 0.2
    _, info = gym.make("PneuNetGrasp-Paper-v0").reset(seed=0)
    assert info["grip_traction_kpa"] * 1e3 == pytest.approx(1000 * G * 0.010 / (2 * 0.5), rel=1e-12)  # 98.1 Pa
