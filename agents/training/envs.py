"""The environments and callbacks of a training run (:mod:`agents.training.train`): the training and evaluation
``VecEnv`` (:func:`make_vec_env`: the batched env, :mod:`pneunet_env.envs.sb3`, or SB3's ``DummyVecEnv`` over
``gym.make``, with the config's wrappers), the callbacks (:func:`make_callbacks`: the seeded evaluation, atomic
checkpoints, the time budget, the config's own) and best-ramp's success on the same evaluation objects
(:func:`reference_success`).

stable-baselines3 is imported inside the functions (extra ``rl``).
"""

from __future__ import annotations

import importlib
import io
import time
import warnings
from collections.abc import Callable
from pathlib import Path
from typing import Any

from agents.training.config import ENV_ID, _wrapper_classes
from pneunet_env.files import atomic_write_bytes, deferred_interrupt

__all__ = ["batched_available", "make_vec_env", "make_callbacks", "evaluation_verdict", "reference_success"]


# ---------------------------------------------------------------------------------------------
# Environments
# ---------------------------------------------------------------------------------------------


def batched_available() -> bool:
    """Whether :mod:`pneunet_env.envs.sb3` (the SB3 adapter of the batched env) can be imported."""
    try:
        import pneunet_env.envs.sb3  # noqa: F401
    except ImportError:
        return False
    return True


def make_vec_env(hp: dict[str, Any], n_envs: int, seed: int, monitor_dir: Path | None, wrap: bool = True):
    """The training or evaluation ``VecEnv`` (``hp["vec_env"]``), monitored, seeded, with the config's
    ``env_wrapper`` and ``vec_env_wrapper`` (``wrap=False``: the env's own actions; ``VecNormalize`` and
    ``frame_stack`` are applied by :func:`train`)."""
    import pneunet_env  # noqa: F401  (registers the env)

    env_wrappers = _wrapper_classes(hp, "env_wrapper") if wrap else []
    kind = hp["vec_env"]
    if kind == "batched" and not batched_available():
        warnings.warn("vec_env: batched needs pneunet_env.envs.sb3, which is missing; using dummy", stacklevel=2)
        kind = "dummy"
    if kind == "batched" and env_wrappers:
        vec_forms = [getattr(cls, "vec_env_form", None) for cls, _ in env_wrappers]
        if any(f is None for f in vec_forms):
            missing = [f"{cls.__module__}.{cls.__qualname__}" for (cls, _), f in zip(env_wrappers, vec_forms,
                                                                                    strict=True) if f is None]
            warnings.warn(f"vec_env: batched cannot apply the per-env wrapper(s) {missing} (no VecEnv form); "
                          "using dummy", stacklevel=2)
            kind = "dummy"
    if kind == "batched":
        venv = _make_batched(hp, n_envs, seed, monitor_dir)
        for cls, kwargs in env_wrappers:  # each env wrapper's VecEnv form, in the same order
            venv = getattr(importlib.import_module(cls.__module__), cls.vec_env_form)(venv, **kwargs)
    else:
        venv = _make_dummy(hp, n_envs, seed, monitor_dir, env_wrappers)
    for cls, kwargs in (_wrapper_classes(hp, "vec_env_wrapper") if wrap else []):
        venv = cls(venv, **kwargs)
    return venv


def _make_batched(hp: dict[str, Any], n_envs: int, seed: int, monitor_dir: Path | None):
    from stable_baselines3.common.vec_env import VecMonitor

    from pneunet_env.envs.sb3 import SB3VecEnv

    venv = SB3VecEnv(num_envs=n_envs, **hp["env_kwargs"])
    if monitor_dir is not None:
        monitor_dir.mkdir(parents=True, exist_ok=True)
    venv = VecMonitor(venv, filename=None if monitor_dir is None else str(monitor_dir / "batched"))
    venv.seed(seed)
    return venv


def _make_dummy(hp: dict[str, Any], n_envs: int, seed: int, monitor_dir: Path | None, env_wrappers):
    from stable_baselines3.common.env_util import make_vec_env as sb3_make_vec_env
    from stable_baselines3.common.vec_env import DummyVecEnv

    def wrap_env(env):
        for cls, kwargs in env_wrappers:
            env = cls(env, **kwargs)
        return env

    if monitor_dir is not None:
        monitor_dir.mkdir(parents=True, exist_ok=True)
    return sb3_make_vec_env(ENV_ID, n_envs=n_envs, seed=seed, vec_env_cls=DummyVecEnv,
                            env_kwargs=dict(hp["env_kwargs"]), wrapper_class=wrap_env if env_wrappers else None,
                            monitor_dir=None if monitor_dir is None else str(monitor_dir))


# ---------------------------------------------------------------------------------------------
# Callbacks
# ---------------------------------------------------------------------------------------------


