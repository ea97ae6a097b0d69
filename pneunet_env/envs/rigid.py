"""``RigidGrasp-v1``: a rigid, position-controlled gripper faces the objects of ``PneuNetGrasp-v1``, blind.

The comparison the seed paper's introduction makes in words, made measurable: the same objects, the same
damage and slip criteria, the same episode, the same reward; only the hand differs. It is an environment
variant (not a policy on a side model) so that every scripted policy, the best-ramp search and the
evaluation run on it unchanged; it reuses :mod:`pneunet_env.task` for everything but the mechanics.

## The gripper

Two rigid jaws, position-controlled. The command is the jaw closure ``c`` (mm) past the surface of the
*nominal* object (the middle of the catalogue classes' radii; from ranges, of the config's curvature range).
The jaw is an arc of radius ``R_jaw = 1/kappa_nom - c``; the object's surface is at ``1/kappa_obj``, so the
indentation is

    delta = 1/kappa_obj - R_jaw = c + (1/kappa_obj - 1/kappa_nom)      (in contact while delta > 0)

and the traction is the Winkler law of eq. 3.1, ``F = k_obj delta``. The jaw is blind to each object's size: on
the default task (the catalogue's ``kitchen``, radii 15-40 mm) the nominal object is the middle of the classes'
radii, 27.5 mm, so a fixed jaw position indents a large object deeper than a small one (the blind rigid gripper's
real weakness); the pneu-net, which curls until it touches, has no such offset. With one object size (the paper's
ring) ``delta = c`` exactly: the jaws close to a fixed indentation.

There are no dynamics: the jaw is where it is commanded (a stiff position servo, quasi-static like the
pneu-net's step). There is no force limit.

## Action Space

``Box(-1, 1, (1,), float32)``: the closure change in units of ``jaw_step_mm``, then clipped to
``[0, jaw_travel_mm]``: the exact analogue of the pneu-net's pressure change, so
:class:`agents.policies.scripted.LinearRamp`
and :class:`agents.policies.scripted.StepPolicy` drive it unchanged (their targets are then fractions of the travel).

## Observation Space

``Box(0, 1, (1,), float32)``: the closure ``c / jaw_travel_mm`` (proprioception only: blind).

## Default Task

The objects, the rules, the reward and the episode of ``PneuNetGrasp-v1`` (its defaults, ``EnvConfig()``: see its
docstring's Default Task and Catalogue), with the jaw's own (a test checks these against ``RigidGrasp-v1``):

| Default               | Value           | Meaning                                                            |
|-----------------------|-----------------|--------------------------------------------------------------------|
| ``jaw_travel_mm``     | 17.6            | twice the deepest compliant layer drawn (``H`` up to 8.8 mm)       |
| ``jaw_step_mm``       | 0.88            | ``jaw_travel_mm / 20``: full travel in 20 steps                    |
| nominal radius (mm)   | 27.5            | the middle of the classes' radii (``1e3 / nominal_curvature_per_m``) |
| ``damage_rule``       | ``hoop_strain`` | as ``PneuNetGrasp-v1``'s                                           |
| episode steps         | 100             | ``squeeze_steps + hold_steps``                                     |

## Rewards, Starting State, Episode End

Those of ``PneuNetGrasp-v1`` (:mod:`pneunet_env.task`): squeeze phase, then hold phase; damage by the config's
``damage_rule`` (by default ``hoop_strain``: overstressed when the traction exceeds the class's failure stress,
crushed when the hoop strain ``delta kappa_obj`` exceeds its failure strain); slip in the hold phase when friction
on the jaws cannot carry the object's weight (the same hold rule, the jaws as long and as wide as the pneu-net's
fingers, so that only the hand's compliance differs); ``info["is_success"]`` at the end. ``reset(seed=s)`` draws the
same object as ``PneuNetGrasp-v1``'s ``reset(seed=s)`` (the same config); ``reset(options=...)`` pins as there.

## Version History

* v1 (0.14): the hold rule of ``PneuNetGrasp-v1`` (the object's weight in 3D, not a slab of depth ``H``); the v0
  id keeps the slab rule.
* v0 (0.5): the default objects changed with ``PneuNetGrasp-v0``'s (a stiffer apple for the same seed), and again
  in 0.6 (the apple's flesh modulus only).
* v0 (0.3): the default objects became the catalogue's ``kitchen`` under the hoop-strain rule; the nominal object
  is the middle of the classes' radii, the default travel twice their deepest compliant layer.
* v0 (0.1, 0.2): the paper's ring; travel ``2 crush_fraction H``.

## Arguments

``gym.make("RigidGrasp-v1", config=None, jaw_travel_mm=None, jaw_step_mm=None, **overrides)``: ``config`` and
``overrides`` as for ``PneuNetGrasp-v1`` (an :class:`pneunet_env.config.EnvConfig`, a mapping or a YAML path);
``jaw_travel_mm`` defaults to twice the deepest compliant layer of the classes drawn (``2 H_max``; from ranges,
the deepest allowed indentation ``2 crush_fraction H_max``), kept below 90 % of the nominal object's radius;
``jaw_step_mm`` defaults to the same fraction of the travel that ``max_pressure_step_kpa`` is of
``max_pressure_kpa`` (1/20: full travel in 20 steps).

## Info

The keys of ``PneuNetGrasp-v1``'s info (:func:`pneunet_env.task.build_info`, at the same ``info_level``), with the
pressure 0 and the solver's entries those of an exact kinematic answer (converged, no iterations), plus
``jaw_closure_mm``, ``jaw_travel_mm`` and ``gripper = "rigid"``. The curvature is the jaw arc's ``w / R_jaw``.
"""

