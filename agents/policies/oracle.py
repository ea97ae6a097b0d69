"""The oracle: it knows the object and picks the best constant target pressure for it. Not blind.

It is the feasibility ceiling of the ramp family. At each episode's start (:meth:`Oracle.begin_episode`,
given ``reset``'s ``info``) it reads the object (``k~``, ``w kappa_obj``) and its thresholds, follows the
quasi-static loading path from rest with the env's own solver (:func:`pneunet_env.load_path`, on a pressure
grid of ``resolution_kpa``), and picks the pressure ``p*`` with the widest margin

    margin(p) = min( log(F(p) / F_grip),  -log max_{p' <= p} damage_ratio(p') )

where ``damage_ratio = max(F / F_failure, delta / delta_crush)``: the grip must hold at ``p*`` and no pressure on
the way up may damage. It then steps to ``p*`` as fast as the action allows and holds it. If the best margin is
negative, no constant target on the loading path both holds and spares that object. The plan uses the full
model (the env's default, ``model: full``); with ``model: linear`` or ``auto`` the env's states differ slightly
from the plan's.

That the ceiling is a property of the thresholds, not of the schedule's blindness, follows from a bound that
no schedule (monotone or not) can beat: the object is held only if ``F = k_obj delta >= F_grip`` and intact only
if ``delta <= crush_fraction H`` (and ``F <= sigma_f``), a condition on the *state* alone. So where
``k_obj crush_fraction H < F_grip`` (:func:`feasible_stiffness`) no state, hence no schedule, succeeds.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from pneunet_env.config import EnvConfig
from pneunet_env.physics.solver import load_path

__all__ = ["Oracle", "OraclePlan", "plan_target", "feasible_stiffness"]


GRID_POINTS = 120
"""The oracle's pressure grid: ``max_pressure_kpa / 120`` apart by default (0.5 kPa at 60 kPa)."""


def default_resolution(config: EnvConfig) -> float:
    """The oracle's default pressure grid spacing (kPa): ``max_pressure_kpa /`` :data:`GRID_POINTS`."""
    return config.task.max_pressure_kpa / GRID_POINTS


class OraclePlan(dict):
    """The oracle's choice for one object: ``target`` (fraction of ``p_max``), ``pressure_kpa``, ``margin``
    (natural log; > 0 is feasible), ``feasible`` (bool), ``grip_ratio``, ``damage_ratio`` at the target, and
    ``reached_kpa``: the highest pressure of the grid that the loading path reaches (``max_pressure_kpa``, or less
    where the path ends: see :func:`plan_target`)."""


def plan_target(
    object_stiffness: float,
    object_curvature: float,
    failure_traction: float,
    crush_indentation: float,
    grip_traction: float,
    config: EnvConfig,
    resolution_kpa: float | None = None,
) -> OraclePlan:
    """The best constant pressure for one object (all arguments dimensionless: ``/mu``, ``/w``).

    Args:
        object_stiffness: ``k~``.
        object_curvature: ``w kappa_obj``.
        failure_traction, crush_indentation, grip_traction: the object's thresholds (``F~_f``, ``delta~_c``,
            ``F~_g``; :func:`pneunet_env.task.object_thresholds`).
        config: the env's config (actuator, pressure range, solver).
        resolution_kpa: the pressure grid's spacing; ``None``: ``max_pressure_kpa / 120`` (:data:`GRID_POINTS`;
            0.5 kPa at the default 60 kPa), so a soft actuator's few kPa get as fine a grid as Table 1's.

    The candidates are the pressures the loading path reaches. Where it ends below ``max_pressure_kpa`` (from some
    pressure on the solver finds no equilibrium: a neo-Hookean material, ``gent_limit: 1e9``, whose actuator
    balloons or bends shut without the Gent limit's stiffening, or a very soft one, ``shear_modulus_kpa: 0.1``, at
    hundreds of ``mu``), the pressures above its end are not candidates: the env's step fails there as well, and its
    episode truncates. ``reached_kpa`` says where it ended.
    """
    resolution_kpa = default_resolution(config) if resolution_kpa is None else resolution_kpa
    if not resolution_kpa > 0.0:
        raise ValueError(f"resolution_kpa must be > 0, got {resolution_kpa!r}")
    p_max = config.pressure_max
    n = max(2, int(math.ceil(config.task.max_pressure_kpa / resolution_kpa)) + 1)
    ps = np.linspace(0.0, p_max, n)
    lp = load_path(ps, object_stiffness, object_curvature, config.actuator_params, config.solver)
    # the path's end: its first pressure without an equilibrium, and every one above it (the env's step fails there
    # too, and its episode truncates): a soft or neo-Hookean material's actuator that bends shut or balloons
    reached = int(np.argmin(lp.converged)) if not lp.converged.all() else n
    if reached == 0:  # pragma: no cover - rest, at p = 0, is an equilibrium of every valid material
        raise ValueError(f"oracle: the material (shear modulus {config.actuator.shear_modulus_kpa:g} kPa, Gent limit "
                         f"{config.actuator.gent_limit:g}) has no equilibrium at rest: the loading path cannot start")
    ps = ps[:reached]
    F = lp.contact_force[:reached]
    in_contact = np.array([e.in_contact for e in lp.equilibria[:reached]])
    delta = np.where(in_contact, lp.indentation[:reached], 0.0)
    with np.errstate(divide="ignore"):
        damage = np.maximum(F / failure_traction if failure_traction > 0 else np.inf * (F > 0),
                            delta / crush_indentation)
        worst = np.maximum.accumulate(damage)
        grip = F / grip_traction
        margin = np.minimum(np.log(grip), -np.log(worst))
    margin = np.where(np.isnan(margin), -np.inf, margin)
    i = int(np.argmax(margin))
    return OraclePlan(
        target=float(ps[i] / p_max),
        pressure_kpa=float(ps[i] * config.actuator.shear_modulus_kpa),
        margin=float(margin[i]),
        feasible=bool(margin[i] >= 0.0),
        grip_ratio=float(grip[i]),
        damage_ratio=float(worst[i]),
        reached_kpa=float(ps[-1] * config.actuator.shear_modulus_kpa),
    )


