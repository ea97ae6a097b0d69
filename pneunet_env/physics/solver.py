"""The quasi-static minimiser's Python API: its options, its entry points and the solved-state record.

An equilibrium at pressure ``p`` is the local minimum of the energy (:mod:`pneunet_env.physics.mechanics`)
reached from the previous state, followed by pressure continuation. The algorithm (the safeguarded Newton descent,
the continuation and its step control), its constants, status codes and records, and its compiled scalar code are
:mod:`pneunet_env.physics.continuation`'s; this module re-exports those names (``from pneunet_env.physics.solver
import X`` finds them here too).

This module holds the solver's options (:class:`SolverOptions`, :data:`OPTION_BOUNDS`, :data:`DEFAULT_OPTIONS`),
the compiled entries Python calls, cached on disk (:data:`step_state`, ``step_state_from``, :data:`evaluate_state`),
the one solved-state type (:class:`Equilibrium`, built by :func:`equilibrium`) and the validated calls:
:func:`solve_equilibrium`, :func:`minimise_state`, :func:`load_path` (:class:`LoadPath`), :func:`check_pressure`,
:func:`params_tuple`.
"""

from __future__ import annotations

import sys
from dataclasses import dataclass
from typing import Any, NamedTuple

import numpy as np

from pneunet_env.physics import _jit, contact, continuation, mechanics, xp
from pneunet_env.physics._jit import njit, python_entry
from pneunet_env.physics.contact import scalar_contact
from pneunet_env.physics.continuation import (  # noqa: F401  (the algorithm's names, re-exported)
    ACCEPT_GTOL,
    ARMIJO,
    BRANCH_MIDPOINT_FRACTION,
    BRANCH_PREDICTED_CHANGE,
    EASY_CORRECTOR_ITERATIONS,
    ENERGY_ROUNDOFF,
    ESCAPE_GRADIENT,
    ESCAPE_STEP,
    GROW,
    LAST_STEP_SLACK,
    MIN_STEP_LENGTH,
    PREDICTED_JUMP_FRACTION,
    SHRINK,
    STATUS_BUDGET,
    STATUS_CONVERGED,
    STATUS_INACTIVE,
    STATUS_LINE_SEARCH,
    STATUS_MAX_ITER,
    STATUS_MESSAGES,
    STATUS_OUTSIDE,
    STATUS_ROUNDOFF,
    STATUS_STALLED,
    STEP_AFTER_FOLD,
    STEP_CONTROLS,
    ActuatorNumbers,
    Continuation,
    Descent,
    Minimum,
    Solve,
    _descend,
    _evaluate,
    _follow_ev,
    _follow_from,
    _make_parts,
    _minimise,
    hermite_midpoint,
    hessian_solve,
    make_sym2,
    predicted_change_limit,
    status_message,
    sym2_eigvals,
    sym2_eigvec,
)
from pneunet_env.physics.mechanics import Evaluation
from pneunet_env.physics.params import ActuatorParams, check_finite, check_object

__all__ = [
    "SolverOptions",
    "DEFAULT_OPTIONS",
    "Equilibrium",
    "ActuatorNumbers",
    "Minimum",
    "Descent",
    "Solve",
    "Continuation",
    "LoadPath",
    "STATUS_MESSAGES",
    "status_message",
    "make_sym2",
    "minimise_state",
    "solve_equilibrium",
    "load_path",
    "equilibrium",
    "sym2_eigvals",
    "sym2_eigvec",
    "step_state",
    "step_state_from",
    "evaluate_state",
    "params_tuple",
    "check_pressure",
    "ACCEPT_GTOL",
]


