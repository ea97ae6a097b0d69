"""``pneunet-grasp design``: which actuator lets one blind pressure schedule hold a use case's objects, with margin.

The seed paper's §4 ("general criteria for actuator design") says that the walls' thicknesses, the chamber's
shape, the elastomer's modulus and its Gent limit shape the pressure-curvature curve, and so where one blind
pressure is safe for soft objects yet firm enough for stiff ones. This module turns that into a search:

* **The design space** (:data:`DESIGN_SPACE`): the top, side and base wall thicknesses, the chamber height and
  width, and the elastomer, one of the commercial casting elastomers of ``pneunet_env/data/elastomers.yaml``
  (its small-strain shear modulus ``mu`` and Gent limit ``J`` from a fit to measured curves, each with its
  source), or the paper's Table 1 material. A design with a low Gent limit and a soft modulus is therefore
  always a material one can buy. Every bound says where it comes from (:class:`Bound`).
* **The pressure scale follows the elastomer.** A design's ``max_pressure_kpa`` is ``1.2 mu`` (the paper's
  ``p~ = 1.2``, Table 1's 60 kPa) and its step ``0.06 mu`` (Table 1's 3 kPa), so a stiffer elastomer is not
  cut off at 60 kPa (:func:`design_config`).
* **One evaluation of a design** (:func:`evaluate_design`) is batched (:mod:`agents.batch`): every object x every
  candidate blind pressure (:data:`TARGETS`, 60 ramps to ``p~ = 0.02 .. 1.2``) is one vector env run. From it:

  - the best blind ramp (the search's rule: most objects held; ties to the higher mean return, then the middle);
  - its success on force- and position-controlled objects, by Table 1's labels (the same split for every
    design: what the objects are) and by the design's own (what its mechanics make of them);
  - the grid oracle: whether *some* constant pressure of the grid holds each object (what a schedule that
    knew the object could reach with this actuator: a design that makes objects ungraspable shows here);
  - the pressure window: the contiguous range of blind pressures whose success stays within 5 points of the
    best, as a fraction of the best pressure;
  - the success under manufacturing error: :data:`N_ERRORS` perturbed actuators (wall thicknesses
    uniform within +-10 %, modulus within +-20 %, the same draws for every design) run the *same* schedule
    (the same pressures in kPa), and each object meets one of them, drawn per object.

* **The search** runs on Optuna (a multi-objective TPE or NSGA-II sampler) over three objectives to maximise:
  blind success on force-controlled objects, on position-controlled ones (Table 1's labels: a Pareto pair),
  and the worse of the two under manufacturing error. Its storage is a SQLite file in the output folder, so a
  stopped run resumes where it stopped; ``--storage URL`` names any Optuna storage (an RDB URL, or
  ``journal:PATH`` for a journal file), so workers on several machines join one study, and ``--jobs N`` runs
  N worker processes here. The Table 1 design is always trial 0.
* **Held out.** Designs are searched on ``--objects`` objects (seeds ``seed * 1_000_003 + i``) and the best are
  reported on ``--held-out`` others (the demo's seeds), with the blind schedule found on the search objects.

The best design is the one whose worst of (blind force-controlled, blind position-controlled, both under error)
is highest, ties to the wider window (:func:`design_rank`). Outputs (``--out DIR``): ``design.json``,
``pareto.png``, ``curves.png`` (the pressure-curvature curves of the best designs beside Table 1, in the style
of the paper's Fig. 3), ``importance.png`` (Optuna's fANOVA importance of each parameter for the design score),
and ``designs/rank-K.yaml``: each best design as an env config, with its tuned ramp beside it
(``rank-K.best_ramp.json``, which ``pneunet-grasp demo --config rank-K.yaml`` runs). ``--export PATH.yaml`` also
writes the best one there.

The model is one chamber of uniform curvature, with one modulus and one ``J`` for both walls: see
``docs/design.md`` for what a designer would also want, and what each would take.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import sys
import time
from collections.abc import Mapping, Sequence
from dataclasses import asdict, dataclass, field
from functools import lru_cache
from pathlib import Path
from typing import Any

import numpy as np

from pneunet_env.config import EnvConfig, load_config

__all__ = ["Bound", "Elastomer", "DESIGN_SPACE", "TARGETS", "N_ERRORS", "P_TILDE_MAX", "elastomers",
           "design_config", "table1_design", "DesignScore", "evaluate_design", "design_rank", "run_study",
           "parse_bounds", "add_arguments", "run", "main"]

P_TILDE_MAX = 1.2
"""A design's largest pressure over its shear modulus (Table 1: 60 kPa over 50 kPa; the paper's Fig. 3 axis)."""
P_TILDE_STEP = 0.06
"""A design's largest pressure change per step over its modulus (Table 1: 3 kPa over 50 kPa)."""
TARGETS = tuple(round(i / 60, 10) for i in range(1, 61))
"""The candidate blind pressures, fractions of ``max_pressure_kpa``: ``p~ = 0.02 .. 1.2`` in steps of 0.02."""
RAMP_STEPS = 20
"""The blind ramp's duration: any duration that ends inside the squeeze phase gives the same outcomes
(:data:`agents.search.DURATIONS` says how that was measured)."""
N_ERRORS = 8
"""Perturbed actuators per design for the manufacturing-error score."""
WALL_ERROR = 0.10
"""Wall thicknesses' manufacturing error: uniform within +-10 %."""
MODULUS_ERROR = 0.20
"""The elastomer's modulus error (batch to batch, cure): uniform within +-20 %."""
WINDOW_POINTS = 0.05
"""The pressure window: the blind pressures whose success stays within this of the best."""


# ---------------------------------------------------------------------------------------------
# The design space
# ---------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class Bound:
    """A continuous design parameter: an ``EnvConfig`` actuator key, its range and why."""

    key: str
    low: float
    high: float
    unit: str
    source: str


@dataclass(frozen=True)
class Elastomer:
    """A casting elastomer: its small-strain shear modulus and Gent limit, from a fit to measured curves."""

    name: str
    shear_modulus_kpa: float
    gent_limit: float
    source: str


@lru_cache(maxsize=1)
def _elastomer_data() -> dict[str, Any]:
    """``pneunet_env/data/elastomers.yaml`` (package data), read by the config's YAML reader (no duplicate keys)."""
    import pneunet_env.data
    from pneunet_env.config import _read_yaml

    path = Path(pneunet_env.data.__file__).resolve().parent / "elastomers.yaml"
    data = _read_yaml(path)
    if not isinstance(data.get("elastomers"), dict):
        raise ValueError(f"{path} must hold a mapping 'elastomers'")
    return data


