"""The ``info`` dict of the envs: one table, :data:`INFO`, from each key to the function that computes it.

Each key's :class:`InfoKey` gives its function (of an :class:`InfoContext`: the state, the step's result and the
task's numbers), its level and what it means. The levels are derived from the table:

* ``"lean"`` (the default): the keys marked ``"lean"`` every step (:data:`LEAN_KEYS`), and the object's constants
  (``"object"``, :data:`OBJECT_KEYS`) at reset;
* ``"full"``: every key, every step (:data:`FULL_KEYS`, the table's order).

The values are physical (``*_kpa``, ``*_mm``, ``*_per_m``) or dimensionless as named, on the array namespace the
task's params carry (Python scalars for one env, ``(N,)`` arrays or tensors for a batch); ``solver_status`` is always
on the host (strings). A new key is one row of the table.
"""

from __future__ import annotations

from collections.abc import Callable
from functools import cached_property
from typing import Any, NamedTuple

from pneunet_env.objects import GraspObject
from pneunet_env.physics.solver import status_message
from pneunet_env.task_objects import Thresholds, contact_length_mm

# The task's records (TaskParams, EnvState, Step) are typed Any here: pneunet_env.task imports this module.

__all__ = ["INFO", "InfoKey", "InfoContext", "INFO_LEVELS", "LEAN_KEYS", "OBJECT_KEYS", "FULL_KEYS", "info_keys",
           "build_info", "object_info", "object_info_one", "lean_info"]

INFO_LEVELS = ("lean", "full")
"""``info_level`` of the envs: ``"lean"`` (default) gives :data:`LEAN_KEYS` every step and the object's constants
at reset; ``"full"`` gives every key of :data:`INFO` every step."""


class InfoContext:
    """What the info's values are computed from: one state (after a step, or at reset) and the task's numbers.

    Attributes: ``eq``, ``obj``, ``thresholds``, ``task`` (the state's records), ``solve`` (the step's solve; the
    state's equilibrium at reset), ``outcome`` (the rules' :class:`~pneunet_env.task.Outcome`; ``None`` at reset),
    ``action_clipped``, ``solver_failed``, ``params`` and its ``ops``, ``mu`` (kPa) and ``w`` (mm).
    """

    def __init__(self, params: Any, obj: GraspObject, thresholds: Thresholds, state: Any = None,
                 result: Any = None) -> None:
        self.params, self.ops = params, params.ops
        self.mu, self.w = params.shear_modulus_kpa, params.width_mm
        self.obj, self.thresholds = obj, thresholds
        if state is not None:
            self.eq, self.task = state.eq, state.task
            self.solve = self.eq if result is None else result.solve
        self.result = result
        self.outcome = None if result is None else result.outcome

    @property
    def action_clipped(self):
        """The step's action was clipped (``False`` at reset)."""
        return self.no() if self.result is None else self.result.action_clipped

    @property
    def solver_failed(self):
        """The step's solve failed (``False`` at reset)."""
        return self.no() if self.result is None else self.result.solver_failed

    def no(self):
        """``False`` on the namespace, in the state's shape (a flag at reset, before any step)."""
        return self.ops.full_like(self.eq.pressure, False, "bool")

    def flag(self, name: str):
        """The outcome's flag ``name`` (``False`` at reset)."""
        return self.no() if self.outcome is None else getattr(self.outcome, name)

    @cached_property
    def delta(self):
        """The indentation ``delta~``, 0 out of contact."""
        return self.ops.where(self.eq.in_contact, self.eq.indentation, 0.0)

    def ratio(self, a, b):
        """``a / b``, and 0 where ``b`` is 0 (an object of zero modulus carries no traction)."""
        where = self.ops.where
        return where(b > 0.0, a / where(b > 0.0, b, 1.0), 0.0)


class InfoKey(NamedTuple):
    """One key of the info: how it is computed, at which level it is given, what it is."""

    value: Callable[[InfoContext], Any]
    level: str  # "lean": every step at both levels; "object": at reset (lean) and every step (full); "full"
    doc: str


