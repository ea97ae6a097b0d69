"""``RigidGrasp-v0``: a rigid, position-controlled gripper faces the objects of ``PneuNetGrasp-v0``, blind.

The comparison the seed paper's introduction makes in words, made measurable: the same objects, the same
damage and slip criteria, the same episode, the same reward; only the hand differs. It is an environment
variant (not a policy on a side model) so that every scripted policy, the best-ramp search and the
evaluation run on it unchanged; it reuses :mod:`pneunet_env.task` for everything but the mechanics.

## The gripper

Two rigid jaws, position-controlled. The command is the jaw closure ``c`` (mm) past the surface of the
*nominal* object (the middle of the config's curvature range). The jaw is an arc of radius
``R_jaw = 1/kappa_nom - c``; the object's surface is at ``1/kappa_obj``, so the indentation is

    delta = 1/kappa_obj - R_jaw = c + (1/kappa_obj - 1/kappa_nom)      (in contact while delta > 0)

and the traction is the Winkler law of eq. 3.1, ``F = k_obj delta``. With the default config (one object
size) ``delta = c`` exactly: the jaws close to a fixed indentation, as the issue asks. If the config's
curvature range is wide, a fixed jaw position meets objects of different sizes (the blind rigid
gripper's real weakness); the pneu-net, which curls until it touches, has no such offset.

There are no dynamics: the jaw is where it is commanded (a stiff position servo, quasi-static like the
pneu-net's step). There is no force limit.

## Action Space

``Box(-1, 1, (1,), float32)``: the closure change in units of ``jaw_step_mm``, then clipped to
``[0, jaw_travel_mm]``: the exact analogue of the pneu-net's pressure change, so :class:`agents.scripted.LinearRamp`
and :class:`agents.scripted.StepPolicy` drive it unchanged (their targets are then fractions of the travel).

## Observation Space

``Box(0, 1, (1,), float32)``: the closure ``c / jaw_travel_mm`` (proprioception only: blind).

## Rewards, Starting State, Episode End

Those of ``PneuNetGrasp-v0`` (:mod:`pneunet_env.task`): squeeze phase, then hold phase; damage when the
traction exceeds the failure stress or the indentation exceeds ``crush_fraction H``; slip in the hold phase
when the traction is below ``rho g H / (grip_faces mu_f)``; ``info["is_success"]`` at the end.
``reset(seed=s)`` draws the same object as ``PneuNetGrasp-v0``'s ``reset(seed=s)`` (the same config).

## Arguments

``gym.make("RigidGrasp-v0", config=None, jaw_travel_mm=None, jaw_step_mm=None, **overrides)``: ``config`` and
``overrides`` as for ``PneuNetGrasp-v0`` (an :class:`pneunet_env.config.EnvConfig`, a mapping or a YAML path);
``jaw_travel_mm`` defaults to twice the deepest allowed indentation, ``2 crush_fraction H_max``, kept below
90 % of the nominal object's radius; ``jaw_step_mm`` defaults to the same fraction of the travel that
``max_pressure_step_kpa`` is of ``max_pressure_kpa`` (1/20: full travel in 20 steps).

## Info

The keys of ``PneuNetGrasp-v0``'s info (:func:`pneunet_env.task.build_info`), with ``pressure`` 0 and the
solver's entries those of an exact kinematic answer (``solver_status = "kinematic"``), plus
``jaw_closure_mm``, ``jaw_travel_mm`` and ``gripper = "rigid"``. ``curvature`` is the jaw arc's ``w / R_jaw``.
"""

from __future__ import annotations

import math
from typing import Any

import gymnasium as gym
import numpy as np
from gymnasium import spaces

from pneunet_env import task
from pneunet_env.config import EnvConfig, load_config
from pneunet_env.physics.params import check_positive

__all__ = ["RigidGraspEnv", "ENV_ID", "jaw_indentation", "default_jaw_travel_mm"]

ENV_ID = "RigidGrasp-v0"


def default_jaw_travel_mm(config: EnvConfig) -> float:
    """``2 crush_fraction H_max``, capped at 90 % of the nominal object's radius (mm)."""
    radius_mm = 1e3 / _nominal_curvature_per_m(config)
    return min(2.0 * config.crush_fraction * config.object_thickness_mm[1], 0.9 * radius_mm)


def _nominal_curvature_per_m(config: EnvConfig) -> float:
    lo, hi = config.object_curvature_per_m
    return 0.5 * (lo + hi)


def jaw_indentation(closure_mm, object_curvature_per_m, nominal_curvature_per_m):
    """The indentation ``delta = c + 1/kappa_obj - 1/kappa_nom`` (mm) of a jaw closed by ``c`` mm; broadcasts.

    Negative means no contact (the jaw stops short of a smaller object).
    """
    return closure_mm + 1e3 / np.asarray(object_curvature_per_m) - 1e3 / nominal_curvature_per_m


