"""What is trusted (issue 37, items 1 and 2): no pickle is loaded unless its path is named (``train --resume`` reads
the statistics beside a checkpoint as numbers), and a model's sidecar that contradicts the hyperparameters it records
is refused by name, not believed."""

from __future__ import annotations

import json
import pickle
import shutil
import warnings
from pathlib import Path

import numpy as np
import pytest

MODELS = Path(__file__).resolve().parents[2] / "agents" / "models"
KITCHEN = MODELS / "ppo_kitchen.zip"  # trained through pneunet_env.wrappers.PressureSetpoint: a setpoint model


class _Payload:
    """A pickle whose loading creates a marker file (what an attacker's ``vecnormalize.pkl`` would do, and worse)."""

    def __init__(self, marker: Path) -> None:
        self.marker = marker

    def __reduce__(self):
        return (exec, (f"open({str(self.marker)!r}, 'w').close()",))


def _vecnormalize(steps: int = 30):
    """A ``VecNormalize`` on Pendulum whose statistics have moved (both observation and return)."""
    import gymnasium as gym
    from stable_baselines3.common.vec_env import DummyVecEnv, VecNormalize

    vn = VecNormalize(DummyVecEnv([lambda: gym.make("Pendulum-v1")] * 2), gamma=0.97, clip_obs=7.0, clip_reward=4.0)
    vn.seed(0)
    vn.reset()
    rng = np.random.default_rng(0)
    for _ in range(steps):
        vn.step(rng.uniform(-2, 2, (2, 1)).astype(np.float32))
    return vn


# ------------------------------------------------------------------------------------------------ 1. no unnamed pickle
def test_resume_from_another_folder_never_unpickles_the_statistics_beside_it(tmp_path, cli):
    """Before: ``--resume OTHER/model_256_steps.zip`` unpickled ``OTHER/model_vecnormalize_256_steps.pkl`` (its code
    ran), then failed with an ``AttributeError`` traceback."""
    pytest.importorskip("stable_baselines3")
    other = tmp_path / "other"
    other.mkdir()
    shutil.copyfile(KITCHEN, other / "model_256_steps.zip")
    marker = tmp_path / "pickle-ran"
    pkl = other / "model_vecnormalize_256_steps.pkl"
    pkl.write_bytes(pickle.dumps(_Payload(marker)))
    rc, _, err = cli(["train", "--config", "ppo", "--run-dir", str(tmp_path / "run"), "--resume",
                       str(other / "model_256_steps.zip"), "--timesteps", "512", "--n-envs", "2", "--vec-env", "dummy",
                       "--no-progress"])
    assert not marker.exists()  # never unpickled
    assert rc not in (0, None)
    line = err.strip().splitlines()[-1]
    assert str(pkl) in line and "--resume-vecnormalize" in line and "Traceback" not in err
    assert not (tmp_path / "run").exists()  # refused before the work starts


def test_resume_vecnormalize_needs_resume(tmp_path, cli):
    rc, _, err = cli(["train", "--config", "ppo", "--run-dir", str(tmp_path / "run"), "--resume-vecnormalize",
                       str(tmp_path / "s.json")])
    assert rc not in (0, None) and "--resume-vecnormalize" in err and "needs --resume" in err


