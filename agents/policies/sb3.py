"""Stable-baselines3 models as policies (:class:`SB3Policy`), and their normalisation statistics as numbers.

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
import pickle
import warnings
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from pneunet_env.config import EnvConfig
from pneunet_env.files import atomic_write_bytes, stage_file  # noqa: F401  (re-exported: the one atomic writer)
from pneunet_env.wrappers import setpoint_to_rate
from pneunet_env.yamlio import check_input_file, load_json_file, short_repr

__all__ = ["STATS_SUFFIX", "vecnormalize_path", "ACTION_MODES", "STATS_FORMAT", "RunningStats", "NormalizationStats",
           "load_pickled_vecnormalize", "convert_vecnormalize", "check_model_zip", "SB3Policy"]


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
            raise ValueError("dict observation statistics are not supported (PneuNetGrasp-v1's observation is a Box)")

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
        raise ValueError(f"model {str(path)!r}: observes shape {shape}; PneuNetGrasp-v1 gives (1,) (the pressure) "
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
                              "with agents.policies.sb3.convert_vecnormalize", stacklevel=2)
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