class RigidGraspEnv(gym.Env):
    """A rigid, position-controlled gripper grasps the objects of ``PneuNetGrasp-v0`` (see the module docstring)."""

    metadata = {"render_modes": []}

    def __init__(
        self,
        render_mode: str | None = None,
        config: Any = None,
        jaw_travel_mm: float | None = None,
        jaw_step_mm: float | None = None,
        **overrides: Any,
    ) -> None:
        if render_mode is not None:
            raise ValueError(f"RigidGrasp-v0 does not render (render_mode must be None), got {render_mode!r}")
        self.render_mode = None
        self.config: EnvConfig = load_config(config, **overrides)
        cfg = self.config
        self._nominal = _nominal_curvature_per_m(cfg)
        radius_mm = 1e3 / self._nominal
        travel = (
            default_jaw_travel_mm(cfg) if jaw_travel_mm is None else check_positive("jaw_travel_mm", jaw_travel_mm)
        )
        if travel >= radius_mm:
            raise ValueError(
                f"jaw_travel_mm = {travel!r} reaches the centre of the nominal object (radius {radius_mm:g} mm)"
            )
        step = travel * cfg.max_pressure_step_kpa / cfg.max_pressure_kpa if jaw_step_mm is None else jaw_step_mm
        step = check_positive("jaw_step_mm", step)
        if step > travel:
            raise ValueError(f"jaw_step_mm = {step!r} exceeds jaw_travel_mm = {travel!r}")
        self.jaw_travel_mm = float(travel)
        self.jaw_step_mm = float(step)
        self._task = task.TaskParams.from_config(cfg)
        # The jaw closure, in the same normalised units the pneu-net's pressure uses: the task's
        # ``update_pressure`` then moves it (clip to [-1, 1], step, clip to [0, travel]).
        self._jaw_task = self._task._replace(pressure_max=self.jaw_travel_mm, pressure_step=self.jaw_step_mm)
        self.action_space = spaces.Box(-1.0, 1.0, (1,), np.float32)
        self.observation_space = spaces.Box(0.0, 1.0, (1,), np.float32)
        self._obj = None
        self._thresholds = None
        self._closure = 0.0
        self._state = task.initial_state()
        self._started = False

    @property
    def object(self):
        """The current episode's :class:`pneunet_env.objects.GraspObject` (``None`` before ``reset``)."""
        return self._obj

    def _contact(self) -> task.SolvedState:
        """The kinematic contact, as the task's :class:`~pneunet_env.task.SolvedState` (nothing to solve)."""
        obj, w = self._obj, self.config.width_mm
        delta_mm = float(jaw_indentation(self._closure, obj.curvature_per_m, self._nominal))
        in_contact = delta_mm > 0.0 and obj.stiffness > 0.0
        delta = delta_mm / w if in_contact else 0.0
        r_jaw_mm = 1e3 / self._nominal - self._closure
        return task.SolvedState(
            pressure=0.0,
            curvature=w / r_jaw_mm,
            side_strain=0.0,
            top_strain=0.0,
            contact_force=obj.stiffness * delta,  # F~ = k~ delta~ (eq. 3.1)
            indentation=delta,
            in_contact=in_contact,
            volume_change=0.0,
            energy=0.0,
            gradient_norm=0.0,
            min_eigenvalue=math.inf,
            converged=True,
            iterations=0,
            substeps=0,
            snapped=False,
            status="kinematic",
        )

    def _obs(self) -> np.ndarray:
        return np.array([self._closure / self.jaw_travel_mm], dtype=np.float32)

    def _info(self, contact: task.SolvedState, outcome=None, clipped=False) -> dict[str, Any]:
        info = task.build_info(contact, contact, self._obj, self._thresholds, self._state, self._task, outcome,
                               bool(clipped), False)
        info.update(jaw_closure_mm=self._closure, jaw_travel_mm=self.jaw_travel_mm, gripper="rigid")
        return info

    def reset(self, *, seed: int | None = None, options: dict[str, Any] | None = None):
        super().reset(seed=seed)
        if options is not None and not isinstance(options, dict):
            raise ValueError(f"options must be a dict of object properties to pin, got {options!r}")
        self._obj = task.sample_object(self.np_random, self.config, pinned=options)
        self._thresholds = task.object_thresholds(self._obj, self._task)
        self._closure = 0.0
        self._state = task.initial_state()
        self._started = True
        return self._obs(), self._info(self._contact())

    def step(self, action):
        if not self._started:
            raise RuntimeError("call reset() before step()")
        a = task.single_action(action)
        self._closure, clipped = task.update_pressure(self._closure, a, self._jaw_task)  # raises on NaN
        c = self._contact()
        out = task.transition(self._state, c.contact_force, c.indentation, c.in_contact, self._thresholds, False,
                              self._task)
        self._state = out.state
        info = self._info(c, out, clipped)
        terminated, truncated = bool(out.terminated), bool(out.truncated)
        if terminated or truncated:
            info["is_success"] = bool(out.success)
        return self._obs(), float(out.reward), terminated, truncated, info

