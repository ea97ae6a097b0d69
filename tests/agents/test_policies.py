"""SB3 models in the policy registry: statistics as numbers, no pickle loaded unless named, the shipped model."""

from __future__ import annotations

import pickle
import shutil
import warnings
from pathlib import Path

import numpy as np
import pytest

from agents.policies.registry import make_policy
from agents.policies.sb3 import NormalizationStats, RunningStats, SB3Policy, convert_vecnormalize, vecnormalize_path

MODELS = Path(__file__).resolve().parents[2] / "agents" / "models"
SHIPPED = MODELS / "ppo_pneunet.zip"

# The shipped model's outputs on p/p_max = 0, 0.05, ..., 1, computed with its statistics loaded from the old
# agents/models/ppo_pneunet_vecnormalize.pkl (before it was converted to ppo_pneunet_vecnormalize.json and removed).
OLD_SETPOINTS = [0.1858729124069214, 0.20918190479278564, 0.23868298530578613, 0.2759345769882202,
                 0.3212904930114746, 0.37267565727233887, 0.42515480518341064, 0.47232651710510254,
                 0.5087788105010986, 0.5313961505889893, 0.5387016534805298, 0.5295640230178833, 0.5029959678649902,
                 0.4599111080169678, 0.40568792819976807, 0.3498727083206177, 0.30153167247772217,
                 0.26499462127685547, 0.23991632461547852, 0.22374224662780762, 0.21369493007659912]
OLD_ACTIONS = [1.0] * 14 + [0.056879520416259766] + [-1.0] * 6
# ... and the pickle's statistics (a VecNormalize with norm_obs=False, norm_reward=True).
OLD_STATS = {"norm_obs": False, "norm_reward": True, "clip_obs": 10.0, "clip_reward": 10.0, "epsilon": 1e-08,
             "gamma": 0.999, "ret_rms": (0.20426301874185668, 0.17352485582552413, 2600000.0001)}


class _Payload:
    """A pickle whose loading creates a marker file (what an attacker's ``vecnormalize.pkl`` would do, and worse)."""

    def __init__(self, marker: Path) -> None:
        self.marker = marker

    def __reduce__(self):
        return (exec, (f"open({str(self.marker)!r}, 'w').close()",))


def _model_copy(folder: Path) -> Path:
    folder.mkdir(parents=True, exist_ok=True)
    shutil.copyfile(SHIPPED, folder / "m.zip")
    shutil.copyfile(SHIPPED.with_suffix(".json"), folder / "m.json")
    return folder / "m.zip"


def test_shipped_statistics_are_numbers_and_predictions_unchanged():
    pytest.importorskip("stable_baselines3")
    assert not (MODELS / "ppo_pneunet_vecnormalize.pkl").exists() and not list(MODELS.glob("*.pkl"))
    stats_path = vecnormalize_path(SHIPPED)
    assert stats_path == MODELS / "ppo_pneunet_vecnormalize.json"
    stats = NormalizationStats.load(stats_path)
    rms = OLD_STATS["ret_rms"]
    assert (stats.ret_rms.mean, stats.ret_rms.var, stats.ret_rms.count) == rms and stats.obs_rms is None
    assert all(getattr(stats, k) == v for k, v in OLD_STATS.items() if k != "ret_rms")

    pol = SB3Policy(SHIPPED)
    assert pol.vecnormalize_path == stats_path and isinstance(pol._norm, NormalizationStats)
    assert pol.action_mode == "setpoint"
    obs = (np.arange(21, dtype=np.float32) / 20).reshape(-1, 1)
    u, _ = pol.model.predict(pol.normalize(obs), deterministic=True)
    # float32 network outputs: equal to a few ulps (torch's CPU kernels differ in the last bit between CPUs: seen
    # 1.2e-7 on one machine of this project's kind)
    np.testing.assert_allclose(np.asarray(u, np.float32).ravel(), np.array(OLD_SETPOINTS, np.float32), rtol=2e-6,
                               atol=1e-6)
    np.testing.assert_allclose(pol(obs).ravel(), np.array(OLD_ACTIONS, np.float32), rtol=2e-6, atol=1e-6)


