"""``pneunet-grasp bench solvers``: the solver study (speed against accuracy, stability map, step size).

Every method solves fixed loading paths (scenes) the way a user would: one solve per pressure, warm-started
from its own previous answer. Each answer is compared with a high-precision reference
(:mod:`pneunet_env.physics.reference`: mpmath, 30 digits, on the quasi-static branch) and classified:

=================  ==============================================================================
outcome            meaning
=================  ==============================================================================
correct            state error ``max(|d kappa~|, |d e_s|) <= 1e-6`` (:data:`CORRECT_TOL`)
slow               (map only) correct, but :data:`SLOW_FACTOR` times the method's median effort
model error        an approximate model (linear, auto) whose answer is off by more than 1e-6
wrong branch       a minimum of the energy, but not the one on the quasi-static path (a jump to
                   another basin), or an unfinished descent heading into another basin
saddle/maximum     a stationary point whose Hessian is not positive definite, accepted as an answer
left the domain    an answer outside the energy's domain (Gent limit, ``kappa~ < 0``, ...)
NaN                a NaN (or an exception) instead of a state
no convergence     stopped short of the reference's minimum (which a safeguarded descent then reaches)
=================  ==============================================================================

The last five are *failures* (``failure`` in ``solvers.json``); "model error" is the accuracy of an
approximation, reported as its ``error``.

Outputs in ``--out``: ``solvers.json`` (records ``{method, scene, time_s, error, failure, default, ...}``),
``solvers_details.json`` (scenes, thresholds, the map, the step-size study, the ``auto`` model's
tolerance sweep), ``speed_accuracy.png``, ``stability_map.png``, ``step_size.png``.
"""

from __future__ import annotations

import argparse
import json
import math
import platform
import time
import warnings
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from pneunet_env.bench.models import AUTO_TOLERANCE, equilibrium_for_model
from pneunet_env.physics import mechanics
from pneunet_env.physics._jit import HAVE_NUMBA
from pneunet_env.physics.linear import LinearModel, linear_reach, linear_state
from pneunet_env.physics.params import ActuatorParams
from pneunet_env.physics.solver import Equilibrium, minimise_state, solve_equilibrium
from pneunet_env.progress import add_progress_argument
from pneunet_env.progress import progress as progress_bar

__all__ = [
    "CORRECT_TOL",
    "STATIONARY_TOL",
    "SLOW_FACTOR",
    "FAILURES",
    "OUTCOMES",
    "Scene",
    "Method",
    "PathRun",
    "make_scenes",
    "catalogue_corners",
    "make_methods",
    "solve_path",
    "solve_steps",
    "classify",
    "reference_states",
    "run_study",
    "add_arguments",
    "run",
]

CORRECT_TOL = 1e-6
"""A state within this of the reference (``max(|d kappa~|, |d e_s|)``) is correct."""
STATIONARY_TOL = 1e-7
"""A state whose full-Newton step ``|H^-1 grad U|_inf`` is below this is a stationary point."""
SLOW_FACTOR = 5.0
"""On the map, a correct solve that took this many times the method's median evaluations is "slow"."""
BRANCH_TOL = 1e-3
"""Step-size study: a point within this of the reference is on the reference's branch."""

OUTCOMES = ("correct", "slow", "model error", "no convergence", "wrong branch", "saddle/maximum",
            "left the domain", "NaN")
FAILURES = ("no convergence", "wrong branch", "saddle/maximum", "left the domain", "NaN")
_FAILURE_TEXT = {
    "no convergence": "no convergence",
    "wrong branch": "wrong branch (jumped to another basin)",
    "saddle/maximum": "saddle/maximum accepted (Hessian not positive definite)",
    "left the domain": "left the domain",
    "NaN": "NaN",
}
_OUTCOME_COLOURS = {
    "correct": "#2ca02c",
    "slow": "#98df8a",
    "model error": "#bcbd22",
    "no convergence": "#ff7f0e",
    "wrong branch": "#d62728",
    "saddle/maximum": "#9467bd",
    "left the domain": "#8c564b",
    "NaN": "#111111",
}


# --------------------------------------------------------------------------------------------- scenes
@dataclass(frozen=True)
class Scene:
    """A loading path: pressures ``p~`` in order (may decrease: unloading), one object, one actuator."""

    name: str
    description: str
    pressures: tuple[float, ...]
    object_stiffness: float = 0.0
    object_curvature: float = 0.02
    params: ActuatorParams = field(default_factory=ActuatorParams)

    def as_dict(self) -> dict:
        return {
            "name": self.name,
            "description": self.description,
            "pressures": list(self.pressures),
            "object_stiffness": self.object_stiffness,
            "object_curvature": self.object_curvature,
            "gent_limit": self.params.gent_limit,
            "params": dict(zip(("d", "h_b", "h_s", "h_m", "E_b", "nu", "J"), self.params.as_tuple(), strict=True)),
        }


def _ramp(p_max: float, dp: float, unload: bool = False, first: float | None = None) -> tuple[float, ...]:
    """``dp, 2 dp, ..., p_max`` (then back down to ``dp`` if ``unload``); ``first`` is prepended if given."""
    up = [round(dp * i, 10) for i in range(1, int(round(p_max / dp)) + 1)]
    if first is not None and first < up[0]:
        up = [first] + up
    return tuple(up + up[-2::-1]) if unload else tuple(up)


@dataclass(frozen=True)
class CatalogueCorner:
    """One corner of an object class's range box in the catalogue (``pneunet_env/data/objects.yaml``).

    ``youngs_modulus_kpa``, ``radius_mm`` and ``thickness_mm`` are the class's values at the corner;
    ``object_stiffness`` is eq. 3.2's ``k~ = k_obj w/mu`` there and ``object_curvature`` is ``w kappa_obj = w/R``,
    at the paper's scales ``w = 5 mm``, ``mu = 50 kPa``.
    """

    name: str
    youngs_modulus_kpa: float
    radius_mm: float
    thickness_mm: float
    object_stiffness: float
    object_curvature: float