TABLE1_ELASTOMER = Elastomer("table1", 50.0, 20.0, "the seed paper's supplement Table 1 (mu 50 kPa, J 20)")


def elastomers() -> dict[str, Elastomer]:
    """The elastomers a design may use: every entry of ``elastomers.yaml`` with both ``mu`` and ``J`` sourced,
    and the paper's Table 1 material."""
    out = {TABLE1_ELASTOMER.name: TABLE1_ELASTOMER}
    for name, e in _elastomer_data()["elastomers"].items():
        mu, j = e.get("shear_modulus_kpa"), e.get("gent_limit")
        if mu is None or j is None:
            continue  # no sourced Gent limit: not a design choice
        out[str(name)] = Elastomer(str(name), float(mu), float(j), str(e.get("source", "")))
    return out


DESIGN_SPACE: tuple[Bound, ...] = (
    Bound("top_thickness_mm", 1.0, 3.75, "mm",
          "1 mm: the thinnest cast pneu-net wall read (the Soft Robotics Toolkit's PneuNets mould, elastomers.yaml "
          "wall_thickness_mm); 3.75 mm: h/w = 0.75 at w = 5 mm, the top of the seed paper's Fig. 3 (a thicker wall "
          "is no harder to cast)"),
    Bound("side_thickness_mm", 1.0, 3.75, "mm", "as the top wall"),
    Bound("base_thickness_mm", 1.0, 3.75, "mm", "as the top wall (the paper: it changes little)"),
    Bound("chamber_height_mm", 5.0, 15.0, "mm",
          "5 mm: Table 1; 15 mm: the Soft Robotics Toolkit's cast chamber (elastomers.yaml chamber_mm)"),
    Bound("width_mm", 5.0, 15.0, "mm", "as the chamber height"),
)
"""The continuous parameters, each a manufacturable range with its source. A wall of 1 mm in a 15 mm chamber is
``h/w = 0.07``, far below the paper's computed ``h/w = 0.25 .. 0.75`` (the Toolkit's own actuator is at 0.07 ..
0.13): the thin-wall model is defined there, and thin walls are where it is most apt, but the paper did not
compute it, so such designs leave the range the seed paper checked (:func:`validity`)."""


def validity(params: Mapping[str, Any]) -> dict[str, float | bool]:
    """The design's wall-to-width ratios and whether they lie in the seed paper's computed range 0.25 .. 0.75."""
    w = float(params["width_mm"])
    r = {k: float(params[k]) / w for k in ("top_thickness_mm", "side_thickness_mm", "base_thickness_mm")}
    return {**{f"{k.split('_')[0]}_over_width": v for k, v in r.items()},
            "chamber_aspect": float(params["chamber_height_mm"]) / w,
            "in_paper_range": all(0.25 <= v <= 0.75 for v in r.values())}


def parse_bounds(items: Sequence[str]) -> dict[str, tuple[float, float]]:
    """``KEY=LOW:HIGH`` strings -> narrowed bounds (each inside :data:`DESIGN_SPACE`'s, ``LOW < HIGH``)."""
    space = {b.key: b for b in DESIGN_SPACE}
    out: dict[str, tuple[float, float]] = {}
    for item in items:
        key, sep, rng = str(item).partition("=")
        lo_s, sep2, hi_s = rng.partition(":")
        if not sep or not sep2:
            raise ValueError(f"--bound must be KEY=LOW:HIGH, got {item!r}")
        if key not in space:
            raise ValueError(f"--bound {item!r}: unknown parameter {key!r}; valid: {', '.join(space)}")
        try:
            lo, hi = float(lo_s), float(hi_s)
        except ValueError:
            raise ValueError(f"--bound {item!r}: LOW and HIGH must be numbers") from None
        b = space[key]
        if not (math.isfinite(lo) and math.isfinite(hi)) or not lo < hi:
            raise ValueError(f"--bound {item!r}: need finite LOW < HIGH")
        if lo < b.low or hi > b.high:
            raise ValueError(f"--bound {item!r}: outside the manufacturable range {b.low:g}..{b.high:g} {b.unit} "
                             f"({b.source})")
        out[key] = (lo, hi)
    return out


def design_config(params: Mapping[str, Any], base: EnvConfig | None = None) -> EnvConfig:
    """The env config of a design: ``params`` (actuator keys of :data:`DESIGN_SPACE`, and ``elastomer``, a name
    of :func:`elastomers`) on ``base``, with the pressure scale following the modulus (:data:`P_TILDE_MAX`)."""
    base = EnvConfig() if base is None else base
    p = dict(params)
    name = p.pop("elastomer", None)
    if name is not None:
        table = {TABLE1_ELASTOMER.name: TABLE1_ELASTOMER} if name == TABLE1_ELASTOMER.name else elastomers()
        if name not in table:
            raise ValueError(f"unknown elastomer {name!r}; valid: {', '.join(table)}")
        p["shear_modulus_kpa"] = table[name].shear_modulus_kpa
        p["gent_limit"] = table[name].gent_limit
    mu = float(p.get("shear_modulus_kpa", base.actuator.shear_modulus_kpa))
    p.setdefault("max_pressure_kpa", round(P_TILDE_MAX * mu, 6))
    p.setdefault("max_pressure_step_kpa", round(P_TILDE_STEP * mu, 6))
    return load_config(base, **p)


def table1_design() -> dict[str, Any]:
    """The seed paper's Table 1 actuator as design parameters."""
    a = EnvConfig().actuator
    return {b.key: getattr(a, b.key) for b in DESIGN_SPACE} | {"elastomer": TABLE1_ELASTOMER.name}


# ---------------------------------------------------------------------------------------------
# One design's score
# ---------------------------------------------------------------------------------------------


def _rate(ok: np.ndarray, mask: np.ndarray) -> float:
    return float(ok[mask].mean()) if mask.any() else math.nan


def _regime_rates(ok: np.ndarray, regimes: np.ndarray) -> dict[str, float]:
    from pneunet_env.physics.regimes import FORCE, POSITION

    return {"force": _rate(ok, regimes == FORCE), "position": _rate(ok, regimes == POSITION),
            "all": float(ok.mean())}


