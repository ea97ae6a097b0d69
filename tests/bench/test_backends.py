"""``bench speed --backend ...``: the backend sweep (env-steps/s against N per backend and device) end to end."""

from __future__ import annotations

import json

import pytest

from pneunet_env.cli import main
from pneunet_env.physics._jit import HAVE_NUMBA

pytest.importorskip("torch")


@pytest.mark.slow
def test_backend_sweep_writes_json_png_and_compares(tmp_path, capsys):
    backends = (["numba"] if HAVE_NUMBA else []) + ["numpy", "torch"]
    rc = main(["bench", "speed", "--backend", *backends, "--device", "cpu", "--num-envs", "8", "64", "--quick",
               "--out", str(tmp_path)])
    assert rc == 0
    res = json.loads((tmp_path / "backends.json").read_text())
    assert (tmp_path / "backends.png").stat().st_size > 5000
    rows = res["rows"]
    assert {r["backend"] for r in rows} == set(backends) and {r["num_envs"] for r in rows} == {8, 64}
    for r in rows:
        assert r["steps_per_s"] > 0 and r["cartpole_steps_per_s"] > 0 and r["state_bytes_per_env"] > 0
        assert 0.0 <= r["unconverged_fraction"] <= 1.0
        if HAVE_NUMBA:
            assert r["speedup_over_numba"] > 0
    out = capsys.readouterr().out
    assert "CartPoleVec" in out and "torch (cpu)" in out


def test_backend_sweep_rejects_a_missing_device(tmp_path):
    with pytest.raises(SystemExit, match="not available"):
        main(["bench", "speed", "--backend", "torch", "--device", "cuda:99", "--out", str(tmp_path)])
    with pytest.raises(SystemExit, match="num-envs"):
        main(["bench", "speed", "--backend", "numpy", "torch", "--num-envs", "0", "--out", str(tmp_path)])