def catalogue_corners() -> dict[str, CatalogueCorner]:
    """``{"stiff": ..., "soft": ...}``: the largest and the smallest ``k~`` over the catalogue's classes inside
    eq. 3.2's annulus model (the corners :func:`pneunet_env.catalogue.stiffness_range` takes its extremes at:
    top modulus, smallest radius, thickest layer; and the opposite)."""
    from pneunet_env.catalogue import load_catalogue
    from pneunet_env.physics.contact import winkler_stiffness
    from pneunet_env.physics.units import Scales

    w, mu = Scales().width_mm, Scales().shear_modulus_kpa
    corners = []
    for cls in load_catalogue().values():
        if not cls.in_annulus_model:
            continue
        for i, j in ((1, 0), (0, 1)):  # (stiff: E_hi, R_lo, H_hi), (soft: E_lo, R_hi, H_lo)
            e, r, h = cls.youngs_modulus_kpa[i], cls.radius_mm[j], cls.thickness_mm[i]
            k = float(winkler_stiffness(e / 3.0, h, 1e3 / r, w, mu))
            corners.append(CatalogueCorner(cls.name, e, r, h, k, w / r))
    return {"stiff": max(corners, key=lambda c: c.object_stiffness),
            "soft": min(corners, key=lambda c: c.object_stiffness)}


def _corner_text(c: CatalogueCorner) -> str:
    return (f"{c.name}, E = {c.youngs_modulus_kpa:g} kPa, R = {c.radius_mm:g} mm, H = {c.thickness_mm:g} mm: "
            f"k~ = {c.object_stiffness:.3g}, w kappa_obj = {c.object_curvature:.3g}")


def make_scenes(quick: bool = False) -> list[Scene]:
    """The study's scenes (paper defaults unless stated).

    ``quick`` doubles the pressure increment (but keeps a first point at ``p~ = 0.05``, where ``auto`` answers
    with the linear model). The last two are hand-scale objects of the catalogue (:func:`catalogue_corners`),
    loaded to the environment's ``p~ = 1.2`` and unloaded, as an episode does.
    """
    dp = 0.1 if quick else 0.05
    first = 0.05
    corners = catalogue_corners()
    hard, soft = corners["stiff"], corners["soft"]
    return [
        Scene("free", "free actuator through the balloon instability (k~ = 0, p~ to 1.2)", _ramp(1.2, dp, first=first)),
        Scene("soft", "soft object k~ = 1e-5: follows the free actuator, traction saturates",
              _ramp(1.2, dp, first=first), 1e-5),
        Scene("fold", "k~ = 1e-4 through its snap-through fold, loading to p~ = 1.2 and unloading",
              _ramp(1.2, dp, unload=True, first=first), 1e-4),
        Scene("stiff", "stiff object k~ = 1e-2 (curvature pinned near w kappa_obj), p~ to 2",
              _ramp(2.0, dp, first=first), 1e-2),
        Scene("very stiff", "very stiff object k~ = 1 (Hessian condition number ~1e7), p~ to 2",
              _ramp(2.0, dp, first=first), 1.0),
        Scene("Gent limit", "free actuator to p~ = 6: the side wall within 4 % of the Gent limit (log barrier)",
              _ramp(6.0, 2 * dp, first=first)),
        Scene("large steps", "k~ = 1e-4 in increments of 0.2, loading to 1.2 and unloading",
              _ramp(1.2, 0.2, unload=True), 1e-4),
        Scene("hand stiff", f"the catalogue's stiffest corner ({_corner_text(hard)}; contact ratio "
              f"k~/(w kappa_obj)^4 = {hard.object_stiffness / hard.object_curvature ** 4:.2g}): contact just past "
              "the balloon, then the curvature held near w kappa_obj; loading to 1.2 and unloading",
              _ramp(1.2, dp, unload=True, first=first), hard.object_stiffness, hard.object_curvature),
        Scene("hand soft", f"the catalogue's softest corner ({_corner_text(soft)}): contact inside the balloon, then "
              "the actuator curls on almost as if free (force control); loading to 1.2 and unloading",
              _ramp(1.2, dp, unload=True, first=first), soft.object_stiffness, soft.object_curvature),
    ]


# ----------------------------------------------------------------------------------------- reference
_REFERENCE_CACHE: dict[tuple, np.ndarray] = {}


def reference_states(pressures: Sequence[float], object_stiffness: float, object_curvature: float,
                     params: ActuatorParams) -> np.ndarray:
    """High-precision states ``(n, 2)`` along the quasi-static path (``reference_path``).

    Cached per path within the process.
    """
    key = (tuple(float(p) for p in pressures), float(object_stiffness), float(object_curvature), params)
    if key not in _REFERENCE_CACHE:
        from pneunet_env.physics.reference import reference_path

        k, s = reference_path(np.asarray(key[0]), object_stiffness, object_curvature, params)
        _REFERENCE_CACHE[key] = np.column_stack([k, s])
    return _REFERENCE_CACHE[key]


# ------------------------------------------------------------------------------------------- methods
@dataclass
class PathRun:
    """One method along one path: states ``(n, 2)``, energy evaluations ``(n,)``, seconds ``(n,)``, messages."""

    states: np.ndarray
    evaluations: np.ndarray
    seconds: np.ndarray
    messages: list[str]


class Method:
    """A way to compute equilibria, one pressure at a time, carrying its own memory between solves.

    ``begin()`` is the memory at rest, ``warm(x, p)`` the memory of a given equilibrium ``x`` at ``p``, and
    ``step(memo, p) -> (x, evaluations, message, memo)`` solves at ``p``. ``kind`` is ``"solver"`` or
    ``"model"`` (an approximation: its error is accuracy, not failure).
    """

    kind = "solver"
    default = False

    def __init__(self, name: str, label: str) -> None:
        self.name, self.label = name, label

    def begin(self, k: float, ko: float, params: ActuatorParams):
        return None

    def warm(self, x, p: float, k: float, ko: float, params: ActuatorParams):
        return None

    def step(self, memo, p: float, k: float, ko: float, params: ActuatorParams):
        raise NotImplementedError