@dataclass
class DesignScore:
    """What one design achieves on one object set (rates are fractions; pressures kPa).

    ``blind``, ``oracle`` and ``robust`` are ``{"force", "position", "all"}`` rates by Table 1's regime labels;
    ``blind_own`` by the design's own. ``robust_worst`` is the worst single perturbed actuator's.
    """

    params: dict[str, Any]
    pressure_kpa: float
    target: float
    blind: dict[str, float]
    blind_own: dict[str, float]
    oracle: dict[str, float]
    robust: dict[str, float]
    robust_worst: dict[str, float]
    window_kpa: tuple[float, float]
    window_fraction: float
    objects: dict[str, int]
    by_class: dict[str, dict[str, float]] = field(default_factory=dict)
    rate_vs_pressure: list[float] = field(default_factory=list)
    pressures_kpa: list[float] = field(default_factory=list)
    seconds: float = 0.0

    @property
    def score(self) -> float:
        """The design's rank value: the worst of its blind and under-error success, by regime (:func:`design_rank`)."""
        return design_rank(self)[0]

    def to_dict(self) -> dict[str, Any]:
        d = asdict(self)
        d["score"] = self.score
        return d


def design_rank(s: DesignScore) -> tuple[float, float]:
    """``(worst of blind force/position and under-error force/position, window fraction)``: higher is better.

    An empty regime (NaN) does not count; a design that holds nothing scores 0."""
    vals = [v for v in (s.blind["force"], s.blind["position"], s.robust["force"], s.robust["position"])
            if not math.isnan(v)]
    return (min(vals) if vals else 0.0, s.window_fraction)


def _error_draws(seed: int, n_objects: int) -> tuple[np.ndarray, np.ndarray]:
    """``(factors, assignment)``: :data:`N_ERRORS` rows of (top, side, base, modulus) factors, and which row each
    object meets. The same for every design of a study (common random numbers)."""
    rng = np.random.default_rng([int(seed), 7_919])
    walls = rng.uniform(1 - WALL_ERROR, 1 + WALL_ERROR, size=(N_ERRORS, 3))
    mod = rng.uniform(1 - MODULUS_ERROR, 1 + MODULUS_ERROR, size=(N_ERRORS, 1))
    return np.hstack([walls, mod]), rng.integers(0, N_ERRORS, size=n_objects)


def perturbed_config(config: EnvConfig, factors: Sequence[float]) -> EnvConfig:
    """``config``'s actuator made with errors: top, side and base walls and the modulus times ``factors``; the
    pressure scale (the schedule's kPa) is the nominal design's."""
    a = config.actuator
    return load_config(config, top_thickness_mm=a.top_thickness_mm * factors[0],
                       side_thickness_mm=a.side_thickness_mm * factors[1],
                       base_thickness_mm=a.base_thickness_mm * factors[2],
                       shear_modulus_kpa=a.shear_modulus_kpa * factors[3])


def reference_regimes(seeds: Sequence[int], base: EnvConfig | None = None) -> np.ndarray:
    """Table 1's regime of each object of ``seeds`` (the same physical objects for every design)."""
    from agents.batch import ramp_grid
    from agents.evaluate import object_regimes

    cfg = load_config(base) if base is not None else EnvConfig()
    cfg = design_config(table1_design(), cfg)
    o = ramp_grid(cfg, seeds, [1e-6], 1).outcome  # a reset is all it takes; one step of a near-zero ramp
    return object_regimes(o.stiffness, o.curvature, cfg)


def evaluate_design(params: Mapping[str, Any], seeds: Sequence[int], reference: np.ndarray,
                    base: EnvConfig | None = None, seed: int = 0, target: float | None = None,
                    backend: str = "auto", parallel: bool | None = None) -> DesignScore:
    """Score one design on the objects of ``seeds`` (see the module docstring).

    Args:
        params: the design (:func:`design_config`'s).
        seeds: the objects' episode seeds.
        reference: Table 1's regime of each object (:func:`reference_regimes`).
        base: the env config the design changes (its objects and task); the defaults if ``None``.
        seed: the manufacturing-error draws' seed.
        target: evaluate this blind target (a fraction of the design's ``max_pressure_kpa``) instead of searching
            for the best: the held-out report uses the schedule found on the search objects.
    """
    from agents.batch import ramp_actions, ramp_grid, run_batch
    from agents.evaluate import object_regimes

    t0 = time.perf_counter()
    cfg = design_config(params, base)
    seeds = np.asarray(seeds, dtype=np.int64)
    grid = ramp_grid(cfg, seeds, TARGETS, RAMP_STEPS, backend, parallel)
    o = grid.outcome
    i = grid.best() if target is None else int(np.argmin(np.abs(grid.targets - target)))
    if target is not None and abs(grid.targets[i] - target) > 1e-9:
        extra = ramp_grid(cfg, seeds, [target], RAMP_STEPS, backend, parallel).outcome
        ok = extra.success[0]
        t_best = float(target)
    else:
        ok = o.success[i]
        t_best = float(grid.targets[i])
    own = object_regimes(o.stiffness, o.curvature, cfg)
    lo, hi = grid.window(i, WINDOW_POINTS)
    p_best = t_best * cfg.task.max_pressure_kpa
    # manufacturing error: the same blind schedule (kPa) on perturbed actuators, one per object
    factors, assign = _error_draws(seed, seeds.size)
    hits = np.zeros((N_ERRORS, seeds.size), bool)
    for g, f in enumerate(factors):
        pc = perturbed_config(cfg, f)
        act = ramp_actions(np.full(seeds.size, t_best), RAMP_STEPS, pc)
        hits[g] = run_batch(pc, seeds, act, backend=backend, parallel=parallel).success[0]
    robust_ok = hits[assign, np.arange(seeds.size)]
    worst = [_regime_rates(h, reference) for h in hits]
    classes = np.array(o.classes)
    by_class = {c: {"draws": int((classes == c).sum()), "blind": float(ok[classes == c].mean()),
                    "oracle": float(grid.oracle()[classes == c].mean())} for c in dict.fromkeys(o.classes)}
    from pneunet_env.physics.regimes import FORCE, POSITION

    return DesignScore(
        params=dict(params), pressure_kpa=p_best, target=t_best,
        blind=_regime_rates(ok, reference), blind_own=_regime_rates(ok, own),
        oracle=_regime_rates(grid.oracle(), reference), robust=_regime_rates(robust_ok, reference),
        robust_worst={k: min(w[k] for w in worst) for k in ("force", "position", "all")},
        window_kpa=(lo, hi), window_fraction=(hi - lo) / p_best if p_best > 0 else 0.0,
        objects={"all": int(seeds.size), "force": int((reference == FORCE).sum()),
                 "position": int((reference == POSITION).sum()), "own_force": int((own == FORCE).sum()),
                 "own_position": int((own == POSITION).sum())},
        by_class=by_class, rate_vs_pressure=[float(x) for x in grid.rates()],
        pressures_kpa=[float(x) for x in grid.pressure_kpa], seconds=time.perf_counter() - t0,
    )