def make_callbacks(hp: dict[str, Any], run_dir: Path, eval_env, seed: int, deadline: float, resuming: bool = False,
                   *, save_model: Callable[[Any, Path], Path], save_checkpoint: Callable[[Any, Path], Path]) -> list:
    """The run's callbacks, in order: the seeded evaluation (``evaluations.npz``; a new best model saved with
    ``save_model(model, run_dir / "best_model")``), the checkpoints (``save_checkpoint(model, folder)``), the
    wall-clock budget (``deadline``, :func:`time.monotonic`'s clock), then the config's own ``callback`` classes.

    ``seed`` re-seeds the evaluation env before each evaluation (the same objects every time); ``resuming`` starts
    the evaluation log from the run's earlier ``evaluations.npz``.
    """
    from stable_baselines3.common.callbacks import BaseCallback, CheckpointCallback, EvalCallback

    class SaveBest(BaseCallback):
        """On a new best model: save it with its VecNormalize statistics (JSON, and SB3's pickle), each file
        written whole or not at all (EvalCallback's own save writes the zip in place: an interrupt cut it)."""

        def _on_step(self) -> bool:
            save_model(self.model, run_dir / "best_model")
            return True

    class AtomicCheckpoint(CheckpointCallback):
        """SB3's CheckpointCallback (same names: ``model_<N>_steps.zip``, ``model_vecnormalize_<N>_steps.pkl``),
        each file written to a temporary name and renamed; the statistics before the model, so that a checkpoint
        zip that exists always has its statistics."""

        def _on_step(self) -> bool:
            if self.n_calls % self.save_freq == 0:
                save_checkpoint(self.model, Path(self.save_path))
            return True

    class SeededEval(EvalCallback):
        """EvalCallback on the same objects every time (the eval env is re-seeded before each evaluation).

        On a resumed run it starts from the earlier evaluations (``evaluations.npz`` keeps them all, and a new best
        model must beat the earlier best).

        Its log (``verbose``) is SB3's three lines per evaluation (mean return, episode length, success rate), then
        this project's line on the best model (:func:`evaluation_verdict`) instead of SB3's "New best mean reward!":
        step 0, the untrained policy, is never the best model, so SB3 would call the first trained evaluation a new
        best even below step 0's return."""

        untrained_mean_reward: float | None = None
        """Step 0's mean return (the untrained policy), once evaluated (or read back on a resumed run)."""

        def _init_callback(self) -> None:
            super()._init_callback()
            previous = run_dir / "evaluations.npz"
            if resuming and previous.is_file():
                import numpy as np

                data = np.load(previous)
                keep = [i for i, t in enumerate(data["timesteps"]) if t <= self.model.num_timesteps]  # a hard kill
                self.evaluations_timesteps = [int(data["timesteps"][i]) for i in keep]  # evaluated past the model
                self.evaluations_results = [list(data["results"][i]) for i in keep]
                self.evaluations_length = [list(data["ep_lengths"][i]) for i in keep]
                if "successes" in data:
                    self.evaluations_successes = [list(data["successes"][i]) for i in keep]
                pairs = list(zip(self.evaluations_timesteps, self.evaluations_results, strict=True))
                trained = [r for t, r in pairs if t > 0]
                if trained:  # step 0, the untrained start, is never the best model
                    self.best_mean_reward = float(max(np.mean(r) for r in trained))
                self.untrained_mean_reward = next((float(np.mean(r)) for t, r in pairs if t == 0), None)

        def _on_training_start(self) -> None:
            """A new run is evaluated before its first update too: step 0, the untrained policy, the learning curve's
            start. It is logged but cannot become the best model: what a run exports is a trained model (an
            untrained network may already command a good blind pressure, and would otherwise be exported as the
            "trained" one, as 0.7's first seed study found). A run interrupted before that evaluation resumes from
            its step-0 checkpoint and evaluates it then."""
            super()._on_training_start()
            if self.eval_freq > 0 and self.model.num_timesteps == 0 and 0 not in self.evaluations_timesteps:
                calls, self.n_calls = self.n_calls, 0
                path, on_best = self.best_model_save_path, self.callback_on_new_best
                self.best_model_save_path, self.callback_on_new_best = None, None
                try:
                    self._on_step()
                finally:
                    self.n_calls = calls
                    self.best_model_save_path, self.callback_on_new_best = path, on_best
                    self.best_mean_reward = -float("inf")

        def _on_step(self) -> bool:
            evaluating = self.eval_freq > 0 and self.n_calls % self.eval_freq == 0
            if evaluating:
                self.eval_env.seed(seed)
            # EvalCallback's np.savez goes into memory, then to evaluations.npz whole (never a cut file)
            self.log_path = io.BytesIO()
            best_before, verbose = self.best_mean_reward, self.verbose
            self.verbose = 0  # SB3's own lines: printed below, with this project's line on the best model
            try:
                go_on = super()._on_step()
            finally:
                self.verbose = verbose
            if data := self.log_path.getvalue():
                with deferred_interrupt():
                    atomic_write_bytes(run_dir / "evaluations.npz", data)
            if evaluating:
                self._report(best_before)
            return go_on

        def _report(self, best_before: float) -> None:
            """Print the evaluation just made (SB3's lines, then :func:`evaluation_verdict`'s); note step 0's return."""
            import numpy as np

            rewards, lengths = self.evaluations_results[-1], self.evaluations_length[-1]
            mean = float(np.mean(rewards))
            if self.num_timesteps == 0:
                self.untrained_mean_reward = mean
            if self.verbose < 1:
                return
            print(f"Eval num_timesteps={self.num_timesteps}, episode_reward={mean:.2f} +/- {np.std(rewards):.2f}")
            print(f"Episode length: {np.mean(lengths):.2f} +/- {np.std(lengths):.2f}")
            if self._is_success_buffer:
                print(f"Success rate: {100 * np.mean(self._is_success_buffer):.2f}%")
            verdict = evaluation_verdict(self.num_timesteps, mean, new_best=self.best_mean_reward > best_before,
                                         untrained=self.untrained_mean_reward)
            if verdict:
                print(verdict)

    class WallClock(BaseCallback):
        """Stop training once the invocation's time budget is spent."""

        def _on_step(self) -> bool:
            if time.monotonic() > deadline:
                if self.verbose:
                    print(f"\ntime budget of {hp['max_train_minutes']:g} min spent at {self.num_timesteps} steps")
                return False
            return True

    n = hp["n_envs"]
    evaluation = SeededEval(eval_env, callback_on_new_best=SaveBest(),
                            n_eval_episodes=hp["n_eval_episodes"], eval_freq=max(1, hp["eval_freq"] // n),
                            log_path=str(run_dir), best_model_save_path=None, deterministic=True,
                            verbose=1)
    checkpoints = AtomicCheckpoint(max(1, hp["checkpoint_freq"] // n), str(run_dir / "checkpoints"),
                                   name_prefix="model", save_vecnormalize=True)
    # the config's own callbacks (rl-zoo3's `callback` key), after ours
    extra = [cls(**kwargs) for cls, kwargs in _wrapper_classes(hp, "callback")]
    return [evaluation, checkpoints, WallClock(verbose=1), *extra]


def evaluation_verdict(timesteps: int, mean_reward: float, *, new_best: bool, untrained: float | None) -> str:
    """The training log's line on an evaluation's standing ("" when there is nothing to say).

    Step 0 (the untrained policy) is evaluated for the learning curve but never kept as the best model: what a run
    exports is trained. So the first trained evaluation is the first best model even when its mean return is below
    step 0's, and the line says so (SB3's EvalCallback prints "New best mean reward!" there, with no comparison).

    Args:
        timesteps: the model's timesteps at the evaluation.
        mean_reward: its mean episode return.
        new_best: whether it became the run's best model (``best_model.zip``).
        untrained: step 0's mean return, if it was evaluated.
    """
    if timesteps == 0:
        return "Step 0 (the untrained policy): evaluated for the learning curve, never kept as the best model"
    if not new_best:
        return ""
    line = f"New best trained model (mean reward {mean_reward:.2f}): saved as best_model.zip"
    if untrained is not None and mean_reward < untrained:
        line += (f"; below step 0's {untrained:.2f}, but step 0 (the untrained policy) is never kept as the best "
                 "model")
    return line


def reference_success(hp: dict[str, Any], seed: int, spec: str = "best-ramp") -> float | None:
    """The success rate of a scripted policy (``best-ramp``) on the evaluation objects of the run.

    The same vec env, seeds and episode split as :class:`EvalCallback`'s evaluations (the eval env's objects are
    drawn from per-env streams, the same whatever the episodes' lengths), so the numbers compare directly.
    """
    import numpy as np
    from stable_baselines3.common.evaluation import evaluate_policy

    from agents.policies.registry import make_policy
    from pneunet_env.config import load_config

    try:
        policy = make_policy(spec, load_config(None, **hp["env_kwargs"])).policy
    except ValueError:
        return None
    venv = make_vec_env(hp, hp["n_eval_envs"], seed, None, wrap=False)  # the env's own action
    venv.seed(seed)
    successes: list[bool] = []

    def log(locals_, globals_):
        if locals_["done"]:
            successes.append(bool(locals_["info"].get("is_success", False)))

    evaluate_policy(policy, venv, n_eval_episodes=hp["n_eval_episodes"], deterministic=True, callback=log)
    venv.close()
    return float(np.mean(successes)) if successes else None
