"""The design study on Optuna: the objective, workers, and the held-out report (its storage:
:mod:`agents.design.storage`)."""

from __future__ import annotations

import contextlib
import datetime
import json
import logging
import math
import os
import signal
import socket
import threading
import time
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from agents.design.outputs import write_outputs
from agents.design.score import DesignScore, design_rank, evaluate_design, reference_regimes
from agents.design.space import (
    DESIGN_SPACE,
    FIT_STRETCH,
    MODULUS_ERROR,
    N_ERRORS,
    PRESSURE_ERROR_KPA,
    RAMP_STEPS,
    TARGETS,
    WALL_ERROR,
    WINDOW_POINTS,
    elastomers,
    finger_width_range,
    table1_design,
    validity,
)
from agents.design.storage import _knowingly, _optuna, make_storage
from pneunet_env.config import EnvConfig, load_config

STUDY_SETTINGS = ("use_case", "class_weights", "objects", "seed", "bounds", "elastomers", "config",
                  "pressure_error_kpa", "catalogue")
"""What a study was made with: a resumed (or joined) study must be run with the same."""


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
    pressure_error_kpa: float = PRESSURE_ERROR_KPA
    catalogue: str | None = None

    def __post_init__(self) -> None:
        e = self.pressure_error_kpa
        if isinstance(e, bool) or not isinstance(e, (int, float)) or not math.isfinite(e) or e < 0:
            raise ValueError(f"pressure_error_kpa must be a finite number >= 0 (kPa), got {e!r}")
        for name in ("trials", "objects", "held_out", "jobs", "top"):
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, (int, np.integer)) or v < 1:
                raise ValueError(f"{name} must be an integer >= 1, got {v!r}")
        if isinstance(self.seed, bool) or not isinstance(self.seed, (int, np.integer)) or self.seed < 0:
            raise ValueError(f"seed must be an integer >= 0, got {self.seed!r}")
        if self.sampler not in ("tpe", "nsga2"):
            raise ValueError(f"sampler must be 'tpe' or 'nsga2', got {self.sampler!r}")
        _space(self)  # the use case, weights and bounds are checked here (the finger against the objects), before
        # any work

    def base_config(self) -> EnvConfig:
        """The env config the designs change: ``config`` (the defaults without it) with the objects of ``use_case``
        or ``class_weights`` where given (of ``catalogue`` where given), else the config's own objects."""
        over: dict[str, Any] = {}
        if self.class_weights is not None:
            over["class_weights"] = self.class_weights
        elif self.use_case is not None:
            over["use_case"] = self.use_case
        if self.catalogue is not None:
            from agents.common.cli import with_catalogue

            over = with_catalogue(over, self.catalogue)
        return load_config(self.config, **over)

    @property
    def name(self) -> str:
        if self.study_name:
            return self.study_name
        oc = self.base_config().objects
        what = ("weights" if self.class_weights is not None else oc.use_case if oc.from_catalogue and
                oc.class_weights is None else "weights" if oc.from_catalogue else "ranges")
        return f"design-{what}"

    def settings(self) -> dict[str, Any]:
        return {"use_case": self.use_case, "class_weights": self.class_weights, "catalogue": self.catalogue,
                "objects": self.objects,
                "seed": self.seed, "bounds": {k: list(v) for k, v in sorted(self.bounds.items())},
                "elastomers": sorted(elastomers()), "config": self.config,
                "pressure_error_kpa": float(self.pressure_error_kpa)}


_INTEGER_KEYS = frozenset(b.key for b in DESIGN_SPACE if b.integer)


def _space(spec: StudySpec, base: EnvConfig | None = None) -> dict[str, tuple[float, float]]:
    """Each parameter's range: :data:`DESIGN_SPACE`'s, narrowed by ``--bound``, the finger no wider than the
    narrowest object of ``base`` (``spec.base_config()`` if ``None``; :func:`agents.design.space.finger_width_range`:
    the hold rule presses the whole width)."""
    space = {b.key: spec.bounds.get(b.key, (b.low, b.high)) for b in DESIGN_SPACE}
    space["finger_width_mm"] = finger_width_range(spec.bounds, spec.base_config() if base is None else base)
    return space