# ---------------------------------------------------------------------------------------------
# The study (Optuna)
# ---------------------------------------------------------------------------------------------

STUDY_SETTINGS = ("use_case", "class_weights", "objects", "seed", "bounds", "elastomers", "config")
"""What a study was made with: a resumed (or joined) study must be run with the same."""


def _optuna():
    try:
        import optuna
    except ImportError:
        raise ValueError("pneunet-grasp design needs optuna: pip install -e '.[design]'") from None
    optuna.logging.set_verbosity(optuna.logging.WARNING)
    return optuna


def make_storage(storage: str | None, out: Path):
    """The study's storage: ``None`` -> a SQLite file ``out/study.db``; ``journal:PATH`` -> an Optuna journal file
    (one file several processes append to); any other string -> an Optuna RDB URL (``sqlite:///...``,
    ``postgresql://...``, ``mysql://...``), which workers on several machines can share."""
    optuna = _optuna()
    if storage is None:
        return f"sqlite:///{(out / 'study.db').resolve()}"
    if not isinstance(storage, str) or not storage.strip():
        raise ValueError(f"--storage must be an Optuna storage URL or journal:PATH, got {storage!r}")
    if storage.startswith("journal:"):
        path = storage[len("journal:"):]
        if not path:
            raise ValueError(f"--storage {storage!r}: journal: needs a file path")
        from optuna.storages.journal import JournalFileBackend

        return optuna.storages.JournalStorage(JournalFileBackend(path))
    scheme = storage.split("://", 1)[0] if "://" in storage else ""
    if not scheme or scheme.split("+")[0] not in ("sqlite", "postgresql", "mysql", "oracle", "mssql"):
        raise ValueError(f"--storage {storage!r} is not an RDB URL (sqlite:///PATH, postgresql://..., mysql://...) "
                         "or journal:PATH")
    try:
        return optuna.storages.RDBStorage(storage, heartbeat_interval=60, grace_period=120)
    except Exception as exc:  # a driver missing, a bad URL, a server that does not answer: named, one line
        raise ValueError(f"--storage {storage!r}: cannot open it ({type(exc).__name__}: {exc})") from None


@dataclass
class StudySpec:
    """A design study's settings (what :func:`run_study` and its workers take)."""

    out: Path
    use_case: str | None = "kitchen"
    class_weights: dict[str, float] | None = None
    trials: int = 120
    jobs: int = 1
    storage: str | None = None
    study_name: str | None = None
    seed: int = 0
    objects: int = 200
    held_out: int = 400
    sampler: str = "tpe"
    bounds: dict[str, tuple[float, float]] = field(default_factory=dict)
    config: str | None = None
    top: int = 3

    def __post_init__(self) -> None:
        for name in ("trials", "objects", "held_out", "jobs", "top"):
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, (int, np.integer)) or v < 1:
                raise ValueError(f"{name} must be an integer >= 1, got {v!r}")
        if isinstance(self.seed, bool) or not isinstance(self.seed, (int, np.integer)) or self.seed < 0:
            raise ValueError(f"seed must be an integer >= 0, got {self.seed!r}")
        if self.sampler not in ("tpe", "nsga2"):
            raise ValueError(f"sampler must be 'tpe' or 'nsga2', got {self.sampler!r}")
        self.base_config()  # the use case and weights are checked here, before any work

    def base_config(self) -> EnvConfig:
        over: dict[str, Any] = {}
        if self.class_weights is not None:
            over["class_weights"] = self.class_weights
        elif self.use_case is not None:
            over["use_case"] = self.use_case
        return load_config(self.config, **over)

    @property
    def name(self) -> str:
        if self.study_name:
            return self.study_name
        what = self.use_case if self.class_weights is None else "weights"
        return f"design-{what}"

    def settings(self) -> dict[str, Any]:
        return {"use_case": self.use_case, "class_weights": self.class_weights, "objects": self.objects,
                "seed": self.seed, "bounds": {k: list(v) for k, v in sorted(self.bounds.items())},
                "elastomers": sorted(elastomers()), "config": self.config}


def _space(spec: StudySpec) -> dict[str, tuple[float, float]]:
    return {b.key: spec.bounds.get(b.key, (b.low, b.high)) for b in DESIGN_SPACE}


def _suggest(trial, spec: StudySpec) -> dict[str, Any]:
    p: dict[str, Any] = {k: trial.suggest_float(k, lo, hi) for k, (lo, hi) in _space(spec).items()}
    p["elastomer"] = trial.suggest_categorical("elastomer", sorted(elastomers()))
    return p


def _objectives(s: DesignScore) -> tuple[float, float, float]:
    """Blind force-controlled and position-controlled success, and the worse of the two under error (an empty
    regime counts as 1: there is nothing in it to fail)."""
    f = lambda x: 1.0 if math.isnan(x) else x  # noqa: E731
    return f(s.blind["force"]), f(s.blind["position"]), min(f(s.robust["force"]), f(s.robust["position"]))


def _objective(spec: StudySpec, seeds: np.ndarray, reference: np.ndarray, parallel: bool | None):
    optuna = _optuna()
    base = spec.base_config()

    def objective(trial):
        params = _suggest(trial, spec)
        try:
            s = evaluate_design(params, seeds, reference, base, spec.seed, parallel=parallel)
        except ValueError as exc:  # a geometry the model refuses (no cavity left): not a design
            trial.set_user_attr("invalid", str(exc))
            raise optuna.TrialPruned(str(exc)) from None
        trial.set_user_attr("score", s.to_dict())
        trial.set_user_attr("worker", f"{os.uname().nodename}:{os.getpid()}")
        return _objectives(s)

    return objective