class _Energy:
    """The energy at fixed pressure, with its analytic derivatives, as scipy wants it; counts evaluations.

    The formulas are :data:`pneunet_env.physics.mechanics.scalar_terms` (those of ``energy_grad_hess``, on Python
    floats). Outside the domain the energy is ``inf`` and the derivatives NaN, as ``energy_grad_hess`` gives.
    """

    def __init__(self, p: float, k: float, ko: float, params: ActuatorParams) -> None:
        self.args = (p, *params.as_tuple(), k, ko)
        self.n = 0

    def terms(self, x):
        self.n += 1
        return mechanics.scalar_terms(float(x[0]), float(x[1]), *self.args)

    def fun(self, x) -> float:
        return self.terms(x)[1]

    def fun_grad(self, x):
        ok, U, gk, gs, *_ = self.terms(x)
        return (U, np.array([gk, gs])) if ok else (math.inf, np.array([math.nan, math.nan]))

    def hess(self, x):
        ok, _, _, _, a, b, c, *_ = self.terms(x)
        return np.array([[a, b], [b, c]]) if ok else np.full((2, 2), math.nan)


class NaiveMethod(Method):
    """A fixed-pressure minimiser warm-started from its own previous answer, as a user would call it.

    After a NaN or an answer outside the domain, the next solve restarts from the last usable answer.
    """

    def __init__(self, name: str, label: str, solve: Callable) -> None:
        super().__init__(name, label)
        self.solve = solve

    def begin(self, k, ko, params):
        return np.zeros(2)

    def warm(self, x, p, k, ko, params):
        return np.asarray(x, dtype=float)

    def step(self, memo, p, k, ko, params):
        energy = _Energy(float(p), k, ko, params)
        try:
            with warnings.catch_warnings(), np.errstate(all="ignore"):
                warnings.simplefilter("ignore")
                x, msg = self.solve(energy, memo.copy())
        except Exception as exc:  # noqa: BLE001 - a method that raises is a recorded failure, not a crash
            x, msg = np.array([math.nan, math.nan]), f"raised {type(exc).__name__}: {exc}"
        x = np.asarray(x, dtype=float)
        usable = bool(np.all(np.isfinite(x))) and bool(mechanics.in_domain(x[0], x[1], params))
        return x, energy.n, msg, (x if usable else memo)


class PackageMethod(Method):
    """The package's solver, as the environment calls it: continuation from the previous equilibrium."""

    default = True

    def warm(self, x, p, k, ko, params):
        return (float(x[0]), float(x[1])), float(p)

    def step(self, memo, p, k, ko, params):
        if memo is None or isinstance(memo, Equilibrium):  # (Equilibrium is a tuple too: test it first)
            eq = solve_equilibrium(float(p), k, ko, params, initial=memo)
        else:  # warm(): a state and the pressure it is in equilibrium at
            eq = solve_equilibrium(float(p), k, ko, params, initial=memo[0], initial_pressure=memo[1])
        # Newton iterations over all sub-steps (each is one evaluation of energy, gradient and Hessian).
        return np.array(eq.state), eq.iterations, eq.message + (" (snapped)" if eq.snapped else ""), eq


class AutoMethod(Method):
    """:func:`pneunet_env.bench.models.equilibrium_for_model` with ``model="auto"``, from the previous equilibrium."""

    kind = "model"

    def __init__(self, name: str, label: str, tolerance: float = AUTO_TOLERANCE) -> None:
        super().__init__(name, label)
        self.tolerance = tolerance

    def warm(self, x, p, k, ko, params):
        return solve_equilibrium(float(p), k, ko, params, initial=(float(x[0]), float(x[1])))

    def step(self, memo, p, k, ko, params):
        ans = equilibrium_for_model("auto", float(p), k, ko, params, previous=memo, tolerance=self.tolerance)
        eq = ans.equilibrium
        return np.array(eq.state), (eq.iterations if ans.model == "full" else 1), ans.model, eq


class LinearMethod(Method):
    """The linearised model (closed form, history-free; object term linearised about first contact)."""

    kind = "model"

    def step(self, memo, p, k, ko, params):
        kk, ss, *_ = linear_state(float(p), k, ko, params)
        msg = "closed form" if math.isfinite(kk) else "beyond the linear model's validity"
        return np.array([kk, ss]), 0, msg, memo


def _plain_newton(energy: _Energy, x, max_iter: int = 100):
    """Newton's method with no safeguard: full steps ``-H^-1 g``, no line search, no Hessian modification."""
    k, s = float(x[0]), float(x[1])
    for _ in range(max_iter):
        ok, _, g0, g1, a, b, c, *_ = energy.terms((k, s))
        if not ok:
            return np.array([k, s]), "left the domain"
        if math.hypot(g0, g1) <= 1e-11:
            return np.array([k, s]), "converged"
        det = a * c - b * b
        dk, ds = -(c * g0 - b * g1) / det, -(a * g1 - b * g0) / det
        k, s = k + dk, s + ds
        if not (math.isfinite(k) and math.isfinite(s)):
            return np.array([k, s]), "NaN step"
        if max(abs(dk), abs(ds)) <= 1e-15 * (1.0 + abs(k) + abs(s)):
            return np.array([k, s]), "converged (step)"
    return np.array([k, s]), "iteration limit"


def _scipy(method: str, **kw) -> Callable:
    def solve(energy: _Energy, x):
        from scipy.optimize import minimize

        if method == "Nelder-Mead":
            r = minimize(energy.fun, x, method=method, **kw)
        elif method.startswith("trust"):
            r = minimize(energy.fun_grad, x, jac=True, hess=energy.hess, method=method, **kw)
        else:
            r = minimize(energy.fun_grad, x, jac=True, method=method, **kw)
        return np.asarray(r.x, dtype=float), f"{'success' if r.success else 'failure'}: {r.message}"

    return solve


def make_methods() -> list[Method]:
    """The methods compared (the package's solver first: it is the default)."""
    tight = {"gtol": 1e-10}
    return [
        PackageMethod("package", "package: safeguarded Newton + continuation"),
        AutoMethod("auto model", "models 'auto': linear where accurate, else the package's solver"),
        NaiveMethod("plain Newton", "plain Newton (no line search, no Hessian fix)", _plain_newton),
        NaiveMethod("BFGS", "scipy BFGS (analytic gradient)", _scipy("BFGS", options=tight)),
        NaiveMethod("L-BFGS-B", "scipy L-BFGS-B (box bounds of the domain)", _scipy(
            "L-BFGS-B", bounds=[(0.0, math.pi), (-1.0, None)], options={"gtol": 1e-10, "ftol": 1e-15})),
        NaiveMethod("trust-exact", "scipy trust-exact (analytic Hessian)", _scipy("trust-exact", options=tight)),
        NaiveMethod("trust-constr", "scipy trust-constr (analytic Hessian)",
                    _scipy("trust-constr", options={"gtol": 1e-10, "xtol": 1e-14})),
        NaiveMethod("Nelder-Mead", "scipy Nelder-Mead (no derivatives)",
                    _scipy("Nelder-Mead", options={"xatol": 1e-10, "fatol": 1e-14, "maxiter": 2000})),
        LinearMethod("linear", "linearised model (supplement eqs. 15-17)"),
    ]