def _suggest(trial, space: dict[str, tuple[float, float]]) -> dict[str, Any]:
    """One design from ``space`` (:func:`_space`): the integer parameters as whole numbers, and an elastomer."""
    p: dict[str, Any] = {k: trial.suggest_int(k, int(lo), int(hi)) if k in _INTEGER_KEYS else
                         trial.suggest_float(k, lo, hi) for k, (lo, hi) in space.items()}
    p["elastomer"] = trial.suggest_categorical("elastomer", sorted(elastomers()))
    return p


def _objectives(s: DesignScore) -> tuple[float, float, float]:
    """Blind force-controlled and position-controlled success, and the worse of the two at the worst corner (an
    empty regime counts as 1: there is nothing in it to fail)."""
    f = lambda x: 1.0 if math.isnan(x) else x  # noqa: E731
    worst = s.worst_corner or s.robust
    return f(s.blind["force"]), f(s.blind["position"]), min(f(worst["force"]), f(worst["position"]))


def _end_session(study) -> None:
    """Close the RDB storage's session and connections (``RDBStorage.remove_session``, the engine disposed): a
    transaction that a Ctrl-C cut is rolled back, and the lock it held on an SQLite file released (else the next
    write waits for it, then fails)."""
    storage = getattr(study._storage, "_backend", study._storage)  # Optuna wraps an RDB storage in a cache
    with contextlib.suppress(Exception):
        if hasattr(storage, "remove_session"):
            storage.remove_session()
            storage.engine.dispose()  # every pooled connection closed: whatever the cut left open goes with it


def _worker_name(pid: int | None = None) -> str:
    """How a trial names the process that runs it: ``HOST:PID``."""
    return f"{socket.gethostname()}:{os.getpid() if pid is None else pid}"


class _Interrupts:
    """While a study optimises: a Ctrl-C raises ``KeyboardInterrupt`` only inside a design's evaluation
    (:meth:`evaluation`). Elsewhere (Optuna's storage writes: a trial's creation, its parameters, its result) it is
    noted, and raised as the next evaluation begins or when the optimisation ends: a write cut half-way leaves a
    trial that Optuna can neither tell nor fail (its ``AssertionError('Should not reach.')``) and an SQLite file
    locked. An error that compiled code made of a Ctrl-C (numba's compiler) is the interrupt all the same. Only in
    the main thread, under Python's handler or :func:`pneunet_env.files.interrupt_once` (a worker's); else nothing
    changes."""

    def __init__(self) -> None:
        self.noted = self.armed = self.active = False
        self.previous: Any = None

    def __enter__(self) -> _Interrupts:
        from pneunet_env.files import interrupt_once

        previous = signal.getsignal(signal.SIGINT)
        if threading.current_thread() is threading.main_thread() and previous in (signal.default_int_handler,
                                                                                 interrupt_once):
            self.previous, self.active = previous, True
            signal.signal(signal.SIGINT, self._handle)
        return self

    def _handle(self, signum, frame) -> None:
        self.noted = True
        if self.armed:
            self.armed = False
            raise KeyboardInterrupt

    @contextlib.contextmanager
    def evaluation(self):
        if self.noted:
            raise KeyboardInterrupt
        self.armed = True
        try:
            yield
        finally:
            self.armed = False

    def __exit__(self, kind, value, tb) -> None:
        from pneunet_env.files import interrupt_once

        if self.active:  # a worker's one interrupt, once spent, stays spent
            signal.signal(signal.SIGINT, signal.SIG_IGN if self.noted and self.previous is interrupt_once
                          else self.previous)
        if self.noted and (kind is None or not issubclass(kind, KeyboardInterrupt)):
            raise KeyboardInterrupt from None


