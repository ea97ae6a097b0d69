"""Stable-Baselines3 on the batched env: :class:`SB3VecEnv`, an SB3 ``VecEnv`` over a Gymnasium vector env.

SB3 does not accept a ``gymnasium.vector.VectorEnv``; it has its own ``VecEnv`` API (``reset()`` returns the
observations only, ``step_async``/``step_wait``, a list of one info dict per env, an episode that ends is reset
in the same step with its last observation in ``info["terminal_observation"]`` and ``info["TimeLimit.truncated"]``
set when a time limit, not a terminal state, ended it). :class:`SB3VecEnv` translates, so PPO, SAC, A2C, ...
train straight on :class:`pneunet_env.envs.grasp_vector.PneuNetGraspVectorEnv` (its ``SAME_STEP`` autoreset is SB3's
convention already)::

    from stable_baselines3 import PPO
    from stable_baselines3.common.vec_env import VecMonitor
    from pneunet_env.envs.sb3 import SB3VecEnv

    venv = VecMonitor(SB3VecEnv(num_envs=64))          # gym.make_vec("PneuNetGrasp-v1", num_envs=64) inside
    PPO("MlpPolicy", venv).learn(200_000)

This module imports stable_baselines3 (the ``rl`` extra); ``import pneunet_env`` does not.

**Infos.** SB3 wants one dict per env, so that part is a Python loop over envs by SB3's design. By default
the dicts hold only what SB3 reads: ``TimeLimit.truncated`` (every step, as SB3's ``DummyVecEnv``), and on the
step an episode ends ``terminal_observation`` and ``is_success`` (for ``EvalCallback``).
``info_keys=("contact_force_kpa", ...)`` or ``"all"`` copies entries of the vector env's info too (at a cost
of about 0.1 microsecond per key and env).
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence
from typing import Any

import numpy as np
from gymnasium.vector import AutoresetMode, VectorEnv
from stable_baselines3.common.vec_env.base_vec_env import VecEnv, VecEnvIndices, VecEnvStepReturn

from pneunet_env.physics.xp import is_torch
from pneunet_env.task import class_name

__all__ = ["SB3VecEnv"]


class SB3VecEnv(VecEnv):
    """An SB3 ``VecEnv`` over a Gymnasium vector env with ``AutoresetMode.SAME_STEP`` (the package's batched env).

    Args:
        env: the vector env; ``None`` makes ``gym.make_vec(env_id, num_envs=num_envs, **make_kwargs)``
            (:class:`~pneunet_env.envs.grasp_vector.PneuNetGraspVectorEnv` with the registered 100-step time limit).
        num_envs: the number of envs when ``env`` is ``None``.
        info_keys: keys of the vector env's info to copy into SB3's per-env info dicts: ``()`` (default: only
            ``TimeLimit.truncated``, and ``terminal_observation`` and ``is_success`` at episode ends), a list of
            keys, or ``"all"``. On the step an episode ends, an env's dict holds that step's values (Gymnasium's
            ``final_info``), and the reset's go to ``reset_infos`` (as SB3's ``DummyVecEnv`` does).
        env_id: the registered id used when ``env`` is ``None``.
        make_kwargs: passed to ``gym.make_vec`` (config keys, ``render_mode``, ...).

    The sub-envs share one batched env: ``get_attr``/``env_method`` answer with the vector env's attribute or
    method result for every requested index, and ``set_attr`` applies to all envs (only ``indices=None`` or all).
    ``seed(s)`` seeds env ``i`` with ``s + i`` at the next ``reset()`` (SB3's convention, and the vector env's).
    """

    def __init__(
        self,
        env: VectorEnv | None = None,
        num_envs: int | None = None,
        info_keys: Sequence[str] | str = (),
        env_id: str = "PneuNetGrasp-v1",
        **make_kwargs: Any,
    ) -> None:
        if env is None:
            import gymnasium as gym

            env = gym.make_vec(env_id, num_envs=1 if num_envs is None else num_envs, **make_kwargs)
        elif num_envs is not None and num_envs != env.num_envs:
            raise ValueError(f"num_envs={num_envs} does not match the given env's num_envs={env.num_envs}")
        elif make_kwargs:
            raise ValueError(f"make arguments {sorted(make_kwargs)} given with an existing env")
        if not isinstance(env, VectorEnv):
            raise ValueError(f"env must be a gymnasium.vector.VectorEnv, got {type(env).__name__}")
        mode = env.metadata.get("autoreset_mode")
        if mode != AutoresetMode.SAME_STEP:
            raise ValueError(f"SB3VecEnv needs a vector env with AutoresetMode.SAME_STEP (SB3's convention), "
                             f"got {mode!r}")
        if isinstance(info_keys, str):
            if info_keys != "all":
                raise ValueError(f"info_keys must be a sequence of info keys or 'all', got {info_keys!r}")
            self._info_keys: tuple[str, ...] | None = None
        else:
            keys = tuple(info_keys) if isinstance(info_keys, Iterable) and not isinstance(info_keys, bytes) else None
            if keys is None or not all(isinstance(k, str) for k in keys):
                raise ValueError(f"info_keys must be a sequence of info keys (strings) or 'all', got {info_keys!r}")
            self._info_keys = keys
        self.env = env
        super().__init__(env.num_envs, env.single_observation_space, env.single_action_space)
        self._actions: np.ndarray | None = None

    # ---- infos ----------------------------------------------------------------------------------------------
    def _keys(self, info: dict[str, Any]) -> list[str]:
        if self._info_keys is None:
            return [k for k in info if not k.startswith("_") and k not in ("final_obs", "final_info")]
        missing = [k for k in self._info_keys if k not in info]
        if missing:
            raise KeyError(f"info_keys {missing} are not in the env's info (keys: {sorted(info)})")
        return list(self._info_keys)

    def _dicts(self, info: dict[str, Any], idx: np.ndarray | None = None) -> list[dict[str, Any]]:
        """One dict per env (or per env of ``idx``) from a Gymnasium vector info: the entries whose ``_key`` mask
        is set, as Python scalars (``tolist``)."""
        m = self.num_envs if idx is None else len(idx)
        keys = self._keys(info)
        if not keys:
            return [{} for _ in range(m)]
        cols = [np.asarray(info[k]) for k in keys]
        cols = [(c if idx is None else c[idx]).tolist() for c in cols]
        dicts = [dict(zip(keys, vals, strict=True)) for vals in zip(*cols, strict=True)]
        for k in keys:
            mask = info.get("_" + k)
            if mask is None:
                continue
            mask = np.asarray(mask, dtype=bool)
            if idx is not None:
                mask = mask[idx]
            for j in np.flatnonzero(~mask).tolist():
                del dicts[j][k]
        if "object_class" in keys:  # per-env dicts read like a single env's: the class by name
            names = self.env.unwrapped.object_class_names
            for d in dicts:
                if "object_class" in d:
                    d["object_class"] = class_name(names, int(d["object_class"]))
        return dicts

    # ---- SB3 VecEnv API -------------------------------------------------------------------------------------
    def reset(self) -> np.ndarray:
        seeds = list(self._seeds)
        seed = None if all(s is None for s in seeds) else seeds
        obs, info = self.env.reset(seed=seed, options=self._merged_options())
        self._reset_seeds()
        self._reset_options()
        self.reset_infos = self._dicts(info)
        return obs

    def _merged_options(self) -> dict[str, Any] | None:
        opts = self._options
        if all(not o for o in opts):
            return None
        first = opts[0]
        if all(o == first for o in opts):
            return dict(first)
        keys = set(first)
        if any(set(o) != keys for o in opts):
            raise ValueError("per-env reset options must all have the same keys (values may differ per env)")
        return {k: np.array([o[k] for o in opts]) for k in keys}

    def step_async(self, actions: np.ndarray) -> None:
        # a torch tensor (the torch backend) stays one, detached; anything else is read by numpy
        self._actions = actions.detach() if is_torch(actions) else np.asarray(actions)

    def step_wait(self) -> VecEnvStepReturn:
        if self._actions is None:
            raise RuntimeError("step_wait() called without step_async()")
        actions, self._actions = self._actions, None
        obs, rewards, terminated, truncated, info = self.env.step(actions)
        terminated = np.asarray(terminated, dtype=bool)
        truncated = np.asarray(truncated, dtype=bool)
        dones = terminated | truncated
        infos = self._dicts({k: v for k, v in info.items() if k not in ("final_obs", "final_info")})
        if dones.any():
            # The envs whose episode ended: their info is the ended step's (Gymnasium's final_info) and the
            # reset's goes to reset_infos, as SB3's DummyVecEnv does.
            idx = np.flatnonzero(dones)
            final = info["final_info"]
            final_obs = info["final_obs"]
            success = final.get("is_success")
            for i in idx.tolist():
                self.reset_infos[i] = infos[i]
            final_dicts = self._dicts(final, idx)
            for j, i in enumerate(idx.tolist()):
                d = final_dicts[j]
                d["terminal_observation"] = final_obs[i]
                if success is not None:
                    d["is_success"] = bool(success[i])
                infos[i] = d
        for d, t in zip(infos, (truncated & ~terminated).tolist(), strict=True):  # on every step, as DummyVecEnv
            d["TimeLimit.truncated"] = t
        return obs, np.asarray(rewards, dtype=np.float32), dones, infos

    def close(self) -> None:
        self.env.close()

    def _indices(self, indices: VecEnvIndices) -> list[int]:
        idx = list(self._get_indices(indices))
        for i in idx:
            if not 0 <= int(i) < self.num_envs:
                raise IndexError(f"env index {i} out of range for {self.num_envs} envs")
        return idx

    def get_attr(self, attr_name: str, indices: VecEnvIndices = None) -> list[Any]:
        value = getattr(self.env, attr_name)
        return [value for _ in self._indices(indices)]

    def set_attr(self, attr_name: str, value: Any, indices: VecEnvIndices = None) -> None:
        idx = self._indices(indices)
        if sorted(set(idx)) != list(range(self.num_envs)):
            raise ValueError(f"the {self.num_envs} envs share one batched env: set_attr({attr_name!r}) applies to all "
                             f"of them (indices=None), got indices {idx}")
        setattr(self.env, attr_name, value)

    def env_method(self, method_name: str, *method_args, indices: VecEnvIndices = None, **method_kwargs) -> list[Any]:
        idx = self._indices(indices)
        result = getattr(self.env, method_name)(*method_args, **method_kwargs)
        return [result for _ in idx]

    def env_is_wrapped(self, wrapper_class: type, indices: VecEnvIndices = None) -> list[bool]:
        """The sub-envs are rows of one batched env, not wrapped ``gym.Env`` objects: ``False`` for each index."""
        return [False for _ in self._indices(indices)]

    def get_images(self) -> Sequence[np.ndarray | None]:
        if self.render_mode != "rgb_array":
            return [None for _ in range(self.num_envs)]
        frames = self.env.render()
        return list(frames) if isinstance(frames, Iterable) else [None for _ in range(self.num_envs)]

    @property
    def vector_env(self) -> VectorEnv:
        """The wrapped Gymnasium vector env."""
        return self.env
