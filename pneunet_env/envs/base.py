"""The shell every single env shares: the state, the reset and the step around :mod:`pneunet_env.task`'s pure step.

:class:`SingleGraspEnv` holds one env's :class:`~pneunet_env.task.EnvState`, draws its object on ``reset`` from
``self.np_random``, and steps it with :func:`pneunet_env.task.step` and the subclass's contact. A subclass
(:class:`pneunet_env.envs.grasp.PneuNetGraspEnv`, :class:`pneunet_env.envs.rigid.RigidGraspEnv`) sets ``env_id``,
``metadata``, its :class:`~pneunet_env.task.EnvParams` (``_params``), its contact (``_contact``) and the spaces, and
builds its info (:meth:`SingleGraspEnv._info`); it may check the object it is given (:meth:`_accept_object`) and
keep what it needs of the new episode (:meth:`_after_reset`), and may step faster without building records
(:meth:`_step_fast`: its state is then built when asked for, :meth:`_packed_state`). Only this class writes
``_state`` and ``_ended``.
"""

from __future__ import annotations

from typing import Any, ClassVar

import gymnasium as gym
import numpy as np
from gymnasium import spaces
from gymnasium.error import ClosedEnvironmentError, ResetNeeded

from pneunet_env import task
from pneunet_env.config import EnvConfig, load_config
from pneunet_env.objects import GraspObject
from pneunet_env.physics.solver import Equilibrium
from pneunet_env.physics.xp import is_torch

__all__ = ["SingleGraspEnv"]