def solve_path(method: Method, pressures: Sequence[float], k: float, ko: float, params: ActuatorParams) -> PathRun:
    """``method`` along ``pressures`` from rest, each solve warm-started from the method's previous one."""
    n = len(pressures)
    states, evals, secs = np.zeros((n, 2)), np.zeros(n, dtype=int), np.zeros(n)
    msgs: list[str] = []
    memo = method.begin(k, ko, params)
    for i, p in enumerate(pressures):
        t0 = time.perf_counter()
        x, ev, msg, memo = method.step(memo, float(p), k, ko, params)
        secs[i] = time.perf_counter() - t0
        states[i], evals[i] = x, ev
        msgs.append(msg)
    return PathRun(states, evals, secs, msgs)


def solve_steps(method: Method, pressures: Sequence[float], ref: np.ndarray, k: float, ko: float,
                params: ActuatorParams) -> PathRun:
    """``method`` at each pressure, warm-started from the *reference* equilibrium at the previous one.

    Isolates what one step does (no cascade after a first failure): the stability map's test.
    """
    n = len(pressures)
    states, evals, secs = np.zeros((n, 2)), np.zeros(n, dtype=int), np.zeros(n)
    msgs: list[str] = []
    for i, p in enumerate(pressures):
        memo = method.begin(k, ko, params) if i == 0 else method.warm(ref[i - 1], pressures[i - 1], k, ko, params)
        t0 = time.perf_counter()
        x, ev, msg, _ = method.step(memo, float(p), k, ko, params)
        secs[i] = time.perf_counter() - t0
        states[i], evals[i] = x, ev
        msgs.append(msg)
    return PathRun(states, evals, secs, msgs)


# ------------------------------------------------------------------------------------ classification
def _newton_step(x, p, k, ko, params) -> tuple[float, float]:
    """``(|H^-1 g|_inf, lam_min)`` of the full energy at ``x``."""
    ok, _, g0, g1, a, b, c, *_ = mechanics.scalar_terms(float(x[0]), float(x[1]), p, *params.as_tuple(), k, ko)
    if not ok:
        return math.inf, math.nan
    lmin = 0.5 * (a + c) - math.hypot(0.5 * (a - c), b)
    det = a * c - b * b
    if det == 0.0:
        return math.inf, lmin
    return max(abs((c * g0 - b * g1) / det), abs((a * g1 - b * g0) / det)), lmin


def classify(x, ref, p: float, k: float, ko: float, params: ActuatorParams, kind: str = "solver") -> tuple[str, float]:
    """The outcome of a method's answer ``x`` against the reference ``ref`` at pressure ``p``.

    Returns ``(outcome, error)``: ``outcome`` is one of :data:`OUTCOMES` but ``"slow"`` (which compares
    effort across cells, see :func:`run_study`), ``error = max(|d kappa~|, |d e_s|)`` (NaN if ``x`` is not
    finite). ``kind="model"`` marks an approximation: an inaccurate answer is then a "model error".
    """
    x = np.asarray(x, dtype=float)
    if not np.all(np.isfinite(x)):
        return "NaN", math.nan
    err = float(np.max(np.abs(x - np.asarray(ref, dtype=float))))
    if not bool(mechanics.in_domain(x[0], x[1], params)):
        return "left the domain", err
    if err <= CORRECT_TOL:
        return "correct", err
    if kind == "model":
        return "model error", err
    dist, lmin = _newton_step(x, p, k, ko, params)
    if dist <= STATIONARY_TOL:
        return ("saddle/maximum" if not lmin > 0.0 else "wrong branch"), err
    # Not stationary: where does a safeguarded descent from here end? At the reference: it stopped short.
    r = minimise_state(x, p, params, k, ko)
    if r[6] <= 1 and max(abs(r[0] - ref[0]), abs(r[1] - ref[1])) > 10.0 * CORRECT_TOL:
        return "wrong branch", err
    return "no convergence", err


# ------------------------------------------------------------------------------------------ the study
def _timed_path(method: Method, pressures, k, ko, params, repeats: int) -> PathRun:
    run = solve_path(method, pressures, k, ko, params)
    for _ in range(repeats - 1):  # timing only: keep the fastest pass (the answers are deterministic)
        again = solve_path(method, pressures, k, ko, params)
        if again.seconds.sum() < run.seconds.sum():
            run.seconds = again.seconds
    return run


def _evaluate(method: Method, run: PathRun, pressures, ref, k, ko, params) -> list[tuple[str, float]]:
    return [classify(run.states[i], ref[i], float(p), k, ko, params, method.kind) for i, p in enumerate(pressures)]


def _stationarity(states: np.ndarray, scene: Scene) -> tuple[float | None, float | None]:
    """``(max |grad U~|_2, min lambda_min(H))`` of the full energy over the answers inside the domain (``None``
    if there is none): an answer is a converged minimum when ``|grad| <= 1e-10`` and ``lambda_min > 0``."""
    grads, eigs = [], []
    for x, p in zip(states, scene.pressures, strict=True):
        if not np.all(np.isfinite(x)):
            continue
        ok, _, g0, g1, a, b, c, *_ = mechanics.scalar_terms(float(x[0]), float(x[1]), float(p),
                                                             *scene.params.as_tuple(), scene.object_stiffness,
                                                             scene.object_curvature)
        if ok:
            grads.append(math.hypot(g0, g1))
            eigs.append(0.5 * (a + c) - math.hypot(0.5 * (a - c), b))
    return (max(grads), min(eigs)) if grads else (None, None)