def open_study(spec: StudySpec, create: bool = True):
    """Create or load the study; a resumed or joined study must have been made with the same settings."""
    optuna = _optuna()
    spec.out.mkdir(parents=True, exist_ok=True)
    storage = make_storage(spec.storage, spec.out)
    sampler = (optuna.samplers.TPESampler(seed=spec.seed, multivariate=True, group=True, n_startup_trials=24)
               if spec.sampler == "tpe" else optuna.samplers.NSGAIISampler(seed=spec.seed, population_size=24))
    try:
        study = optuna.create_study(study_name=spec.name, storage=storage, sampler=sampler, load_if_exists=create,
                                    directions=["maximize"] * 3)
    except optuna.exceptions.DuplicatedStudyError:  # pragma: no cover - load_if_exists=False only
        raise ValueError(f"study {spec.name!r} exists already") from None
    want = json.loads(json.dumps(spec.settings()))
    have = study.user_attrs.get("settings")
    if have is None:
        study.set_user_attr("settings", want)
        study.set_metric_names(["blind force-controlled", "blind position-controlled", "worst under error"])
        if not study.trials:
            study.enqueue_trial(table1_design(), user_attrs={"table1": True})
    elif have != want:
        diff = {k: (have.get(k), want.get(k)) for k in want if have.get(k) != want.get(k)}
        raise ValueError(f"study {spec.name!r} in {spec.storage or spec.out / 'study.db'} was made with other "
                         f"settings: {diff} (stored, given); use another --out, --storage or --study-name")
    return study


def _finished(study) -> int:
    import optuna

    return sum(t.state in (optuna.trial.TrialState.COMPLETE, optuna.trial.TrialState.PRUNED) for t in study.trials)


def work(spec: StudySpec, parallel: bool | None = None, progress: bool | None = None) -> int:
    """Run trials until the study has ``spec.trials`` finished ones (complete or refused); returns how many this
    process ran. Any number of processes, here or on other machines, may do this on one study at once."""
    optuna = _optuna()
    from agents.batch import episode_seeds
    from pneunet_env.cli.progress import progress as progress_bar

    study = open_study(spec)
    seeds = episode_seeds(spec.objects, spec.seed)
    reference = reference_regimes(seeds, spec.base_config())
    left = spec.trials - _finished(study)
    if left <= 0:
        return 0
    bar = progress_bar(total=left, desc=f"design {spec.name}", unit="design", enabled=progress)
    ran = 0

    def tick(study, trial):
        nonlocal ran
        ran += 1
        bar.update()

    stop = optuna.study.MaxTrialsCallback(spec.trials, states=(optuna.trial.TrialState.COMPLETE,
                                                               optuna.trial.TrialState.PRUNED))
    study.optimize(_objective(spec, seeds, reference, parallel), callbacks=[stop, tick], gc_after_trial=False)
    bar.close()
    return ran


def _worker(spec: StudySpec) -> int:  # a --jobs process: one numba thread, no bar
    return work(spec, parallel=False, progress=False)


def run_study(spec: StudySpec, progress: bool | None = None, log=print) -> dict[str, Any]:
    """Run (or resume, or join) the study to ``spec.trials`` finished trials with ``spec.jobs`` processes, then
    report: the best designs re-scored on held-out objects, and every output file."""
    t0 = time.perf_counter()
    open_study(spec)  # checked (and created) once, before any worker starts
    if spec.jobs == 1:
        work(spec, progress=progress)
    else:
        import multiprocessing as mp

        ctx = mp.get_context("spawn")  # fresh interpreters: no numba or SQLite state forked
        with ctx.Pool(spec.jobs) as pool:
            pool.map(_worker, [spec] * spec.jobs)
    search_s = time.perf_counter() - t0
    return report(spec, search_s, progress, log)


def _trial_scores(study) -> list[tuple[Any, DesignScore]]:
    import optuna

    out = []
    for t in study.trials:
        if t.state is optuna.trial.TrialState.COMPLETE and "score" in t.user_attrs:
            d = dict(t.user_attrs["score"])
            d.pop("score", None)
            d["window_kpa"] = tuple(d["window_kpa"])
            out.append((t, DesignScore(**d)))
    return out


def _pareto(points: np.ndarray) -> np.ndarray:
    """Which rows of ``points`` (to maximise) no other row dominates."""
    keep = np.ones(len(points), bool)
    for i, p in enumerate(points):
        dom = np.all(points >= p, axis=1) & np.any(points > p, axis=1)
        keep[i] = not dom.any()
    return keep


def report(spec: StudySpec, search_s: float = math.nan, progress: bool | None = None, log=print) -> dict[str, Any]:
    """The study's results: top designs (and Table 1) on held-out objects; ``design.json`` and the figures."""
    from agents.batch import episode_seeds

    study = open_study(spec)
    scored = _trial_scores(study)
    if not scored:
        raise ValueError(f"study {spec.name!r} has no finished design yet")
    ranked = sorted(scored, key=lambda ts: design_rank(ts[1]), reverse=True)
    table1 = next((ts for ts in scored if ts[0].user_attrs.get("table1")), None)
    top = []
    seen: set[str] = set()
    for t, s in ranked:
        key = json.dumps(s.params, sort_keys=True)
        if key not in seen:
            seen.add(key)
            top.append((t, s))
        if len(top) == spec.top:
            break
    base = spec.base_config()
    held = episode_seeds(spec.held_out, spec.seed, held_out=True)
    ref_held = reference_regimes(held, base)
    rows = []
    for label, (t, s) in [("table1", table1)] * (table1 is not None) + [(f"rank-{k + 1}", ts) for k, ts in
                                                                      enumerate(top)]:
        h = evaluate_design(s.params, held, ref_held, base, spec.seed, target=s.target)
        rows.append({"label": label, "trial": t.number, "params": s.params, "validity": validity(s.params),
                     "elastomer": asdict(elastomers()[s.params["elastomer"]]), "search": s.to_dict(),
                     "held_out": h.to_dict()})
        log(_line(label, s, h))
    vals = np.array([_objectives(s) for _, s in scored])
    front = _pareto(vals)
    importance = _importance(study)
    result = {
        "study": spec.name, "settings": spec.settings(), "trials": len(study.trials), "scored": len(scored),
        "search_seconds": search_s, "objects": spec.objects, "held_out": spec.held_out,
        "targets": list(TARGETS), "ramp_steps": RAMP_STEPS, "errors": {"walls": WALL_ERROR, "modulus": MODULUS_ERROR,
                                                                      "actuators": N_ERRORS},
        "window_points": WINDOW_POINTS, "importance": importance, "designs": rows,
        "all": [{"trial": t.number, "params": s.params, "objectives": list(_objectives(s)),
                 "score": s.score, "window_fraction": s.window_fraction, "pressure_kpa": s.pressure_kpa,
                 "oracle": s.oracle, "pareto": bool(f)} for (t, s), f in zip(scored, front, strict=True)],
    }
    _write_outputs(spec, result, base)
    return result