def test_resume_statistics_come_from_json_a_named_file_or_the_runs_own_pickle(tmp_path):
    pytest.importorskip("stable_baselines3")
    from agents.policies.sb3 import NormalizationStats
    from agents.training.export import resume_stats

    vn = _vecnormalize()
    want = NormalizationStats.from_vecnormalize(vn).to_dict()
    run, other = tmp_path / "run", tmp_path / "other"
    for folder in (run / "checkpoints", other):
        folder.mkdir(parents=True)
        shutil.copyfile(KITCHEN, folder / "model_64_steps.zip")
    marker = tmp_path / "pickle-ran"
    evil = pickle.dumps(_Payload(marker))
    # the JSON beside a checkpoint is read, and the pickle beside it is not (wherever it is)
    for folder in (run / "checkpoints", other):
        NormalizationStats.from_vecnormalize(vn).save(folder / "model_vecnormalize_64_steps.json")
        (folder / "model_vecnormalize_64_steps.pkl").write_bytes(evil)
        assert resume_stats(folder / "model_64_steps.zip", run).to_dict() == want
    assert not marker.exists()
    # a pickle alone, outside the run folder: refused by name, never loaded
    (other / "model_vecnormalize_64_steps.json").unlink()
    with pytest.raises(ValueError, match="--resume-vecnormalize") as info:
        resume_stats(other / "model_64_steps.zip", run)
    assert str(other / "model_vecnormalize_64_steps.pkl") in str(info.value) and not marker.exists()
    # ... unless named (it is then trusted: the user said so)
    good = tmp_path / "named.pkl"
    good.write_bytes(pickle.dumps(vn))
    assert resume_stats(other / "model_64_steps.zip", run, named=good).to_dict() == want
    assert resume_stats(other / "model_64_steps.zip", run, named=run / "checkpoints" /
                        "model_vecnormalize_64_steps.json").to_dict() == want
    # the run's own pickle, in its --run-dir (a checkpoint of a version before checkpoints carried JSON)
    (run / "checkpoints" / "model_vecnormalize_64_steps.json").unlink()
    (run / "checkpoints" / "model_vecnormalize_64_steps.pkl").write_bytes(pickle.dumps(vn))
    assert resume_stats(run / "checkpoints" / "model_64_steps.zip", run).to_dict() == want
    # no statistics at all: refused (a trained model would go on with fresh ones), naming the checkpoint
    (other / "model_vecnormalize_64_steps.pkl").unlink()
    with pytest.raises(ValueError, match="no normalisation statistics beside"):
        resume_stats(other / "model_64_steps.zip", run)
    vn.close()


def test_statistics_as_numbers_rebuild_what_vecnormalize_load_rebuilds(tmp_path):
    """``NormalizationStats.to_vecnormalize`` (what ``--resume`` now does) == ``VecNormalize.load`` of the pickle
    (what it did): the same settings, statistics and normalised observations and rewards, bit for bit."""
    pytest.importorskip("stable_baselines3")
    import gymnasium as gym
    from stable_baselines3.common.vec_env import DummyVecEnv, VecNormalize

    from agents.policies.sb3 import NormalizationStats

    vn = _vecnormalize()
    vn.save(tmp_path / "vn.pkl")
    fresh = lambda: DummyVecEnv([lambda: gym.make("Pendulum-v1")] * 2)  # noqa: E731
    old = VecNormalize.load(str(tmp_path / "vn.pkl"), fresh())
    new = NormalizationStats.from_vecnormalize(vn).to_vecnormalize(fresh())
    for name in ("norm_obs", "norm_reward", "clip_obs", "clip_reward", "gamma", "epsilon", "training"):
        assert getattr(new, name) == getattr(old, name), name
    for name in ("obs_rms", "ret_rms"):
        a, b = getattr(new, name), getattr(old, name)
        np.testing.assert_array_equal(a.mean, b.mean)
        np.testing.assert_array_equal(a.var, b.var)
        assert a.count == b.count
    np.testing.assert_array_equal(new.returns, old.returns)
    obs = np.random.default_rng(1).normal(0, 3, (5, 3)).astype(np.float32)
    np.testing.assert_array_equal(new.normalize_obs(obs), old.normalize_obs(obs))
    np.testing.assert_array_equal(new.normalize_reward(np.arange(5.0)), old.normalize_reward(np.arange(5.0)))
    # statistics of another observation are named
    wide = NormalizationStats.from_vecnormalize(vn)
    wide.obs_rms.mean, wide.obs_rms.var = np.zeros(4), np.ones(4)
    with pytest.raises(ValueError, match=r"the_file: obs_rms has shape \(4,\)"):
        wide.to_vecnormalize(fresh(), source="the_file")
    for env in (vn, old, new):
        env.close()