def _record(method: Method, scene: Scene, run: PathRun, outcomes: list[tuple[str, float]]) -> dict:
    errors = np.array([e for _, e in outcomes])
    grad, eig = _stationarity(run.states, scene)
    kinds = [o for o, _ in outcomes]
    failed = [i for i, o in enumerate(kinds) if o in FAILURES]
    ok = [i for i in range(len(kinds)) if i not in failed]
    return {
        "method": method.name,
        "scene": scene.name,
        "time_s": float(run.seconds.sum() / len(run.seconds)),
        "error": None if np.isnan(errors).any() else float(errors.max()),
        "failure": _FAILURE_TEXT[kinds[failed[0]]] if failed else None,
        "default": method.default,
        "kind": method.kind,
        "label": method.label,
        "solves": len(kinds),
        "failed_solves": len(failed),
        "outcomes": {o: kinds.count(o) for o in OUTCOMES if o in kinds},
        "first_failure_pressure": float(scene.pressures[failed[0]]) if failed else None,
        "first_failure_message": run.messages[failed[0]] if failed else None,
        "error_where_not_failed": float(np.max(errors[ok])) if ok else None,
        "evaluations_per_solve": float(run.evaluations.mean()),
        "max_gradient_norm": grad,
        "min_hessian_eigenvalue": eig,
    }


def _fold_window(k: float, ko: float, params: ActuatorParams, p_max: float, dp: float = 1e-3) -> tuple[float, float]:
    """``(p_down, p_up)``: the last pressure still on the upper branch when unloading, and the loading snap.

    Found with the package's continuation on a ``dp`` grid: the bistable window is ``(p_down, p_up)`` to
    within ``dp``.
    """
    from pneunet_env.physics.solver import load_path

    ps = np.round(np.arange(1, int(round(p_max / dp)) + 1) * dp, 10)
    path = load_path(np.concatenate([ps, ps[-2::-1]]), k, ko, params)
    n = len(ps)
    i_up = np.flatnonzero(path.snapped[:n])
    i_down = np.flatnonzero(path.snapped[n:])
    p_up = float(ps[i_up[0]]) if len(i_up) else math.nan
    p_down = float(ps[-2::-1][i_down[0]] + dp) if len(i_down) else math.nan
    return p_down, p_up


def _anchored_ramp(anchor: float, p_max: float, dp: float) -> tuple[float, ...]:
    """Load from ``p > 0`` to ``<= p_max`` and back, on the grid ``anchor + j dp`` (which always holds ``anchor``)."""
    j0 = -int(math.floor((anchor - 1e-9) / dp))
    up = [round(anchor + j * dp, 10) for j in range(j0, int(math.floor((p_max - anchor) / dp + 1e-9)) + 1)]
    up = [p for p in up if p > 0.0]
    return tuple(up + up[-2::-1])


def run_study(quick: bool = False, repeats: int | None = None, progress: bool | None = None,
              methods: Sequence[Method] | None = None) -> tuple[list[dict], dict]:
    """Run the whole study; return ``(records, details)`` (what ``solvers.json`` and ``solvers_details.json`` hold).

    ``progress``: bars on stderr; ``None`` (default): when stderr is a terminal.
    """
    repeats = (1 if quick else 3) if repeats is None else repeats
    methods = list(make_methods() if methods is None else methods)
    scenes = make_scenes(quick)
    solve_equilibrium(0.1, 1e-4)  # compile the numba kernels outside the timings
    t_start = time.perf_counter()

    # 1. scenes x methods, each method warm-started from its own previous answer
    refs = {s.name: reference_states(s.pressures, s.object_stiffness, s.object_curvature, s.params)
            for s in progress_bar(scenes, desc="reference paths (mpmath)", enabled=progress)}
    records: list[dict] = []
    tasks = [(m, s) for m in methods for s in scenes]
    for m, s in progress_bar(tasks, desc="methods x scenes", enabled=progress):
        run = _timed_path(m, s.pressures, s.object_stiffness, s.object_curvature, s.params, repeats)
        outcomes = _evaluate(m, run, s.pressures, refs[s.name], s.object_stiffness, s.object_curvature, s.params)
        records.append(_record(m, s, run, outcomes))

    # 2. stability map: pressure x stiffness, one step from the reference's previous equilibrium
    params = ActuatorParams()
    dp_map = 0.1 if quick else 0.05
    map_ps = _ramp(2.0, dp_map)
    map_ks = [0.0, 1e-6, 1e-5, 1e-4, 1e-3, 1e-2, 1e-1, 1.0] if quick else [0.0] + [
        float(v) for v in np.logspace(-6, 0, 13)]
    map_refs = {k: reference_states(map_ps, k, 0.02, params)
                for k in progress_bar(map_ks, desc="map reference paths", enabled=progress)}
    grid: dict[str, list[list[str]]] = {}
    evals: dict[str, list[list[int]]] = {}
    tasks2 = [(m, k) for m in methods for k in map_ks]
    for m, k in progress_bar(tasks2, desc="stability map", enabled=progress):
        run = solve_steps(m, map_ps, map_refs[k], k, 0.02, params)
        grid.setdefault(m.name, []).append([o for o, _ in _evaluate(m, run, map_ps, map_refs[k], k, 0.02, params)])
        evals.setdefault(m.name, []).append([int(v) for v in run.evaluations])
    for m in methods:  # "slow": correct, but SLOW_FACTOR times the method's typical effort
        ev = np.array(evals[m.name], dtype=float)
        typical = float(np.median(ev))
        for i, row in enumerate(grid[m.name]):
            for j, o in enumerate(row):
                if o == "correct" and ev[i, j] > SLOW_FACTOR * max(typical, 1.0):
                    row[j] = "slow"

    # 3. step size: the fold scene's loop at increasing pressure increments
    k_fold, p_top = 1e-4, 1.2
    window = _fold_window(k_fold, 0.02, params, p_top)
    anchor = round(0.5 * (window[0] + window[1]), 3)
    steps = [0.05, 0.1, 0.2, 0.4] if quick else [0.01, 0.02, 0.05, 0.1, 0.2, 0.3, 0.4]
    step_rows = []
    tasks3 = [(m, dp) for dp in steps for m in methods]
    for m, dp in progress_bar(tasks3, desc="step sizes", enabled=progress):
        ps = _anchored_ramp(anchor, p_top, dp)
        ref = reference_states(ps, k_fold, 0.02, params)
        run = solve_path(m, ps, k_fold, 0.02, params)
        outcomes = _evaluate(m, run, ps, ref, k_fold, 0.02, params)
        errs = np.array([e for _, e in outcomes])
        step_rows.append({
            "method": m.name, "increment": dp, "solves": len(ps),
            "error": None if np.isnan(errs).any() else float(errs.max()),
            "failures": sum(o in FAILURES for o, _ in outcomes),
            "loop": _loop_status(ps, run.states, ref, window),
        })

    # 4. the auto model: what it saves and costs along the scenes, for several tolerances
    auto = _auto_sweep(scenes, refs, repeats, progress)

    details = {
        "quick": quick,
        "repeats": repeats,
        "wall_s": time.perf_counter() - t_start,
        "numba": HAVE_NUMBA,
        "python": platform.python_version(),
        "machine": platform.machine(),
        "thresholds": {"correct": CORRECT_TOL, "stationary": STATIONARY_TOL, "slow_factor": SLOW_FACTOR,
                       "branch": BRANCH_TOL, "auto_tolerance": AUTO_TOLERANCE},
        "linear_valid_until": LinearModel(params).valid_until,
        "scenes": [s.as_dict() for s in scenes],
        "methods": [{"name": m.name, "label": m.label, "kind": m.kind, "default": m.default} for m in methods],
        "map": {"pressures": list(map_ps), "stiffnesses": map_ks, "object_curvature": 0.02, "outcomes": grid,
                "evaluations": evals},
        "step_size": {"object_stiffness": k_fold, "p_max": p_top, "fold_window": list(window), "anchor": anchor,
                      "rows": step_rows},
        "auto": auto,
    }
    return records, details


