"""``PneuNetGrasp-v0``: a pneu-net actuator grasps an object of unknown stiffness, blind.

A thin shell around the pure step of :mod:`pneunet_env.task` (:func:`~pneunet_env.task.step` on scalars, with the
Newton contact): this module holds the Gymnasium API, the spaces and the rendering hook, nothing of the physics
or the rules.
"""

from __future__ import annotations

from typing import Any

import gymnasium as gym
import numpy as np
from gymnasium import spaces
from gymnasium.error import ResetNeeded

from pneunet_env import task
from pneunet_env.config import EnvConfig, load_config
from pneunet_env.physics.params import check_object
from pneunet_env.physics.solver import Equilibrium

__all__ = ["PneuNetGraspEnv", "observation_space", "single_env_step"]


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

    ## Version History

    * v0: the paper's object (a 250 mm ring, 10 mm thick) with its shear modulus log-uniform in 0.1-1500 kPa.
    * ``info["is_success"]`` is set on the last step of every episode: held to the end, intact.

    ## Arguments

    ``gym.make("PneuNetGrasp-v0", render_mode=None, config=None, info_level="lean", **overrides)``: ``config``
    is ``None`` (defaults), a dict (nested by section or flat), an :class:`~pneunet_env.config.EnvConfig` or a
    YAML path; ``overrides`` are config keys (``configs/env/default.yaml`` lists them all, with units). An
    unknown key or an invalid value raises ``ValueError`` naming it. If the config changes the episode length,
    also pass ``max_episode_steps=`` (the registered time limit is the default 100 steps). ``info_level``:
    see Info.

    ## Info

    ``info_level="lean"`` (default): every step gives the pressure, curvature and contact in physical units
    (``pressure_kpa``, ``curvature_per_m``, ``contact_force_kpa``, ``indentation_mm``, ``in_contact``), the task's
    flags (``step``, ``in_hold``, ``held``, ``damaged``, ``overstressed``, ``crushed``, ``dropped``, ``slipping``,
    ``action_clipped``) and the solver's status (``snapped``, ``solver_converged``, ``solver_failed``); the reset
    info adds the object's constants (``object_stiffness`` ``k~``, ``object_shear_modulus_kpa``, ... and its
    thresholds: :data:`pneunet_env.task.OBJECT_KEYS`). ``info_level="full"`` gives every key of
    :func:`pneunet_env.task.build_info` every step (44: the dimensionless state, the object, the thresholds'
    ratios, the solver's diagnostics). ``is_success`` is added on an episode's last step.

    ## Rendering

    ``render_mode="rgb_array"``: an ``(render_height, render_width, 3)`` uint8 picture (480 x 360): the
    actuator's chambers curling along their arc, the object's arc with its indentation, the load on it in
    colour (red when damaged), a pressure bar, a traction gauge (log scale, with the grip and failure
    marks), the episode's progress, a status lamp and, on frames of at least 240 x 180, a text label (top left:
    the object's class, or its ``k~`` when it has none or its stiffness was pinned, the step, the pressure in kPa
    and the state: free, squeezing, gripping, held, slipped, crushed or damaged). ``"human"`` shows the same
    picture in a matplotlib window (matplotlib is imported only then).
    """

    metadata = {"render_modes": ["human", "rgb_array"], "render_fps": 20}

    def __init__(self, render_mode: str | None = None, config: Any = None, info_level: str = "lean",
                 **overrides: Any) -> None:
        if render_mode is not None and render_mode not in self.metadata["render_modes"]:
            raise ValueError(f"render_mode must be one of {self.metadata['render_modes']} or None, got {render_mode!r}")
        if info_level not in task.INFO_LEVELS:
            raise ValueError(f"info_level must be one of {task.INFO_LEVELS}, got {info_level!r}")
        self.config: EnvConfig = load_config(config, **overrides)
        self.render_mode = render_mode
        self.info_level = info_level
        self._params = task.EnvParams.from_config(self.config)
        self._class_names = task.class_names(self.config)
        self.action_space = spaces.Box(-1.0, 1.0, (1,), np.float32)
        self.observation_space = observation_space(self.config)
        self._state: task.EnvState | None = None
        self._ended = False
        self._warned = False
        self._static_info: dict[str, Any] | None = None
        self._viewer = None
        self._render_name = ""

    # ---- the object and state, for users -------------------------------------------------------
    @property
    def state(self) -> task.EnvState | None:
        """The whole state (:class:`pneunet_env.task.EnvState`; ``None`` before ``reset``)."""
        return self._state

    @property
    def equilibrium(self) -> Equilibrium | None:
        """The current quasi-static state (an :class:`~pneunet_env.physics.solver.Equilibrium`)."""
        return None if self._state is None else self._state.eq

    # ---- Gymnasium API -----------------------------------------------------------------------------
    def reset(self, *, seed: int | None = None, options: dict[str, Any] | None = None):
        super().reset(seed=seed)
        self._ended = False
        if options is not None and not isinstance(options, dict):
            raise ValueError(f"options must be a dict of object properties to pin, got {options!r}")
        obj = task.sample_object(self.np_random, self.config, pinned=options)
        check_object(obj.stiffness, obj.curvature)
        self._warned = task.warn_if_beyond_convergence(obj, self._warned)
        self._state = state = task.reset_state(obj, self._params, task.newton_contact)
        self._static_info = task.object_info(obj, state.thresholds, self._params.task)
        self._static_info["object_class"] = task.class_name(self._class_names, obj.class_id)
        # the frame's label names the object by its class, unless its stiffness was pinned (then by its k~)
        pinned_material = options is not None and any(
            options.get(k) is not None for k in ("object_stiffness", "object_shear_modulus_kpa"))
        self._render_name = "" if pinned_material or obj.class_id < 0 else self._static_info["object_class"]
        obs = task.observation(state.command, state.eq.volume_change, self._params.task, self._params.volume_scale)
        info = task.build_info(state, self._params.task, None, self.info_level, self._static_info)
        if self.render_mode == "human":
            self.render()
        return obs, info

    def step(self, action):
        out = single_env_step(self, action, task.newton_contact, lambda res: task.build_info(
            res.state, self._params.task, res, self.info_level, self._static_info))
        if self.render_mode == "human":
            self.render()
        return out

    def render(self):
        if self.render_mode is None:
            gym.logger.warn(
                "You are calling render method without specifying any render mode. "
                'Pass render_mode="rgb_array" or "human" to gym.make("PneuNetGrasp-v0", ...).'
            )
            return None
        from pneunet_env.envs.render import HumanViewer, render_frame

        r = self.config.render
        frame = render_frame(self.render_state(), r.width, r.height, chambers=r.chambers)
        if self.render_mode == "rgb_array":
            return frame
        if self._viewer is None:
            self._viewer = HumanViewer(title="PneuNetGrasp-v0", fps=self.metadata["render_fps"])
        self._viewer.show(frame)
        return None

    def render_state(self):
        """What :func:`pneunet_env.envs.render.render_frame` draws, from the current state."""
        from pneunet_env.envs.render import render_state

        if self._state is None:
            raise RuntimeError("call reset() before render()")
        return render_state(self._state, self._params, object_name=self._render_name)

    def close(self):
        if self._viewer is not None:
            self._viewer.close()
            self._viewer = None
        super().close()


def single_env_step(env, action, contact: task.Contact, make_info):
    """One Gymnasium ``step`` of a single env (this one, or the rigid jaw's) around :func:`pneunet_env.task.step`.

    ``env`` holds ``_state``, ``_params`` and ``_ended``; ``make_info(res)`` builds its info. Stepping before ``reset``
    or past an episode's end raises ``ResetNeeded``; ``is_success`` is added on the episode's last step.
    """
    if env._state is None:
        raise ResetNeeded("call reset() before step()")
    if env._ended:
        raise ResetNeeded("the episode has ended (terminated or truncated): call reset() before step()")
    res = task.step(env._state, task.single_action(action), env._params, contact)
    env._state = res.state
    info = make_info(res)
    terminated, truncated = bool(res.terminated), bool(res.truncated)
    if terminated or truncated:
        info["is_success"] = bool(res.outcome.success)
        env._ended = True
    return res.obs, float(res.reward), terminated, truncated, info


def observation_space(config: EnvConfig) -> spaces.Box:
    """One env's observation space: ``[p / p_max]``, or ``[p / p_max, dV / dV_free(p_max)]`` with ``observe_volume``."""
    if config.task.observe_volume:
        return spaces.Box(np.array([0.0, -np.inf], np.float32), np.array([1.0, np.inf], np.float32), dtype=np.float32)
    return spaces.Box(0.0, 1.0, (1,), np.float32)