INFO: dict[str, InfoKey] = {
    "pressure": InfoKey(lambda c: c.eq.pressure, "full", "p~ = p / mu (a rigid jaw's closure, mm)"),
    "pressure_kpa": InfoKey(lambda c: c.eq.pressure * c.mu, "lean", "p (kPa)"),
    "curvature": InfoKey(lambda c: c.eq.curvature, "full", "kappa~ = w kappa, the base's curvature"),
    "curvature_per_m": InfoKey(lambda c: c.eq.curvature / (c.w * 1e-3), "lean", "kappa (1/m)"),
    "side_strain": InfoKey(lambda c: c.eq.side_strain, "full", "e_s"),
    "top_strain": InfoKey(lambda c: c.eq.top_strain, "full", "e_m"),
    "contact_force": InfoKey(lambda c: c.eq.contact_force, "full", "F~ = F / mu, the traction on the object"),
    "contact_force_kpa": InfoKey(lambda c: c.eq.contact_force * c.mu, "lean", "F (kPa)"),
    "indentation": InfoKey(lambda c: c.delta, "full", "delta~ = delta / w (0 out of contact)"),
    "indentation_mm": InfoKey(lambda c: c.delta * c.w, "lean", "delta (mm)"),
    "volume_change": InfoKey(lambda c: c.eq.volume_change, "full", "(V1 - V0) / (w^2 t)"),
    "volume_change_mm3": InfoKey(lambda c: c.eq.volume_change * c.w * c.w * c.params.depth_mm, "full",
                                 "V1 - V0 (mm^3)"),
    "in_contact": InfoKey(lambda c: c.eq.in_contact, "lean", "the actuator presses on the object"),
    "object_stiffness": InfoKey(lambda c: c.obj.stiffness, "object", "k~ = k_obj w / mu"),
    "object_stiffness_kpa_per_mm": InfoKey(lambda c: c.obj.stiffness * c.mu / c.w, "object", "k_obj (kPa/mm)"),
    "object_shear_modulus_kpa": InfoKey(lambda c: c.obj.shear_modulus_kpa, "object", "mu_obj (kPa)"),
    "object_curvature": InfoKey(lambda c: c.obj.curvature, "object", "w kappa_obj"),
    "object_curvature_per_m": InfoKey(lambda c: c.obj.curvature_per_m, "object", "kappa_obj (1/m)"),
    "object_thickness_mm": InfoKey(lambda c: c.obj.thickness_mm, "object", "H (mm)"),
    "object_density_kg_m3": InfoKey(lambda c: c.obj.density_kg_m3, "object", "rho (kg/m^3)"),
    "object_failure_strain": InfoKey(lambda c: c.obj.failure_strain, "object", "eps_f"),
    "object_mass_g": InfoKey(lambda c: c.obj.mass_kg * 1e3, "object",
                             "m (g), from its 3D shape: what the grip must carry (hold_rule weight)"),
    "contact_length_mm": InfoKey(lambda c: contact_length_mm(c.obj, c.params), "object",
                                 "L_c (mm): each finger's contact, its length up to the object's share of wrap"),
    "object_class": InfoKey(lambda c: c.obj.class_id, "object",
                            "the catalogue class's code (-1: drawn from ranges); its name in a single env"),
    "failure_traction_kpa": InfoKey(lambda c: c.thresholds.failure_traction * c.mu, "object",
                                    "overstressed above this traction (kPa)"),
    "crush_indentation_mm": InfoKey(lambda c: c.thresholds.crush_indentation * c.w, "object",
                                    "crushed above this indentation (mm)"),
    "grip_traction_kpa": InfoKey(lambda c: c.thresholds.grip_traction * c.mu, "object",
                                 "slips below this traction in the hold phase (kPa)"),
    "grip_force_n": InfoKey(lambda c: c.params.grip_faces * c.params.friction_coefficient * c.eq.contact_force
                            * c.mu * contact_length_mm(c.obj, c.params) * c.params.finger_width_mm * 1e-3, "full",
                            "grip_faces mu_f F L_c b (N): the weight friction can carry now (hold_rule weight)"),
    "grip_ratio": InfoKey(lambda c: c.ratio(c.eq.contact_force, c.thresholds.grip_traction), "full",
                          "F over the grip traction (>= 1 holds)"),
    "damage_ratio": InfoKey(lambda c: c.ops.maximum(c.ratio(c.eq.contact_force, c.thresholds.failure_traction),
                                                    c.ratio(c.delta, c.thresholds.crush_indentation)), "full",
                            "the larger of F and delta over their damage thresholds (>= 1 damages)"),
    "peak_contact_force_kpa": InfoKey(lambda c: c.task.peak_force * c.mu, "full", "the largest F so far (kPa)"),
    "step": InfoKey(lambda c: c.task.step, "lean", "steps taken"),
    "damaged": InfoKey(lambda c: c.task.damaged, "lean", "damaged so far (sticky)"),
    "dropped": InfoKey(lambda c: c.task.dropped, "lean", "slipped in the hold phase so far (sticky)"),
    "snapped": InfoKey(lambda c: c.solve.snapped, "lean", "the step's solve crossed a fold"),
    "solver_converged": InfoKey(lambda c: c.solve.converged, "lean", "the step's solve converged"),
    "solver_failed": InfoKey(lambda c: c.solver_failed, "lean",
                             "it did not: the state was kept and the episode truncates"),
    "solver_iterations": InfoKey(lambda c: c.solve.iterations, "full", "Newton iterations of the step's solve"),
    "solver_substeps": InfoKey(lambda c: c.solve.substeps, "full", "its pressure sub-steps"),
    "solver_evaluations": InfoKey(lambda c: c.solve.evaluations, "full",
                                  "its energy evaluations (the work; fewer where the vector env's cache had one)"),
    "solver_backtracks": InfoKey(lambda c: c.solve.backtracks, "full", "its rejected line-search trials"),
    "solver_status": InfoKey(lambda c: status_message(c.ops.to_host(c.solve.status)), "full",
                             "its status, in words (on the host)"),
    "gradient_norm": InfoKey(lambda c: c.solve.gradient_norm, "full", "|grad U| at its answer"),
    "min_eigenvalue": InfoKey(lambda c: c.solve.min_eigenvalue, "full", "the Hessian's smallest eigenvalue there"),
    "action_clipped": InfoKey(lambda c: c.action_clipped, "lean", "the action was outside [-1, 1] and clipped"),
    "in_hold": InfoKey(lambda c: c.flag("in_hold"), "lean", "the step is in the hold phase"),
    "overstressed": InfoKey(lambda c: c.flag("overstressed"), "lean", "F above the failure traction now"),
    "crushed": InfoKey(lambda c: c.flag("crushed"), "lean", "delta above the crush indentation now (in contact)"),
    "slipping": InfoKey(lambda c: c.flag("slipping"), "lean", "hold phase, F below the grip traction now"),
    "held": InfoKey(lambda c: c.flag("held"), "lean", "a hold-phase step with the object held and intact"),
}
"""Every info key, in the full info's order: its function, its level and its meaning."""