def _objective(spec: StudySpec, seeds: np.ndarray, reference: np.ndarray, parallel: bool | None,
               interrupts: _Interrupts | None = None):
    optuna = _optuna()
    base = spec.base_config()
    space = _space(spec, base)  # once per worker: the config (and a user catalogue) is read here, not per trial
    interrupts = interrupts or _Interrupts()

    def objective(trial):
        # first of all: a trial whose process dies from here on is known by its process (:func:`fail_trials_of`)
        trial.set_user_attr("worker", _worker_name())
        params = _suggest(trial, space)
        same = _scored_before(trial.study, params, trial.number)
        if same is not None:  # scored already: not run again, and not counted (the budget is of designs)
            trial.set_user_attr("duplicate_of", same.number)
            raise optuna.TrialPruned(f"the design of trial {same.number}")
        try:
            with interrupts.evaluation():
                s = evaluate_design(params, seeds, reference, base, spec.seed, parallel=parallel,
                                    pressure_error_kpa=spec.pressure_error_kpa)
        except ValueError as exc:  # a geometry the model refuses (no cavity left): not a design
            trial.set_user_attr("invalid", str(exc))
            raise optuna.TrialPruned(str(exc)) from None
        trial.set_user_attr("score", s.to_dict())
        return _objectives(s)

    return objective




class _NoInterruptLogs(logging.Filter):
    """Drops Optuna's "Trial N failed ... KeyboardInterrupt()" record with its traceback, and the "Trial N failed with
    value None." that follows it: an interrupted trial is marked failed and retried on resume, and the command says
    so in its one line."""

    def __init__(self) -> None:
        super().__init__()
        self.cut: str | None = None

    def filter(self, record: logging.LogRecord) -> bool:
        exc = record.exc_info[0] if record.exc_info else None
        text = record.getMessage()
        if (exc is not None and issubclass(exc, KeyboardInterrupt)) or "KeyboardInterrupt" in text:
            self.cut = text.split(" failed", 1)[0]  # "Trial N"
            return False
        return not (self.cut is not None and text.startswith(f"{self.cut} failed with value"))


@contextlib.contextmanager
def _quiet_interrupts():
    log = logging.getLogger("optuna.study._optimize")
    quiet = _NoInterruptLogs()
    log.addFilter(quiet)
    try:
        yield
    finally:
        log.removeFilter(quiet)


def _sampler(spec: StudySpec, seed: int):
    optuna = _optuna()
    with _knowingly():
        return (optuna.samplers.TPESampler(seed=seed, multivariate=True, group=True, n_startup_trials=24)
                if spec.sampler == "tpe" else optuna.samplers.NSGAIISampler(seed=seed, population_size=24))


def sampler_seed(spec: StudySpec, worker: int | str, stored: int) -> int:
    """The seed of one worker's sampler: from the study's seed, the worker (its index among ``--jobs``, or for a
    ``--worker`` joining from elsewhere its ``HOST:PID``) and how many trials the storage held when it started; so
    no two workers, and no two resumptions, replay one sequence of designs (each alone reproducible)."""
    import zlib

    who = worker if isinstance(worker, int) else (1 << 20) + zlib.crc32(str(worker).encode())
    return int(np.random.SeedSequence([int(spec.seed), who, int(stored)]).generate_state(1)[0])


def open_study(spec: StudySpec, create: bool = True):
    """Create or load the study; a resumed or joined study must have been made with the same settings. A new study's
    first trial is Table 1's design (enqueued before the settings are stored, so that a study cut between the two
    still gets it)."""
    optuna = _optuna()
    spec.out.mkdir(parents=True, exist_ok=True)
    storage = make_storage(spec.storage, spec.out)
    sampler = _sampler(spec, spec.seed)
    try:
        study = optuna.create_study(study_name=spec.name, storage=storage, sampler=sampler, load_if_exists=create,
                                    directions=["maximize"] * 3)
    except optuna.exceptions.DuplicatedStudyError:  # pragma: no cover - load_if_exists=False only
        raise ValueError(f"study {spec.name!r} exists already") from None
    want = json.loads(json.dumps(spec.settings()))
    have = study.user_attrs.get("settings")
    if have is None:
        if not any(t.user_attrs.get("table1") for t in study.get_trials(deepcopy=False)):
            study.enqueue_trial(table1_design(), user_attrs={"table1": True})
        with _knowingly():
            study.set_metric_names(["blind force-controlled", "blind position-controlled", "worst under error"])
        study.set_user_attr("settings", want)
    elif have != want:
        diff = {k: (have.get(k), want.get(k)) for k in want if have.get(k) != want.get(k)}
        raise ValueError(f"study {spec.name!r} in {spec.storage or spec.out / 'study.db'} was made with other "
                         f"settings: {diff} (stored, given); use another --out, --storage or --study-name")
    return study


_FINISHED = ("COMPLETE", "PRUNED")
"""The trial states a study counts (a design scored, or refused by the model); a failed trial is retried."""