class SingleGraspEnv(gym.Env):
    """One grasp env around :func:`pneunet_env.task.step` (scalars): the shared reset, step and state.

    Stepping before ``reset`` or past an episode's end raises ``gymnasium.error.ResetNeeded``; ``info["is_success"]``
    (held to the end, intact) is added on an episode's last step. With ``render_mode="human"`` every ``reset`` and
    ``step`` calls :meth:`render`. After :meth:`close`, ``step``, ``reset`` and ``render`` raise
    ``gymnasium.error.ClosedEnvironmentError`` (as Gymnasium's vector envs do: a closed env is not reopened; make a
    new one); ``close`` again does nothing.
    """

    env_id: ClassVar[str] = ""
    """The registered id, for messages."""
    metadata: ClassVar[dict[str, Any]] = {"render_modes": []}
    closed: bool = False
    """Whether :meth:`close` was called (Gymnasium's vector envs' attribute, here on a single env too)."""

    def __init__(self, render_mode: str | None, config: Any, info_level: str, overrides: dict[str, Any]) -> None:
        modes = self.metadata["render_modes"]
        if not modes and render_mode is not None:
            raise ValueError(f"{self.env_id} does not render (render_mode must be None), got {render_mode!r}")
        if render_mode is not None and not (isinstance(render_mode, str) and render_mode in modes):
            raise ValueError(f"render_mode must be one of {modes} or None, got {render_mode!r}")
        if not isinstance(info_level, str) or info_level not in task.INFO_LEVELS:
            raise ValueError(f"info_level must be one of {task.INFO_LEVELS}, got {info_level!r}")
        self.render_mode = render_mode
        self.info_level = info_level
        self.config: EnvConfig = load_config(config, **overrides)
        self.action_space = spaces.Box(-1.0, 1.0, (1,), np.float32)
        self._params: task.EnvParams  # set by the subclass
        self._contact: task.Contact  # set by the subclass
        self._record: task.EnvState | None = None  # the state (see _state)
        self._ahead = False  # the subclass's fast step moved the state past _record (see _step_fast)
        self._ended = False

    # ---- the state --------------------------------------------------------------------------------
    @property
    def _state(self) -> task.EnvState | None:
        """The current state's record: built from the subclass's packed state after fast steps (see _step_fast)."""
        if self._ahead:
            self._record, self._ahead = self._packed_state(), False
        return self._record

    @_state.setter
    def _state(self, state: task.EnvState | None) -> None:
        self._record, self._ahead = state, False

    # ---- the state, for users ----------------------------------------------------------------------
    @property
    def state(self) -> task.EnvState | None:
        """The whole state (:class:`pneunet_env.task.EnvState`; ``None`` before ``reset``)."""
        return self._state

    @property
    def equilibrium(self) -> Equilibrium | None:
        """The current quasi-static state (an :class:`~pneunet_env.physics.solver.Equilibrium`)."""
        return None if self._state is None else self._state.eq

    # ---- what a subclass adds ----------------------------------------------------------------------
    def _accept_object(self, obj: GraspObject) -> None:
        """Check the object drawn for a new episode before it is used (raise to refuse it); nothing by default."""

    def _after_reset(self, obj: GraspObject, options: dict[str, Any] | None) -> None:
        """Keep what the subclass needs of the new episode (its state is ``self.state``); nothing by default."""

    def _reset_state(self, obj: GraspObject) -> task.EnvState:
        """The state at ``reset`` with the object ``obj``: :func:`pneunet_env.task.reset_state` with the env's params
        and contact (a subclass may compute the same state faster)."""
        return task.reset_state(obj, self._params, self._contact)

    def _step_state(self, state: task.EnvState, action: float) -> task.Step:
        """One step from ``state``: :func:`pneunet_env.task.step` with the env's params and contact (a subclass may
        compute the same step faster)."""
        return task.step(state, action, self._params, self._contact)

    def _info(self, res: task.Step | None) -> dict[str, Any]:
        """The info of the current state (``res``: the step that reached it; ``None`` on reset)."""
        raise NotImplementedError

    def _step_fast(self, state: task.EnvState | None, action: float) -> tuple | None:
        """``(obs, reward, terminated, truncated, info)`` of one step, as :meth:`step` returns them (with
        ``is_success`` on an episode's last step), from a state the subclass keeps itself, without building the
        :class:`~pneunet_env.task.Step`; ``None`` where it has no such step (the default), and :meth:`step` takes
        :meth:`_step_state`. ``state``: the current state's record, or ``None`` where the current state is the one
        the last fast step left. After a fast step, :meth:`_packed_state` gives the state's record when one is
        needed."""
        return None

    def _packed_state(self) -> task.EnvState:
        """The record of the state the last :meth:`_step_fast` left."""
        raise NotImplementedError

    # ---- Gymnasium API -----------------------------------------------------------------------------
    def _check_open(self, what: str) -> None:
        """``ClosedEnvironmentError`` naming ``what`` once the env is closed."""
        if self.closed:
            raise ClosedEnvironmentError(f"{type(self).__name__}.{what}() after close(): a closed env is not "
                                         f"reopened; make a new one")

    def close(self) -> None:
        """Close the env: from now on ``step``, ``reset`` and ``render`` raise ``ClosedEnvironmentError``. Closing
        again does nothing."""
        self.closed = True
        self._ended = True  # step's "call reset()" branch then names the close: no test of its own on the hot path
        super().close()

    def reset(self, *, seed: int | None = None, options: dict[str, Any] | None = None):
        """A new episode: an object from ``self.np_random`` (``options`` pins its properties:
        :data:`pneunet_env.task.PIN_KEYS`), the command 0 and the actuator at rest."""
        self._check_open("reset")
        super().reset(seed=seed)
        self._ended = False
        if options is not None and not isinstance(options, dict):
            raise ValueError(f"options must be a dict of object properties to pin, got {options!r}")
        obj = task.sample_object(self.np_random, self.config, pinned=options)
        self._accept_object(obj)
        self._state = state = self._reset_state(obj)
        self._after_reset(obj, options)
        p = self._params
        obs = task.observation(state.command, state.eq.volume_change, p.task, p.volume_scale)
        info = self._info(None)
        if self.render_mode == "human":
            self.render()
        return obs, info

    def step(self, action):
        """One step of :func:`pneunet_env.task.step`. A torch tensor is read as its value (detached)."""
        if self._record is None or self._ended:  # (close() sets _ended: a closed env comes here too)
            self._check_open("step")
            if self._record is None:
                raise ResetNeeded("call reset() before step()")
            raise ResetNeeded("the episode has ended (terminated or truncated): call reset() before step()")
        if type(action) is not np.ndarray and is_torch(action):
            action = action.detach()  # a tensor that requires grad is read as its value (the env is not differentiable)
        a = task.single_action(action)
        fast = self._step_fast(None if self._ahead else self._record, a)
        if fast is not None:
            self._ahead = True
            obs, reward, terminated, truncated, info = fast
        else:
            res = self._step_state(self._state, a)
            self._state = res.state
            info = self._info(res)
            obs, reward, terminated, truncated = res.obs, float(res.reward), bool(res.terminated), bool(res.truncated)
            if terminated or truncated:
                info["is_success"] = bool(res.outcome.success)
        if terminated or truncated:
            self._ended = True
        if self.render_mode == "human":
            self.render()
        return obs, reward, terminated, truncated, info
