"""The pressure-setpoint action: the agent commands a pressure, a rate-limited regulator follows it.

``PneuNetGrasp-v1``'s own action is a pressure *increment* (``a`` in ``[-1, 1]`` moves the pressure by
``a * max_pressure_step_kpa``). With the wrappers here the agent's action ``u`` in ``[-1, 1]`` is instead a pressure
*setpoint*, ``(u + 1)/2`` of ``p_max``, and the env receives the increment that moves the pressure toward it as fast
as the env allows (:func:`setpoint_to_rate`: a proportional regulator with a rate limit). The regulator reads only
the pressure (the observation's first entry) and the command, so an agent behind it is as blind as before. This is
what the trained PPO agent uses (``configs/train/ppo.yaml``); why: docs/results-paper.md, "A trained agent".

One formula, two forms:

* :class:`PressureSetpoint`, a ``gymnasium.Wrapper`` around one env: name it in an rl-zoo3 hyperparameter file
  (``env_wrapper: pneunet_env.wrappers.PressureSetpoint``), or wrap ``gym.make("PneuNetGrasp-v1")`` yourself.
* ``PressureSetpointVecEnv``, a stable-baselines3 ``VecEnvWrapper`` around a ``VecEnv`` (the batched env of
  :mod:`pneunet_env.envs.sb3`, which a per-env wrapper cannot reach): ``vec_env_wrapper:
  pneunet_env.wrappers.PressureSetpointVecEnv``. It is built on first access, so ``import pneunet_env.wrappers``
  needs neither stable-baselines3 nor torch (and ``from pneunet_env.wrappers import *`` does not import it).

Both give the env the same actions on the same observations (``tests/agents/test_train.py``), and
:class:`agents.policies.sb3.SB3Policy` applies the same :func:`setpoint_to_rate` when it runs a setpoint model.
"""

from __future__ import annotations

from typing import Any, SupportsFloat

import gymnasium as gym
import numpy as np

from pneunet_env.physics.xp import NUMPY, ops_for

__all__ = ["PressureSetpoint", "setpoint_to_rate", "setpoint_step_fraction"]


def setpoint_to_rate(setpoint, pressure_fraction, step_fraction: float) -> np.ndarray:
    """The env action that moves the pressure toward a commanded setpoint as fast as the env allows.

    Args:
        setpoint: the agent's output ``u`` in ``[-1, 1]`` (clipped), the target ``(u + 1)/2`` of ``p_max``.
        pressure_fraction: the current ``p / p_max`` (the observation's first entry), same leading shape.
        step_fraction: ``max_pressure_step_kpa / max_pressure_kpa`` (:func:`setpoint_step_fraction`).

    Returns:
        ``clip(((u + 1)/2 - p) / step_fraction, -1, 1)``, float32, the shape of ``setpoint`` (a tensor on its device
        for torch tensors).

    This is a proportional pressure regulator with a rate limit: a function of the pressure and the command only,
    so a policy using it still observes nothing but the pressure.
    """
    xp = ops_for(setpoint)
    if xp is NUMPY:
        u, p = np.asarray(setpoint, dtype=np.float64), np.asarray(pressure_fraction, dtype=np.float64)
    else:  # torch tensors (the torch backend): the same formula, on their device
        u, p = setpoint.double(), pressure_fraction.double()
    u = xp.minimum(xp.maximum(u, -1.0), 1.0)
    p = p.reshape(u.shape)
    return xp.to_float32(xp.minimum(xp.maximum((0.5 * (u + 1.0) - p) / step_fraction, -1.0), 1.0))


def setpoint_step_fraction(config) -> float:
    """``max_pressure_step_kpa / max_pressure_kpa`` of an :class:`~pneunet_env.config.EnvConfig`."""
    return config.task.max_pressure_step_kpa / config.task.max_pressure_kpa


def _check_step_fraction(value: Any) -> float:
    """``value`` as a float in ``(0, 1]``; ``TypeError``/``ValueError`` naming ``step_fraction`` otherwise."""
    if value is None or isinstance(value, (bool, np.bool_, str, bytes)):
        raise TypeError(f"step_fraction must be a number in (0, 1], got {value!r}")
    try:
        x = float(value)
    except (TypeError, ValueError, OverflowError):
        raise TypeError(f"step_fraction must be a number in (0, 1], got {value!r}") from None
    if not 0.0 < x <= 1.0:
        raise ValueError(f"step_fraction must be in (0, 1], got {value!r}")
    return x