OPTION_BOUNDS: dict[str, tuple[float, float, str]] = {
    "gtol": (1e-16, ACCEPT_GTOL, "below 1e-16 no double-precision gradient can be resolved; above ACCEPT_GTOL a "
             "'converged' state would not have a zero gradient"),
    "max_iter": (1, 100_000, "a compiled int64 counter; a descent that needs more has failed anyway"),
    "corrector_max_iter": (1, 1_000, "a corrector that needs more than this is off its branch"),
    "max_step": (1e-6, 1.0, "the env's whole pressure range is p~ = 1.2; a sub-step under 1e-6 (0.05 Pa) measures "
                 "nothing"),
    "min_step": (1e-12, 1.0, "a fold located to better than 1e-12 in p~ (5e-8 Pa) is below round-off of the state"),
    "max_jump": (1e-5, 1.0, "the state (kappa~, e_s) is of order 0.01-1; smaller branch steps only cost sub-steps"),
    "eig_floor": (1e-16, 1e-2, "a relative floor on |lambda|: at most a percent, at least round-off"),
    "max_substeps": (1, 1_000_000, "the budget of sub-step attempts of one call: a call that spends it is flagged "
                     "unconverged, never hangs"),
}
"""``(low, high, why)`` of every :class:`SolverOptions` field: the bounds the physics and the arithmetic justify."""
MAX_ITERATIONS = int(OPTION_BOUNDS["max_iter"][1])

_INT_OPTIONS = ("max_iter", "corrector_max_iter", "max_substeps")


@dataclass(frozen=True)
class SolverOptions:
    """Tolerances of the minimiser (dimensionless); each within :data:`OPTION_BOUNDS`.

    Attributes:
        gtol: Stop once ``|grad|_2 <= gtol`` and the Hessian is positive definite. (A state that stalls
            at round-off above ``gtol`` still counts as converged if ``|grad|_2 <= 1e-10``.)
        max_iter: Newton iterations allowed for a full descent (after a snap, or a cold start).
        corrector_max_iter: Newton iterations allowed for a continuation corrector before the
            sub-step is shrunk.
        max_step: Largest pressure sub-step ``dp~``.
        min_step: Smallest pressure sub-step; a branch that cannot be followed over it has ended (fold).
        max_jump: Largest state change ``max(|d kappa~|, |d e_s|)`` over one sub-step on the same branch (under
            ``step_control="branch"``: from the sub-step's predictor, its ends checked to lie on one branch); a fold
            whose jump is larger sets ``snapped``.
        eig_floor: Relative floor on the modified Hessian's eigenvalues.
        max_substeps: Sub-step attempts (accepted, shrunk or a fold) allowed in one call; when they are spent the
            call stops with status :data:`STATUS_BUDGET` (not converged). The env's steps take at most about 50.
        free_table: Whether the envs' compiled step (numba: the vector env's fused step, the single env's compiled
            call) takes a step that touches nothing along the free actuator's tabulated path
            (:mod:`pneunet_env.physics.free_table`): one or two energy evaluations instead of 4 to 11, the state a
            converged minimum as always, within the tolerance of the continuation's (not bit for bit). ``False``:
            the continuation for every step, bit for bit the array step's. The continuation's own calls
            (:func:`solve_equilibrium`, :func:`step_state`, the array step) do not read it; it is not part of
            :meth:`as_tuple`.
        step_control: How long a continuation sub-step may be. ``"jump"`` (the default until 0.12): a sub-step is
            accepted only if the state moved at most ``max_jump`` from its start, and sized so that the tangent
            predicts ``0.75 max_jump``. ``"branch"`` (the default): also a longer one (a predicted change up to
            :data:`BRANCH_PREDICTED_CHANGE`) whose corrector converged within ``max_jump`` of its predictor and whose
            two ends lie on one branch (the Newton correction at the middle of their cubic Hermite interpolant is
            at most :data:`BRANCH_MIDPOINT_FRACTION` ``max_jump``); folds are found and ``snapped`` set as before.
            About half the evaluations where the path is steep (contact: ``docs/studies/step-control``); the same
            minima to the tolerance, not bit for bit. Every backend has both (the scalar solver, compiled or plain
            Python, and the masked solver of numpy and torch make the same decisions).
    """

    gtol: float = 1e-11
    max_iter: int = 200
    corrector_max_iter: int = 12
    max_step: float = 0.05
    min_step: float = 1e-9
    max_jump: float = 0.02
    eig_floor: float = 1e-10
    max_substeps: int = 10_000
    free_table: bool = True
    step_control: str = "branch"

    def __post_init__(self) -> None:
        if not isinstance(self.step_control, str) or self.step_control not in STEP_CONTROLS:
            raise ValueError(f"SolverOptions.step_control must be one of {STEP_CONTROLS}, got {self.step_control!r}")
        if type(self.free_table).__name__ not in ("bool", "bool_"):
            raise ValueError(f"SolverOptions.free_table must be true or false, got {self.free_table!r}")
        object.__setattr__(self, "free_table", bool(self.free_table))
        for name, (lo, hi, why) in OPTION_BOUNDS.items():
            v = getattr(self, name)
            if name in _INT_OPTIONS:
                try:
                    i = int(v)
                except (TypeError, ValueError, OverflowError):
                    raise ValueError(f"SolverOptions.{name} must be an integer, got {v!r}") from None
                if isinstance(v, (bool, str, bytes)) or i != v:
                    raise ValueError(f"SolverOptions.{name} must be an integer, got {v!r}")
                v = i
            else:
                if isinstance(v, (bool, str, bytes)):
                    raise ValueError(f"SolverOptions.{name} must be a number, got {v!r}")
                v = check_finite(f"SolverOptions.{name}", v)
            if not lo <= v <= hi:
                raise ValueError(
                    f"SolverOptions.{name} must be in [{lo:g}, {hi:g}] ({why}), got {getattr(self, name)!r}"
                )
            object.__setattr__(self, name, v)
        if self.min_step > self.max_step:
            raise ValueError(f"SolverOptions.min_step={self.min_step!r} exceeds max_step={self.max_step!r}")

    def as_tuple(self) -> tuple:
        """The continuation's numbers in order, as the compiled solver takes them (all fields but ``free_table``;
        ``step_control`` as its index in :data:`STEP_CONTROLS`)."""
        return (
            float(self.gtol),
            int(self.max_iter),
            int(self.corrector_max_iter),
            float(self.max_step),
            float(self.min_step),
            float(self.max_jump),
            float(self.eig_floor),
            int(self.max_substeps),
            STEP_CONTROLS.index(self.step_control),
        )