def _loop_status(ps, states, ref, window) -> str:
    """``captured``, ``missed`` (a point of the loop on the wrong branch) or ``unresolved`` (no pressure inside)."""
    p_down, p_up = window
    inside = [i for i, p in enumerate(ps) if p_down < p < p_up]
    if not inside:
        return "unresolved"
    ok = all(np.all(np.isfinite(states[i])) and np.max(np.abs(states[i] - ref[i])) <= BRANCH_TOL for i in inside)
    return "captured" if ok else "missed"


def _auto_sweep(scenes: list[Scene], refs: dict, repeats: int, progress: bool | None) -> dict:
    """``auto`` against ``full`` (the package's solver) along the scenes, for several tolerances.

    Times are the fastest of ``max(repeats, 5)`` passes, ``full`` and ``auto`` passes interleaved so that both
    see the same machine load.
    """
    from pneunet_env.physics.solver import load_path

    tolerances = sorted({1e-5, 1e-4, 1e-3, 1e-2, AUTO_TOLERANCE})
    passes = max(repeats, 5)
    n_total = sum(len(s.pressures) for s in scenes)
    full = PackageMethod("full", "full")
    rows = []
    for tol in progress_bar(tolerances, desc="auto tolerance sweep", enabled=progress):
        auto = AutoMethod("auto", "auto", tol)
        t_auto, t_full, n_lin, err_ref, per_scene = 0.0, 0.0, 0, 0.0, {}
        for s in scenes:
            args = (s.pressures, s.object_stiffness, s.object_curvature, s.params)
            best_full, best_auto, run = math.inf, math.inf, None
            for _ in range(passes):
                best_full = min(best_full, solve_path(full, *args).seconds.sum())
                run = solve_path(auto, *args)
                best_auto = min(best_auto, run.seconds.sum())
            t_auto += best_auto
            t_full += best_full
            lin = sum(msg == "linear" for msg in run.messages)
            n_lin += lin
            e = float(np.max(np.abs(run.states - refs[s.name])))
            err_ref = max(err_ref, e)
            per_scene[s.name] = {"linear_solves": lin, "solves": len(s.pressures), "error": e,
                                 "time_per_solve_s": best_auto / len(s.pressures),
                                 "full_time_per_solve_s": best_full / len(s.pressures)}
        rows.append({
            "tolerance": tol,
            "linear_fraction": n_lin / n_total,
            "time_per_solve_s": t_auto / n_total,
            "full_time_per_solve_s": t_full / n_total,
            "time_saved_fraction": 1.0 - t_auto / t_full,
            "max_error": err_ref,
            "scenes": per_scene,
        })
    # The linear model alone on the free actuator: its error against the full model, on a fine grid.
    params = ActuatorParams()
    dp = 1e-3
    ps = np.round(np.arange(1, 401) * dp, 10)
    fp = load_path(ps, 0.0, 0.02, params)
    xs = np.column_stack([fp.curvature, fp.side_strain])
    lin = np.array([linear_state(float(p), 0.0, 0.02, params)[:2] for p in ps])
    lin_err = np.max(np.abs(lin - xs), axis=1)
    slope = np.max(np.abs(np.gradient(xs, dp, axis=0)), axis=1)  # |dx/dp|_inf of the full path
    reach, p_equiv = {}, {}
    for t in tolerances:
        i = int(np.flatnonzero(lin_err > t)[0]) - 1 if (lin_err > t).any() else len(ps) - 1
        reach[f"{t:g}"] = float(ps[i])
        p_equiv[f"{t:g}"] = float(lin_err[i] / slope[i])  # the pressure shift that moves the full state as much
    small = ps <= 0.05
    coef = float(np.sum(lin_err[small] * ps[small] ** 2) / np.sum(ps[small] ** 4))  # least squares err = c p^2
    # One step where auto answers with the linear model (p~ 0.04 -> 0.05), against the full solve of it.
    prev = solve_equilibrium(0.04)
    t_lin, t_full = math.inf, math.inf
    for _ in range(passes):
        t0 = time.perf_counter()
        for _ in range(200):
            equilibrium_for_model("auto", 0.05, previous=prev)
        t1 = time.perf_counter()
        for _ in range(200):
            solve_equilibrium(0.05, initial=prev)
        t2 = time.perf_counter()
        t_lin, t_full = min(t_lin, (t1 - t0) / 200), min(t_full, (t2 - t1) / 200)
    return {
        "linear_step_time_s": t_lin,
        "full_step_time_s": t_full,
        "tolerance": AUTO_TOLERANCE,
        "sweep": rows,
        "linear_error_free": {"pressures": ps[::10].tolist(), "error": lin_err[::10].tolist()},
        "linear_reach_free_measured": reach,
        "linear_reach_free_estimated": {f"{t:g}": linear_reach(params, t) for t in tolerances},
        "pressure_equivalent_of_error_at_reach": p_equiv,
        "linear_error_coefficient": coef,
    }