ORPHAN_S = 10.0
"""A running trial that names no process this long after its start is an orphan (seconds): its process died
between Optuna's creating it and the objective's first line, which names the process within milliseconds."""


def _finished(study) -> int:
    """The trials the budget counts: a design scored, or refused by the model (a duplicate pruned unscored is not
    one)."""
    return sum(t.state.name in _FINISHED and "duplicate_of" not in t.user_attrs
               for t in study.get_trials(deepcopy=False))


def _counted(study) -> int:
    """:func:`_finished`, and the trials running now (another worker's, which will count once finished)."""
    return _finished(study) + sum(t.state.name == "RUNNING" and "duplicate_of" not in t.user_attrs
                                  for t in study.get_trials(deepcopy=False))


def _same_params(a: dict[str, Any], b: dict[str, Any]) -> bool:
    return a.keys() == b.keys() and all(a[k] == b[k] for k in a)


def _scored_before(study, params: dict[str, Any], number: int):
    """A finished trial (scored, or refused by the model) with ``params`` exactly, other than trial ``number``."""
    for t in study.get_trials(deepcopy=False):
        if (t.number != number and t.state.name in _FINISHED and "duplicate_of" not in t.user_attrs
                and ("score" in t.user_attrs or "invalid" in t.user_attrs) and _same_params(t.params, params)):
            return t
    return None


def _waiting(study) -> int:
    return sum(t.state.name == "WAITING" for t in study.get_trials(deepcopy=False))


def fail_trials_of(study, pid: int, cause: str) -> list[int]:
    """Mark failed the trials that the process ``pid`` of this host left running (it died, or was interrupted
    before Optuna could say so), each with its ``failed`` cause; returns their numbers."""
    optuna = _optuna()
    name = _worker_name(pid)
    failed = []
    for t in study.get_trials(deepcopy=False, states=(optuna.trial.TrialState.RUNNING,)):
        if t.user_attrs.get("worker") == name:
            _fail(study, t, cause)
            failed.append(t.number)
    return failed


def _fail(study, frozen, cause: str) -> None:
    optuna = _optuna()
    try:
        optuna.trial.Trial(study, frozen._trial_id).set_user_attr("failed", cause)
        study.tell(frozen.number, state=optuna.trial.TrialState.FAIL, skip_if_finished=True)
    except (RuntimeError, ValueError):  # it ended meanwhile (a worker elsewhere finished it): as it ended
        pass


def _orphans(study, now: datetime.datetime) -> tuple[list, float]:
    """The running trials whose process is gone (a process of this host, dead; or none named :data:`ORPHAN_S` after
    the start), and how long to wait before a younger unnamed one can be judged (seconds)."""
    from pneunet_env.locks import pid_alive

    optuna = _optuna()
    host = socket.gethostname()
    out, wait = [], 0.0
    for t in study.get_trials(deepcopy=False, states=(optuna.trial.TrialState.RUNNING,)):
        worker = t.user_attrs.get("worker")
        if isinstance(worker, str):
            where, _, pid = worker.rpartition(":")
            if where == host and pid.isdigit() and not pid_alive(int(pid)):
                out.append(t)
        elif t.datetime_start is not None:
            age = (now - t.datetime_start).total_seconds()
            if age >= ORPHAN_S:
                out.append(t)
            else:
                wait = max(wait, ORPHAN_S - age)
    return out, wait


def mend(study) -> dict[str, list[int]]:
    """Before a study's workers start (in the command that runs them, not in each worker): the trials that a dead
    process left running are marked failed; every failed trial not yet retried is enqueued again, with its parameters
    (Table 1's as Table 1: the reference every design is compared with), to run before any new design; and Table 1 is
    enqueued if the study lacks it. Nothing is counted twice (a failed trial counts for nothing; its retry counts
    once) and nothing is lost. Returns ``{"orphans": [...], "retried": [...]}``, trial numbers."""
    optuna = _optuna()
    orphans, wait = _orphans(study, datetime.datetime.now())
    if wait:  # a trial that names no process yet, started moments ago: judged once it could have named one
        time.sleep(wait)
        orphans, _ = _orphans(study, datetime.datetime.now())
    for t in orphans:
        _fail(study, t, "its process ended while it ran")
    trials = study.get_trials(deepcopy=False)
    retried = {t.user_attrs.get("retry_of") for t in trials}
    again = []
    for t in trials:
        if t.state is optuna.trial.TrialState.FAIL and t.number not in retried:
            table1 = bool(t.user_attrs.get("table1"))
            params = table1_design() if table1 else {**t.system_attrs.get("fixed_params", {}), **t.params}
            study.enqueue_trial(params, user_attrs={"retry_of": t.number, **({"table1": True} if table1 else {})})
            again.append(t.number)
    if not any(t.user_attrs.get("table1") for t in trials):
        study.enqueue_trial(table1_design(), user_attrs={"table1": True})
    return {"orphans": [t.number for t in orphans], "retried": again}


