"""The policy registry: a name (or a model file) -> a policy and the environment it drives.

====================  ===============================================================  ==================
spec                  policy                                                           environment
====================  ===============================================================  ==================
``ramp``              :class:`~agents.scripted.LinearRamp` to ``p_max`` over 40 steps  ``PneuNetGrasp-v0``
``step``              :class:`~agents.scripted.StepPolicy` to ``p_max``                ``PneuNetGrasp-v0``
``best-ramp``         the ramp in ``agents/best_ramp.json`` (:mod:`agents.search`)      ``PneuNetGrasp-v0``
``oracle``            :class:`~agents.oracle.Oracle` (knows the object; not blind)      ``PneuNetGrasp-v0``
``rigid``             the jaw ramp in ``agents/best_rigid.json`` (:mod:`agents.search`) ``RigidGrasp-v0``
``PATH.zip``          a stable-baselines3 model, with its ``VecNormalize`` statistics   ``PneuNetGrasp-v0``
====================  ===============================================================  ==================

Parameters follow a colon, comma-separated: ``ramp:target_kpa=30,steps=20``, ``step:target_kpa=45``,
``best-ramp:path=runs/best.json``, ``oracle:resolution_kpa=0.25``, ``rigid:target_mm=9,steps=10``,
``rigid:path=...``. (``target=`` takes a fraction of ``p_max`` or of the jaw travel instead.) A tuned schedule's file
is defined in kPa (mm for the jaw: :func:`agents.scripted.ramp_target`): another ``max_pressure_kpa`` never moves it,
and one above the config's maximum is refused. A config file's own schedule beside it that cannot be read, or that is
missing where the config describes another actuator than the package's schedule was tuned for, is refused by name
(:func:`tuned_path`, :func:`_refuse_another_actuator`).

A policy maps an observation (or a batch) to an action in ``Box(-1, 1, (1,))``, has ``predict`` (SB3's
signature) and ``begin_episode(info)`` (called with ``reset``'s ``info``; only the oracle uses it).

An SB3 model ``DIR/NAME.zip`` is loaded with the algorithm named in ``DIR/NAME.json`` (written by
``pneunet-grasp train``; else inferred from the saved policy class) and the normalisation statistics of
``DIR/NAME_vecnormalize.json`` (else ``DIR/vecnormalize.json``; none if neither exists): plain numbers
(:class:`NormalizationStats`), read without ``pickle``. ``PATH.zip:vecnormalize=STATS,action=setpoint`` names
them (and the action mode) explicitly. The action mode (``rate``: the env's pressure change; ``setpoint``: a
commanded pressure) is never guessed: both have the same action space, so a model with no metadata (no
``NAME.json`` and no training run's ``run.json`` around it), a cut one, or one that contradicts the hyperparameters
it records (``"action": "rate"`` beside a training through the ``PressureSetpoint`` wrapper), is refused by name
unless the spec gives ``action=``. A cut or damaged model zip is refused by name too. torch and stable-baselines3
are imported only for such a model.

**Security: load only models you trust.** A model ``.zip`` is code: stable-baselines3 unpickles parts of it
(``cloudpickle``), so loading one runs whatever its author put there. Statistics are never unpickled implicitly:
a ``vecnormalize.pkl`` lying next to a model (as rl-zoo3 and SB3's ``VecNormalize.save`` write them) is ignored,
with a warning, and is loaded only when its path is named explicitly (``SB3Policy(..., vecnormalize=PATH)``,
``PATH.zip:vecnormalize=PATH.pkl``); :func:`convert_vecnormalize` turns such a pickle, once trusted, into the
JSON form.
"""

from __future__ import annotations

import json
import math
import os
import pickle
import warnings
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from agents.scripted import LinearRamp, StepPolicy, load_ramp
from pneunet_env.config import EnvConfig
from pneunet_env.files import atomic_write_bytes, stage_file  # noqa: F401  (re-exported: the one atomic writer)
from pneunet_env.wrappers import setpoint_to_rate
from pneunet_env.yamlio import check_input_file, load_json_file, short_repr

__all__ = ["PolicyEntry", "REGISTRY", "make_policy", "parse_spec", "SB3Policy", "BEST_RAMP_PATH", "BEST_RIGID_PATH",
           "vecnormalize_path", "setpoint_to_rate", "ACTION_MODES", "NormalizationStats", "RunningStats",
           "convert_vecnormalize", "atomic_write_bytes", "stage_file", "check_model_zip", "schedule_origin",
           "tuned_schedules_text", "warn_untuned"]

AGENTS_DIR = Path(__file__).resolve().parent
BEST_RAMP_PATH = AGENTS_DIR / "best_ramp.json"
"""The ``best-ramp`` policy's parameters on the default task (written by ``python -m agents.search``)."""
BEST_RIGID_PATH = AGENTS_DIR / "best_rigid.json"
"""The ``rigid`` policy's parameters on the default task (written by ``python -m agents.search --gripper rigid``)."""
BEST_RAMP_PAPER_PATH = AGENTS_DIR / "best_ramp_paper.json"
"""The same on the paper's task (``PneuNetGrasp-Paper-v0``: its ring, objects drawn from ranges)."""
BEST_RIGID_PAPER_PATH = AGENTS_DIR / "best_rigid_paper.json"


def _beside_path(config_path: str | os.PathLike, gripper: str = "pneunet") -> Path:
    """Where a schedule tuned for the config file ``DIR/NAME.yaml`` is shipped: ``DIR/NAME.best_ramp.json``
    (``DIR/NAME.best_rigid.json`` for the rigid gripper), whether or not it exists."""
    path = Path(config_path)
    return path.with_name(f"{path.stem}.best_{'rigid' if gripper == 'rigid' else 'ramp'}.json")