# -------------------------------------------------------------------------------------------- charts
def plot_speed_accuracy(records: list[dict], path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    methods = list(dict.fromkeys(r["method"] for r in records))
    scenes = list(dict.fromkeys(r["scene"] for r in records))
    colours = {m: plt.cm.tab10(i % 10) for i, m in enumerate(methods)}
    markers = dict(zip(scenes, "osD^v<>pPX*h", strict=False))
    floor, cap, nan_level = 1e-16, 3.0, 30.0
    fig, ax = plt.subplots(figsize=(9.5, 6.2))
    for r in records:
        err = nan_level if r["error"] is None else min(max(r["error"], floor), cap)
        failed = r["failure"] is not None
        ax.scatter(r["time_s"], err, s=70 if r["default"] else 42, marker=markers[r["scene"]],
                   facecolors="none" if failed else colours[r["method"]], edgecolors=colours[r["method"]],
                   linewidths=1.6, zorder=3)
    ok = [r for r in records if r["failure"] is None and r["error"] is not None]
    front, best = [], math.inf
    for t, e in sorted((r["time_s"], min(max(r["error"], floor), cap)) for r in ok):
        if e < best:  # not dominated: nothing at least as fast is at least as accurate
            front.append((t, e))
            best = e
    if front:
        ts = [t for t, _ in front] + [front[-1][0] * 30]  # the front continues: slower is no better
        es = [e for _, e in front] + [front[-1][1]]
        ax.step(ts, es, where="post", color="k", ls="--", lw=1.0, zorder=2)
    ax.axhspan(nan_level / 2, nan_level * 2, color="0.9", zorder=0)
    ax.text(0.99, nan_level, "NaN ", transform=ax.get_yaxis_transform(), ha="right", va="center", fontsize=8)
    ax.text(0.99, cap, "≥ 3 ", transform=ax.get_yaxis_transform(), ha="right", va="center", fontsize=8)
    ax.axhline(1e-9, color="0.5", lw=0.8, ls=":")
    ax.text(0.99, 1e-9, "1e-9 ", transform=ax.get_yaxis_transform(), ha="right", va="bottom", fontsize=8, color="0.4")
    ax.set_xscale("log")
    ax.set_yscale("log")
    ax.set_xlabel("time per solve [s] (this machine, warm-started along the scene)")
    ax.set_ylabel("max error along the scene, max(|Δκ~|, |Δe_s|), vs mpmath reference")
    ax.set_ylim(floor / 3, nan_level * 2)
    from matplotlib.lines import Line2D

    h_m = [Line2D([], [], ls="", marker="o", color=colours[m], label=m) for m in methods]
    h_s = [Line2D([], [], ls="", marker=markers[s], color="0.3", mfc="none", label=s) for s in scenes]
    h_f = [Line2D([], [], ls="", marker="o", mfc="none", mec="0.3", label="hollow: failed somewhere")]
    h_p = [Line2D([], [], ls="--", color="k", label="Pareto front")]
    leg1 = ax.legend(handles=h_m, title="method", loc="upper left", bbox_to_anchor=(1.01, 1.0), fontsize=8)
    ax.add_artist(leg1)
    ax.legend(handles=h_s + h_f + h_p, title="scene", loc="lower left", bbox_to_anchor=(1.01, 0.0), fontsize=8)
    ax.set_title("Speed against accuracy: every method on every scene")
    ax.grid(True, which="major", alpha=0.3)
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)