def _pct(x: float) -> str:
    return "  -" if x is None or (isinstance(x, float) and math.isnan(x)) else f"{x:4.0%}"


def _line(label: str, s: DesignScore, h: DesignScore) -> str:
    return (f"{label:>8}: {s.params['elastomer']:>16} h_m {s.params['top_thickness_mm']:.2f} h_s "
            f"{s.params['side_thickness_mm']:.2f} h_b {s.params['base_thickness_mm']:.2f} d "
            f"{s.params['chamber_height_mm']:.2f} w {s.params['width_mm']:.2f} mm; blind {h.pressure_kpa:5.1f} kPa | "
            f"held out: force {_pct(h.blind['force'])} position {_pct(h.blind['position'])} (oracle "
            f"{_pct(h.oracle['force'])} {_pct(h.oracle['position'])}), under error {_pct(h.robust['force'])} "
            f"{_pct(h.robust['position'])}, window {h.window_fraction:.0%}")


def _importance(study) -> dict[str, float]:
    """Optuna's fANOVA importance of each parameter for the design score (:func:`design_rank`'s first value)."""
    import optuna

    done = [t for t in study.trials if t.state is optuna.trial.TrialState.COMPLETE and "score" in t.user_attrs]
    if len(done) < 8:
        return {}
    try:
        imp = optuna.importance.get_param_importances(
            study, target=lambda t: float(t.user_attrs["score"]["score"]),
            evaluator=optuna.importance.FanovaImportanceEvaluator(seed=0))
    except (RuntimeError, ValueError):  # too few distinct trials
        return {}
    return {k: float(v) for k, v in imp.items()}


# ---------------------------------------------------------------------------------------------
# Outputs
# ---------------------------------------------------------------------------------------------


def design_yaml(params: Mapping[str, Any], base: EnvConfig, note: str) -> str:
    """The env config of a design as YAML (the actuator, its pressure scale and the objects it was designed for)."""
    import yaml

    cfg = design_config(params, base)
    d = cfg.to_dict()
    body = {"actuator": d["actuator"],
            "objects": {"use_case": d["objects"]["use_case"], "class_weights": d["objects"]["class_weights"]},
            "task": {"max_pressure_kpa": d["task"]["max_pressure_kpa"],
                     "max_pressure_step_kpa": d["task"]["max_pressure_step_kpa"]}}
    head = "".join(f"# {line}\n" for line in note.splitlines())
    return head + yaml.safe_dump(body, sort_keys=False)


def write_design(path: Path, row: dict[str, Any], base: EnvConfig, study: str) -> Path:
    """``PATH.yaml`` (the design's env config) and ``PATH.best_ramp.json`` (its blind ramp, found on the search
    objects), both written atomically."""
    from agents.policies import atomic_write_bytes
    from agents.scripted import LinearRamp

    s, h = row["search"], row["held_out"]
    e = row["elastomer"]
    note = (f"A pneu-net designed by `pneunet-grasp design` (study {study!r}, trial {row['trial']}): "
            f"{row['label']}.\n"
            f"Elastomer: {e['name']} (mu {e['shear_modulus_kpa']:g} kPa, J {e['gent_limit']:g}; {e['source']}).\n"
            f"Blind ramp beside it ({path.stem}.best_ramp.json): {s['pressure_kpa']:.1f} kPa over {RAMP_STEPS} "
            "steps.\n"
            f"Held-out objects ({h['objects']['all']}): force-controlled {h['blind']['force']:.1%}, "
            f"position-controlled {h['blind']['position']:.1%} (Table 1's labels); oracle "
            f"{h['oracle']['force']:.1%} / {h['oracle']['position']:.1%}; under manufacturing error "
            f"{h['robust']['force']:.1%} / {h['robust']['position']:.1%}.\n"
            'Load with gym.make("PneuNetGrasp-v0", config="<this file>").')
    path.parent.mkdir(parents=True, exist_ok=True)
    atomic_write_bytes(path, design_yaml(row["params"], base, note).encode())
    cfg = design_config(row["params"], base)
    ramp = LinearRamp(s["target"], RAMP_STEPS, cfg)
    data = {**ramp.to_dict(), "gripper": "pneunet", "target_kpa": s["pressure_kpa"],
            "search": {"by": "pneunet-grasp design", "study": study, "trial": row["trial"],
                       "objects": s["objects"]["all"]},
            "score": {"search": {k: s[k] for k in ("blind", "oracle", "robust")},
                      "held_out": {k: h[k] for k in ("blind", "oracle", "robust")}}}
    atomic_write_bytes(path.with_suffix(".best_ramp.json"), (json.dumps(data, indent=1) + "\n").encode())
    return path


def _write_outputs(spec: StudySpec, result: dict[str, Any], base: EnvConfig) -> None:
    from agents.policies import atomic_write_bytes

    out = spec.out
    for row in result["designs"]:
        write_design(out / "designs" / f"{row['label']}.yaml", row, base, spec.name)
    atomic_write_bytes(out / "design.json", (json.dumps(result, indent=1, default=_jsonable) + "\n").encode())
    try:
        plt = _plt()
    except ImportError:
        return
    plot_pareto(result, out / "pareto.png", plt)
    plot_curves(result, base, out / "curves.png", plt)
    plot_importance(result, out / "importance.png", plt)


def _jsonable(x: Any) -> Any:
    if isinstance(x, np.generic):
        return x.item()
    if isinstance(x, np.ndarray):
        return x.tolist()
    if isinstance(x, Path):
        return str(x)
    raise TypeError(f"cannot write {type(x).__name__} to JSON")


def _plt():
    from agents.evaluate import _matplotlib

    return _matplotlib()


