"""``PneuNetGrasp-v0``: a pneu-net actuator grasps an object of unknown stiffness, blind."""

from __future__ import annotations

import functools
from typing import Any

import gymnasium as gym
import numpy as np
from gymnasium import spaces

from pneunet_env import task
from pneunet_env.config import EnvConfig, load_config
from pneunet_env.physics.params import ActuatorParams, check_object
from pneunet_env.physics.solver import Equilibrium, SolverOptions, params_tuple, solve_equilibrium, step_state

__all__ = ["PneuNetGraspEnv", "free_volume_change"]


@functools.lru_cache(maxsize=32)
def free_volume_change(params: ActuatorParams, pressure: float, options: SolverOptions) -> float:
    """The free actuator's chamber volume change ``(V1 - V0)/(w^2 t)`` at ``pressure`` (loaded from rest)."""
    eq = solve_equilibrium(pressure, 0.0, 0.02, params, options=options)
    if not eq.converged:  # pragma: no cover - the free actuator always converges at the defaults
        raise RuntimeError(f"the free actuator did not converge at p~={pressure}: {eq.status}")
    return eq.volume_change


class PneuNetGraspEnv(gym.Env):
    """A soft pneumatic finger (a pneu-net) closes on an object it cannot see, lifts it and holds it.

    ## Description

    One pneu-net chamber (the unit cell of the seed paper: a stiff PDMS base, Gent-elastomer side and
    top walls) is inflated; the object is an arc of curvature ``kappa_obj`` and thickness ``H`` on a
    Winkler foundation of stiffness ``k_obj`` (eq. 3.2 from its shear modulus). Each step is quasi-static:
    the equilibrium at the new pressure is the local energy minimum reached from the previous one
    (:func:`pneunet_env.solve_equilibrium`, with pressure continuation, so folds are never jumped over).
    The policy sees only the pressure: it is blind to the object on purpose. The paper's claim is that a
    blind schedule grasps soft objects (force-limited: the traction saturates) and stiff ones
    (position-limited: the curvature stays at the object's) alike.

    An episode is one grasp: a **squeeze phase** (``squeeze_steps``, default 50) in which the object rests
    on its support, then a **hold phase** (``hold_steps``, default 50) in which it is lifted and friction
    must carry its weight.

    ## Action Space

    ``Box(-1, 1, (1,), float32)``: the pressure change, in units of ``max_pressure_step_kpa`` (3 kPa).

    | Num | Action          | Min | Max | Unit                    |
    |-----|-----------------|-----|-----|-------------------------|
    | 0   | pressure change | -1  | 1   | ``max_pressure_step_kpa`` |

    The pressure is then clipped to ``[0, max_pressure_kpa]`` (60 kPa, ``p~ = 1.2``). A finite action
    outside ``[-1, 1]`` is clipped and ``info["action_clipped"]`` is true; a NaN or infinite action raises
    ``ValueError``.

    ## Observation Space

    ``Box(0, 1, (1,), float32)`` by default (proprioception only):

    | Num | Observation                                    | Min  | Max | Unit                               |
    |-----|------------------------------------------------|------|-----|------------------------------------|
    | 0   | pressure ``p / p_max``                         | 0    | 1   | fraction of ``max_pressure_kpa``   |
    | 1   | chamber volume change (``observe_volume`` only)| -inf | inf | of the free actuator's at ``p_max`` |

    The volume entry is 0 at rest and about 1 for the free actuator at ``p_max`` (an object only lowers it);
    its bounds are left open because a round-off of order 1e-16 below 0 can occur at rest.

    ## Rewards

    | Event                                              | Reward                    |
    |----------------------------------------------------|---------------------------|
    | each hold-phase step with the object held, intact  | ``+reward_hold`` (0.02)   |
    | the episode's last step reached, held, intact      | ``+reward_success`` (1)   |
    | the object is damaged (the step it happens)        | ``-penalty_damage`` (2)   |
    | the object slips / is dropped (the step it happens)| ``-penalty_slip`` (1)     |

    A full successful episode earns ``hold_steps * reward_hold + reward_success = 2``.

    **Damage**: the contact traction exceeds the object's failure stress ``3 eps_f mu_obj``, or the
    indentation exceeds ``crush_fraction`` times its thickness. **Slip** (hold phase): the traction is
    below ``rho g H / (grip_faces mu_f)``, the weight per unit contact area over the friction. See
    ``docs/env.md`` for the physics of each threshold.

    ## Starting State

    Pressure 0, the actuator at rest (flat, unstrained). A new object is drawn from ``self.np_random``:
    shear modulus log-uniform in ``object_shear_modulus_kpa`` (0.1 to 1500 kPa, i.e. ``k~`` from 6.8e-6 to
    0.10 at the paper's size), thickness, curvature, density and failure strain from their ranges (fixed
    at the paper's values by default). ``reset(options={...})`` pins any of ``object_stiffness`` (``k~``),
    ``object_shear_modulus_kpa``, ``object_curvature`` (``w kappa_obj``), ``object_curvature_per_m``,
    ``object_thickness_mm``, ``object_density_kg_m3``, ``object_failure_strain``.

    ## Episode End

    * **Termination**: the object is damaged (irreversible), or it slips in the hold phase (dropped).
      (Configurable: ``terminate_on_damage``, ``terminate_on_slip``.)
    * **Truncation**: the hold phase ends (``squeeze_steps + hold_steps`` = 100 steps; this is the
      registered ``max_episode_steps``). A solve that fails to converge keeps the previous state and
      truncates, with ``info["solver_failed"]`` (it has never happened in testing).
    * ``info["is_success"]`` is set on the last step of every episode: held to the end, intact.

    ## Arguments

    ``gym.make("PneuNetGrasp-v0", render_mode=None, config=None, **overrides)``: ``config`` is ``None``
    (defaults), a dict, an :class:`~pneunet_env.config.EnvConfig` or a YAML path; ``overrides`` are config
    keys (``configs/env/default.yaml`` lists them all, with units). An unknown key or an invalid value
    raises ``ValueError`` naming it. If the config changes the episode length, also pass
    ``max_episode_steps=`` (the registered time limit is the default 100 steps). ``model="full"``
    (default), ``"linear"`` or ``"auto"`` picks the model a step solves (:mod:`pneunet_env.physics.models`):
    ``auto`` uses the linearised model (supplement eqs. 15-17) only where its estimated state error is
    below ``1e-3``; the solver study found it saves no time at this model's size, so ``full`` stays the default.

    ## Info

    Dimensionless (the model's units: pressure and traction ``/mu``, lengths ``/w``) and physical:
    ``pressure`` / ``pressure_kpa``, ``curvature`` (``w kappa``) / ``curvature_per_m``, ``side_strain``,
    ``top_strain``, ``contact_force`` (``F~``) / ``contact_force_kpa``, ``indentation`` (``delta~``) /
    ``indentation_mm``, ``volume_change`` / ``volume_change_mm3``, ``in_contact``; the object's
    ``object_stiffness`` (``k~``), ``object_stiffness_kpa_per_mm``, ``object_shear_modulus_kpa``,
    ``object_curvature`` / ``object_curvature_per_m``, ``object_thickness_mm``, ``object_density_kg_m3``,
    ``object_failure_strain``; its thresholds ``failure_traction_kpa``, ``crush_indentation_mm``,
    ``grip_traction_kpa``, and ``grip_ratio`` (``F`` over the grip traction, >= 1 holds), ``damage_ratio``
    (>= 1 damages), ``peak_contact_force_kpa``; the task's ``step``, ``in_hold``, ``damaged``,
    ``overstressed``, ``crushed``, ``slipping``, ``dropped``, ``held``, ``action_clipped``; the solver's
    ``snapped`` (a fold was crossed), ``solver_converged``, ``solver_failed``, ``solver_iterations``,
    ``solver_substeps``, ``solver_status``, ``gradient_norm``, ``min_eigenvalue``; and ``is_success`` at
    the episode's end.

    ## Rendering

    ``render_mode="rgb_array"``: an ``(render_height, render_width, 3)`` uint8 picture (480 x 360): the
    actuator's chambers curling along their arc, the object's arc with its indentation, the load on it in
    colour (red when damaged), a pressure bar, a traction gauge (log scale, with the grip and failure
    marks), the episode's progress and a status lamp. ``"human"`` shows the same picture in a matplotlib
    window (matplotlib is imported only then).
    """

    metadata = {"render_modes": ["human", "rgb_array"], "render_fps": 20}

    def __init__(self, render_mode: str | None = None, config: Any = None, **overrides: Any) -> None:
        if render_mode is not None and render_mode not in self.metadata["render_modes"]:
            raise ValueError(f"render_mode must be one of {self.metadata['render_modes']} or None, got {render_mode!r}")
        self.config: EnvConfig = load_config(config, **overrides)
        self.render_mode = render_mode
        cfg = self.config
        self._params = cfg.actuator_params
        self._options = cfg.solver_options
        self._task = task.TaskParams.from_config(cfg)
        # The hot path calls the compiled continuation directly with these (see step()).
        self._prm = params_tuple(self._params)
        self._opts = self._options.as_tuple()
        self._model = cfg.model  # "full" (default), "linear" or "auto": see pneunet_env.physics.models
        self._volume_scale = (
            free_volume_change(self._params, cfg.pressure_max, self._options) if cfg.observe_volume else None
        )
        self.action_space = spaces.Box(-1.0, 1.0, (1,), np.float32)
        if cfg.observe_volume:
            self.observation_space = spaces.Box(
                np.array([0.0, -np.inf], np.float32), np.array([1.0, np.inf], np.float32), dtype=np.float32
            )
        else:
            self.observation_space = spaces.Box(0.0, 1.0, (1,), np.float32)
        self._eq: task.SolvedState | None = None
        self._obj = None
        self._thresholds = None
        self._static_info: dict[str, Any] | None = None
        self._state = task.initial_state()
        self._outcome: task.Outcome | None = None
        self._viewer = None

    # ---- the object and state, for users -------------------------------------------------------
    @property
    def object(self):
        """The current episode's :class:`pneunet_env.objects.GraspObject` (``None`` before ``reset``)."""
        return self._obj

    @property
    def equilibrium(self) -> Equilibrium | None:
        """The current quasi-static state (an :class:`~pneunet_env.physics.solver.Equilibrium`, built on request)."""
        if self._eq is None:
            return None
        return Equilibrium(*self._eq, self._obj.stiffness, self._obj.curvature)

    def _solve(self, kappa: float, side_strain: float, p0: float, p1: float) -> task.SolvedState:
        """The continuation from ``(kappa~, e_s)`` at ``p0`` to ``p1`` for the current object, as a SolvedState.

        What :func:`pneunet_env.solve_equilibrium` computes, without its argument checks (the pressure comes
        from :func:`task.update_pressure`, the object was checked at reset) or its dataclass: a step's cost is
        mostly Python overhead, and this is the hot path.
        """
        obj = self._obj
        if self._model != "full":
            return self._solve_model(kappa, side_strain, p0, p1)
        r = step_state(kappa, side_strain, p0, p1, self._prm, obj.stiffness, obj.curvature, self._opts)
        return task.solved_state(p1, r[0], r[1], r[9], r[2], r[3], r[4], r[5], r[6], r[7], r[8], obj.stiffness,
                                 obj.curvature, self._prm[0])

    def _solve_model(self, kappa: float, side_strain: float, p0: float, p1: float) -> task.SolvedState:
        """The step under ``config.model`` = ``"linear"`` or ``"auto"`` (``models.equilibrium_for_model``)."""
        from pneunet_env.physics.models import equilibrium_for_model

        obj = self._obj
        prev = None
        if self._eq is not None and p0 > 0.0:
            prev = Equilibrium(*self._eq, obj.stiffness, obj.curvature)
        eq = equilibrium_for_model(self._model, p1, obj.stiffness, obj.curvature, self._params, previous=prev,
                                   options=self._options)
        return task.SolvedState(*(getattr(eq, f) for f in task.SolvedState._fields))

    # ---- Gymnasium API -----------------------------------------------------------------------------
    def reset(self, *, seed: int | None = None, options: dict[str, Any] | None = None):
        super().reset(seed=seed)
        if options is not None and not isinstance(options, dict):
            raise ValueError(f"options must be a dict of object properties to pin, got {options!r}")
        obj = task.sample_object(self.np_random, self.config, pinned=options)
        check_object(obj.stiffness, obj.curvature)
        self._obj = obj
        self._thresholds = task.object_thresholds(obj, self._task)
        self._static_info = task.object_info(obj, self._thresholds, self._task)
        self._eq = self._solve(0.0, 0.0, 0.0, 0.0)  # the rest state (what solve_equilibrium(0.0, ...) returns)
        self._state = task.initial_state()
        self._outcome = None
        obs = task.observation(self._eq.pressure, self._eq.volume_change, self._task, self._volume_scale)
        info = task.build_info(self._eq, self._eq, obj, self._thresholds, self._state, self._task,
                               static=self._static_info)
        if self.render_mode == "human":
            self.render()
        return obs, info

    def step(self, action):
        if self._eq is None:
            raise RuntimeError("call reset() before step()")
        a = task.single_action(action)
        prev = self._eq
        pressure, clipped = task.update_pressure(prev.pressure, a, self._task)  # raises on NaN/inf
        obj = self._obj
        solve = self._solve(prev.curvature, prev.side_strain, prev.pressure, pressure)
        failed = not solve.converged
        eq = prev if failed else solve
        self._eq = eq
        out = task.transition(
            self._state, eq.contact_force, eq.indentation, eq.in_contact, self._thresholds, failed, self._task
        )
        self._state = out.state
        self._outcome = out
        obs = task.observation(eq.pressure, eq.volume_change, self._task, self._volume_scale)
        info = task.build_info(eq, solve, obj, self._thresholds, out.state, self._task, out, bool(clipped), failed,
                               static=self._static_info)
        terminated, truncated = bool(out.terminated), bool(out.truncated)
        if terminated or truncated:
            info["is_success"] = bool(out.success)
        if self.render_mode == "human":
            self.render()
        return obs, float(out.reward), terminated, truncated, info

    def render(self):
        if self.render_mode is None:
            gym.logger.warn(
                "You are calling render method without specifying any render mode. "
                'Pass render_mode="rgb_array" or "human" to gym.make("PneuNetGrasp-v0", ...).'
            )
            return None
        from pneunet_env.envs.render import HumanViewer, render_frame

        frame = render_frame(self.render_state(), self.config.render_width, self.config.render_height,
                             chambers=self.config.render_chambers)
        if self.render_mode == "rgb_array":
            return frame
        if self._viewer is None:
            self._viewer = HumanViewer(title="PneuNetGrasp-v0", fps=self.metadata["render_fps"])
        self._viewer.show(frame)
        return None

    def render_state(self):
        """What :func:`pneunet_env.envs.render.render_frame` draws, from the current state."""
        from pneunet_env.envs.render import RenderState

        if self._eq is None:
            raise RuntimeError("call reset() before render()")
        eq, obj, thr, st, out = self._eq, self._obj, self._thresholds, self._state, self._outcome
        return RenderState(
            curvature=eq.curvature,
            side_strain=eq.side_strain,
            params=self._params,
            pressure_fraction=eq.pressure / self._task.pressure_max,
            object_curvature=obj.curvature,
            object_thickness=obj.thickness,
            contact_force=eq.contact_force,
            indentation=eq.indentation if eq.in_contact else 0.0,
            in_contact=eq.in_contact,
            failure_traction=thr.failure_traction,
            crush_indentation=thr.crush_indentation,
            grip_traction=thr.grip_traction,
            damaged=bool(st.damaged),
            dropped=bool(st.dropped),
            in_hold=bool(out.in_hold) if out is not None else False,
            progress=st.step / self._task.episode_steps,
            hold_start=self._task.squeeze_steps / self._task.episode_steps,
        )

    def close(self):
        if self._viewer is not None:
            self._viewer.close()
            self._viewer = None
        super().close()