def tuned_path(config: EnvConfig, gripper: str = "pneunet", *, config_path: str | os.PathLike | None = None) -> Path:
    """The tuned schedule for the task ``config`` describes: the default task's (objects from the catalogue) or the
    paper's (objects from ranges). Each was searched on its own task; a blind schedule is tuned to a distribution.

    ``config_path``: the YAML file ``config`` was loaded from, if any. A schedule shipped beside it
    (:func:`_beside_path`: ``DIR/NAME.best_ramp.json`` or ``DIR/NAME.best_rigid.json``) wins when it exists, whatever
    overrides were applied on top of the file; else the package's own, as above (``best-ramp`` refuses that for a
    config of another actuator: :func:`_refuse_another_actuator`).

    Raises:
        ValueError: the schedule beside the config exists but is not a regular file (a folder, a device, a FIFO, a
            link to nothing): named, never skipped for another schedule.
    """
    if config_path is not None and os.path.lexists(beside := _beside_path(config_path, gripper)):
        if not beside.is_file():
            what = ("a link to nothing" if not beside.exists() else "a folder" if beside.is_dir()
                    else "not a regular file (a device, a FIFO or a socket)")
            raise ValueError(f"the schedule beside the config {str(config_path)!r}, {str(beside)!r}, is {what}: "
                             "replace it with the config's ramp file, remove it, or name another schedule "
                             f"(--policy {'rigid' if gripper == 'rigid' else 'best-ramp'}:path=FILE)")
        return beside
    paper = not config.objects.from_catalogue
    if gripper == "rigid":
        return BEST_RIGID_PAPER_PATH if paper else BEST_RIGID_PATH
    return BEST_RAMP_PAPER_PATH if paper else BEST_RAMP_PATH

PNEUNET_ENV = "PneuNetGrasp-v0"
RIGID_ENV = "RigidGrasp-v0"


@dataclass
class PolicyEntry:
    """A policy ready to run, and what it needs.

    Attributes:
        name: the spec it was made from (``best-ramp``, ``models/ppo.zip``, ...).
        label: a human-readable description (for tables and legends).
        policy: the policy object.
        env_id: the environment it drives (``PneuNetGrasp-v0`` or ``RigidGrasp-v0``).
        blind: whether it acts on the observation alone (the oracle does not).
        command: what the observation and action move: ``"pressure"`` or ``"jaw"``.
        env_kwargs: extra keyword arguments for ``gym.make`` (the rigid gripper's travel; a trained model's
            ``observe_volume``).
        tuned_on: a tuned schedule's file and what it was tuned on, in words (:func:`schedule_origin`); ``""`` for
            a policy that is not loaded from a tuned schedule.
        fits_objects: whether the config's objects are the ones that schedule was tuned on; ``None`` where that is
            not known (a schedule given by ``path=``) or does not apply.
    """

    name: str
    label: str
    policy: Any
    env_id: str = PNEUNET_ENV
    blind: bool = True
    command: str = "pressure"
    env_kwargs: dict[str, Any] = field(default_factory=dict)
    tuned_on: str = ""
    fits_objects: bool | None = None

    def make_env(self, config: EnvConfig):
        """``gym.make`` the policy's environment with ``config``."""
        import gymnasium as gym

        import pneunet_env  # noqa: F401  (registers PneuNetGrasp-v0)
        return gym.make(self.env_id, config=config, **self.env_kwargs)


def parse_spec(spec: str) -> tuple[str, dict[str, str]]:
    """``"name:k=v,k2=v2"`` -> ``("name", {"k": "v", "k2": "v2"})``; ``ValueError`` on a malformed one."""
    if not isinstance(spec, str) or not spec.strip():
        raise ValueError(f"policy spec must be a non-empty string, got {spec!r}")
    name, _, rest = spec.strip().partition(":")
    params: dict[str, str] = {}
    if rest:
        for item in rest.split(","):
            key, eq, value = item.partition("=")
            if not eq or not key.strip():
                raise ValueError(f"policy spec {spec!r}: parameters must be key=value, got {item!r}")
            params[key.strip()] = value.strip()
    return name.strip(), params


def _float(spec: str, key: str, value: str) -> float:
    """A spec's number: finite (``nan``, ``inf`` and ``1e400``, which overflows, are refused by name)."""
    try:
        x = float(value)
    except ValueError:
        raise ValueError(f"policy spec {spec!r}: {key}={value!r} is not a number") from None
    if not math.isfinite(x):
        raise ValueError(f"policy spec {spec!r}: {key}={value!r} is not a finite number")
    return x


def _int(spec: str, key: str, value: str) -> int:
    x = _float(spec, key, value)
    if x != int(x):
        raise ValueError(f"policy spec {spec!r}: {key}={value!r} is not an integer")
    return int(x)


def _target(spec: str, params: dict[str, str], full_scale: float, unit_key: str, default: float) -> float:
    """A target as a fraction of full scale, from ``target=`` (fraction) or ``<unit_key>=`` (physical)."""
    if "target" in params and unit_key in params:
        raise ValueError(f"policy spec {spec!r}: give 'target' or {unit_key!r}, not both")
    if "target" in params:
        return _float(spec, "target", params.pop("target"))
    if unit_key in params:
        return _float(spec, unit_key, params.pop(unit_key)) / full_scale
    return default


def _check_empty(spec: str, params: dict[str, str], valid: str) -> None:
    if params:
        raise ValueError(f"policy spec {spec!r}: unknown parameter(s) {sorted(params)}; valid: {valid}")


def _ramp(spec, params, config):
    t = _target(spec, params, config.task.max_pressure_kpa, "target_kpa", 1.0)
    n = _int(spec, "steps", params.pop("steps", "40"))
    _check_empty(spec, params, "target, target_kpa, steps")
    pol = LinearRamp(t, n, config)
    return PolicyEntry(spec, f"ramp to {t * config.task.max_pressure_kpa:.3g} kPa over {n} steps", pol)


def _step(spec, params, config):
    t = _target(spec, params, config.task.max_pressure_kpa, "target_kpa", 1.0)
    _check_empty(spec, params, "target, target_kpa")
    return PolicyEntry(spec, f"step to {t * config.task.max_pressure_kpa:.3g} kPa", StepPolicy(t, config))


def _best_ramp(spec, params, config, config_path=None):
    given = params.pop("path", None)
    path = Path(given) if given is not None else tuned_path(config, config_path=config_path)
    _check_empty(spec, params, "path")
    if given is None and config_path is not None:
        _refuse_another_actuator(path, config_path)
    pol = load_ramp(path, config)
    label = f"best-ramp ({_describe(pol, config.task.max_pressure_kpa, 'kPa')}{_source(path)})"
    tuned_on, fits = schedule_origin(path, config, config_path=config_path)
    return PolicyEntry(spec, label, pol, tuned_on=tuned_on, fits_objects=fits)