def _save(fig, path: Path, plt) -> Path:
    """Save a figure atomically (a temporary PNG in the same folder, then renamed)."""
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(f".{path.name}.{os.getpid()}.tmp.png")
    fig.savefig(tmp, dpi=120)
    plt.close(fig)
    os.replace(tmp, path)
    return path


def _use_case_title(result: dict[str, Any]) -> str:
    st = result["settings"]
    return st["use_case"] if st["class_weights"] is None else "class weights " + ", ".join(
        f"{k} {v:g}" for k, v in st["class_weights"].items())


def plot_pareto(result: dict[str, Any], path: Path, plt) -> Path:
    """Blind success on force- against position-controlled objects (Table 1's labels), every design of the study;
    colour: the worse regime under manufacturing error; the Pareto front ringed; Table 1 and the best marked."""
    pts = result["all"]
    x = np.array([p["objectives"][0] for p in pts])
    y = np.array([p["objectives"][1] for p in pts])
    c = np.array([p["objectives"][2] for p in pts])
    front = np.array([p["pareto"] for p in pts])
    fig, ax = plt.subplots(figsize=(6.4, 5.0))
    sc = ax.scatter(x, y, c=c, cmap="viridis", vmin=0, vmax=1, s=22, alpha=0.85, lw=0)
    ax.scatter(x[front], y[front], s=70, facecolors="none", edgecolors="black", lw=0.9, label="Pareto front")
    for row in result["designs"]:
        s = row["search"]
        if row["label"] == "table1":
            ax.plot(s["blind"]["force"], s["blind"]["position"], "*", ms=16, color="#d62728", mec="black",
                    label=f"Table 1 actuator ({s['pressure_kpa']:.1f} kPa)")
        elif row["label"] == "rank-1":
            ax.plot(s["blind"]["force"], s["blind"]["position"], "D", ms=9, color="#ff7f0e", mec="black",
                    label=f"best design ({row['params']['elastomer']}, {s['pressure_kpa']:.1f} kPa)")
    fig.colorbar(sc, ax=ax, label="worse regime under manufacturing error")
    ax.set_xlabel("blind success, force-controlled objects")
    ax.set_ylabel("blind success, position-controlled objects")
    ax.set_xlim(-0.03, 1.03)
    ax.set_ylim(-0.03, 1.03)
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize=7.5, loc="lower left")
    ax.set_title(f"Actuator designs for {_use_case_title(result)}: one blind ramp each\n"
                 f"({result['scored']} designs, {result['objects']} search objects; regimes by Table 1's labels)",
                 fontsize=9)
    fig.tight_layout()
    return _save(fig, path, plt)


def free_curve(params: Mapping[str, Any], base: EnvConfig, n: int = 121) -> tuple[np.ndarray, np.ndarray]:
    """The free actuator's pressure-curvature curve of a design: ``(p~, kappa~)`` from rest to ``p~ = 1.2``."""
    from pneunet_env.physics.solver import load_path

    cfg = design_config(params, base)
    ps = np.linspace(0.0, P_TILDE_MAX, n)
    lp = load_path(ps, 0.0, 0.02, cfg.actuator_params, cfg.solver)
    return ps, lp.curvature


def plot_curves(result: dict[str, Any], base: EnvConfig, path: Path, plt) -> Path:
    """The best designs beside Table 1: (a) the free pressure-curvature curve, dimensionless as the paper's Fig. 3;
    (b) the same in kPa and 1/m, with the blind pressure and the objects' curvatures; (c) blind success against
    the blind pressure, with the window within 5 points of the best."""
    from pneunet_env.catalogue import class_table

    fig, axes = plt.subplots(1, 3, figsize=(15, 4.4))
    cmap = plt.get_cmap("tab10")
    for j, row in enumerate(result["designs"]):
        col = "#d62728" if row["label"] == "table1" else cmap(j)
        s = row["search"]
        mu = row["elastomer"]["shear_modulus_kpa"]
        w = row["params"]["width_mm"]
        ps, k = free_curve(row["params"], base)
        lab = ("Table 1" if row["label"] == "table1" else row["label"]) + f" ({row['params']['elastomer']})"
        axes[0].plot(ps, k, color=col, lw=1.6, label=lab)
        axes[1].plot(ps * mu, k / (w * 1e-3), color=col, lw=1.6, label=lab)
        kb = np.interp(s["pressure_kpa"] / mu, ps, k) / (w * 1e-3)
        axes[1].plot(s["pressure_kpa"], kb, "o", color=col, mec="black", ms=7)
        axes[2].plot(s["pressures_kpa"], s["rate_vs_pressure"], color=col, lw=1.6, label=lab)
        axes[2].axvspan(*s["window_kpa"], color=col, alpha=0.12, lw=0)
        axes[2].plot(s["pressure_kpa"], s["blind"]["all"], "o", color=col, mec="black", ms=7)
    cfg = base
    radius = class_table(cfg.objects.class_items).radius_mm if cfg.objects.from_catalogue else None
    if radius is not None:
        lo, hi = 1e3 / float(np.max(radius[1])), 1e3 / float(np.min(radius[0]))
        axes[1].axhspan(lo, hi, color="#888888", alpha=0.15, lw=0,
                        label=f"objects' curvature (R {float(np.min(radius[0])):g}-{float(np.max(radius[1])):g} mm)")
    axes[0].set_xlabel("p~ = p / mu")
    axes[0].set_ylabel("kappa~ = w kappa (free actuator)")
    axes[0].set_title("(a) free actuator, dimensionless (the paper's Fig. 3)", fontsize=9)
    axes[1].set_xlabel("pressure (kPa)")
    axes[1].set_ylabel("curvature (1/m), free actuator")
    axes[1].set_xscale("log")
    axes[1].set_title("(b) in physical units; dot: the blind pressure", fontsize=9)
    axes[2].set_xlabel("blind ramp's pressure (kPa)")
    axes[2].set_ylabel("success, search objects")
    axes[2].set_xscale("log")
    axes[2].set_ylim(-0.03, 1.03)
    axes[2].set_title(f"(c) one blind pressure for all; band: within {WINDOW_POINTS:.0%} of the best", fontsize=9)
    for ax in axes:
        ax.grid(True, alpha=0.3)
        ax.legend(fontsize=7)
    fig.suptitle(f"Why the design works ({_use_case_title(result)})", fontsize=10)
    fig.tight_layout()
    return _save(fig, path, plt)