LEAN_KEYS = tuple(k for k, e in INFO.items() if e.level == "lean")
"""The keys of a lean step info: pressure, curvature, contact, the task's flags and the solver's status."""

OBJECT_KEYS = tuple(k for k, e in INFO.items() if e.level == "object")
"""The object's constants (:func:`object_info`): in every reset info, and in every step's with ``"full"``."""

FULL_KEYS = tuple(INFO)
"""The keys of a full info (:func:`build_info` with ``level="full"``)."""

_KEYS = {("lean", False): LEAN_KEYS, ("lean", True): tuple(k for k in FULL_KEYS if INFO[k].level != "full"),
         ("full", False): FULL_KEYS, ("full", True): FULL_KEYS}
"""The keys of an info by ``(level, at reset)``."""

_ROWS = {key: tuple((k, INFO[k].value, INFO[k].level == "object") for k in keys) for key, keys in _KEYS.items()}
"""``(key, function, an object constant?)`` of each key of :data:`_KEYS` (looked up once, not on every step)."""


def info_keys(level: str) -> tuple[str, ...]:
    """Every key an info of ``level`` can hold (the lean level's reset info adds the object's constants)."""
    if level not in INFO_LEVELS:
        raise ValueError(f"info_level must be one of {INFO_LEVELS}, got {level!r}")
    return LEAN_KEYS + OBJECT_KEYS if level == "lean" else FULL_KEYS


def object_info(obj: GraspObject, thresholds: Thresholds, params: Any) -> dict[str, Any]:
    """The entries of :func:`build_info` that depend only on the object (constant over an episode).

    An environment may compute them once per episode and pass them to :func:`build_info` as ``static``
    (the values are the same; only the work is saved).
    """
    c = InfoContext(params, obj, thresholds)
    return {k: INFO[k].value(c) for k in OBJECT_KEYS}