def _package_task(path: Path) -> EnvConfig | None:
    """The config a package schedule (``agents/best_*.json``) was tuned on: the default task, or the paper's; ``None``
    for any other file."""
    from pneunet_env import PAPER_TASK
    from pneunet_env.config import load_config

    where = path.resolve()
    if where in (BEST_RAMP_PATH, BEST_RIGID_PATH):
        return EnvConfig()
    if where in (BEST_RAMP_PAPER_PATH, BEST_RIGID_PAPER_PATH):
        return load_config(None, **PAPER_TASK)
    return None


def _refuse_another_actuator(path: Path, config_path: str | os.PathLike) -> None:
    """``ValueError`` where ``best-ramp`` would run the package's schedule ``path`` (none lies beside the config file
    ``config_path``) on a config of another actuator than the one it was tuned for (a designed config copied without
    its ``.best_ramp.json``): its kPa were found for Table 1's actuator and mean nothing for another. The error names
    the missing file, the schedule it would have run, and how to give one. A config of Table 1's actuator runs the
    package's schedule, as before."""
    from pneunet_env.config import load_config

    tuned = _package_task(path)
    if tuned is None or load_config(config_path).actuator == tuned.actuator:
        return
    data = load_json_file(path, "ramp file")
    beside = _beside_path(config_path)
    raise ValueError(f"best-ramp: the config {str(config_path)!r} describes another actuator than the package's "
                     f"schedule agents/{path.name} ({data.get('target_kpa', '?')} kPa over {data.get('n_steps', '?')} "
                     f"steps) was tuned for (Table 1's), and its own schedule {str(beside)!r} is missing: put that "
                     f"file beside it, tune one (pneunet-grasp search --config {config_path}), or name a schedule "
                     "(--policy best-ramp:path=FILE)")


def _source(path: Path) -> str:
    """``"; from NAME.best_ramp.json"`` for a schedule outside the package (a config's own, or ``path=``)."""
    return "" if path.resolve().parent == AGENTS_DIR else f"; from {path.name}"


def _objects_key(objects) -> tuple:
    """What an object draw is, for comparing two configs' objects: the catalogue's classes and weights, or the
    ranges (the fields that the other kind of draw ignores are left out)."""
    from pneunet_env.config import RANGE_FIELDS

    if objects.from_catalogue:
        return ("catalogue", objects.class_items)
    return ("ranges", tuple(tuple(getattr(objects, f)) for f in RANGE_FIELDS))


def _ring_text(objects) -> str:
    """``"its 250 mm ring"`` where the ranges fix the object's outer radius, else ``"objects from ranges"``."""
    lo, hi = objects.object_curvature_per_m
    return f"its {1e3 / lo:.3g} mm ring" if lo == hi else "objects from ranges"


def schedule_origin(path: str | os.PathLike, config: EnvConfig, gripper: str = "pneunet", *,
                    config_path: str | os.PathLike | None = None) -> tuple[str, bool | None]:
    """What the tuned schedule file ``path`` was tuned on, in words, and whether ``config``'s objects are those.

    The package's schedules were searched on the default task (``agents/best_ramp.json``, ``best_rigid.json``: the
    catalogue's default use case) and on the paper's task (``*_paper.json``: its ring, objects from ranges); one
    shipped beside a config file (:func:`tuned_path`) on that file's objects. Returns ``(text, fits)``: ``text`` as
    ``"agents/best_ramp_paper.json, tuned on the paper's task (its 250 mm ring)"``; ``fits`` ``True`` when
    ``config`` draws the same objects (the same catalogue classes and weights, or the same ranges), ``False`` when
    not, ``None`` for any other file (given by ``path=``: what it was tuned on is not known here).
    """
    from pneunet_env.config import load_config

    path = Path(path)
    where = path.resolve()
    if (package := _package_task(path)) is not None:
        tuned = package.objects
        text = (f"agents/{path.name}, tuned on the default task (the catalogue's {tuned.use_case!r} use case)"
                if where in (BEST_RAMP_PATH, BEST_RIGID_PATH) else
                f"agents/{path.name}, tuned on the paper's task ({_ring_text(tuned)})")
    elif config_path is not None and where == _beside_path(config_path, gripper).resolve():
        tuned = load_config(config_path).objects
        text = f"{path.name}, tuned for the config {Path(config_path).name} (beside it)"
    else:
        return f"{path} (given by path=: what it was tuned on is not recorded here)", None
    return text, _objects_key(config.objects) == _objects_key(tuned)


def tuned_schedules_text(entries) -> str:
    """``"tuned schedules: best-ramp: agents/best_ramp.json, tuned on ...; rigid: ..."``: which file each tuned
    schedule (``best-ramp``, ``rigid``) was loaded from and what it was tuned on (:func:`schedule_origin`); ``""``
    where no policy runs one."""
    parts = [f"{e.name}: {e.tuned_on}" for e in entries if e.tuned_on]
    return f"tuned schedules: {'; '.join(parts)}" if parts else ""


def warn_untuned(prog: str, entries, config_path: str | None = None, overrides=()) -> bool:
    """Warn (one line on stderr, :func:`pneunet_env.extras.warn`) where a tuned schedule runs on objects it was not
    tuned on (no shipped schedule was tuned for the config's objects): it names each such schedule, what it was
    tuned on, and the ``pneunet-grasp search`` command that tunes one for these objects (its output beside
    ``config_path``, where a config file is given, so that ``best-ramp`` and ``rigid`` then load it). ``overrides``:
    the ``--set KEY=VALUE`` items as typed. Returns whether it warned."""
    import shlex

    from pneunet_env.extras import PROG as ROOT
    from pneunet_env.extras import warn

    off = [e for e in entries if e.fits_objects is False]
    if not off:
        return False
    sets = "".join(f" --set {shlex.quote(str(o))}" for o in overrides)
    commands, loads = [], []
    for e in off:
        rigid = e.command == "jaw"
        if config_path is not None:
            out = _beside_path(config_path, "rigid" if rigid else "pneunet")
        else:
            out = Path("best_rigid.json" if rigid else "best_ramp.json")
        commands.append(f"{ROOT} search{' --gripper rigid' if rigid else ''}"
                        f"{f' --config {shlex.quote(str(config_path))}' if config_path is not None else ''}{sets} "
                        f"--out {shlex.quote(str(out))}")
        loads.append(f"--policy {'rigid' if rigid else 'best-ramp'}:path={shlex.quote(str(out))}")
    runs = "; ".join(f"{e.name} runs {e.tuned_on}" for e in off)
    then = (f"which {prog.split()[-1]} then loads from beside the config" if config_path is not None
            else f"then pass {' '.join(loads)}")
    warn(prog, f"no shipped schedule was tuned for this config's objects: {runs}. Tune "
               f"{'one' if len(off) == 1 else 'them'} for these objects with {' and '.join(commands)}, {then}")
    return True