DUPLICATES_IN_A_ROW = 20
"""A worker whose sampler proposes this many designs in a row that the study has scored already stops (its space is
spent: a --bound too narrow)."""


def work(spec: StudySpec, parallel: bool | None = None, progress: bool | None = None, worker: int | str | None = None,
         share: int | None = None) -> int:
    """Run trials until the study has ``spec.trials`` finished ones (complete or refused) and no trial waits (a
    failed trial's retry, Table 1: run even if the count is reached); returns how many this process ran. Any number
    of processes, here or on other machines, may do this on one study at once: before each trial a worker asks the
    storage how many are finished or running, and starts none once they are ``spec.trials``; a worker given a
    ``share`` (:func:`shares`: the ``--jobs`` of one command) runs that many at most.

    Every trial is a new design: the sampler is seeded per worker and per resumption (:func:`sampler_seed`; ``worker``
    is the index among ``--jobs``, or ``None`` for this process's ``HOST:PID``), and a design the study has scored
    already is pruned unrun as a duplicate (``duplicate_of``), which the budget does not count.

    Ctrl-C: the trial it cut is marked failed (Optuna's log of it is not printed), and ``KeyboardInterrupt``
    propagates; :func:`mend` retries the trial when the study is run again. A Ctrl-C cuts only a design's evaluation,
    never Optuna's writes to the storage (:class:`_Interrupts`)."""
    _optuna()
    from agents.evaluation.batch import episode_seeds
    from pneunet_env.progress import progress as progress_bar

    study = open_study(spec)
    study.sampler = _sampler(spec, sampler_seed(spec, _worker_name() if worker is None else worker,
                                                len(study.get_trials(deepcopy=False))))
    seeds = episode_seeds(spec.objects, spec.seed)
    reference = reference_regimes(seeds, spec.base_config())
    left = max(spec.trials - _counted(study), _waiting(study))
    if share is not None:
        left = min(left, share)
    if left <= 0:
        return 0
    bar = progress_bar(total=left, desc=f"design {spec.name}", unit="design", enabled=progress)
    ran = in_a_row = 0

    def tick(study, trial):
        nonlocal ran, in_a_row
        if "duplicate_of" in trial.user_attrs:
            in_a_row += 1
            return
        ran, in_a_row = ran + 1, 0
        bar.update()

    def more() -> bool:
        if _waiting(study):
            return share is None or ran < share or worker == 0  # worker 0 runs what waits (its share counts it)
        if share is not None and ran >= share:
            return False
        return _counted(study) < spec.trials and in_a_row < DUPLICATES_IN_A_ROW

    try:
        with _quiet_interrupts(), _knowingly(), _Interrupts() as interrupts:
            objective = _objective(spec, seeds, reference, parallel, interrupts)
            while more():
                study.optimize(objective, n_trials=1, callbacks=[tick], gc_after_trial=False)
    except KeyboardInterrupt as exc:
        _end_session(study)  # a transaction the interrupt cut, rolled back: its lock on the database goes
        with contextlib.suppress(Exception):  # a trial the interrupt cut before Optuna could mark it
            fail_trials_of(study, os.getpid(), "interrupted")
        raise KeyboardInterrupt(*exc.args) from None
    finally:
        bar.close()
    return ran