def feasible_stiffness(config: EnvConfig, density_kg_m3: float | None = None) -> float:
    """The smallest ``k~`` at which some state both holds an object of the config's ranges and spares it: the grip
    traction over the crush indentation, ``F~_grip / delta~_c``, of the env's own thresholds (both hold rules, both
    damage rules), at the corner of the ranges where it is smallest.

    Under the paper's rules (``hold_rule: slab``, ``damage_rule: crush_fraction``) ``F~_grip = rho g H / (grip_faces
    mu_f mu)`` and ``delta~_c = crush_fraction H/w``, so ``H`` cancels: ``k~ = rho g w / (grip_faces mu_f
    crush_fraction mu)``, set by the density alone. The lightest objects (``density_kg_m3`` default: the range's low
    end) are the easiest to hold, so below this ``k~`` no object of the config can be held intact. (The
    failure-stress rule is not part of this bound: at the paper's size ``k_obj H = 0.0076 sigma_f``.)
    """
    from pneunet_env.task import TaskParams, object_thresholds, sample_object

    oc = config.objects
    rho = oc.object_density_kg_m3[0] if density_kg_m3 is None else float(density_kg_m3)
    params = TaskParams.from_config(config)
    ranges = config.replace(use_case=None, class_weights=None)  # the corners of the ranges, the config's shape
    best = np.inf
    for thickness in oc.object_thickness_mm:
        for curvature in oc.object_curvature_per_m:
            pins = {"object_shear_modulus_kpa": 1.0, "object_thickness_mm": thickness, "object_curvature_per_m":
                    curvature, "object_density_kg_m3": rho, "object_failure_strain": oc.object_failure_strain[1]}
            obj = sample_object(np.random.default_rng(0), ranges, None, pins)
            thr = object_thresholds(obj, params)
            best = min(best, float(thr.grip_traction / thr.crush_indentation))
    return best


class Oracle:
    """Knows each object (from ``reset``'s ``info``) and steps to its best constant pressure (:func:`plan_target`).

    Args:
        config: the env's config (the defaults if ``None``).
        resolution_kpa: the pressure grid the choice is made on (``None``: ``max_pressure_kpa / 120``).

    Call :meth:`begin_episode` with ``reset``'s ``info`` before the episode's first action
    (:func:`agents.evaluation.episodes.run_episode` does). ``plan`` holds the last choice.
    """

    blind = False

    def __init__(self, config: EnvConfig | None = None, resolution_kpa: float | None = None) -> None:
        self.config = EnvConfig() if config is None else config
        self.resolution_kpa = float(default_resolution(self.config) if resolution_kpa is None else resolution_kpa)
        if not (math.isfinite(self.resolution_kpa) and self.resolution_kpa > 0.0):  # refused now, not at first use
            raise ValueError(f"resolution_kpa must be a finite number > 0 (kPa), got {resolution_kpa!r}")
        self.step_fraction = self.config.task.max_pressure_step_kpa / self.config.task.max_pressure_kpa
        self.plan: OraclePlan | None = None
        self._cache: dict[tuple[float, ...], OraclePlan] = {}

    def begin_episode(self, info: dict[str, Any] | None = None) -> None:
        if info is None or "object_stiffness" not in info:
            raise ValueError("the oracle needs reset()'s info (object_stiffness, thresholds) at each episode start")
        cfg = self.config
        mu, w = cfg.actuator.shear_modulus_kpa, cfg.actuator.width_mm
        key = (float(info["object_stiffness"]), float(info["object_curvature"]), float(info["failure_traction_kpa"]),
               float(info["crush_indentation_mm"]), float(info["grip_traction_kpa"]))
        if key not in self._cache:
            self._cache[key] = plan_target(key[0], key[1], key[2] / mu, key[3] / w, key[4] / mu, cfg,
                                           self.resolution_kpa)
        self.plan = self._cache[key]

    def reset(self) -> None:
        self.plan = None

    def __call__(self, observation) -> np.ndarray:
        if self.plan is None:
            raise RuntimeError("Oracle: call begin_episode(info) with reset()'s info first")
        p = np.asarray(observation, dtype=np.float64)[..., 0]
        a = (self.plan["target"] - p) / self.step_fraction
        return np.clip(a, -1.0, 1.0)[..., None].astype(np.float32)

    def predict(self, observation, state=None, episode_start=None, deterministic: bool = True):
        return self(observation), state

    def __repr__(self) -> str:
        return f"Oracle(resolution_kpa={self.resolution_kpa:g})"