def _describe(pol, full_scale: float, unit: str) -> str:
    if isinstance(pol, LinearRamp):
        return f"{pol.target * full_scale:.3g} {unit} over {pol.n_steps} steps"
    return f"step to {pol.target * full_scale:.3g} {unit}"


def _oracle(spec, params, config):
    from agents.oracle import Oracle

    res = _float(spec, "resolution_kpa", params.pop("resolution_kpa")) if "resolution_kpa" in params else None
    _check_empty(spec, params, "resolution_kpa")
    return PolicyEntry(spec, "oracle (knows k~; best constant pressure)", Oracle(config, res), blind=False)


def _rigid(spec, params, config, config_path=None):
    from pneunet_env.envs.rigid import default_jaw_travel_mm

    travel = _float(spec, "travel_mm", params.pop("travel_mm")) if "travel_mm" in params else None
    env_kwargs = {} if travel is None else {"jaw_travel_mm": travel}
    full = default_jaw_travel_mm(config) if travel is None else travel
    path = None
    if "target" in params or "target_mm" in params:
        t = _target(spec, params, full, "target_mm", 0.5)
        n = _int(spec, "steps", params.pop("steps", "20"))
        pol = LinearRamp(t, n, config)
        _check_empty(spec, params, "target, target_mm, steps, travel_mm, path")
    else:
        path = Path(params.pop("path", tuned_path(config, "rigid", config_path=config_path)))
        _check_empty(spec, params, "target, target_mm, steps, travel_mm, path")
        pol = _load_rigid(path, config, full)
    label = f"rigid gripper ({_describe(pol, full, 'mm')}{'' if path is None else _source(path)})"
    tuned_on, fits = ("", None) if path is None else schedule_origin(path, config, "rigid", config_path=config_path)
    return PolicyEntry(spec, label, pol, env_id=RIGID_ENV, command="jaw", env_kwargs=env_kwargs, tuned_on=tuned_on,
                       fits_objects=fits)


def _load_rigid(path: Path, config: EnvConfig, travel_mm: float):
    """The saved jaw ramp; its target is defined in mm (``target_mm``; travels differ between configs) and re-expressed
    as a fraction of ``travel_mm`` here; one beyond the travel is refused, not clipped
    (:func:`agents.scripted.ramp_target`)."""
    return load_ramp(path, config, full_scale=travel_mm, unit="mm")


REGISTRY: dict[str, Callable[[str, dict[str, str], EnvConfig], PolicyEntry]] = {
    "ramp": _ramp,
    "step": _step,
    "best-ramp": _best_ramp,
    "oracle": _oracle,
    "rigid": _rigid,
}
"""Scripted policy names -> factories ``(spec, params, config) -> PolicyEntry``."""


_TUNED = ("best-ramp", "rigid")
"""The registry's tuned schedules: their factories take ``config_path`` (:func:`tuned_path`)."""


def make_policy(spec: str, config: EnvConfig | None = None, *,
                config_path: str | os.PathLike | None = None) -> PolicyEntry:
    """The policy named by ``spec`` (a registry name with optional parameters, or a ``*.zip`` SB3 model, optionally
    ``PATH.zip:vecnormalize=STATS,action=setpoint``; a model is code: load only models you trust).

    ``config_path``: the YAML file ``config`` came from, if any: ``best-ramp`` and ``rigid`` (without ``path=``)
    then load the schedule shipped beside it, ``DIR/NAME.best_ramp.json`` or ``DIR/NAME.best_rigid.json``, where
    it exists (:func:`tuned_path`).

    Raises:
        ValueError: an unknown name, a bad parameter, or a missing model file (named).
    """
    config = EnvConfig() if config is None else config
    if isinstance(spec, str):
        from agents.resources import resolve_model

        head, colon, tail = spec.strip().partition(":")
        if head not in REGISTRY and (shipped := resolve_model(head)) is not None:  # a shipped model, by name
            spec = f"{shipped}:{tail}" if colon else str(shipped)
    if isinstance(spec, str) and (spec.strip().endswith(".zip") or ".zip:" in spec):
        model, sep, rest = spec.strip().rpartition(".zip:") if ".zip:" in spec else (spec.strip()[:-4], "", "")
        path = Path(model + ".zip")
        params = parse_spec("model:" + rest)[1] if sep else {}
        if not path.is_file():
            raise ValueError(f"policy {spec!r}: no such model file")
        stats = params.pop("vecnormalize", None)
        action = params.pop("action", None)
        _check_empty(spec, params, "vecnormalize, action")
        pol = SB3Policy(path, vecnormalize=stats, action=action, config=config)
        seen = "pressure and chamber volume" if pol.observe_volume else "pressure only"
        # the env it was trained on: a model that observes the volume runs with observe_volume=True, and vice versa
        return PolicyEntry(spec, f"{pol.algo}, {seen} ({path.name})", pol,
                           env_kwargs={"observe_volume": pol.observe_volume})
    name, params = parse_spec(spec)
    if name not in REGISTRY:
        from agents.resources import model_names

        raise ValueError(f"unknown policy {name!r}; valid: {', '.join(REGISTRY)}, a shipped model "
                         f"({', '.join(model_names())}) or a path to an SB3 model .zip")
    if config_path is not None and name in _TUNED:
        return REGISTRY[name](spec, dict(params), config, config_path=config_path)
    return REGISTRY[name](spec, dict(params), config)


