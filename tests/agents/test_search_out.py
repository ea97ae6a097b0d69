"""Where ``pneunet-grasp search`` writes its schedule: beside a config file, never over the package's own."""

from __future__ import annotations

import hashlib

import pytest

from agents.policies import registry as policies
from pneunet_env.config import load_config


def _digest(path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()


@pytest.mark.slow  # two small searches, ~3 s each
@pytest.mark.parametrize("objects", ["use_case: null\n", ""], ids=["ranges", "catalogue"])
def test_a_config_files_search_lands_beside_it_not_over_the_shipped_schedule(tmp_path, objects):
    from pneunet_env.cli import main

    config = tmp_path / "fruit.yaml"
    config.write_text(objects + "max_pressure_kpa: 60\n")
    shipped = {p: _digest(p) for p in (policies.BEST_RAMP_PATH, policies.BEST_RAMP_PAPER_PATH)}
    rc = main(["search", "--config", str(config), "--objects", "2", "--targets", "0.5", "--durations", "20",
               "--refine", "0", "--quiet"])
    assert rc == 0
    assert (tmp_path / "fruit.best_ramp.json").is_file()
    assert {p: _digest(p) for p in shipped} == shipped, "the package's own schedule was overwritten"
    # and demo/evaluate find it there: the config's own schedule wins
    assert policies.tuned_path(load_config(config), config_path=config) == tmp_path / "fruit.best_ramp.json"