DEFAULT_OPTIONS = SolverOptions()
_DEFAULT_OPTIONS_TUPLE = DEFAULT_OPTIONS.as_tuple()


# Compiled code (the batched and fused loops) calls continuation's compiled parts (_evaluate, _minimise, _follow_ev,
# _follow_from, _descend). Python calls the entries below: compiled once and cached on disk (a new process loads them
# instead of compiling the solver for seconds), they return the same records as plain tuples, which Python turns back
# into records (python_entry: a NamedTuple returned to Python can turn a Ctrl-C into a segmentation fault).


@njit
def _solve_numbers(r):
    """A :class:`Solve`'s fields (a :class:`Continuation`'s before its ``evaluation``) as a plain tuple."""
    return (r.kappa, r.side_strain, r.energy, r.gradient_norm, r.min_eigenvalue, r.iterations, r.substeps, r.snapped,
            r.status, r.volume_change, r.evaluations, r.backtracks)


@njit
def _evaluation_numbers(e):
    """An :class:`Evaluation`'s fields as a plain tuple."""
    return (e.ok, e.energy, e.g_kappa, e.g_strain, e.h_kk, e.h_ks, e.h_ss, e.volume_change, e.v_kappa, e.v_strain)


def _make_entries(stamp: int):
    def plain_step_state(k, s, p0, p1, prm, kobj, ko, opts):
        if stamp < 0:  # the stamp keys the disk cache (see _jit.njit_cached)
            raise AssertionError
        return _solve_numbers(_follow_ev(k, s, p0, p1, prm, kobj, ko, opts))

    def plain_evaluate(k, s, p, prm, kobj, ko):
        if stamp < 0:
            raise AssertionError
        return _evaluation_numbers(_evaluate(k, s, p, prm, kobj, ko))

    def plain_step_state_from(k, s, p0, p1, prm, kobj, ko, opts, ev0):
        if stamp < 0:
            raise AssertionError
        r = _follow_from(k, s, p0, p1, prm, kobj, ko, opts, ev0)
        return _solve_numbers(r) + (_evaluation_numbers(r.evaluation),)

    def plain_minimise(k, s, p, prm, kobj, ko, gtol, max_iter, eig_floor):
        if stamp < 0:
            raise AssertionError
        r = _minimise(k, s, p, prm, kobj, ko, gtol, max_iter, eig_floor)
        return (r.kappa, r.side_strain, r.energy, r.gradient_norm, r.min_eigenvalue, r.iterations, r.status,
                r.evaluations, r.backtracks)

    return {"step_state": plain_step_state, "evaluate": plain_evaluate, "step_state_from": plain_step_state_from,
            "minimise": plain_minimise}