# ---------------------------------------------------------------------------------------------
# stable-baselines3 models
# ---------------------------------------------------------------------------------------------


STATS_SUFFIX = "_vecnormalize.json"


def vecnormalize_path(model_path: str | Path) -> Path | None:
    """``DIR/NAME_vecnormalize.json`` if it exists, else ``DIR/vecnormalize.json`` if it exists, else ``None``.

    Only the JSON statistics are looked up next to a model: a pickle is never loaded unless named explicitly.
    """
    model_path = Path(model_path)
    for cand in (model_path.with_name(model_path.stem + STATS_SUFFIX), model_path.with_name("vecnormalize.json")):
        if cand.is_file():
            return cand
    return None


def _stray_pickles(model_path: Path) -> list[Path]:
    return [p for p in (model_path.with_name(model_path.stem + "_vecnormalize.pkl"),
                        model_path.with_name("vecnormalize.pkl")) if p.is_file()]


_ALGOS = ("PPO", "SAC", "TD3", "A2C", "DDPG")
ACTION_MODES = ("rate", "setpoint")
"""How a trained agent's output drives the env: ``rate`` is the env's own action (the pressure change);
``setpoint`` is a commanded pressure, followed by a rate-limited regulator (:func:`setpoint_to_rate`, the formula of
:class:`pneunet_env.wrappers.PressureSetpoint`)."""


# ---------------------------------------------------------------------------------------------
# Normalisation statistics, as numbers
# ---------------------------------------------------------------------------------------------


STATS_FORMAT = "pneunet_env/vecnormalize-stats/1"


@dataclass
class RunningStats:
    """A running mean and variance (SB3's ``RunningMeanStd``): float64 arrays (or scalars) and a count."""

    mean: np.ndarray
    var: np.ndarray
    count: float

    def to_dict(self) -> dict[str, Any]:
        return {"mean": np.asarray(self.mean, np.float64).tolist(), "var": np.asarray(self.var, np.float64).tolist(),
                "count": float(self.count)}

    @classmethod
    def from_dict(cls, data: dict[str, Any]) -> RunningStats:
        mean = np.asarray(data["mean"], dtype=np.float64)
        var = np.asarray(data["var"], dtype=np.float64)
        count = float(data["count"])
        if mean.shape != var.shape:
            raise ValueError(f"statistics: mean shape {mean.shape} != var shape {var.shape}")
        # numbers that would reach the model as NaN (or divide by a negative variance's root) are refused here, not
        # found inside torch ("invalid values: tensor([[nan]])")
        if not (np.isfinite(mean).all() and np.isfinite(var).all() and (var >= 0.0).all()):
            raise ValueError(f"the mean and the variance must be finite numbers, the variance >= 0, got mean "
                             f"{mean.tolist()!r} and var {var.tolist()!r}")
        if not (math.isfinite(count) and count >= 0.0):
            raise ValueError(f"the count must be a finite number >= 0, got {count!r}")
        return cls(mean, var, count)