from __future__ import annotations

import functools
import math
from typing import Any

import numpy as np
from gymnasium import spaces

from pneunet_env import task
from pneunet_env.config import EnvConfig
from pneunet_env.envs.base import SingleGraspEnv
from pneunet_env.physics.params import check_positive
from pneunet_env.physics.solver import STATUS_CONVERGED, Equilibrium

__all__ = ["RigidGraspEnv", "jaw_indentation", "default_jaw_travel_mm", "kinematic_contact", "jaw_task_params"]


def default_jaw_travel_mm(config: EnvConfig) -> float:
    """``2 crush_fraction H_max``, capped at 90 % of the nominal object's radius (mm)."""
    radius_mm = 1e3 / _nominal_curvature_per_m(config)
    if config.objects.from_catalogue:  # twice the deepest compliant layer of the classes drawn
        h_max = float(np.max(config.objects.table.thickness_mm[1]))
        return min(2.0 * h_max, 0.9 * radius_mm)
    return min(2.0 * config.task.crush_fraction * config.objects.object_thickness_mm[1], 0.9 * radius_mm)


def _nominal_curvature_per_m(config: EnvConfig) -> float:
    if config.objects.from_catalogue:  # the middle of the classes' radii: the jaw is blind to each object's size
        r = config.objects.table.radius_mm
        return 2e3 / (float(np.min(r[0])) + float(np.max(r[1])))
    lo, hi = config.objects.object_curvature_per_m
    return 0.5 * (lo + hi)


def jaw_indentation(closure_mm, object_curvature_per_m, nominal_curvature_per_m):
    """The indentation ``delta = c + 1/kappa_obj - 1/kappa_nom`` (mm) of a jaw closed by ``c`` mm; broadcasts.

    Negative means no contact (the jaw stops short of a smaller object).
    """
    return closure_mm + 1e3 / np.asarray(object_curvature_per_m) - 1e3 / nominal_curvature_per_m


def kinematic_contact(kappa, side_strain, p0, closure_mm, obj, params, nominal_curvature_per_m: float) -> Equilibrium:
    """The rigid jaw's contact: nothing to solve. The jaw closed by ``closure_mm`` indents the object by
    :func:`jaw_indentation`; the traction is eq. 3.1's, ``F~ = k~ delta~``. The start state is ignored (a
    position-controlled jaw has no history). A :data:`pneunet_env.task.Contact` for one env."""
    w = params.task.width_mm
    delta_mm = float(jaw_indentation(closure_mm, obj.curvature_per_m, nominal_curvature_per_m))
    in_contact = delta_mm > 0.0 and obj.stiffness > 0.0
    delta = delta_mm / w if in_contact else 0.0
    r_jaw_mm = 1e3 / nominal_curvature_per_m - closure_mm
    return Equilibrium(
        pressure=0.0, curvature=w / r_jaw_mm, side_strain=0.0, top_strain=0.0,
        contact_force=obj.stiffness * delta,  # F~ = k~ delta~ (eq. 3.1)
        indentation=delta, in_contact=in_contact, volume_change=0.0, energy=0.0, gradient_norm=0.0,
        min_eigenvalue=math.inf, converged=True, iterations=0, substeps=0, snapped=False, status=STATUS_CONVERGED,
        object_stiffness=obj.stiffness, object_curvature=obj.curvature,
    )


