"""``PneuNetGrasp-v1``: a pneu-net actuator grasps an object of unknown stiffness, blind.

A thin shell around the pure step of :mod:`pneunet_env.task` (:func:`~pneunet_env.task.step` on scalars, with the
Newton contact): the reset, the step and the state are the single envs' shared shell
(:class:`pneunet_env.envs.base.SingleGraspEnv`); this module adds the spaces, the info, the rendering and the
docs of the task, nothing of the physics or the rules.
"""

from __future__ import annotations

import copy
from typing import Any

import gymnasium as gym
import numpy as np
from gymnasium import spaces

from pneunet_env import fused, task
from pneunet_env.config import EnvConfig
from pneunet_env.envs.base import SingleGraspEnv
from pneunet_env.info import lean_info, object_info_one
from pneunet_env.physics.params import check_object
from pneunet_env.physics.solver import Solve, equilibrium, step_state

__all__ = ["PneuNetGraspEnv", "observation_space"]

_RESET_KEYS = tuple(k for k in task.FULL_KEYS if k in task.LEAN_KEYS or k in task.OBJECT_KEYS)
"""The keys of a lean reset info, in :func:`pneunet_env.task.build_info`'s order (the table's)."""
_RESET_TEMPLATE = dict.fromkeys(_RESET_KEYS)
"""A lean reset info's keys in their order, each value ``None`` (copied and filled in at every reset)."""