@dataclass
class NormalizationStats:
    """``VecNormalize``'s statistics and settings as plain numbers (JSON), read and written without ``pickle``.

    ``normalize_obs`` is ``VecNormalize.normalize_obs``: ``clip((obs - mean) / sqrt(var + epsilon), +-clip_obs)``
    as float32 when ``norm_obs`` (else the observation unchanged), bit for bit. Box observations only.
    """

    norm_obs: bool
    norm_reward: bool
    clip_obs: float
    clip_reward: float
    epsilon: float
    gamma: float
    obs_rms: RunningStats | None = None
    ret_rms: RunningStats | None = None

    def normalize_obs(self, obs) -> np.ndarray:
        obs = np.asarray(obs)
        if not self.norm_obs or self.obs_rms is None:
            return obs.copy()
        rms = self.obs_rms
        return np.clip((obs - rms.mean) / np.sqrt(rms.var + self.epsilon), -self.clip_obs,
                       self.clip_obs).astype(np.float32)

    @classmethod
    def from_vecnormalize(cls, vn) -> NormalizationStats:
        """From a ``VecNormalize`` (or the object ``VecNormalize.save`` pickled)."""
        state = vars(vn)  # an unpickled VecNormalize has no venv: getattr on a missing attribute would recurse
        obs_rms, ret_rms = state.get("obs_rms"), state.get("ret_rms")
        if isinstance(obs_rms, dict):
            raise ValueError("dict observation statistics are not supported (PneuNetGrasp-v0's observation is a Box)")

        def rms(r):
            return None if r is None else RunningStats(np.array(r.mean, np.float64), np.array(r.var, np.float64),
                                                       float(r.count))

        return cls(norm_obs=bool(state["norm_obs"]), norm_reward=bool(state["norm_reward"]),
                   clip_obs=float(state["clip_obs"]), clip_reward=float(state["clip_reward"]),
                   epsilon=float(state["epsilon"]), gamma=float(state["gamma"]), obs_rms=rms(obs_rms),
                   ret_rms=rms(ret_rms))

    def to_dict(self) -> dict[str, Any]:
        return {"format": STATS_FORMAT, "norm_obs": self.norm_obs, "norm_reward": self.norm_reward,
                "clip_obs": self.clip_obs, "clip_reward": self.clip_reward, "epsilon": self.epsilon,
                "gamma": self.gamma, "obs_rms": None if self.obs_rms is None else self.obs_rms.to_dict(),
                "ret_rms": None if self.ret_rms is None else self.ret_rms.to_dict()}

    @classmethod
    def from_dict(cls, data: Any, source: str = "statistics") -> NormalizationStats:
        if not isinstance(data, dict) or data.get("format") != STATS_FORMAT:
            raise ValueError(f"{source}: not a normalisation statistics file (format {STATS_FORMAT!r})")
        try:
            stats = cls(norm_obs=bool(data["norm_obs"]), norm_reward=bool(data["norm_reward"]),
                        clip_obs=float(data["clip_obs"]), clip_reward=float(data["clip_reward"]),
                        epsilon=float(data["epsilon"]), gamma=float(data["gamma"]),
                        obs_rms=None if data.get("obs_rms") is None else RunningStats.from_dict(data["obs_rms"]),
                        ret_rms=None if data.get("ret_rms") is None else RunningStats.from_dict(data["ret_rms"]))
            for name in ("clip_obs", "clip_reward", "epsilon"):  # (a clip may be inf: no clipping)
                if not getattr(stats, name) > 0.0:
                    raise ValueError(f"{name} must be > 0, got {getattr(stats, name)!r}")
            if not 0.0 <= stats.gamma <= 1.0:
                raise ValueError(f"gamma must be in [0, 1], got {stats.gamma!r}")
            return stats
        except (KeyError, TypeError, ValueError) as exc:
            raise ValueError(f"{source}: malformed statistics ({exc})") from None

    def check_observation(self, shape: tuple[int, ...], source: str = "statistics") -> None:
        """``ValueError`` naming ``source`` unless the observation statistics (where they normalise) have the shape
        of the model's observation, ``shape`` (statistics of another env would fail inside SB3)."""
        if self.norm_obs and self.obs_rms is not None and np.shape(self.obs_rms.mean) != tuple(shape):
            raise ValueError(f"{source}: its observation statistics have shape {np.shape(self.obs_rms.mean)}, but the "
                             f"model observes shape {tuple(shape)}: statistics of another model or env")

    def to_vecnormalize(self, venv, training: bool = True, source: str = "statistics"):
        """A ``VecNormalize`` around ``venv`` with these settings and statistics: what ``VecNormalize.load`` makes of
        the pickle these numbers came from (its running returns start at zero, as ``set_venv`` sets them), without
        unpickling anything. ``ValueError`` naming ``source`` where the observation statistics' shape is not
        ``venv``'s observation's."""
        from stable_baselines3.common.vec_env import VecNormalize

        vn = VecNormalize(venv, training=training, norm_obs=self.norm_obs, norm_reward=self.norm_reward,
                          clip_obs=self.clip_obs, clip_reward=self.clip_reward, gamma=self.gamma, epsilon=self.epsilon)
        for name in ("obs_rms", "ret_rms"):
            ours, theirs = getattr(self, name), vars(vn).get(name)  # no obs_rms without norm_obs
            if ours is None or theirs is None:
                continue
            if np.shape(ours.mean) != np.shape(theirs.mean):
                raise ValueError(f"{source}: {name} has shape {np.shape(ours.mean)}, but the env's is "
                                 f"{np.shape(theirs.mean)}: statistics of another env")
            theirs.mean, theirs.var, theirs.count = np.array(ours.mean), np.array(ours.var), float(ours.count)
        return vn

    def save(self, path: str | Path) -> Path:
        """Write the JSON (atomically: a temporary file in the same folder, then ``os.replace``)."""
        return atomic_write_bytes(path, (json.dumps(self.to_dict(), indent=1) + "\n").encode())

    @classmethod
    def load(cls, path: str | Path) -> NormalizationStats:
        """Read the JSON written by :meth:`save` (no code runs)."""
        path = Path(path)
        data = load_json_file(path, "statistics")  # ValueError naming it: unreadable, not JSON, a duplicate key
        return cls.from_dict(data, str(path))


def load_pickled_vecnormalize(path: str | Path):
    """Unpickle a ``VecNormalize`` file. **Runs code from the file**: call it only on a path you trust. A FIFO, a
    device or a folder is refused by name before it is opened (:func:`pneunet_env.yamlio.check_input_file`)."""
    check_input_file(path, f"statistics {short_repr(str(path))}")
    with open(path, "rb") as fh:
        return pickle.load(fh)


def convert_vecnormalize(pickle_path: str | Path, json_path: str | Path) -> Path:
    """A ``VecNormalize`` pickle (SB3's ``VecNormalize.save``, rl-zoo3's ``vecnormalize.pkl``) -> the JSON form.

    Unpickles ``pickle_path``, which runs code from it: convert only files you trust.
    """
    return NormalizationStats.from_vecnormalize(load_pickled_vecnormalize(pickle_path)).save(json_path)


def _observes_volume(path: Path, model, meta: dict[str, Any]) -> bool:
    """Whether a trained model observes ``[pressure, volume change]`` (``observe_volume=True``) or the pressure alone.

    Its training's metadata says so where there is one (``hyperparameters.env_kwargs.observe_volume``; a
    frame-stacked model is refused: :class:`SB3Policy` feeds one observation); else its observation's shape:
    ``(1,)`` or ``(2,)``. ``ValueError`` for any other shape, or a shape that contradicts the metadata.
    ``meta`` is the model's metadata, :func:`_model_meta`, read once by the caller.
    """
    shape = tuple(getattr(model.observation_space, "shape", None) or ())
    hp = meta.get("hyperparameters")
    hp = hp if isinstance(hp, dict) else {}
    if hp.get("frame_stack") not in (None, 1):
        raise ValueError(f"model {str(path)!r}: trained with frame_stack={hp['frame_stack']!r}; a frame-stacked model "
                         "is not supported here (the policy is fed one observation at a time)")
    if shape not in ((1,), (2,)):
        raise ValueError(f"model {str(path)!r}: observes shape {shape}; PneuNetGrasp-v0 gives (1,) (the pressure) "
                         "or (2,) (with observe_volume: the pressure and the chamber's volume change)")
    env_kwargs = hp.get("env_kwargs") if isinstance(hp.get("env_kwargs"), dict) else {}
    volume = bool(env_kwargs.get("observe_volume", shape == (2,)))
    if volume != (shape == (2,)):
        raise ValueError(f"model {str(path)!r}: its metadata says observe_volume={volume} but it observes shape "
                         f"{shape}")
    return volume


def _meta_files(path: Path) -> list[Path]:
    """Where a model's metadata is looked for, in order: its sidecar ``DIR/NAME.json``, then the ``run.json`` of the
    training run it lies in (``best_model.zip`` in the run folder, ``checkpoints/model_*.zip`` one level down)."""
    return [path.with_suffix(".json"), path.parent / "run.json", path.parent.parent / "run.json"]


