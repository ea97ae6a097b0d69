"""The policy registry: a name (or a model file) -> a policy and the environment it drives.

====================  ===============================================================  ==================
spec                  policy                                                           environment
====================  ===============================================================  ==================
``ramp``              :class:`~agents.policies.scripted.LinearRamp` to ``p_max`` over 40 steps  ``PneuNetGrasp-v1``
``step``              :class:`~agents.policies.scripted.StepPolicy` to ``p_max``                ``PneuNetGrasp-v1``
``best-ramp``         the ramp in ``agents/best_ramp.json`` (:mod:`agents.search`)      ``PneuNetGrasp-v1``
``oracle``            :class:`~agents.policies.oracle.Oracle` (knows the object; not blind)      ``PneuNetGrasp-v1``
``rigid``             the jaw ramp in ``agents/best_rigid.json`` (:mod:`agents.search`) ``RigidGrasp-v1``
``PATH.zip``          a stable-baselines3 model, with its ``VecNormalize`` statistics   ``PneuNetGrasp-v1``
====================  ===============================================================  ==================

Parameters follow a colon, comma-separated: ``ramp:target_kpa=30,steps=20``, ``step:target_kpa=45``,
``best-ramp:path=runs/best.json``, ``oracle:resolution_kpa=0.25``, ``rigid:target_mm=9,steps=10``,
``rigid:path=...``. (``target=`` takes a fraction of ``p_max`` or of the jaw travel instead.) A tuned schedule's file
is defined in kPa (mm for the jaw: :func:`agents.policies.scripted.ramp_target`): another ``max_pressure_kpa`` never
moves it, and one above the config's maximum is refused. A config file's own schedule beside it that cannot be read, or
that is missing where the config describes another actuator than the package's schedule was tuned for, is refused by
name (:func:`tuned_path`, :func:`_refuse_another_actuator`).

A policy maps an observation (or a batch) to an action in ``Box(-1, 1, (1,))``, has ``predict`` (SB3's
signature) and ``begin_episode(info)`` (called with ``reset``'s ``info``; only the oracle uses it).

Stable-baselines3 models load through :mod:`agents.policies.sb3`.
"""

from __future__ import annotations

import math
import os
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from agents.common.envs import PNEUNET_ENV, RIGID_ENV
from agents.common.resources import AGENTS_DIR, MODELS_DIR
from agents.common.words import is_paper_ring
from agents.policies.sb3 import SB3Policy
from agents.policies.scripted import LinearRamp, StepPolicy, load_ramp
from pneunet_env.config import EnvConfig
from pneunet_env.files import atomic_write_bytes, atomic_write_text, stage_file  # noqa: F401  (re-exported: the one atomic writer)
from pneunet_env.yamlio import load_json_file

__all__ = ["BEST_RAMP_PATH", "BEST_RIGID_PATH", "BEST_RAMP_PAPER_PATH", "BEST_RIGID_PAPER_PATH", "tuned_path",
           "PolicyEntry", "parse_spec", "schedule_origin", "tuned_schedules_text", "warn_untuned", "REGISTRY",
           "make_policy", "DEFAULT_MODEL", "PAPER_MODEL", "default_model"]


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


@dataclass
class PolicyEntry:
    """A policy ready to run, and what it needs.

    Attributes:
        name: the spec it was made from (``best-ramp``, ``models/ppo.zip``, ...).
        label: a human-readable description (for tables and legends).
        policy: the policy object.
        env_id: the environment it drives (``PneuNetGrasp-v1`` or ``RigidGrasp-v1``).
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

        import pneunet_env  # noqa: F401  (registers PneuNetGrasp-v1)
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

    if objects.from_catalogue:  # the same class names in another catalogue file are other objects
        return ("catalogue", objects.catalogue, objects.class_items)
    return ("ranges", tuple(tuple(getattr(objects, f)) for f in RANGE_FIELDS), objects.shape,
            objects.object_length_mm)


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


def warn_untuned(prog: str, entries, config_path: str | None = None, overrides=(),
                 catalogue: str | None = None) -> bool:
    """Warn (one line on stderr, :func:`pneunet_env.extras.warn`) where a tuned schedule runs on objects it was not
    tuned on (no shipped schedule was tuned for the config's objects): it names each such schedule, what it was
    tuned on, and the ``pneunet-grasp search`` command that tunes one for these objects (its output beside
    ``config_path``, where a config file is given, so that ``best-ramp`` and ``rigid`` then load it). ``overrides``:
    the ``--set KEY=VALUE`` items as typed; ``catalogue``: the ``--catalogue PATH`` given. Returns whether it
    warned."""
    import shlex

    from pneunet_env.extras import PROG as ROOT
    from pneunet_env.extras import warn

    off = [e for e in entries if e.fits_objects is False]
    if not off:
        return False
    sets = "".join(f" --set {shlex.quote(str(o))}" for o in overrides)
    if catalogue is not None:
        sets = f" --catalogue {shlex.quote(str(catalogue))}{sets}"
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
    from agents.policies.oracle import Oracle

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
    (:func:`agents.policies.scripted.ramp_target`)."""
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
        from agents.common.resources import resolve_model

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
        from agents.common.resources import model_names

        raise ValueError(f"unknown policy {name!r}; valid: {', '.join(REGISTRY)}, a shipped model "
                         f"({', '.join(model_names())}) or a path to an SB3 model .zip")
    if config_path is not None and name in _TUNED:
        return REGISTRY[name](spec, dict(params), config, config_path=config_path)
    return REGISTRY[name](spec, dict(params), config)


DEFAULT_MODEL = MODELS_DIR / "ppo_kitchen.zip"
"""PPO trained on the default task (pressure only); ``models/ppo_pneunet.zip`` was trained on the paper's task."""


PAPER_MODEL = DEFAULT_MODEL.with_name("ppo_pneunet.zip")
"""PPO trained on the paper's task (its ring, the crush-fraction rule)."""


def default_model(config: EnvConfig) -> Path | None:
    """The shipped PPO model of ``config``'s task, if present: :data:`DEFAULT_MODEL` on the catalogue's objects,
    :data:`PAPER_MODEL` on the paper's ring under its crush-fraction rule, else ``None``."""
    if config.objects.from_catalogue:
        path = DEFAULT_MODEL
    elif is_paper_ring(config) and config.task.damage_rule == "crush_fraction":
        path = PAPER_MODEL
    else:
        return None
    return path if path.is_file() else None