def shares(left: int, waiting: int, jobs: int) -> list[int]:
    """How many trials each of ``jobs`` workers runs, ``left`` in all (``--trials`` less those finished, or the
    ``waiting`` ones if more), in equal parts; worker 0 runs the waiting trials (Table 1, retries) within its part,
    or only them where they are more and the others share the rest. The workers together run ``left`` trials,
    whatever ``jobs`` is."""
    left, waiting = max(left, 0), min(max(waiting, 0), max(left, 0))
    even = [left // jobs + (k < left % jobs) for k in range(jobs)]
    if even[0] >= waiting:
        return even
    rest = left - waiting
    return [waiting] + [rest // (jobs - 1) + (k < rest % (jobs - 1)) for k in range(jobs - 1)]


def _worker(job: tuple[StudySpec, int, int]) -> int:  # a --jobs process: one numba thread, no bar
    spec, index, share = job
    if index:  # the trials that wait (Table 1, the retries) are worker 0's: on SQLite two processes can both take
        study = open_study(spec)  # one waiting trial (it has no row locks) and run it twice
        while _waiting(study):
            time.sleep(0.2)
    return work(spec, parallel=False, progress=False, worker=index, share=share)


def run_study(spec: StudySpec, progress: bool | None = None, log=print) -> dict[str, Any]:
    """Run (or resume, or join) the study to ``spec.trials`` finished trials with ``spec.jobs`` processes, then
    report: the best designs re-scored on held-out objects, and every output file.

    First the study is mended (:func:`mend`: what a dead or interrupted process left is failed and retried). With
    ``--jobs``, the workers run under :func:`agents.common.workers.run_jobs`: a worker that dies is noticed at once, the
    trial it ran is marked failed, the other workers are stopped as Ctrl-C stops them (their trials marked failed
    too), and a ``SystemExit`` says so in one line; the same command retries them all. Ctrl-C: ``KeyboardInterrupt``
    with a note naming the trials to be retried."""
    t0 = time.perf_counter()
    study = open_study(spec)  # checked (and created) once, before any worker starts
    mended = mend(study)
    if mended["retried"]:
        log(f"retrying trial(s) {', '.join(map(str, mended['retried']))} (failed or cut short before)")
    if spec.jobs == 1:
        trials = study.get_trials(deepcopy=False)
        before, failed = _running(trials), {t.number for t in trials if t.state.name == "FAIL"}
        try:
            work(spec, progress=progress, worker=0)
        except KeyboardInterrupt:
            _fail_unnamed(study, before)
            cut = [t.number for t in study.get_trials(deepcopy=False) if t.state.name == "FAIL"
                   and t.number not in failed]
            raise KeyboardInterrupt(_retry_note(cut)) from None
    else:
        _work_in_processes(spec, study)
    search_s = time.perf_counter() - t0
    return report(spec, search_s, progress, log)


def _running(trials) -> set[int]:
    return {t.number for t in trials if t.state.name == "RUNNING"}


def _fail_unnamed(study, before: set[int]) -> None:
    """Every process of this run has ended: a trial it started (not running ``before`` it) and left running without
    a process named was cut between Optuna's starting it and the objective's first line; it is marked failed."""
    optuna = _optuna()
    for t in study.get_trials(deepcopy=False, states=(optuna.trial.TrialState.RUNNING,)):
        if t.number not in before and not isinstance(t.user_attrs.get("worker"), str):
            _fail(study, t, "its process ended while it ran")


def _retry_note(trials: list[int]) -> str:
    if not trials:
        return "(no trial was cut): the same command goes on"
    return (f"(trial{'s' if len(trials) > 1 else ''} {', '.join(map(str, trials))} marked failed): the same command "
            "retries and goes on")


def _work_in_processes(spec: StudySpec, study) -> None:
    """``spec.jobs`` worker processes on ``study`` (see :func:`run_study`)."""
    from agents.common.workers import run_jobs

    failed: dict[int, list[int]] = {}

    def on_end(out) -> bool:
        cause = "interrupted" if out.state == "interrupted" else (out.cause() if out.state == "died" else
                                                                  f"its worker ended: {out.state}")
        failed[out.index] = fail_trials_of(study, out.pid, cause) if out.pid is not None else []
        return out.state == "done"

    trials = study.get_trials(deepcopy=False)
    before, was_failed = _running(trials), {t.number for t in trials if t.state.name == "FAIL"}
    parts = shares(max(spec.trials - _counted(study), _waiting(study)), _waiting(study), spec.jobs)
    ran = run_jobs(_worker, [(spec, k, n) for k, n in enumerate(parts) if n or not k], spec.jobs, on_end=on_end,
                   preload=("agents.design.study", "optuna"))
    if ran.clean:
        return
    _fail_unnamed(study, before)
    cut = sorted(t.number for t in study.get_trials(deepcopy=False) if t.state.name == "FAIL"
                 and t.number not in was_failed)
    died = [o for o in ran.outcomes if o.state == "died"]
    errors = [o for o in ran.outcomes if o.state == "error"]
    if ran.interrupted or not (died or errors):
        raise KeyboardInterrupt(_retry_note(cut))

    def during(o) -> str:
        return f" during trial {', '.join(map(str, failed[o.index]))}" if failed.get(o.index) else ""

    parts = [f"design worker {o.index}: {o.cause()}{during(o)}" for o in died]
    parts += [f"design worker {o.index} failed: {type(o.value).__name__}: {o.value}" for o in errors]
    if spec.jobs > len(died) + len(errors):
        parts.append("the other workers were stopped")
    what = (f"trial{'s' if len(cut) > 1 else ''} {', '.join(map(str, cut))} marked failed" if cut else
            "no trial was cut")
    raise SystemExit(f"pneunet-grasp design: {'; '.join(p for p in parts if p)} ({what}): run the same command "
                     "again to retry and go on")


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
    from agents.evaluation.batch import episode_seeds

    study = open_study(spec)
    scored = _trial_scores(study)
    table1 = next((ts for ts in scored if ts[0].user_attrs.get("table1")), None)
    if table1 is None and not any(t.user_attrs.get("table1") and t.state.name == "PRUNED" for t in study.trials):
        raise ValueError(f"study {spec.name!r} has no finished Table 1 design (the reference every design is compared "
                         "with: it failed or has not run yet); run the study (without --report) to run it")
    if not scored:
        raise ValueError(f"study {spec.name!r} has no finished design yet")
    ranked = sorted(scored, key=lambda ts: design_rank(ts[1]), reverse=True)
    # the ranks are of designs a lab could build: an elastomer with data, its walls within the stretch it was fitted
    # on; the best design that is not buildable is reported beside them as a requirement (the mu and J it needs)
    buildable = [ts for ts in ranked if _buildable(ts[1])] or ranked
    top = []
    seen: set[str] = set()
    for t, s in buildable:
        key = json.dumps(s.params, sort_keys=True)
        if key not in seen:
            seen.add(key)
            top.append((t, s))
        if len(top) == spec.top:
            break
    requirement = [("requirement", ranked[0])] if not _buildable(ranked[0][1]) and ranked[0] not in top else []
    base = spec.base_config()
    held = episode_seeds(spec.held_out, spec.seed, held_out=True)
    ref_held = reference_regimes(held, base)
    rows = []
    for label, (t, s) in ([("table1", table1)] * (table1 is not None) + [(f"rank-{k + 1}", ts) for k, ts in
                                                                       enumerate(top)] + requirement):
        h = evaluate_design(s.params, held, ref_held, base, spec.seed, target=s.target,
                            pressure_error_kpa=spec.pressure_error_kpa)
        rows.append({"label": label, "trial": t.number, "params": s.params, "validity": validity(s.params),
                     "elastomer": asdict(elastomers()[s.params["elastomer"]]), "search": s.to_dict(),
                     "held_out": h.to_dict(), "buildable": h.outside_data is False})
        log(_line(label, s, h))
        if label == "requirement":
            log(f"             no buildable design reaches it: it needs a material of mu {_mu(s):g} kPa and J "
                f"{_j(s):g} with data up to a stretch of {h.wall_stretch:.2f}")
    vals = np.array([_objectives(s) for _, s in scored])
    front = _pareto(vals)
    importance, importance_note = _importance(study)
    result = {
        "study": spec.name, "settings": spec.settings(), "trials": len(study.trials), "scored": len(scored),
        "distinct": len({json.dumps(t.params, sort_keys=True) for t, _ in scored}),
        "duplicates": sum("duplicate_of" in t.user_attrs for t in study.trials),
        "search_seconds": search_s, "objects": spec.objects, "held_out": spec.held_out,
        "targets": list(TARGETS), "ramp_steps": RAMP_STEPS,
        "errors": {"walls": WALL_ERROR, "modulus": MODULUS_ERROR, "actuators": N_ERRORS,
                   "pressure_kpa": spec.pressure_error_kpa, "fit_stretch": FIT_STRETCH,
                   "corners": ("walls x{0.9, 1.1} crossed with modulus x{0.8, 1.2}; the elastomer's J range and "
                               "data-sheet mu at nominal walls; the blind pressure -/+ the regulator's error")},
        "window_points": WINDOW_POINTS, "importance": importance, "importance_note": importance_note,
        "designs": rows,
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
            f"{s.params['chamber_height_mm']:.2f} w {s.params['width_mm']:.2f} mm; {_finger(s.params)}; blind "
            f"{h.pressure_kpa:5.1f} kPa | "
            f"held out: force {_pct(h.blind['force'])} position {_pct(h.blind['position'])} (oracle "
            f"{_pct(h.oracle['force'])} {_pct(h.oracle['position'])}), worst corner "
            f"{_pct(h.worst_corner.get('force', math.nan))} {_pct(h.worst_corner.get('position', math.nan))}, random "
            f"error {_pct(h.robust['force'])} {_pct(h.robust['position'])}, window {h.window_fraction:.0%}; wall "
            f"stretch {h.wall_stretch:.2f}{_data_note(h)}")


def _finger(params: dict[str, Any]) -> str:
    """The finger in 3D: its width, length and count (Table 1's where a study made before 0.15 has none)."""
    t1 = table1_design()
    b, length, n = (params.get(k, t1[k]) for k in ("finger_width_mm", "length_mm", "grip_faces"))
    return f"{n} fingers {b:.1f} x {length:.0f} mm"


def _buildable(s: DesignScore) -> bool:
    """A design a lab could build: its elastomer has data (not the paper's own material) and its walls stretch no
    further than the data its material was fitted on."""
    return s.outside_data is False


def _mu(s: DesignScore) -> float:
    return elastomers()[s.params["elastomer"]].shear_modulus_kpa


def _j(s: DesignScore) -> float:
    return elastomers()[s.params["elastomer"]].gent_limit


def _data_note(s: DesignScore) -> str:
    if s.outside_data is None:
        return " (no material data: the paper's material)"
    return " OUTSIDE THE MATERIAL DATA (fitted to 3): not buildable as scored" if s.outside_data else ""


TIED_IMPORTANCE = ("no importance: the top designs' scores tie with the rest (PED-ANOVA's target and region "
                   "quantiles select the same designs), so no parameter can be told apart")
"""What the report says where PED-ANOVA cannot rank the parameters (Optuna warns that their importances are equal)."""


def _importance(study) -> tuple[dict[str, float], str]:
    """Optuna's PED-ANOVA importance of each parameter for the design score (:func:`design_rank`'s first value):
    how differently the parameter is distributed among the top designs than among all (Watanabe et al. 2023; it
    needs no scikit-learn, which fANOVA does); and a note where there is none (:data:`TIED_IMPORTANCE` when the
    scores tie, as they do when most designs hold nothing at their worst corner)."""
    import warnings

    import optuna

    done = [t for t in study.trials if t.state is optuna.trial.TrialState.COMPLETE and "score" in t.user_attrs]
    if len(done) < 8:
        return {}, "too few designs for an importance estimate"
    try:
        with _knowingly(), warnings.catch_warnings(record=True) as caught:
            # PED-ANOVA's note that it looks for low values: the target is negated for that
            warnings.simplefilter("always")
            imp = optuna.importance.get_param_importances(
                study, target=lambda t: -float(t.user_attrs["score"]["score"]),
                evaluator=optuna.importance.PedAnovaImportanceEvaluator())
    except (RuntimeError, ValueError, ImportError):  # too few distinct trials
        return {}, "too few distinct designs for an importance estimate"
    for w in caught:
        if "select the same set of trials" in str(w.message):
            return {}, TIED_IMPORTANCE
        if not issubclass(w.category, optuna.exceptions.ExperimentalWarning) and "low `target`" not in str(w.message):
            warnings.warn_explicit(w.message, w.category, w.filename, w.lineno)  # any other: passed on, not hidden
    return {k: float(v) for k, v in imp.items()}, ""