def object_info_one(obj: GraspObject, thresholds: Thresholds, params: Any) -> dict[str, Any]:
    """:func:`object_info` of one object (Python scalars), written out: the same keys in the same order, the same
    values of the same types (a test keeps the two equal, key for key), without the table's rows and their context
    (about 5 us of a single env's reset). A new ``"object"`` row of :data:`INFO` is a new line here too."""
    mu, w = params.shear_modulus_kpa, params.width_mm
    return {
        "object_stiffness": obj.stiffness,
        "object_stiffness_kpa_per_mm": obj.stiffness * mu / w,
        "object_shear_modulus_kpa": obj.shear_modulus_kpa,
        "object_curvature": obj.curvature,
        "object_curvature_per_m": obj.curvature_per_m,
        "object_thickness_mm": obj.thickness_mm,
        "object_density_kg_m3": obj.density_kg_m3,
        "object_failure_strain": obj.failure_strain,
        "object_mass_g": obj.mass_kg * 1e3,
        "contact_length_mm": contact_length_mm(obj, params),
        "object_class": obj.class_id,
        "failure_traction_kpa": thresholds.failure_traction * mu,
        "crush_indentation_mm": thresholds.crush_indentation * w,
        "grip_traction_kpa": thresholds.grip_traction * mu,
    }


def build_info(
    state: Any,
    params: Any,
    result: Any = None,
    level: str = "lean",
    static: dict[str, Any] | None = None,
) -> dict[str, Any]:
    """The ``info`` dict of ``state``: the keys of ``level`` (see the module), each computed by its row of :data:`INFO`.

    Args:
        state: the state after the step (or at reset).
        params: the task's numbers (with the array namespace, ``params.ops``).
        result: the step's :class:`~pneunet_env.task.Step` (``None`` at reset).
        level: ``"lean"`` or ``"full"``.
        static: ``object_info(obj, thresholds, params)``, if the caller keeps it (computed here otherwise).

    Every array value is freshly computed or one of the state's own arrays (which a batched env copies), unless
    ``static`` holds arrays.
    """
    if level not in INFO_LEVELS:
        raise ValueError(f"info_level must be one of {INFO_LEVELS}, got {level!r}")
    c = InfoContext(params, state.obj, state.thresholds, state, result)
    rows = _ROWS[level, result is None]
    if static is None:
        return {k: value(c) for k, value, _ in rows}
    return {k: static[k] if constant else value(c) for k, value, constant in rows}


def lean_info(pressure: float, curvature: float, contact_force: float, indentation: float, in_contact: bool,
              step: int, damaged: bool, dropped: bool, snapped: bool, converged: bool, failed: bool, clipped: bool,
              in_hold: bool, overstressed: bool, crushed: bool, slipping: bool, held: bool, mu: float,
              w: float) -> dict[str, Any]:
    """A single env's lean step info (:data:`LEAN_KEYS`, in their order) from Python scalars: the state's
    equilibrium and task state after the step, the step's solve (``snapped``, ``converged``) and flags, and the
    task's ``mu`` (kPa) and ``w`` (mm).

    The same values, of the same types, as :func:`build_info` gives with ``level="lean"`` after a step (a test keeps
    the two equal, key for key): the rows of :data:`INFO` marked ``"lean"``, written out for the single env's
    compiled step (:meth:`pneunet_env.fused.SingleStep.step_lean`), which builds no records (the table's rows cost
    about 5 us a step). A new lean row of :data:`INFO` is a new line here too.
    """
    return {
        "pressure_kpa": pressure * mu,
        "curvature_per_m": curvature / (w * 1e-3),
        "contact_force_kpa": contact_force * mu,
        "indentation_mm": (indentation if in_contact else 0.0) * w,
        "in_contact": in_contact,
        "step": step,
        "damaged": damaged,
        "dropped": dropped,
        "snapped": snapped,
        "solver_converged": converged,
        "solver_failed": failed,
        "action_clipped": clipped,
        "in_hold": in_hold,
        "overstressed": overstressed,
        "crushed": crushed,
        "slipping": slipping,
        "held": held,
    }