_SOURCES = (mechanics, contact, continuation, xp, _jit, sys.modules[__name__])
"""The sources the compiled solver is built from."""


def _entry(name: str, record: type, nested=None):
    return python_entry(_jit.njit_cached(lambda stamp: _make_entries(stamp)[name], _SOURCES), record, nested)


step_state = _entry("step_state", Solve)
step_state_from = _entry("step_state_from", Continuation, {"evaluation": Evaluation})
evaluate_state = _entry("evaluate", Evaluation)
"""``evaluate_state(kappa~, e_s, p, prm, k~_obj, w kappa_obj) -> Evaluation``: the energy kernel, from Python."""
_minimise_entry = _entry("minimise", Minimum)
# step_state_from(kappa~, e_s, p0, p1, prm, k~_obj, w kappa_obj, opts, ev0) -> Continuation: step_state from a start
# whose energy evaluation ev0 (the kernel's Evaluation at (kappa~, e_s, p0)) is known; returns step_state's fields and
# the evaluation at the answer, so that a caller can keep it for the next step (pneunet_env.fused caches it).
"""The fast entry point: ``step_state(kappa~, e_s, p0, p1, prm, k~_obj, w kappa_obj, opts)`` returns a :class:`Solve`
``(kappa~, e_s, U, |grad|, lam_min, iterations, substeps, snapped, status, volume_change, evaluations, backtracks)``.

It is the compiled continuation behind :func:`solve_equilibrium` (see :func:`_make_parts`), from an equilibrium
``(kappa~, e_s)`` at ``p0`` to ``p1``, with no validation and
no objects built: for callers on a hot path (an env's step), about a microsecond for a small pressure
step with numba. ``prm`` is :func:`params_tuple`, ``opts`` :meth:`SolverOptions.as_tuple`; ``status``
indexes :data:`STATUS_MESSAGES` (``<= 1``: converged); ``volume_change`` is ``(V1 - V0)/(w^2 t)`` at the
result (NaN only if the start was outside the domain). Inputs must already be valid (finite,
``p >= 0``, ``k~_obj >= 0``, ``0 < w kappa_obj < pi``, the start in the domain)."""


class Equilibrium(NamedTuple):
    """A quasi-static equilibrium: the one solved-state type of the package (all dimensionless: lengths / ``w``,
    stresses / ``mu``).

    Fields are Python scalars for one actuator (:func:`solve_equilibrium`, the single env) or numpy arrays of
    shape ``(N,)`` for a batch (:func:`pneunet_env.physics.batched.solve_batch`, the vector env).

    Attributes:
        pressure: ``p~ = p/mu``.
        curvature: ``kappa~ = w kappa`` of the base.
        side_strain: ``e_s``.
        top_strain: ``e_m = d (1 + e_s) kappa~``.
        contact_force: traction on the object ``F~ = F/mu`` (eq. 3.1); 0 out of contact.
        indentation: ``delta~ = w (1/kappa_obj - 1/kappa)`` in contact, else 0.
        in_contact: whether the actuator presses on the object (``kappa > kappa_obj``, ``k~_obj > 0``).
        volume_change: ``(V1 - V0)/(w^2 t)``.
        energy: ``U/(mu t w^2)``.
        gradient_norm: ``|grad U|_2`` at the returned state.
        min_eigenvalue: the Hessian's smallest eigenvalue there.
        converged: ``gradient_norm <= 1e-10`` and ``min_eigenvalue > 0`` (``0 <= status <= 1``).
        iterations: Newton iterations spent (all sub-steps).
        substeps: pressure sub-steps taken.
        snapped: a fold was crossed: the previous branch's minimum vanished and the state jumped.
        status: the minimiser's code (:data:`STATUS_MESSAGES`; :attr:`message` gives the words).
        object_stiffness: ``k~_obj``.
        object_curvature: ``w kappa_obj``.
        evaluations: energy evaluations the solve made (its work: what a step costs is about this times one
            evaluation). A caller that already had the start's evaluation (the fused vector step's cache) makes one
            fewer, and none where the pressure did not change and the start is a converged minimum; 0 where
            nothing was solved (a rigid jaw, the linear model).
        backtracks: line-search trials the solve rejected (each halves the Newton step).
    """

    pressure: Any
    curvature: Any
    side_strain: Any
    top_strain: Any
    contact_force: Any
    indentation: Any
    in_contact: Any
    volume_change: Any
    energy: Any
    gradient_norm: Any
    min_eigenvalue: Any
    converged: Any
    iterations: Any
    substeps: Any
    snapped: Any
    status: Any
    object_stiffness: Any
    object_curvature: Any
    evaluations: Any = 0
    backtracks: Any = 0

    @property
    def state(self) -> tuple[Any, Any]:
        """``(kappa~, e_s)``."""
        return (self.curvature, self.side_strain)

    @property
    def message(self):
        """What :attr:`status` means (:func:`status_message`)."""
        return status_message(self.status)


