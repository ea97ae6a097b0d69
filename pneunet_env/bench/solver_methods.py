"""The solver study's ingredients: its loading paths (scenes), the methods compared, the high-precision reference
and the classification of an answer against it (``pneunet-grasp bench solvers``, :mod:`pneunet_env.bench.solvers`).

Everything is dimensionless, as the model is: pressures ``p~ = p/mu``, states ``(kappa~, e_s)``, object stiffness
``k~ = k_obj w/mu`` and curvature ``w kappa_obj`` (the catalogue's corners are converted at the paper's scales,
``w = 5 mm``, ``mu = 50 kPa``).
"""

from __future__ import annotations

import math
import time
import warnings
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field

import numpy as np

from pneunet_env.bench.models import AUTO_TOLERANCE, equilibrium_for_model
from pneunet_env.physics import mechanics
from pneunet_env.physics.linear import linear_state
from pneunet_env.physics.params import ActuatorParams
from pneunet_env.physics.solver import Equilibrium, minimise_state, solve_equilibrium

__all__ = [
    "BRANCH_TOL",
    "CORRECT_TOL",
    "STATIONARY_TOL",
    "SLOW_FACTOR",
    "FAILURES",
    "FAILURE_TEXT",
    "OUTCOMES",
    "AutoMethod",
    "CatalogueCorner",
    "LinearMethod",
    "Method",
    "NaiveMethod",
    "PackageMethod",
    "PathRun",
    "Scene",
    "catalogue_corners",
    "classify",
    "make_methods",
    "make_scenes",
    "ramp",
    "reference_states",
    "solve_path",
    "solve_steps",
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
FAILURE_TEXT = {
    "no convergence": "no convergence",
    "wrong branch": "wrong branch (jumped to another basin)",
    "saddle/maximum": "saddle/maximum accepted (Hessian not positive definite)",
    "left the domain": "left the domain",
    "NaN": "NaN",
}
"""How ``solvers.json`` words each failure (its records' ``failure``)."""


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


def ramp(p_max: float, dp: float, unload: bool = False, first: float | None = None) -> tuple[float, ...]:
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
        Scene("free", "free actuator through the balloon instability (k~ = 0, p~ to 1.2)", ramp(1.2, dp, first=first)),
        Scene("soft", "soft object k~ = 1e-5: follows the free actuator, traction saturates",
              ramp(1.2, dp, first=first), 1e-5),
        Scene("fold", "k~ = 1e-4 through its snap-through fold, loading to p~ = 1.2 and unloading",
              ramp(1.2, dp, unload=True, first=first), 1e-4),
        Scene("stiff", "stiff object k~ = 1e-2 (curvature pinned near w kappa_obj), p~ to 2",
              ramp(2.0, dp, first=first), 1e-2),
        Scene("very stiff", "very stiff object k~ = 1 (Hessian condition number ~1e7), p~ to 2",
              ramp(2.0, dp, first=first), 1.0),
        Scene("Gent limit", "free actuator to p~ = 6: the side wall within 4 % of the Gent limit (log barrier)",
              ramp(6.0, 2 * dp, first=first)),
        Scene("large steps", "k~ = 1e-4 in increments of 0.2, loading to 1.2 and unloading",
              ramp(1.2, 0.2, unload=True), 1e-4),
        Scene("hand stiff", f"the catalogue's stiffest corner ({_corner_text(hard)}; contact ratio "
              f"k~/(w kappa_obj)^4 = {hard.object_stiffness / hard.object_curvature ** 4:.2g}): contact just past "
              "the balloon, then the curvature held near w kappa_obj; loading to 1.2 and unloading",
              ramp(1.2, dp, unload=True, first=first), hard.object_stiffness, hard.object_curvature),
        Scene("hand soft", f"the catalogue's softest corner ({_corner_text(soft)}): contact inside the balloon, then "
              "the actuator curls on almost as if free (force control); loading to 1.2 and unloading",
              ramp(1.2, dp, unload=True, first=first), soft.object_stiffness, soft.object_curvature),
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