def plot_stability_map(details: dict, path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.colors import ListedColormap
    from matplotlib.patches import Patch

    mp = details["map"]
    ps, ks = np.array(mp["pressures"]), mp["stiffnesses"]
    names = list(mp["outcomes"])
    cmap = ListedColormap([_OUTCOME_COLOURS[o] for o in OUTCOMES])
    ncol = 3
    nrow = math.ceil(len(names) / ncol)
    fig, axes = plt.subplots(nrow, ncol, figsize=(4.2 * ncol, 2.9 * nrow + 0.8), sharex=True, sharey=True,
                             squeeze=False)
    dp = ps[1] - ps[0]
    xedges = np.concatenate([ps - dp / 2, [ps[-1] + dp / 2]])
    yedges = np.arange(len(ks) + 1) - 0.5
    for ax, name in zip(axes.flat, names, strict=False):
        codes = np.array([[OUTCOMES.index(o) for o in row] for row in mp["outcomes"][name]])
        ax.pcolormesh(xedges, yedges, codes, cmap=cmap, vmin=-0.5, vmax=len(OUTCOMES) - 0.5)
        present = sorted({o for row in mp["outcomes"][name] for o in row}, key=OUTCOMES.index)
        fails = sum(o in FAILURES for row in mp["outcomes"][name] for o in row)
        ax.set_title(f"{name}  ({fails} failed cells)", fontsize=9)
        del present
    for ax in axes.flat[len(names):]:
        ax.axis("off")
    labels = ["0 (free)" if k == 0 else f"{k:.0e}" for k in ks]
    for ax in axes[:, 0]:
        ax.set_yticks(range(len(ks)))
        ax.set_yticklabels(labels, fontsize=7)
        ax.set_ylabel("object k~")
    for ax in axes[-1, :]:
        ax.set_xlabel("pressure p~")
    handles = [Patch(color=_OUTCOME_COLOURS[o], label=o) for o in OUTCOMES]
    fig.legend(handles=handles, loc="lower center", ncol=len(OUTCOMES), fontsize=8, frameon=False)
    fig.suptitle(f"Stability map: one solve at each cell, warm-started from the exact equilibrium at p~ - {dp:.2g} "
                 f"(w κ_obj = {mp['object_curvature']}; reference: mpmath)", fontsize=10)
    fig.tight_layout(rect=(0, 0.05, 1, 0.96))
    fig.savefig(path, dpi=110)
    plt.close(fig)


def plot_step_size(details: dict, path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    st = details["step_size"]
    rows = st["rows"]
    methods = list(dict.fromkeys(r["method"] for r in rows))
    steps = sorted({r["increment"] for r in rows})
    colours = {m: plt.cm.tab10(i % 10) for i, m in enumerate(methods)}
    fig, (ax1, ax2) = plt.subplots(1, 2, figsize=(13, 5.2), gridspec_kw={"width_ratios": [1.2, 1]})
    floor, cap, nan_level = 1e-16, 3.0, 30.0
    for m in methods:
        rr = sorted((r for r in rows if r["method"] == m), key=lambda r: r["increment"])
        x = [r["increment"] for r in rr]
        y = [nan_level if r["error"] is None else min(max(r["error"], floor), cap) for r in rr]
        ax1.plot(x, y, "-o", color=colours[m], label=m, ms=4)
    ax1.axhspan(nan_level / 2, nan_level * 2, color="0.9", zorder=0)
    ax1.text(0.01, nan_level, " NaN", transform=ax1.get_yaxis_transform(), ha="left", va="center", fontsize=8)
    ax1.text(0.01, cap, " ≥ 3", transform=ax1.get_yaxis_transform(), ha="left", va="bottom", fontsize=8)
    ax1.set_xscale("log")
    ax1.set_yscale("log")
    ax1.set_ylim(floor / 3, nan_level * 2)
    ax1.set_xticks(steps)
    ax1.set_xticklabels([f"{v:g}" for v in steps])
    ax1.minorticks_off()
    ax1.set_xlabel("pressure increment Δp~ per solve")
    ax1.set_ylabel("max error of the path vs mpmath reference")
    ax1.set_title(f"Quasi-static path, k~ = {st['object_stiffness']:g}: load to {st['p_max']} and unload")
    ax1.legend(fontsize=8, loc="center left")
    ax1.grid(True, alpha=0.3)
    style = {"captured": ("o", "#2ca02c", "captured"), "missed": ("X", "#d62728", "missed (wrong branch)"),
             "unresolved": ("s", "0.75", "no pressure inside the loop")}
    for j, m in enumerate(methods):
        for r in rows:
            if r["method"] != m:
                continue
            mk, col, _ = style[r["loop"]]
            ax2.scatter(steps.index(r["increment"]), j, marker=mk, color=col, s=90)
    ax2.set_yticks(range(len(methods)))
    ax2.set_yticklabels(methods, fontsize=8)
    ax2.set_xticks(range(len(steps)))
    ax2.set_xticklabels([f"{s:g}" for s in steps])
    ax2.set_xlabel("pressure increment Δp~ per solve")
    ax2.invert_yaxis()
    pd_, pu = st["fold_window"]
    ax2.set_title(f"Loop captured? (bistable for {pd_:.3f} < p~ < {pu:.3f}; every grid holds p~ = {st['anchor']:g})",
                  fontsize=10)
    from matplotlib.lines import Line2D

    ax2.legend(handles=[Line2D([], [], ls="", marker=v[0], color=v[1], label=v[2]) for v in style.values()],
               loc="upper center", bbox_to_anchor=(0.5, -0.12), ncol=3, fontsize=8, frameon=False)
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)


# ----------------------------------------------------------------------------------------------- CLI
def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--quick", action="store_true", help="fewer pressures and cells (CI: well under a minute)")
    parser.add_argument("--out", type=Path, default=Path("bench_out/solvers"), help="output folder")
    parser.add_argument("--repeats", type=int, default=None,
                        help="timing passes per method and scene, fastest kept (default 1 quick, 3 full)")
    add_progress_argument(parser)


def _table(records: list[dict]) -> str:
    scenes = list(dict.fromkeys(r["scene"] for r in records))
    methods = list(dict.fromkeys(r["method"] for r in records))
    by = {(r["method"], r["scene"]): r for r in records}
    w = 15
    lines = [f"{'method':<14}" + "".join(f"{s:>{w}}" for s in scenes)]
    for m in methods:
        cells = []
        for s in scenes:
            r = by[(m, s)]
            err = "NaN" if r["error"] is None else f"{r['error']:.0e}"
            mark = "!" if r["failure"] else " "
            cells.append(f"{r['time_s'] * 1e3:6.2f}ms {err:>6}{mark}")
        lines.append(f"{m:<14}" + "".join(f"{c:>{w}}" for c in cells))
    lines.append("cells: time per solve, max error vs reference; '!' = failed somewhere (see solvers.json)")
    return "\n".join(lines)


def run(args: argparse.Namespace) -> int:
    if args.repeats is not None and args.repeats < 1:
        raise SystemExit(f"--repeats must be >= 1, got {args.repeats}")
    out: Path = args.out
    out.mkdir(parents=True, exist_ok=True)
    records, details = run_study(quick=args.quick, repeats=args.repeats, progress=args.progress)
    (out / "solvers.json").write_text(json.dumps(records, indent=1) + "\n")
    (out / "solvers_details.json").write_text(json.dumps(details, indent=1) + "\n")
    plot_speed_accuracy(records, out / "speed_accuracy.png")
    plot_stability_map(details, out / "stability_map.png")
    plot_step_size(details, out / "step_size.png")
    print(_table(records))
    print()
    failures = sorted({(r["method"], r["scene"], r["failure"]) for r in records if r["failure"]})
    for m, s, f in failures:
        print(f"  {m:<13} {s:<12} {f}")
    print()
    for row in details["auto"]["sweep"]:
        print(f"auto tolerance {row['tolerance']:.0e}: linear model answers {row['linear_fraction']:.0%} of solves, "
              f"time {row['time_per_solve_s'] * 1e6:.0f} us/solve vs full {row['full_time_per_solve_s'] * 1e6:.0f} "
              f"({row['time_saved_fraction']:+.0%} saved), max error {row['max_error']:.1e}")
    default_bad = [r for r in records if r["default"] and (r["failure"] or r["error"] is None or r["error"] > 1e-9)]
    print(f"\nwrote {out}/solvers.json, solvers_details.json, speed_accuracy.png, stability_map.png, step_size.png "
          f"({details['wall_s']:.1f} s)")
    if default_bad:
        print(f"DEFAULT SOLVER FAILED: {[(r['scene'], r['failure'], r['error']) for r in default_bad]}")
        return 1
    return 0