def check_pressure(pressure: float, name: str = "pressure") -> float:
    """``float(pressure)``; ``ValueError`` naming it unless finite and ``>= 0``."""
    p = check_finite(name, pressure)
    if p < 0.0:
        raise ValueError(f"{name} (p~ = p/mu) must be >= 0, got {pressure!r}")
    return p


_DEFAULT_PARAMS = ActuatorParams()


def params_tuple(params: ActuatorParams | None) -> ActuatorNumbers:
    """The :class:`ActuatorNumbers` ``(d, h_b, h_s, h_m, E_b, nu, J)`` of ``params`` (:meth:`ActuatorParams.as_tuple`
    without its deep copy); ``None``: the defaults."""
    if params is None:
        params = _DEFAULT_PARAMS
    return ActuatorNumbers(params.chamber_height, params.base_thickness, params.side_thickness, params.top_thickness,
                           params.base_modulus, params.poisson_ratio, params.gent_limit)


def equilibrium(pressure, raw: Solve, chamber_height, object_stiffness, object_curvature) -> Equilibrium:
    """The :class:`Equilibrium` of one :func:`step_state` result ``raw``."""
    k, s, status = raw.kappa, raw.side_strain, raw.status
    delta, force, touching = scalar_contact(k, object_stiffness, object_curvature)
    return Equilibrium(
        pressure, k, s, chamber_height * (1.0 + s) * k, force, delta, touching, raw.volume_change, raw.energy,
        raw.gradient_norm, raw.min_eigenvalue, STATUS_CONVERGED <= status <= STATUS_ROUNDOFF, raw.iterations,
        raw.substeps, raw.snapped, status, object_stiffness, object_curvature, raw.evaluations, raw.backtracks,
    )


def minimise_state(x0, pressure, params, object_stiffness=0.0, object_curvature=0.02, options=DEFAULT_OPTIONS):
    """Plain safeguarded descent from ``x0 = (kappa~, e_s)`` at fixed pressure (no continuation).

    Returns a :class:`Minimum` ``(kappa~, e_s, U, |grad|, lam_min, iterations, status)``.
    """
    o = options
    return _minimise_entry(float(x0[0]), float(x0[1]), float(pressure), params_tuple(params),
                           float(object_stiffness), float(object_curvature), o.gtol, o.max_iter, o.eig_floor)