def _model_meta(path: Path) -> dict[str, Any]:
    """The model's metadata: its exported JSON sidecar, else the ``run.json`` of the training run it lies in
    (``best_model.zip``, ``final_model.zip`` in the run folder, ``checkpoints/model_*.zip`` one level down), whose
    ``algo`` and ``action`` say how to run it; ``{}`` if neither exists.

    Raises:
        ValueError: the first of those files that exists is unreadable (cut, not JSON, not a mapping): it names the
            file. The caller decides whether an explicit action mode makes it harmless (:class:`SB3Policy`).
    """
    for i, meta in enumerate(_meta_files(path)):
        if not meta.is_file():
            continue
        try:
            data = load_json_file(meta, "model metadata")
        except (OSError, ValueError) as exc:  # a cut write, not UTF-8, not JSON
            raise _BrokenMeta(meta, f"unreadable ({type(exc).__name__}: {exc})") from None
        if not isinstance(data, dict):
            raise _BrokenMeta(meta, f"not a JSON mapping (a {type(data).__name__})")
        said, trained = data.get("action"), _hp_action(data.get("hyperparameters"), decisive=True)
        if said is not None and trained is not None and said != trained:
            raise _BrokenMeta(meta, f"contradicts itself: it says action {said!r}, but the hyperparameters it records "
                                    f"(the model's training) {_hp_words(data['hyperparameters'])}, which is action "
                                    f"{trained!r}")
        return data if i == 0 else {k: data[k] for k in ("algo", "action") if k in data}
    return {}


class _BrokenMeta(ValueError):
    """A model's metadata file exists but cannot be read."""

    def __init__(self, file: Path, why: str) -> None:
        super().__init__(f"{str(file)!r}: {why}")
        self.file, self.why = file, why


def check_model_zip(path: str | Path) -> None:
    """``ValueError`` naming ``path`` unless it is a whole stable-baselines3 model zip (a cut file, from a hard kill
    or a partial copy, has no zip directory; a damaged one fails its checksums; SB3's own loader would fail deep
    inside with an ``AssertionError`` or a ``BadZipFile``)."""
    import zipfile

    path = Path(path)
    try:
        with zipfile.ZipFile(path) as zf:
            names = zf.namelist()
            bad = zf.testzip()
    except (OSError, EOFError, zipfile.BadZipFile, zipfile.LargeZipFile, ValueError) as exc:
        raise ValueError(f"model {str(path)!r} is not a readable zip file ({exc}): cut short or damaged (an "
                         "interrupted copy or save?); use another copy of it") from None
    if bad is not None:
        raise ValueError(f"model {str(path)!r} is damaged: member {bad!r} fails its checksum; use another copy of it")
    if "data" not in names:
        raise ValueError(f"model {str(path)!r} is not a whole stable-baselines3 model (no 'data' member): cut short "
                         "(an interrupted copy or save?), damaged, or another kind of zip; use another copy of it")


_WRAPPER_KEYS = ("env_wrapper", "vec_env_wrapper")


def _wrapper_names(hp: dict[str, Any]) -> list[str]:
    """The classes a training's ``env_wrapper`` and ``vec_env_wrapper`` name (rl-zoo3's forms: a name, a list, a
    ``{name: kwargs}``)."""
    names: list[str] = []
    for key in _WRAPPER_KEYS:
        value = hp.get(key)
        for item in value if isinstance(value, list) else [value]:
            if isinstance(item, dict):
                names += [str(k) for k in item]
            elif item is not None:
                names.append(str(item))
    return names


def _hp_action(hp: Any, *, decisive: bool = False) -> str | None:
    """A training's hyperparameters -> its action mode: their ``action`` (0.1's project key), else the setpoint
    wrapper in ``env_wrapper`` or ``vec_env_wrapper``: ``setpoint``; else ``rate``. ``None`` if they are not a
    mapping, or (``decisive``) if they say neither (no ``action`` and no wrapper key: hyperparameters cut short, or
    written by hand, are not read as ``rate``)."""
    if not isinstance(hp, dict):
        return None
    if hp.get("action") in ACTION_MODES:
        return str(hp["action"])
    if decisive and not any(k in hp for k in _WRAPPER_KEYS):
        return None
    return "setpoint" if any(n.startswith("pneunet_env.wrappers.PressureSetpoint") for n in _wrapper_names(hp)) \
        else "rate"


def _hp_words(hp: dict[str, Any]) -> str:
    """What a training's hyperparameters say about its action mode, in words (for an error message)."""
    if hp.get("action") in ACTION_MODES:
        return f"say action {hp['action']!r}"
    names = _wrapper_names(hp)
    return f"name the wrapper(s) {', '.join(names)}" if names else "name no wrapper (the env's own action)"


def _action_mode(path: Path, meta: dict[str, Any], broken: _BrokenMeta | None) -> str:
    """The action mode of a model without an explicit one: its metadata's ``action`` (else its hyperparameters'
    wrappers); never a guess: ``ValueError`` naming the missing or broken file and the fix."""
    source = next((f for f in _meta_files(path) if f.is_file()), None)
    if "action" in meta:
        if meta["action"] not in ACTION_MODES:
            raise ValueError(f"model {str(path)!r}: its metadata {str(source)!r} gives action "
                             f"{meta['action']!r}; expected one of {ACTION_MODES}")
        return str(meta["action"])
    if (mode := _hp_action(meta.get("hyperparameters"))) is not None:
        return mode
    fix = (f"give the mode explicitly: the policy spec '{path}:action=setpoint' (or action=rate), or "
           "SB3Policy(..., action=...)")
    both = ("its action space, Box(-1, 1, (1,)), means either a pressure change (rate) or a pressure setpoint "
            "(setpoint)")
    if broken is not None:
        raise ValueError(f"model {str(path)!r}: cannot tell its action mode: its metadata {broken} and {both}; "
                         f"restore that file (pneunet-grasp train --export writes it) or {fix}")
    if source is not None:
        raise ValueError(f"model {str(path)!r}: cannot tell its action mode: its metadata {str(source)!r} says "
                         f"neither 'action' nor 'hyperparameters', and {both}; {fix}")
    raise ValueError(f"model {str(path)!r}: cannot tell its action mode: no metadata {str(path.with_suffix('.json'))!r}"
                     f" beside it (pneunet-grasp train --export writes it; a training run's run.json serves too) and "
                     f"{both}; {fix}")


