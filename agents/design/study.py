"""The design study on Optuna: storage, the objective, workers, and the held-out report."""

from __future__ import annotations

import json
import math
import os
import time
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from agents.design.outputs import write_outputs
from agents.design.score import DesignScore, design_rank, evaluate_design, reference_regimes
from agents.design.space import (
    DESIGN_SPACE,
    MODULUS_ERROR,
    N_ERRORS,
    RAMP_STEPS,
    TARGETS,
    WALL_ERROR,
    WINDOW_POINTS,
    elastomers,
    table1_design,
    validity,
)
from pneunet_env.config import EnvConfig, load_config

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
    from pneunet_env.progress import progress as progress_bar

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
    write_outputs(spec, result, base)
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
    """Optuna's PED-ANOVA importance of each parameter for the design score (:func:`design_rank`'s first value):
    how differently the parameter is distributed among the top designs than among all (Watanabe et al. 2023; it
    needs no scikit-learn, which fANOVA does)."""
    import optuna

    done = [t for t in study.trials if t.state is optuna.trial.TrialState.COMPLETE and "score" in t.user_attrs]
    if len(done) < 8:
        return {}
    try:
        imp = optuna.importance.get_param_importances(
            study, target=lambda t: -float(t.user_attrs["score"]["score"]),  # PED-ANOVA looks for low values
            evaluator=optuna.importance.PedAnovaImportanceEvaluator())
    except (RuntimeError, ValueError, ImportError):  # too few distinct trials
        return {}
    return {k: float(v) for k, v in imp.items()}