class PressureSetpoint(gym.Wrapper):
    """The agent's action is a pressure setpoint; the env receives the rate-limited change toward it.

    Args:
        env: a ``PneuNetGrasp-v1`` env (any wrapping); its observation's first entry is ``p / p_max``.
        step_fraction: ``max_pressure_step_kpa / max_pressure_kpa``; default: read from the env's ``config``.

    The action space is unchanged (``Box(-1, 1, (1,))``) but now means the setpoint ``(u + 1)/2`` of ``p_max``;
    observations, rewards and infos pass through. The last observed pressure is kept between steps (the regulator
    needs it), so :meth:`reset` must come first, as for any env.

    Example (rl-zoo3)::

        PneuNetGrasp-v1:
          env_wrapper: pneunet_env.wrappers.PressureSetpoint
    """

    #: the ``VecEnv`` form of this wrapper (a name in this module), used where per-env wrapping is impossible
    vec_env_form = "PressureSetpointVecEnv"

    def __init__(self, env: gym.Env, step_fraction: float | None = None) -> None:
        super().__init__(env)
        if step_fraction is None:
            step_fraction = setpoint_step_fraction(env.get_wrapper_attr("config"))
        self.step_fraction = _check_step_fraction(step_fraction)
        self._p: np.ndarray | None = None

    def _observe(self, obs) -> None:
        self._p = np.asarray(obs, np.float32)[:1].copy()

    def reset(self, *, seed: int | None = None, options: dict[str, Any] | None = None):
        obs, info = self.env.reset(seed=seed, options=options)
        self._observe(obs)
        return obs, info

    def action(self, setpoint) -> np.ndarray:
        """The env action (the pressure change) for a setpoint at the last observed pressure."""
        if self._p is None:
            raise gym.error.ResetNeeded("PressureSetpoint: call reset() before step()")
        return setpoint_to_rate(setpoint, self._p, self.step_fraction)

    def step(self, action) -> tuple[Any, SupportsFloat, bool, bool, dict[str, Any]]:
        obs, reward, terminated, truncated, info = self.env.step(self.action(action))
        self._observe(obs)
        return obs, reward, terminated, truncated, info


def _vec_env_class():
    """``PressureSetpointVecEnv``, defined on first use (it subclasses stable-baselines3's ``VecEnvWrapper``)."""
    from stable_baselines3.common.vec_env import VecEnvWrapper

    class PressureSetpointVecEnv(VecEnvWrapper):
        """:class:`PressureSetpoint` for a whole ``VecEnv`` (SB3's API): the same formula, on every env at once.

        Args:
            venv: a ``VecEnv`` of ``PneuNetGrasp-v1`` (the batched :class:`~pneunet_env.envs.sb3.SB3VecEnv`, or
                a ``DummyVecEnv``/``SubprocVecEnv``), below any ``VecNormalize`` (it reads the raw pressure).
            step_fraction: ``max_pressure_step_kpa / max_pressure_kpa``; default: read from env 0's ``config``.

        SB3's vec envs reset an ended episode in the same step, so the pressure kept for the next command is the
        new episode's first observation, as with :class:`PressureSetpoint` under ``DummyVecEnv``.
        """

        def __init__(self, venv, step_fraction: float | None = None) -> None:
            super().__init__(venv)
            if step_fraction is None:
                step_fraction = setpoint_step_fraction(venv.get_attr("config", indices=[0])[0])
            self.step_fraction = _check_step_fraction(step_fraction)
            self._p: np.ndarray | None = None

        def _observe(self, obs) -> None:
            self._p = np.asarray(obs, np.float32)[:, :1].copy()

        def reset(self):
            obs = self.venv.reset()
            self._observe(obs)
            return obs

        def actions(self, setpoints) -> np.ndarray:
            """The env actions (pressure changes), shape ``(num_envs, 1)``, for a batch of setpoints."""
            if self._p is None:
                raise gym.error.ResetNeeded("PressureSetpointVecEnv: call reset() before step()")
            return setpoint_to_rate(setpoints, self._p, self.step_fraction)

        def step_async(self, actions) -> None:
            self.venv.step_async(self.actions(actions))

        def step_wait(self):
            obs, rewards, dones, infos = self.venv.step_wait()
            self._observe(obs)  # an ended episode's env is already reset: its new first observation
            return obs, rewards, dones, infos

    PressureSetpointVecEnv.__module__ = __name__
    PressureSetpointVecEnv.__qualname__ = "PressureSetpointVecEnv"  # picklable by name (SubprocVecEnv, cloudpickle)
    return PressureSetpointVecEnv


def __getattr__(name: str):
    if name == "PressureSetpointVecEnv":
        cls = _vec_env_class()
        globals()[name] = cls
        return cls
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


def __dir__() -> list[str]:
    return sorted([*globals(), "PressureSetpointVecEnv"])