def _infer_algo(path: Path, meta: dict[str, Any]) -> str:
    algo = meta.get("algo")
    if isinstance(algo, str) and algo.upper() in _ALGOS:
        return algo.upper()
    from stable_baselines3.common.save_util import load_from_zip_file

    try:
        data, _, _ = load_from_zip_file(path, load_data=True, device="cpu")
    except Exception as exc:  # a zip that passed check_model_zip but SB3 cannot read: named
        raise ValueError(f"model {str(path)!r}: stable-baselines3 cannot read it "
                         f"({type(exc).__name__}: {exc})") from None
    cls = data.get("policy_class") if data else None
    name = getattr(cls, "__name__", str(cls))
    for algo in ("SAC", "TD3"):
        if algo in name:
            return algo
    return "PPO"


class SB3Policy:
    """A trained stable-baselines3 model as a policy: normalises observations with its saved statistics.

    Args:
        path: the model ``.zip``. **It is code** (SB3 unpickles parts of it): load only models you trust.
        deterministic: act with the policy's mean (default) rather than a sample.
        vecnormalize: the normalisation statistics: ``None`` (default) finds the JSON next to the model
            (:func:`vecnormalize_path`); a ``.json`` path reads that file; any other path is unpickled as a
            ``VecNormalize`` (it runs code: name only a pickle you trust); ``False``: none.
        action: ``"rate"`` or ``"setpoint"`` (:data:`ACTION_MODES`); default: the ``action`` of the model's
            metadata (its sidecar ``NAME.json``, which ``pneunet-grasp train --export`` writes, or its training
            run's ``run.json``). Never guessed: with no metadata, or a broken one, it must be given (``ValueError``
            naming the file otherwise), and then it wins (a broken metadata file is ignored, with a warning).
        config: the env's config (the setpoint regulator's step); the defaults if ``None``.
    """

    blind = True

    def __init__(self, path: str | Path, deterministic: bool = True, vecnormalize: str | Path | bool | None = None,
                 action: str | None = None, config: EnvConfig | None = None) -> None:
        import stable_baselines3 as sb3
        import torch

        if torch.get_num_threads() > 2:  # one observation at a time: threads only add overhead
            torch.set_num_threads(1)
        self.path = Path(path)
        if action is not None and action not in ACTION_MODES:
            raise ValueError(f"model {str(path)!r}: action mode must be one of {ACTION_MODES}, got {action!r}")
        check_model_zip(self.path)  # a cut or damaged file is named here, not deep inside SB3
        broken = None
        try:
            meta = _model_meta(self.path)
        except _BrokenMeta as exc:
            if action is None:  # the mode is unknown: refused below, naming the file
                broken, meta = exc, {}
            else:  # the caller says how to run it: the model's own file tells the rest (algorithm, observation)
                warnings.warn(f"model {str(path)!r}: ignoring its metadata {exc} (the action mode was given: "
                              f"{action})", stacklevel=2)
                meta = {}
        if broken is not None and action is None:  # a broken or self-contradicting sidecar: named before SB3 loads
            _action_mode(self.path, meta, broken)
        self.algo = _infer_algo(self.path, meta)
        config = EnvConfig() if config is None else config
        self.step_fraction = config.task.max_pressure_step_kpa / config.task.max_pressure_kpa
        try:
            self.model = getattr(sb3, self.algo).load(self.path, device="cpu")
        except Exception as exc:  # a zip SB3 cannot read: named, not an AssertionError from inside
            raise ValueError(f"model {str(path)!r}: stable-baselines3 cannot load it as {self.algo} "
                             f"({type(exc).__name__}: {exc})") from None
        self.observe_volume = _observes_volume(self.path, self.model, meta)
        self.action_mode = str(action) if action is not None else _action_mode(self.path, meta, broken)
        """Whether the model observes the chamber's volume change: its env needs ``observe_volume=True``."""
        self.deterministic = deterministic
        self._norm = None
        if vecnormalize is False:
            vn = None
        elif vecnormalize is None or vecnormalize is True:
            vn = vecnormalize_path(self.path)
            if vn is None and (stray := _stray_pickles(self.path)):
                warnings.warn(f"model {str(path)!r}: not loading {', '.join(map(str, stray))} (a pickle runs code "
                              "when loaded); name it explicitly (vecnormalize=PATH) if you trust it, or convert it "
                              "with agents.policies.convert_vecnormalize", stacklevel=2)
        else:
            vn = Path(vecnormalize)
        self.vecnormalize_path = vn
        if vn is not None:
            if vn.suffix == ".json":
                self._norm = NormalizationStats.load(vn)
                self._norm.check_observation(self.model.observation_space.shape, f"statistics {str(vn)!r}")
            else:  # named explicitly by the caller
                self._norm = load_pickled_vecnormalize(vn)

    def normalize(self, observation) -> np.ndarray:
        obs = np.asarray(observation, dtype=np.float32)
        if self._norm is None or not getattr(self._norm, "norm_obs", False):
            return obs
        return np.asarray(self._norm.normalize_obs(obs), dtype=np.float32)

    def _act(self, observation, deterministic: bool) -> np.ndarray:
        obs = np.asarray(observation, dtype=np.float32)
        out, _ = self.model.predict(self.normalize(obs), deterministic=deterministic)
        out = np.asarray(out, dtype=np.float32)
        if self.action_mode == "setpoint":
            return setpoint_to_rate(out, obs[..., :1], self.step_fraction)
        return np.clip(out, -1.0, 1.0)

    def __call__(self, observation) -> np.ndarray:
        """The env action (the pressure change) for an observation or a batch."""
        return self._act(observation, self.deterministic)

    def predict(self, observation, state=None, episode_start=None, deterministic: bool = True):
        return self._act(observation, deterministic), state

    def begin_episode(self, info: dict[str, Any] | None = None) -> None:
        """Blind: nothing to do."""

    def reset(self) -> None:
        """Stateless (an MLP on the pressure)."""

    def __repr__(self) -> str:
        return f"SB3Policy({self.algo}, {str(self.path)!r})"