class RigidGraspEnv(SingleGraspEnv):
    """A rigid, position-controlled gripper grasps the objects of ``PneuNetGrasp-v1`` (see the module docstring).

    The command the task steps (:attr:`pneunet_env.task.EnvState.command`) is the jaw closure in mm: the task's
    command ceiling and step (``TaskParams.pressure_max`` and ``pressure_step``, a pressure's for the pneu-net) hold
    :attr:`jaw_travel_mm` and :attr:`jaw_step_mm` here (:func:`jaw_task_params`).
    """

    env_id = "RigidGrasp-v1"
    metadata = {"render_modes": []}

    def __init__(
        self,
        render_mode: str | None = None,
        config: Any = None,
        jaw_travel_mm: float | None = None,
        jaw_step_mm: float | None = None,
        info_level: str = "lean",
        **overrides: Any,
    ) -> None:
        super().__init__(render_mode, config, info_level, overrides)
        cfg = self.config
        for name, value in (("jaw_travel_mm", jaw_travel_mm), ("jaw_step_mm", jaw_step_mm)):
            if isinstance(value, (bool, np.bool_)):
                raise TypeError(f"{name} must be a length in mm (a number) or None, got {value!r}")
        nominal = _nominal_curvature_per_m(cfg)
        radius_mm = 1e3 / nominal
        travel = (
            default_jaw_travel_mm(cfg) if jaw_travel_mm is None else check_positive("jaw_travel_mm", jaw_travel_mm)
        )
        if travel >= radius_mm:
            raise ValueError(
                f"jaw_travel_mm = {travel!r} reaches the centre of the nominal object (radius {radius_mm:g} mm)"
            )
        tc = cfg.task
        step = travel * tc.max_pressure_step_kpa / tc.max_pressure_kpa if jaw_step_mm is None else jaw_step_mm
        step = check_positive("jaw_step_mm", step)
        if step > travel:
            raise ValueError(f"jaw_step_mm = {step!r} exceeds jaw_travel_mm = {travel!r}")
        self.jaw_travel_mm = float(travel)
        self.jaw_step_mm = float(step)
        self.nominal_curvature_per_m = nominal  # the jaw's arc fits an object of this curvature exactly
        self._params = jaw_task_params(task.EnvParams.from_config(cfg), self.jaw_travel_mm, self.jaw_step_mm)
        self._contact = functools.partial(kinematic_contact, nominal_curvature_per_m=nominal)
        self._class_names = task.class_names(cfg)
        self.observation_space = spaces.Box(0.0, 1.0, (1,), np.float32)

    @property
    def state(self) -> task.EnvState | None:
        """The whole state (:class:`pneunet_env.task.EnvState`); ``command`` is the jaw closure in mm."""
        return self._state

    def _info(self, res: task.Step | None) -> dict[str, Any]:
        info = task.build_info(self._state, self._params.task, res, self.info_level)
        if "object_class" in info:
            info["object_class"] = task.class_name(self._class_names, int(info["object_class"]))
        info.update(jaw_closure_mm=self._state.command, jaw_travel_mm=self.jaw_travel_mm, gripper="rigid")
        return info


def jaw_task_params(params: task.EnvParams, jaw_travel_mm: float, jaw_step_mm: float) -> task.EnvParams:
    """``params`` for a jaw whose closure (mm) is the command: the task's command ceiling and step (the fields
    ``pressure_max`` and ``pressure_step`` of :class:`~pneunet_env.task.TaskParams`, named for the pneu-net's
    pressure) become the jaw's travel and step in mm, so the action moves the closure as it moves the pneu-net's
    pressure: clip the action to ``[-1, 1]``, step by ``jaw_step_mm``, clip to ``[0, jaw_travel_mm]``. No volume is
    observed (``volume_scale=None``). Everything else is ``PneuNetGrasp-v1``'s."""
    jaw_task = params.task._replace(pressure_max=jaw_travel_mm, pressure_step=jaw_step_mm)
    return params._replace(task=jaw_task, volume_scale=None, free_table=None)