def plot_importance(result: dict[str, Any], path: Path, plt) -> Path:
    """Optuna's fANOVA importance of each design parameter for the design score."""
    imp = result["importance"]
    fig, ax = plt.subplots(figsize=(6, 3.2))
    if imp:
        names = list(imp)[::-1]
        ax.barh(names, [imp[n] for n in names], color="#4c72b0")
        ax.set_xlabel("share of the design score's variance (fANOVA)")
    else:
        ax.text(0.5, 0.5, "too few designs for an importance estimate", ha="center", va="center")
        ax.set_axis_off()
    ax.set_title(f"What matters for one blind schedule ({_use_case_title(result)}, {result['scored']} designs)",
                 fontsize=9)
    fig.tight_layout()
    return _save(fig, path, plt)


# ---------------------------------------------------------------------------------------------
# Command line: pneunet-grasp design
# ---------------------------------------------------------------------------------------------


def _weights(text: str | None) -> dict[str, float] | None:
    if text is None:
        return None
    out: dict[str, float] = {}
    for item in text.split(","):
        name, sep, val = item.partition("=")
        if not sep or not name.strip():
            raise ValueError(f"--class-weights must be NAME=WEIGHT,NAME=WEIGHT..., got {text!r}")
        try:
            out[name.strip()] = float(val)
        except ValueError:
            raise ValueError(f"--class-weights {text!r}: the weight of {name.strip()!r} is not a number") from None
    return out


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--use-case", default="kitchen",
                        help="catalogue use case whose objects the design must hold (default kitchen; see "
                             "docs/env.md)")
    parser.add_argument("--class-weights", default=None, metavar="NAME=W,...",
                        help="catalogue class weights instead of a use case, e.g. apple=1,gelatin_gel=1")
    parser.add_argument("--trials", type=int, default=120,
                        help="designs in the study, in all (a resumed or joined study runs only the rest; default 120)")
    parser.add_argument("--jobs", type=int, default=1, help="worker processes on this machine (default 1)")
    parser.add_argument("--storage", default=None,
                        help="Optuna storage shared by workers: an RDB URL (sqlite:///PATH, postgresql://...) or "
                             "journal:PATH (default: sqlite in --out, so a stopped run resumes)")
    parser.add_argument("--study-name", default=None, help="study name in the storage (default design-USE_CASE)")
    parser.add_argument("--objects", type=int, default=200, help="search objects per design (default 200)")
    parser.add_argument("--held-out", type=int, default=400,
                        help="held-out objects the best designs are reported on (default 400)")
    parser.add_argument("--top", type=int, default=3, help="best designs reported and written (default 3)")
    parser.add_argument("--seed", type=int, default=0, help="objects' and sampler's seed (default 0)")
    parser.add_argument("--sampler", choices=("tpe", "nsga2"), default="tpe",
                        help="Optuna's multi-objective sampler (default tpe)")
    parser.add_argument("--bound", action="append", default=[], metavar="KEY=LOW:HIGH",
                        help="narrow a parameter's range (repeatable), e.g. top_thickness_mm=1.5:3")
    parser.add_argument("--config", default=None, help="base env config YAML (objects, task) the design changes")
    parser.add_argument("--out", type=Path, default=None, help="output folder (default design/USE_CASE)")
    parser.add_argument("--export", type=Path, default=None,
                        help="also write the best design's env config here (PATH.yaml, with PATH.best_ramp.json)")
    parser.add_argument("--worker", action="store_true",
                        help="only run trials (a worker joining --storage from another machine); no report")
    parser.add_argument("--report", action="store_true", help="only report on the study as it stands")
    from pneunet_env.cli.progress import add_progress_argument

    add_progress_argument(parser, "--quiet")


def spec_from_args(args: argparse.Namespace) -> StudySpec:
    """The study's settings from the command line, every value checked before any work."""
    weights = _weights(args.class_weights)
    out = args.out if args.out is not None else Path("design") / (args.use_case if weights is None else "weights")
    if out.exists() and not out.is_dir():
        raise ValueError(f"--out {str(out)!r} exists and is not a folder")
    if args.export is not None and args.export.suffix not in (".yaml", ".yml"):
        raise ValueError(f"--export must name a .yaml file, got {str(args.export)!r}")
    if args.worker and args.report:
        raise ValueError("--worker and --report exclude each other")
    spec = StudySpec(out=out, use_case=args.use_case, class_weights=weights, trials=args.trials, jobs=args.jobs,
                     storage=args.storage, study_name=args.study_name, seed=args.seed, objects=args.objects,
                     held_out=args.held_out, sampler=args.sampler, bounds=parse_bounds(args.bound),
                     config=args.config, top=args.top)
    if spec.storage is not None:
        make_storage(spec.storage, out)  # a bad URL is named now, not after the work
    _optuna()
    return spec


def run(args: argparse.Namespace) -> int:
    try:
        spec = spec_from_args(args)
        if args.worker:
            n = work(spec, parallel=None if spec.jobs == 1 else False, progress=args.progress)
            print(f"ran {n} designs in study {spec.name!r}")
            return 0
        t0 = time.perf_counter()
        if args.report:
            result = report(spec, progress=args.progress)
        else:
            print(f"design study {spec.name!r}: {spec.trials} designs, {spec.objects} search objects, "
                  f"{spec.held_out} held out, {spec.jobs} process(es); storage "
                  f"{spec.storage or spec.out / 'study.db'}")
            result = run_study(spec, progress=args.progress)
    except ValueError as exc:
        raise SystemExit(f"pneunet-grasp design: {exc}") from None
    best = next(r for r in result["designs"] if r["label"] == "rank-1")
    if args.export is not None:
        write_design(args.export, best, spec.base_config(), spec.name)
        print(f"wrote {args.export} and {args.export.with_suffix('.best_ramp.json')}")
    if result["importance"]:
        imp = result["importance"]
        print("importance (fANOVA, design score): " + ", ".join(f"{k} {v:.2f}" for k, v in imp.items()))
    print(f"{result['scored']} designs scored; wrote {spec.out / 'design.json'}, pareto.png, curves.png, "
          f"importance.png and designs/ in {time.perf_counter() - t0:.0f} s")
    return 0


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="pneunet-grasp design", description=__doc__.split("\n\n")[0])
    add_arguments(parser)
    return run(parser.parse_args(argv))


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