def test_malicious_pickle_beside_a_model_is_not_loaded(tmp_path):
    pytest.importorskip("stable_baselines3")
    model = _model_copy(tmp_path / "m")
    marker = tmp_path / "pwned"
    for name in ("m_vecnormalize.pkl", "vecnormalize.pkl"):
        (model.parent / name).write_bytes(pickle.dumps(_Payload(marker)))

    with pytest.warns(UserWarning, match="not loading"):
        pol = SB3Policy(model)
    assert not marker.exists() and pol._norm is None and pol.vecnormalize_path is None
    with pytest.warns(UserWarning, match="not loading"):
        make_policy(str(model))
    assert not marker.exists()

    # with the JSON statistics beside it: those are read, the pickles still are not (and no warning)
    shutil.copyfile(vecnormalize_path(SHIPPED), model.parent / "m_vecnormalize.json")
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        pol = SB3Policy(model)
    assert not marker.exists() and pol.vecnormalize_path == model.parent / "m_vecnormalize.json"

    # named explicitly, a pickle is loaded (this one runs: the test above is not vacuous)
    SB3Policy(model, vecnormalize=model.parent / "vecnormalize.pkl")
    assert marker.exists()


def test_normalization_stats_match_vecnormalize_bit_for_bit(tmp_path):
    """Statistics with observation normalisation on: the JSON form normalises exactly as the VecNormalize pickle,
    and a model predicts the same with either (the pickle named explicitly)."""
    pytest.importorskip("stable_baselines3")
    import gymnasium as gym
    from stable_baselines3.common.vec_env import DummyVecEnv, VecNormalize

    import pneunet_env  # noqa: F401

    vn = VecNormalize(DummyVecEnv([lambda: gym.make("PneuNetGrasp-v1")]), gamma=0.99, clip_obs=2.5)
    rng = np.random.default_rng(3)
    vn.obs_rms.update(rng.uniform(0.1, 0.6, (50, 1)))
    vn.ret_rms.update(rng.normal(size=20))
    pkl = tmp_path / "vn.pkl"
    vn.save(str(pkl))
    js = convert_vecnormalize(pkl, tmp_path / "vn.json")
    stats = NormalizationStats.load(js)
    assert stats.norm_obs and stats.clip_obs == 2.5 and stats.gamma == 0.99
    np.testing.assert_array_equal(stats.obs_rms.mean, vn.obs_rms.mean)
    obs = rng.uniform(-0.5, 1.5, (200, 1)).astype(np.float32)
    expected = vn.normalize_obs(obs)
    got = stats.normalize_obs(obs)
    assert got.dtype == expected.dtype == np.float32
    np.testing.assert_array_equal(got, expected)
    assert np.abs(got).max() == 2.5  # the clip is exercised

    model = _model_copy(tmp_path / "m")
    grid = (np.arange(41, dtype=np.float32) / 40).reshape(-1, 1)
    from_json = SB3Policy(model, vecnormalize=js)(grid)
    from_pickle = SB3Policy(model, vecnormalize=pkl)(grid)
    np.testing.assert_array_equal(from_json, from_pickle)
    assert not np.array_equal(from_json, SB3Policy(model, vecnormalize=False)(grid))  # the statistics matter
    vn.close()


def test_explicit_statistics_in_a_policy_spec(tmp_path):
    pytest.importorskip("stable_baselines3")
    model = _model_copy(tmp_path / "m")
    rms = RunningStats(np.array([0.4]), np.array([0.01]), 9.0)
    stats = NormalizationStats(True, False, 10.0, 10.0, 1e-8, 0.99, rms)
    path = stats.save(tmp_path / "elsewhere" / "stats.json")
    entry = make_policy(f"{model}:vecnormalize={path},action=rate")
    assert entry.policy.vecnormalize_path == path and entry.policy.action_mode == "rate"
    with pytest.raises(ValueError, match="unknown parameter"):
        make_policy(f"{model}:colour=blue")
    with pytest.raises(ValueError, match="no such model"):
        make_policy(str(tmp_path / "missing.zip") + ":action=rate")


@pytest.mark.parametrize("text, match", [
    ("[1, 2]", "not a normalisation statistics file"),
    ('{"format": "pneunet_env/vecnormalize-stats/1", "norm_obs": true}', "malformed"),
    ("{", "cannot read"),
])
def test_bad_statistics_files_are_rejected(tmp_path, text, match):
    path = tmp_path / "s.json"
    path.write_text(text)
    with pytest.raises(ValueError, match=match):
        NormalizationStats.load(path)


