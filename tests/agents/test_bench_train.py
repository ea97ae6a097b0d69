"""``pneunet-grasp bench train`` prints figures (never a pass/fail on them)."""

import json

import pytest

from pneunet_env.cli import main


@pytest.mark.slow  # three short trainings: about 10 s
@pytest.mark.filterwarnings("ignore::UserWarning")
def test_bench_train_prints_and_keeps_its_figures(tmp_path, capsys):
    pytest.importorskip("stable_baselines3")
    assert main(["bench", "train", "--steps", "2048", "--threads", "1", "--json", str(tmp_path / "t.json")]) == 0
    out = capsys.readouterr().out
    assert "CartPole-v1" in out and "steps/s" in out
    res = json.loads((tmp_path / "t.json").read_text())
    r = res["pneunet"]["1"]
    assert r["steps_per_s"] > 0 and res["cartpole"]["steps_per_s"] > 0
    assert r["ratio_to_cartpole"] == pytest.approx(r["steps_per_s"] / res["cartpole"]["steps_per_s"])


def test_bench_train_rejects_bad_counts():
    pytest.importorskip("stable_baselines3")
    with pytest.raises(SystemExit, match="--steps"):
        main(["bench", "train", "--steps", "0"])