def solve_equilibrium(
    pressure: float,
    object_stiffness: float = 0.0,
    object_curvature: float = 0.02,
    params: ActuatorParams | None = None,
    initial: Equilibrium | tuple[float, float] | None = None,
    initial_pressure: float | None = None,
    options: SolverOptions = DEFAULT_OPTIONS,
) -> Equilibrium:
    """The quasi-static equilibrium at ``pressure`` (dimensionless throughout).

    Args:
        pressure: ``p~ = p/mu >= 0``.
        object_stiffness: ``k~ = k_obj w/mu >= 0``; 0 is the free actuator.
        object_curvature: ``w kappa_obj`` in ``(0, pi)``.
        params: the actuator; paper defaults if ``None``.
        initial: where to start. ``None``: quasi-static loading from rest (``p~ = 0``). An
            :class:`Equilibrium`: continue its branch from its pressure. A ``(kappa~, e_s)`` pair:
            continue from it at ``initial_pressure`` if given, else descend from it at ``pressure``.
        initial_pressure: the pressure at which a ``(kappa~, e_s)`` ``initial`` was in equilibrium.
        options: solver tolerances.

    Returns:
        An :class:`Equilibrium`. ``converged`` is false only if the minimiser failed; the state is
        then the last iterate (finite, in the domain), never NaN.

    A hot loop that needs no :class:`Equilibrium` can call the compiled :func:`step_state` directly.
    """
    prm = params_tuple(params)
    p = check_pressure(pressure)
    kobj, kc = check_object(object_stiffness, object_curvature)
    opts = _DEFAULT_OPTIONS_TUPLE if options is DEFAULT_OPTIONS else options.as_tuple()
    if initial is None:
        out = step_state(0.0, 0.0, 0.0, p, prm, kobj, kc, opts)
    elif isinstance(initial, Equilibrium):
        out = step_state(initial.curvature, initial.side_strain, initial.pressure, p, prm, kobj, kc, opts)
    else:
        try:
            x0 = (check_finite("initial curvature", initial[0]), check_finite("initial side_strain", initial[1]))
        except (TypeError, IndexError):
            raise ValueError(
                f"initial must be None, an Equilibrium or a (curvature, side_strain) pair, got {initial!r}"
            ) from None
        if not evaluate_state(x0[0], x0[1], 0.0, prm, 0.0, 1.0).ok:
            raise ValueError(f"initial state (curvature={x0[0]!r}, side_strain={x0[1]!r}) is outside the domain")
        if initial_pressure is not None:
            p0 = check_pressure(initial_pressure, "initial_pressure")
            out = step_state(x0[0], x0[1], p0, p, prm, kobj, kc, opts)
        else:
            o = options
            r = _minimise_entry(x0[0], x0[1], p, prm, kobj, kc, o.gtol, o.max_iter, o.eig_floor)
            snapped = max(abs(r.kappa - x0[0]), abs(r.side_strain - x0[1])) > o.max_jump
            dv = evaluate_state(r.kappa, r.side_strain, p, prm, kobj, kc).volume_change
            out = Solve(r.kappa, r.side_strain, r.energy, r.gradient_norm, r.min_eigenvalue, r.iterations, 0, snapped,
                        r.status, dv, r.evaluations + 1, r.backtracks)
    return equilibrium(p, out, prm.chamber_height, kobj, kc)


@dataclass(frozen=True)
class LoadPath:
    """A quasi-static loading path: one entry per requested pressure (numpy arrays)."""

    pressure: np.ndarray
    curvature: np.ndarray
    side_strain: np.ndarray
    contact_force: np.ndarray
    indentation: np.ndarray
    energy: np.ndarray
    converged: np.ndarray
    snapped: np.ndarray
    iterations: np.ndarray
    gradient_norm: np.ndarray
    min_eigenvalue: np.ndarray
    equilibria: tuple[Equilibrium, ...]


def load_path(
    pressures,
    object_stiffness: float = 0.0,
    object_curvature: float = 0.02,
    params: ActuatorParams | None = None,
    options: SolverOptions = DEFAULT_OPTIONS,
) -> LoadPath:
    """Follow ``pressures`` in order, from rest at ``p~ = 0``; pressures may decrease (unloading)."""
    params = ActuatorParams() if params is None else params
    ps = np.atleast_1d(np.asarray(pressures, dtype=float))
    if ps.ndim != 1:
        raise ValueError(f"pressures must be one-dimensional, got shape {ps.shape}")
    for i, p in enumerate(ps):
        check_pressure(p, f"pressures[{i}]")
    kobj, kc = check_object(object_stiffness, object_curvature)
    eqs: list[Equilibrium] = []
    prev: Equilibrium | None = None
    for p in ps:
        prev = solve_equilibrium(float(p), kobj, kc, params, initial=prev, options=options)
        eqs.append(prev)

    def col(name, dtype=float):
        return np.array([getattr(e, name) for e in eqs], dtype=dtype)

    return LoadPath(
        pressure=ps.copy(),
        curvature=col("curvature"),
        side_strain=col("side_strain"),
        contact_force=col("contact_force"),
        indentation=col("indentation"),
        energy=col("energy"),
        converged=col("converged", bool),
        snapped=col("snapped", bool),
        iterations=col("iterations", int),
        gradient_norm=col("gradient_norm"),
        min_eigenvalue=col("min_eigenvalue"),
        equilibria=tuple(eqs),
    )