def test_statistics_save_is_atomic(tmp_path, monkeypatch):
    import os

    stats = NormalizationStats(False, True, 10.0, 10.0, 1e-8, 0.999, None, None)
    path = stats.save(tmp_path / "s.json")
    before = path.read_bytes()

    def boom(src, dst):
        raise OSError("rename failed")

    monkeypatch.setattr(os, "replace", boom)
    with pytest.raises(OSError, match="rename failed"):
        NormalizationStats(True, True, 1.0, 1.0, 1e-8, 0.9, None, None).save(path)
    assert path.read_bytes() == before and [p.name for p in tmp_path.iterdir()] == ["s.json"]


@pytest.mark.parametrize("name, volume", [("ppo_kitchen", False), ("ppo_kitchen_volume", True)])
def test_a_model_runs_on_the_env_it_was_trained_for(name, volume):
    # a model trained with observe_volume runs with it (and one trained without, without), whatever the config says;
    # before, the demo crashed inside SB3 on the observation's shape
    pytest.importorskip("stable_baselines3")
    from pneunet_env import load_config

    cfg = load_config(observe_volume=not volume)
    entry = make_policy(str(MODELS / f"{name}.zip"), cfg)
    assert entry.env_kwargs == {"observe_volume": volume}
    assert ("volume" in entry.label) == volume
    env = entry.make_env(cfg)
    obs, _ = env.reset(seed=0)
    assert obs.shape == ((2,) if volume else (1,))
    assert np.all(np.abs(entry.policy(obs)) <= 1.0)
    env.close()


def test_a_model_of_another_observation_is_refused(tmp_path):
    sb3 = pytest.importorskip("stable_baselines3")
    import gymnasium as gym

    class Wide(gym.Env):
        observation_space = gym.spaces.Box(-1.0, 1.0, (3,), np.float32)
        action_space = gym.spaces.Box(-1.0, 1.0, (1,), np.float32)

    sb3.PPO("MlpPolicy", Wide(), n_steps=8, batch_size=8, device="cpu").save(tmp_path / "wide.zip")
    with pytest.raises(ValueError, match=r"observes shape \(3,\)"):
        make_policy(str(tmp_path / "wide.zip"))


def test_a_frame_stacked_model_is_refused_not_misread(tmp_path):
    # a pressure-only model trained with frame_stack: 2 observes shape (2,): its metadata says what it is, and it is
    # refused instead of being run on observe_volume's [pressure, volume]
    pytest.importorskip("stable_baselines3")
    import json

    model = _model_copy(tmp_path)
    meta = json.loads(model.with_suffix(".json").read_text())
    meta["hyperparameters"]["frame_stack"] = 2
    model.with_suffix(".json").write_text(json.dumps(meta))
    with pytest.raises(ValueError, match="frame_stack=2"):
        make_policy(str(model))
    meta["hyperparameters"]["frame_stack"] = None
    meta["hyperparameters"]["env_kwargs"] = {"observe_volume": True}  # contradicts the model's (1,) observation
    model.with_suffix(".json").write_text(json.dumps(meta))
    with pytest.raises(ValueError, match="observe_volume=True but it observes shape"):
        make_policy(str(model))


# ---------------------------------------------------------------------------------------------------------------------
# The action mode is never guessed; a cut model is named (issue 21)
# ---------------------------------------------------------------------------------------------------------------------

KITCHEN = MODELS / "ppo_kitchen.zip"


def _bare_kitchen(folder: Path) -> Path:
    """The shipped setpoint model, copied without its sidecar JSON (its statistics kept)."""
    folder.mkdir(parents=True, exist_ok=True)
    shutil.copyfile(KITCHEN, folder / "ppo_kitchen.zip")
    shutil.copyfile(MODELS / "ppo_kitchen_vecnormalize.json", folder / "ppo_kitchen_vecnormalize.json")
    return folder / "ppo_kitchen.zip"


