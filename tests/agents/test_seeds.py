"""``pneunet-grasp train --seeds N`` (:mod:`agents.training.seeds`) and the shipped files found by name
(:mod:`agents.common.resources`)."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from agents.common import resources
from agents.training.seeds import median_seed, summarise
from pneunet_env.cli import main

ROOT = Path(__file__).resolve().parents[2]


def _scores(trained: dict[int, float], untrained: float = 0.5) -> dict:
    return {"seeds": {str(s): {"trained": {"all": x, "force-controlled": x / 2},
                               "untrained": {"all": untrained, "force-controlled": untrained / 2}}
                      for s, x in trained.items()}}


def test_median_seed_is_the_middle_score_not_the_best():
    scores = _scores({0: 0.9, 1: 0.3, 2: 0.7, 3: 0.8, 4: 0.1})
    assert median_seed(scores) == 2
    assert median_seed(_scores({5: 0.6, 6: 0.2, 7: 0.9, 8: 0.4})) == 8  # an even count: the lower middle
    assert median_seed(_scores({0: 0.5, 1: 0.5, 2: 0.5})) == 1  # ties by the seed


def test_summary_is_mean_sample_std_min_max_over_seeds():
    out = summarise(_scores({0: 0.9, 1: 0.3, 2: 0.6}))
    st = out["trained"]["all"]
    assert st["mean"] == pytest.approx(0.6) and st["std"] == pytest.approx(0.3) and (st["min"], st["max"]) == (
        0.3, 0.9) and st["n"] == 3
    assert out["untrained"]["force-controlled"]["std"] == 0.0
    empty = summarise({"seeds": {"0": {"trained": {"all": None}, "untrained": None}}})["trained"]["all"]
    assert empty["mean"] is None and empty["n"] == 0  # no objects in a group: None, not NaN (JSON has none)


def test_shipped_configs_and_models_are_found_by_name(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)  # not the repository: names, not relative paths
    assert Path(resources.resolve_config("ppo", "train")).resolve() == ROOT / "configs" / "train" / "ppo.yaml"
    assert Path(resources.resolve_config("designed-kitchen", "env")).name == "designed-kitchen.yaml"
    assert {"ppo", "sac"} <= set(resources.config_names("train"))
    assert "ppo.project" not in resources.config_names("train")
    with pytest.raises(ValueError, match=r"'pp0'.*shipped: .*ppo"):
        resources.resolve_config("pp0", "train")
    with pytest.raises(ValueError, match="no such file"):
        resources.resolve_config("elsewhere/ppo.yaml", "train")
    (tmp_path / "ppo").write_text("a file of that name wins")
    assert resources.resolve_config("ppo", "train") == "ppo"  # a path always means the file it names
    assert resources.resolve_config(None, "env") is None
    assert resources.resolve_model("ppo_kitchen") == resources.MODELS_DIR / "ppo_kitchen.zip"
    assert resources.resolve_model("nope") is None and resources.resolve_model("models/ppo_kitchen") is None
    assert "ppo_kitchen" in resources.model_names()


def test_policy_by_model_name():
    pytest.importorskip("stable_baselines3")
    from agents.policies.registry import make_policy

    entry = make_policy("ppo_kitchen")
    assert entry.policy.path == resources.MODELS_DIR / "ppo_kitchen.zip" and entry.policy.action_mode == "setpoint"
    assert make_policy("ppo_kitchen:action=rate").policy.action_mode == "rate"
    with pytest.raises(ValueError, match="ppo_kitchen"):  # the error lists the shipped models
        make_policy("ppo_kitchn")


@pytest.mark.slow  # two tiny trainings and their scoring: about 20 s
@pytest.mark.filterwarnings("ignore::UserWarning")
def test_seed_study_trains_scores_exports_the_median_and_resumes(tmp_path, capsys):
    pytest.importorskip("stable_baselines3")
    from agents.policies.registry import make_policy

    run_dir = tmp_path / "runs"
    argv = ["train", "--config", "ppo", "--seeds", "3", "--timesteps", "512", "--n-envs", "2", "--eval-freq", "256",
            "--n-eval-episodes", "4", "--objects", "12", "--run-dir", str(run_dir), "--no-progress",
            "--export", str(tmp_path / "models" / "ppo_med")]
    assert main(argv) == 0
    out = capsys.readouterr().out
    result = json.loads((run_dir / "seeds.json").read_text())
    assert result["seeds"] == [0, 1, 2] and (run_dir / "learning_curves.png").is_file()
    for s in ("0", "1", "2"):
        assert result["curves"][s]["timesteps"] == [0, 256, 512]  # step 0 is the untrained start
        assert (run_dir / f"seed-{s}" / "initial_model.zip").is_file()
        assert json.loads((run_dir / f"seed-{s}" / "run.json").read_text())["best_eval"]["timesteps"] > 0
        row = result["held_out"]["seeds"][s]
        assert 0.0 <= row["trained"]["all"] <= 1.0 and 0.0 <= row["untrained"]["all"] <= 1.0
    trained = [result["held_out"]["seeds"][s]["trained"]["all"] for s in ("0", "1", "2")]
    assert result["summary"]["trained"]["all"]["mean"] == pytest.approx(np.mean(trained))
    med = result["median_seed"]
    assert sorted(trained)[1] == result["held_out"]["seeds"][str(med)]["trained"]["all"]
    meta = json.loads((tmp_path / "models" / "ppo_med.json").read_text())
    assert meta["seed"] == med and meta["seed_study"]["seed"] == med and "median of 3 seeds" in meta[
        "seed_study"]["chosen"]
    assert make_policy(str(tmp_path / "models" / "ppo_med.zip")).policy.action_mode == "setpoint"
    assert "untrained (step 0)" in out and "median seed" in out
    # run again: every seed is done, nothing retrains, the same scores
    stamp = (run_dir / "seed-1" / "run.json").stat().st_mtime_ns
    assert main(argv) == 0
    assert "0 to train" in capsys.readouterr().out
    assert (run_dir / "seed-1" / "run.json").stat().st_mtime_ns == stamp
    assert json.loads((run_dir / "seeds.json").read_text())["held_out"] == result["held_out"]
    # a larger --timesteps extends the finished study: every seed resumes from its newest checkpoint
    longer = [("768" if a == "512" else a) for a in argv]
    assert main(longer) == 0
    assert "3 to train" in capsys.readouterr().out
    extended = json.loads((run_dir / "seeds.json").read_text())
    for s in ("0", "1", "2"):
        assert extended["curves"][s]["timesteps"] == [0, 256, 512, 768]  # the untrained start evaluated once
        record = json.loads((run_dir / f"seed-{s}" / "run.json").read_text())
        assert record["timesteps"] == 768 and [i["start_timesteps"] for i in record["invocations"]] == [0, 512]


def test_seed_study_rejects_bad_counts(tmp_path):
    for flag in ("--seeds", "--jobs", "--objects"):
        args = ["train", "--config", "ppo", "--seeds", "2", "--run-dir", str(tmp_path), flag, "0"]
        with pytest.raises(SystemExit, match=flag):
            main(args)
    with pytest.raises(SystemExit, match="--resume"):
        main(["train", "--config", "ppo", "--seeds", "2", "--resume", "--run-dir", str(tmp_path)])


def test_the_command_line_takes_shipped_env_configs_by_name(tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    with pytest.raises(SystemExit) as err:
        main(["demo", "--config", "designed-kitchn"])
    assert err.value.code == 2
    line = capsys.readouterr().err.strip()  # one line naming the value, the shipped names listed
    assert "\n" not in line and "designed-kitchen" in line
    assert line.startswith("pneunet-grasp demo: error: --config 'designed-kitchn'")
    assert main(["solve", "--stiffness", "1e-3"]) == 0  # a command without --config is untouched


def test_a_seed_run_is_resumed_only_with_its_own_settings(tmp_path):
    from agents.training.seeds import _check_settings, _done

    hp = {"seed": 0, "n_timesteps": 1000, "max_train_minutes": 10.0, "torch_threads": 1, "n_envs": 16,
          "env_kwargs": {"observe_volume": True}}
    run = tmp_path / "seed-0"
    run.mkdir()
    assert not _done(run, hp)
    (run / "run.json").write_text('{"timesteps": 10')  # a cut write: not done, and no crash
    assert not _done(run, hp)
    _check_settings(run, hp)
    (run / "run.json").write_text(json.dumps({"timesteps": 1000, "hyperparameters": {**hp, "n_timesteps": 500}}))
    assert _done(run, hp) and not _done(run, {**hp, "n_timesteps": 2000})  # a larger budget extends it
    _check_settings(run, {**hp, "n_timesteps": 2000, "max_train_minutes": 60.0, "torch_threads": 2})
    with pytest.raises(SystemExit, match=r"other settings \(env_kwargs, n_envs\)"):
        _check_settings(run, {**hp, "n_envs": 8, "env_kwargs": {}})
