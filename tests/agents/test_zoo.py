"""rl-zoo3 trains from the project's own hyperparameter files (``configs/train/*.yaml``), unmodified.

Needs ``rl_zoo3`` (the ``zoo`` extra: ``pip install -e ".[zoo]"``); skipped without it. The quick test builds the
experiment (envs, wrappers, model) in-process; the slow ones run ``python -m rl_zoo3.train`` for 4096 steps (each
well under a minute on the idle 2-core machine; no wall-clock assertion, which a busy machine would break).
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import time
import warnings
from pathlib import Path

import numpy as np
import pytest

ROOT = Path(__file__).resolve().parents[2]
CONFIGS = ROOT / "configs" / "train"


@pytest.mark.parametrize("algo", ["ppo", "sac"])
def test_rl_zoo3_builds_the_experiment_from_the_config(tmp_path, algo):
    """rl-zoo3's own reading of the file: every key is consumed or accepted by the algorithm, and the env is wrapped
    in the public setpoint wrapper."""
    pytest.importorskip("rl_zoo3")
    from rl_zoo3.exp_manager import ExperimentManager

    import pneunet_env  # noqa: F401  (what --gym-packages pneunet_env does)
    from pneunet_env.wrappers import PressureSetpoint

    exp = ExperimentManager(argparse.Namespace(), algo, "PneuNetGrasp-v1", str(tmp_path), n_timesteps=1000,
                            config=str(CONFIGS / f"{algo}.yaml"), seed=0, verbose=0, device="cpu")
    model, _ = exp.setup_experiment()
    env = model.get_env()
    base = env.venv if hasattr(env, "venv") else env  # VecNormalize (ppo) around the DummyVecEnv
    assert base.num_envs == (16 if algo == "ppo" else 4)
    assert all(isinstance(e, PressureSetpoint) for e in base.envs)
    assert model.seed == 0 and model.use_sde
    env.close()


def _zoo(tmp_path: Path, vec_env: str, extra_env: dict[str, str] | None = None) -> tuple[Path, float]:
    cmd = [sys.executable, "-m", "rl_zoo3.train", "--algo", "ppo", "--env", "PneuNetGrasp-v1",
           "--gym-packages", "pneunet_env", "--conf-file", str(CONFIGS / "ppo.yaml"), "-n", "4096", "--seed", "0",
           "-f", str(tmp_path / "logs"), "--vec-env", vec_env, "--eval-freq", "-1"]
    t0 = time.monotonic()
    # rl-zoo3 gives SB3 no log folder: SB3's goes under tmp_path, not $TMPDIR/SB3-<date> (left behind)
    res = subprocess.run(cmd, cwd=ROOT, capture_output=True, text=True, timeout=300,
                         env={**os.environ, "SB3_LOGDIR": str(tmp_path / "sb3_log"), **(extra_env or {})})
    wall = time.monotonic() - t0
    assert res.returncode == 0, res.stdout[-3000:] + res.stderr[-3000:]
    run = tmp_path / "logs" / "ppo" / "PneuNetGrasp-v1_1"
    assert (run / "PneuNetGrasp-v1.zip").is_file(), sorted(p.name for p in run.iterdir())
    config = (run / "PneuNetGrasp-v1" / "config.yml").read_text()
    assert "pneunet_env.wrappers.PressureSetpoint" in config and "squash_output=True" in config
    return run, wall


@pytest.mark.slow
@pytest.mark.filterwarnings("ignore::UserWarning")
def test_rl_zoo3_trains_ppo_yaml_dummy_vec_env(tmp_path):
    pytest.importorskip("rl_zoo3")
    from agents.policies.sb3 import SB3Policy

    run, wall = _zoo(tmp_path, "dummy")
    print(f"rl-zoo3, dummy vec env, 4096 steps: {wall:.1f} s")  # about 10 s on the idle 2-core machine
    assert len(list(run.glob("*.monitor.csv"))) == 16
    # rl-zoo3's statistics are a pickle, in a subfolder: loaded only because named here
    pkl = run / "PneuNetGrasp-v1" / "vecnormalize.pkl"
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # nothing to warn about: the pickle is named
        pol = SB3Policy(run / "PneuNetGrasp-v1.zip", vecnormalize=pkl, action="setpoint")
    a = pol(np.array([[0.0], [0.5], [1.0]], np.float32))
    assert a.shape == (3, 1) and np.all(np.abs(a) <= 1.0)


@pytest.mark.slow
def test_rl_zoo3_trains_ppo_yaml_subproc_vec_env(tmp_path):
    """16 worker processes on a 2-core machine: numba would compile its kernels in each one (they are not cached),
    so the workers run the numpy solver (PNEUNET_DISABLE_NUMBA=1); what is tested is rl-zoo3 with the file."""
    pytest.importorskip("rl_zoo3")
    _, wall = _zoo(tmp_path, "subproc", {"PNEUNET_DISABLE_NUMBA": "1"})
    print(f"rl-zoo3, subproc vec env, 4096 steps: {wall:.1f} s")  # 31-37 s on the idle 2-core machine