class PneuNetGraspEnv(SingleGraspEnv):
    """A soft pneumatic finger (a pneu-net) closes on an object it cannot see, lifts it and holds it.

    ## Description

    One pneu-net chamber (the unit cell of the seed paper, Table 1's actuator: a stiff PDMS base, Gent-elastomer
    side and top walls) is inflated. The object is an annulus of outer radius ``R = 1/kappa_obj`` and compliant
    depth ``H`` on a Winkler foundation of stiffness ``k_obj`` (eq. 3.2 from its shear modulus ``mu_obj = E/3``).
    Each step is quasi-static: the equilibrium at the new pressure is the local energy minimum reached from the
    previous one (:func:`pneunet_env.solve_equilibrium`, with pressure continuation, so folds are never jumped
    over). The policy sees only the pressure: it is blind to the object on purpose. The paper's claim is that a
    blind schedule grasps soft objects (force-limited: the traction saturates) and stiff ones (position-limited:
    the curvature stays at the object's) alike.

    The default task grasps real objects: the ``kitchen`` use case of the object catalogue (below: apples,
    kiwifruit, soft cheese, gelatin gel, at hand scale) under the hoop-strain damage rule. The paper's own task
    (its 250 mm ring, the crush-fraction rule) is ``PneuNetGrasp-Paper-v0`` (:data:`pneunet_env.PAPER_TASK`).

    An episode is one grasp: a **squeeze phase** (``squeeze_steps``) in which the object rests on its support,
    then a **hold phase** (``hold_steps``) in which it is lifted and friction must carry its weight.

    ## Default Task

    The defaults of ``EnvConfig()`` (``configs/env/default.yaml`` lists every key, with its unit; a test checks
    this table against them):

    | Config key                | Default       | Meaning                                                   |
    |---------------------------|---------------|-----------------------------------------------------------|
    | ``use_case``              | ``kitchen``   | the catalogue's classes drawn, by weight (see Catalogue)  |
    | ``damage_rule``           | ``hoop_strain`` | damaged past the failure stress or the hoop strain      |
    | ``max_pressure_kpa``      | 60            | pressure ceiling ``p_max`` (kPa; ``p~ = 1.2``)            |
    | ``max_pressure_step_kpa`` | 3             | pressure change at ``|action| = 1`` (kPa)                 |
    | ``squeeze_steps``         | 50            | steps of the squeeze phase                                |
    | ``hold_steps``            | 50            | steps of the hold phase (then truncation)                 |
    | ``friction_coefficient``  | 0.5           | ``mu_f`` between the actuator and the object              |
    | ``grip_faces``            | 2             | opposed faces that share the weight                       |
    | ``reward_hold``           | 0.02          | each hold-phase step held, intact                         |
    | ``reward_success``        | 1             | the episode's end reached, held, intact                   |
    | ``penalty_damage``        | 2             | the step the object is damaged                            |
    | ``penalty_slip``          | 1             | the step the object slips                                 |
    | ``terminate_on_damage``   | true          | damage ends the episode                                   |
    | ``terminate_on_slip``     | true          | a drop ends the episode                                   |
    | ``observe_volume``        | false         | add the chamber's volume change to the observation        |

    ## Action Space

    ``Box(-1, 1, (1,), float32)``: the pressure change, in units of ``max_pressure_step_kpa``.

    | Num | Action          | Min | Max | Unit                      |
    |-----|-----------------|-----|-----|---------------------------|
    | 0   | pressure change | -1  | 1   | ``max_pressure_step_kpa`` |

    The pressure is then clipped to ``[0, max_pressure_kpa]``. A finite action outside ``[-1, 1]`` is clipped and
    ``info["action_clipped"]`` is true; a NaN or infinite action raises ``ValueError``. A torch tensor is read as
    its value (detached: the env is not differentiable).

    ## Observation Space

    ``Box(0, 1, (1,), float32)`` by default (proprioception only):

    | Num | Observation                                    | Min  | Max | Unit                                |
    |-----|------------------------------------------------|------|-----|-------------------------------------|
    | 0   | pressure ``p / p_max``                         | 0    | 1   | fraction of ``max_pressure_kpa``    |
    | 1   | chamber volume change (``observe_volume`` only)| -inf | inf | of the free actuator's at ``p_max`` |

    The volume entry is 0 at rest and about 1 for the free actuator at ``p_max`` (an object only lowers it);
    its bounds are left open because a round-off of order 1e-16 below 0 can occur at rest.

    ## Catalogue

    Each episode draws a class of the ``kitchen`` use case by its weight, then the object's properties from the
    class's literature ranges (:mod:`pneunet_env.catalogue`, ``pneunet_env/data/objects.yaml``, each row with its
    sources): modulus, density and failure stress log-uniform; radius, depth and failure strain uniform.

    | Class       | Weight | ``E`` (kPa) | ``R`` (mm) | ``H`` (mm) | ``rho`` (kg/m^3) | ``eps_f``  | ``sigma_f`` (kPa) |
    |-------------|--------|-------------|------------|------------|------------------|------------|-------------------|
    | apple       | 0.30   | 810-3280    | 17.6-32.5  | 4.4-8.8    | 740-890          | 0.11-0.312 | 235-444           |
    | kiwifruit   | 0.25   | 200-400     | 17.5-27.5  | 4.4-8.7    | 1020-1095        | 0.05-0.15  | 20-30             |
    | soft_cheese | 0.25   | 77-230      | 15-40      | 3.75-7.5   | 1050-1150        | 0.33-0.59  | 46-62             |
    | gelatin_gel | 0.20   | 4.3-81      | 15-40      | 3.75-7.5   | 1000-1050        | 0.25-0.35  | 1.1-24            |

    The kitchen's ``sponge_rubber`` and ``bread`` lie outside eq. 3.2's annulus model and are never drawn.
    ``use_case`` picks another use case (``lab_bench``, ``catalogue_uniform``), ``class_weights`` any weights;
    with both ``None`` the objects section's ranges are drawn instead (the paper's ring).

    ## Rewards

    | Event                                              | Reward              |
    |----------------------------------------------------|---------------------|
    | each hold-phase step with the object held, intact  | ``+reward_hold``    |
    | the episode's last step reached, held, intact      | ``+reward_success`` |
    | the object is damaged (the step it happens)        | ``-penalty_damage`` |
    | the object slips / is dropped (the step it happens)| ``-penalty_slip``   |

    A full successful episode earns ``hold_steps * reward_hold + reward_success = 2``.

    **Damage** (``damage_rule: hoop_strain``; irreversible): the object is *overstressed* when the contact
    traction exceeds its failure stress ``sigma_f``, and *crushed* when the hoop strain ``delta kappa_obj`` of its
    indentation ``delta`` exceeds its failure strain ``eps_f`` (eq. 3.2's annulus: an indentation shrinks the whole
    ring). The paper task's rule (``damage_rule: crush_fraction``) is overstressed above ``3 eps_f mu_obj``, crushed
    when ``delta > crush_fraction H``. **Slip** (hold phase only, ``hold_rule: weight``): friction on the fingers
    cannot carry the object's weight, ``grip_faces mu_f F L_c b < m g``: the traction ``F`` over each finger's
    contact (its length ``L_c``, at most the object's share of wrap, and its width ``b = t + 2 h_s``) against the
    object's mass ``m`` from its 3D shape (a solid sphere of radius ``1/kappa_obj`` unless its class says otherwise).
    See ``docs/env.md`` ("The hold rule") for the physics of each threshold.

    ## Starting State

    Pressure 0, the actuator at rest (flat, unstrained). A new object is drawn from ``self.np_random``: a
    catalogue class, then its properties (see Catalogue), so ``reset(seed=s)`` gives the same object every time.
    ``reset(options={...})`` pins any of ``object_stiffness`` (``k~``), ``object_shear_modulus_kpa``,
    ``object_curvature`` (``w kappa_obj``), ``object_curvature_per_m``, ``object_thickness_mm``,
    ``object_density_kg_m3``, ``object_failure_strain`` (the other properties are still those drawn).

    ## Episode End

    * **Termination**: the object is damaged (irreversible), or it slips in the hold phase (dropped).
      (Configurable: ``terminate_on_damage``, ``terminate_on_slip``.)
    * **Truncation**: the hold phase ends (``squeeze_steps + hold_steps`` = 100 steps; this is the
      registered ``max_episode_steps``). A solve that fails to converge keeps the previous state and
      truncates, with ``info["solver_failed"]``.

    ``info["is_success"]`` is set on the last step of every episode: held to the end, intact.

    ## Version History

    * v1 (0.14): the hold rule carries the object's weight in 3D (``hold_rule: weight``: a solid sphere's mass, or
      a catalogue class's shape, on two fingers 90 mm long and ``t + 2 h_s`` wide, ``mu_f = 0.5``), not a slab of
      depth ``H``; the info gains ``object_mass_g``, ``contact_length_mm`` and (full) ``grip_force_n``. The
      traction a grip needs rose 2-30 times on the kitchen's objects, so success rates moved: the v0 ids keep the
      slab rule (``hold_rule: slab``) to reproduce results of 0.13 and earlier.
    * v0 (0.6): the catalogue's apple is its flesh's Young's modulus only, 0.81-3.28 MPa, with its failure strain
      0.11-0.312 and stress 235-444 kPa (0.5's whole-fruit moduli are dropped): a seed draws other apples than
      under 0.5.
    * v0 (0.5): the default objects changed: the catalogue's apple widened to 0.81-4.88 MPa (was 0.81-2.27 MPa), so
      the same seed drew a stiffer apple; results from before 0.5 are not comparable seed for seed (the id was
      kept).
    * v0 (0.3): the default task became the catalogue's ``kitchen`` under the hoop-strain rule; the reset info
      names the object's class (``object_class``). The paper's ring moved to ``PneuNetGrasp-Paper-v0``.
    * v0 (0.1, 0.2): the paper's object (a 250 mm ring, 10 mm thick) with its shear modulus log-uniform in
      0.1-1500 kPa, and the crush-fraction damage rule.

    ## Arguments

    ``gym.make("PneuNetGrasp-v1", render_mode=None, config=None, info_level="lean", **overrides)``: ``config``
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
    :func:`pneunet_env.task.build_info` every step (:data:`pneunet_env.task.FULL_KEYS`: the dimensionless state, the
    object, the thresholds' ratios, the solver's diagnostics). ``is_success`` is added on an episode's last step.

    ## Rendering

    ``render_mode="rgb_array"``: an ``(render_height, render_width, 3)`` uint8 picture (480 x 360): the
    actuator's chambers curling along their arc, the object's arc with its indentation, the load on it in
    colour (red when damaged), a pressure bar, a traction gauge (log scale, with the grip and failure
    marks), the episode's progress, a status lamp and, on frames of at least 240 x 180, a text label (top left:
    the object's class, or its ``k~`` when it has none or its stiffness was pinned, the step, the pressure in kPa
    and the state: free, squeezing, gripping, held, slipped, crushed or damaged). ``"human"`` shows the same
    picture in a matplotlib window (matplotlib is imported only then).
    """

    env_id = "PneuNetGrasp-v1"
    metadata = {"render_modes": ["human", "rgb_array"], "render_fps": 20}

    def __init__(self, render_mode: str | None = None, config: Any = None, info_level: str = "lean",
                 **overrides: Any) -> None:
        super().__init__(render_mode, config, info_level, overrides)
        self._params = task.EnvParams.from_config(self.config)
        self._contact = task.newton_contact
        # with numba, the step as one compiled call (pneunet_env.fused.SingleStep): task.step's result (bit for bit
        # without the free table; with it, a free step is the same minimum to the solver's tolerance)
        self._single = fused.SingleStep(self._params) if fused.HAVE_FUSED else None
        cls = type(self)
        self._own_step = cls._step_state is PneuNetGraspEnv._step_state and cls._info is PneuNetGraspEnv._info
        self._rest: Solve | None = None  # the solve at rest (see _rest_contact)
        self._class_names = task.class_names(self.config)
        self.observation_space = observation_space(self.config)
        self._warned = False
        self._static_info: dict[str, Any] | None = None
        self._viewer = None
        self._render_name = ""

    def _step_state(self, state: task.EnvState, action: float) -> task.Step:
        if self._single is None:
            return super()._step_state(state, action)
        return self._single(state, action)

    def _step_fast(self, state: task.EnvState | None, action: float) -> tuple | None:
        # the lean info straight from the compiled call's numbers (the full info needs the step's records; a subclass
        # with a step or an info of its own gets the record path, which calls them)
        if self._single is None or self.info_level != "lean" or not self._own_step:
            return None
        if state is not None:
            self._single.load(state)
        return self._single.step_lean(action)

    def _packed_state(self) -> task.EnvState:
        return self._single.state()

    def __copy__(self) -> PneuNetGraspEnv:
        """A shallow copy, as ``copy.copy`` makes, but with its own compiled step: the state it steps is packed there
        (after fast steps, the env's state lives only there), so sharing it would step the original too."""
        fields = dict(self.__dict__)
        if self._single is not None:
            fields["_single"] = copy.copy(self._single)
        new = object.__new__(type(self))
        new.__dict__.update(fields)
        return new

    # ---- the episode's object ----------------------------------------------------------------------
    def _reset_state(self, obj) -> task.EnvState:
        return task.reset_state(obj, self._params, self._rest_contact)

    def _rest_contact(self, kappa, side_strain, p0, p1, obj, params: task.EnvParams):
        """:func:`pneunet_env.task.newton_contact` as :func:`~pneunet_env.task.reset_state` calls it: from rest at zero
        pressure to zero pressure. That solve touches no object (``kappa~ = 0 < w kappa_obj``: eq. 3.1's contact and
        its derivatives are zero there), so its numbers are the same for every object: solved at the first reset, its
        record built for each object (a test checks the solve against objects from the softest to the stiffest). A
        subclass's own contact is asked every time."""
        if kappa != 0.0 or side_strain != 0.0 or p0 != 0.0 or p1 != 0.0 or self._contact is not task.newton_contact:
            return self._contact(kappa, side_strain, p0, p1, obj, params)
        if self._rest is None:
            self._rest = step_state(kappa, side_strain, p0, p1, params.actuator, obj.stiffness, obj.curvature,
                                    params.solver)
        return equilibrium(p1, self._rest, params.actuator.chamber_height, obj.stiffness, obj.curvature)

    def _accept_object(self, obj) -> None:
        check_object(obj.stiffness, obj.curvature)
        self._warned = task.warn_if_beyond_convergence(obj, self._warned)

    def _after_reset(self, obj, options: dict[str, Any] | None) -> None:
        # the table's object rows written out for one object (object_info_one: a test keeps them equal)
        self._static_info = object_info_one(obj, self._state.thresholds, self._params.task)
        self._static_info["object_class"] = name = task.class_name(self._class_names, obj.class_id)
        self._render_name = _render_name(name, obj, options)

    def _info(self, res: task.Step | None) -> dict[str, Any]:
        if res is None and self.info_level == "lean" and self._own_step:
            return self._reset_info()
        return task.build_info(self._state, self._params.task, res, self.info_level, self._static_info)

    def _reset_info(self) -> dict[str, Any]:
        """The lean reset info, as :func:`~pneunet_env.task.build_info` gives it (the same keys in the same order, the
        same values of the same types: a test keeps them equal), from the state's numbers and the object's constants
        (``_static_info``): :func:`pneunet_env.info.lean_info`, the lean step info's own line, with the flags of a
        state before any step (no step taken, nothing clipped, failed, held, damaged or dropped yet)."""
        state, tp = self._state, self._params.task
        eq, t = state.eq, state.task
        lean = lean_info(eq.pressure, eq.curvature, eq.contact_force, eq.indentation, eq.in_contact, t.step, t.damaged,
                         t.dropped, eq.snapped, eq.converged, False, False, False, False, False, False, False,
                         tp.shear_modulus_kpa, tp.width_mm)
        info = _RESET_TEMPLATE.copy()  # the keys in build_info's order, the values filled in
        info.update(lean)
        info.update(self._static_info)
        return info

    # ---- rendering ---------------------------------------------------------------------------------
    def render(self):
        self._check_open("render")
        if self.render_mode is None:
            gym.logger.warn(
                "You are calling render method without specifying any render mode. "
                'Pass render_mode="rgb_array" or "human" to gym.make("PneuNetGrasp-v1", ...).'
            )
            return None
        from pneunet_env.envs.render import HumanViewer, render_frame

        r = self.config.render
        frame = render_frame(self.render_state(), r.width, r.height, chambers=r.chambers)
        if self.render_mode == "rgb_array":
            return frame
        if self._viewer is None:
            self._viewer = HumanViewer(title="PneuNetGrasp-v1", fps=self.metadata["render_fps"])
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


def _render_name(class_name: str, obj, options: dict[str, Any] | None) -> str:
    """The frame's label for ``obj``: its class's name, unless it was drawn from ranges or its stiffness was pinned
    (``""``: the frame then names it by its ``k~``)."""
    if obj.class_id < 0 or (options is not None and any(
            options.get(k) is not None for k in ("object_stiffness", "object_shear_modulus_kpa"))):
        return ""
    return class_name


def observation_space(config: EnvConfig) -> spaces.Box:
    """One env's observation space: ``[p / p_max]``, or ``[p / p_max, dV / dV_free(p_max)]`` with ``observe_volume``."""
    if config.task.observe_volume:
        return spaces.Box(np.array([0.0, -np.inf], np.float32), np.array([1.0, np.inf], np.float32), dtype=np.float32)
    return spaces.Box(0.0, 1.0, (1,), np.float32)