@pytest.mark.slow  # two short training runs (about 10 s)
@pytest.mark.filterwarnings("ignore::UserWarning")
def test_a_run_resumes_from_its_checkpoints_json_statistics_not_their_pickle(tmp_path, cli):
    """A checkpoint carries its statistics as JSON: ``--resume`` goes on from them; the pickle beside it (here replaced
    by a hostile one) is never loaded."""
    pytest.importorskip("stable_baselines3")
    from agents.policies.sb3 import NormalizationStats

    run = tmp_path / "run"
    smoke = ["train", "--config", "ppo", "--run-dir", str(run), "--n-envs", "2", "--eval-freq", "256",
             "--n-eval-episodes", "2", "--checkpoint-freq", "256", "--vec-env", "dummy", "--no-progress"]
    assert cli([*smoke, "--timesteps", "512"])[0] == 0
    ckpt = run / "checkpoints"
    stats = NormalizationStats.load(ckpt / "model_vecnormalize_512_steps.json")
    assert stats.norm_reward and stats.ret_rms.count > 1
    marker = tmp_path / "pickle-ran"
    for pkl in ckpt.glob("*.pkl"):
        pkl.write_bytes(pickle.dumps(_Payload(marker)))
    rc, out, err = cli([*smoke, "--timesteps", "768", "--resume"])
    assert rc == 0, err
    assert not marker.exists()
    record = json.loads((run / "run.json").read_text())
    assert record["timesteps"] == 768 and record["invocations"][-1]["resumed_from"].endswith("model_512_steps.zip")


# ------------------------------------------------------------------------------------- 2. a sidecar that contradicts
def _lie(folder: Path, **changes) -> Path:
    """``folder/lie.zip``: the kitchen model (a setpoint model), with its sidecar changed by ``changes``."""
    folder.mkdir(parents=True, exist_ok=True)
    shutil.copyfile(KITCHEN, folder / "lie.zip")
    shutil.copyfile(KITCHEN.with_name("ppo_kitchen_vecnormalize.json"), folder / "lie_vecnormalize.json")
    meta = json.loads(KITCHEN.with_suffix(".json").read_text())
    meta.update(changes)
    (folder / "lie.json").write_text(json.dumps(meta))
    return folder / "lie.zip"


def test_a_sidecar_that_contradicts_its_models_hyperparameters_is_refused_by_name(tmp_path):
    """Before: a sidecar saying ``"action": "rate"`` beside a model whose recorded hyperparameters name the
    ``PressureSetpoint`` wrapper was believed (demo scored it 25 % instead of 85 %)."""
    pytest.importorskip("stable_baselines3")
    from agents.policies.registry import make_policy

    lie = _lie(tmp_path, action="rate")
    with pytest.raises(ValueError) as info:
        make_policy(str(lie))
    msg = str(info.value)
    assert str(tmp_path / "lie.json") in msg and "'rate'" in msg and "'setpoint'" in msg
    assert "pneunet_env.wrappers.PressureSetpoint" in msg
    # the mode given explicitly wins over the contradicting file, with a warning naming it
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        entry = make_policy(f"{lie}:action=setpoint")
    assert entry.policy.action_mode == "setpoint"
    assert any("lie.json" in str(w.message) and "contradicts" in str(w.message) for w in caught)
    # the truth is accepted: the sidecar as shipped, and a sidecar whose hyperparameters say nothing about the mode
    assert make_policy(str(_lie(tmp_path / "true"))).policy.action_mode == "setpoint"
    meta = json.loads(KITCHEN.with_suffix(".json").read_text())["hyperparameters"]
    quiet = {k: v for k, v in meta.items() if k not in ("env_wrapper", "vec_env_wrapper")}
    assert make_policy(str(_lie(tmp_path / "quiet", action="rate", hyperparameters=quiet))).policy.action_mode \
        == "rate"
    # a training whose wrapper is null was a rate model: a sidecar saying setpoint contradicts it
    with pytest.raises(ValueError, match="name no wrapper"):
        make_policy(str(_lie(tmp_path / "null", action="setpoint", hyperparameters={**meta, "env_wrapper": None})))


def test_a_run_record_that_contradicts_itself_is_refused(tmp_path):
    pytest.importorskip("stable_baselines3")
    from agents.policies.registry import make_policy

    run = tmp_path / "run"
    run.mkdir()
    shutil.copyfile(KITCHEN, run / "best_model.zip")
    (run / "run.json").write_text(json.dumps({"algo": "ppo", "action": "rate", "hyperparameters": {
        "env_wrapper": "pneunet_env.wrappers.PressureSetpoint"}}))
    with pytest.raises(ValueError, match=r"run\.json.*contradicts itself.*'rate'.*'setpoint'"):
        make_policy(str(run / "best_model.zip"))