def test_a_model_without_its_sidecar_is_refused_not_run_as_rate(tmp_path):
    # before: it ran silently in rate mode (30 % instead of 85 % on the kitchen objects, under the same label)
    pytest.importorskip("stable_baselines3")
    model = _bare_kitchen(tmp_path)
    with pytest.raises(ValueError, match=r"cannot tell its action mode: no metadata '.*ppo_kitchen\.json'.*"
                                         r"ppo_kitchen\.zip:action=setpoint"):
        make_policy(str(model))
    with pytest.raises(ValueError, match="cannot tell its action mode"):
        SB3Policy(model)
    # the explicit mode wins, and runs the model as the sidecar would have
    entry = make_policy(f"{model}:action=setpoint")
    assert entry.policy.action_mode == "setpoint" and entry.policy.algo == "PPO"
    reference = make_policy(str(KITCHEN)).policy
    obs = (np.arange(11, dtype=np.float32) / 10).reshape(-1, 1)
    np.testing.assert_array_equal(entry.policy(obs), reference(obs))
    assert make_policy(f"{model}:action=rate").policy.action_mode == "rate"
    with pytest.raises(ValueError, match="action mode must be one of"):
        make_policy(f"{model}:action=pressure")


@pytest.mark.parametrize("text, why", [('{"algo": "ppo", "action": "setp', "unreadable"), ("[1]", "not a JSON mapping"),
                                       ("\udcff", "unreadable")])
def test_a_broken_sidecar_is_named(tmp_path, text, why):
    # before: a cut sidecar was read as no metadata at all: rate mode, silently
    pytest.importorskip("stable_baselines3")
    model = _bare_kitchen(tmp_path)
    sidecar = model.with_suffix(".json")
    sidecar.write_bytes(text.encode("utf-8", "surrogateescape"))
    with pytest.raises(ValueError, match=rf"its metadata '{sidecar}': {why}.*restore that file.*action=setpoint"):
        make_policy(str(model))
    with pytest.warns(UserWarning, match=rf"ignoring its metadata '{sidecar}'"):
        assert make_policy(f"{model}:action=setpoint").policy.action_mode == "setpoint"


def test_a_sidecar_without_action_reads_the_mode_from_its_hyperparameters(tmp_path):
    pytest.importorskip("stable_baselines3")
    import json

    model = _bare_kitchen(tmp_path)
    meta = json.loads(KITCHEN.with_suffix(".json").read_text())
    del meta["action"]
    model.with_suffix(".json").write_text(json.dumps(meta))
    assert make_policy(str(model)).policy.action_mode == "setpoint"  # env_wrapper: PressureSetpoint
    meta["hyperparameters"]["env_wrapper"] = None
    model.with_suffix(".json").write_text(json.dumps(meta))
    assert make_policy(str(model)).policy.action_mode == "rate"
    del meta["hyperparameters"]
    model.with_suffix(".json").write_text(json.dumps(meta))
    with pytest.raises(ValueError, match="says neither 'action' nor 'hyperparameters'"):
        make_policy(str(model))
    meta["action"] = "sideways"
    model.with_suffix(".json").write_text(json.dumps(meta))
    with pytest.raises(ValueError, match="gives action 'sideways'"):
        make_policy(str(model))


@pytest.mark.parametrize("cut", [0, 100, 0.5, 0.99])
def test_a_cut_model_zip_is_named(tmp_path, cut):
    # before: an AssertionError (or a BadZipFile) from deep inside stable-baselines3
    pytest.importorskip("stable_baselines3")
    data = KITCHEN.read_bytes()
    model = tmp_path / "m.zip"
    model.write_bytes(data[: int(cut * len(data)) if isinstance(cut, float) else cut])
    shutil.copyfile(KITCHEN.with_suffix(".json"), tmp_path / "m.json")
    with pytest.raises(ValueError, match=rf"model '{model}' .*(cut short|damaged)"):
        make_policy(str(model))


@pytest.mark.parametrize("spec, key", [("ramp:steps=inf", "steps"), ("ramp:steps=nan", "steps"),
                                       ("ramp:target=1e400", "target"),
                                       ("rigid:target_mm=5,travel_mm=inf", "travel_mm"),
                                       ("oracle:resolution_kpa=nan", "resolution_kpa"),
                                       ("oracle:resolution_kpa=-1", "resolution_kpa")])
def test_a_spec_with_a_non_finite_or_bad_number_is_refused_by_name_when_parsed(spec, key):
    # inf used to overflow (OverflowError), nan to pass as an unnamed error, the oracle's bad grid to wait for first use
    from agents.policies.registry import make_policy

    with pytest.raises(ValueError, match=key):
        make_policy(spec)
