"""numba's TBB threading layer where pip puts TBB: a venv's own ``lib/``, which the dynamic loader does not search.

``pneunet_env.physics.batched.preload_tbb`` loads ``$PREFIX/lib/libtbb.so.12`` before numba picks its layer. The slow
test builds what a user's venv is: a venv of an interpreter whose loader does not find TBB by itself (the system
Python), with ``libtbb.so.12`` in the venv's ``lib/`` and this interpreter's packages on its path, and checks that a
parallel step of the vector env runs on ``tbb``, not on numba's slower ``workqueue``.
"""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
import sysconfig
from pathlib import Path

import pytest

from pneunet_env.physics import batched

ROOT = Path(__file__).resolve().parents[2]


def test_preload_tbb_looks_only_where_it_is_told(tmp_path):
    assert batched.preload_tbb([str(tmp_path)]) is None  # no lib/ there
    (tmp_path / "lib").mkdir()
    (tmp_path / "lib" / batched.TBB_LIBRARY).write_bytes(b"not a library")
    assert batched.preload_tbb([str(tmp_path)]) is None  # a broken file is skipped, not raised


def _tbb_file() -> Path | None:
    for prefix in (sys.prefix, sys.base_prefix):
        p = Path(prefix) / "lib" / batched.TBB_LIBRARY
        if p.is_file():
            return p
    return None


@pytest.mark.slow
def test_a_venv_with_tbb_in_its_lib_runs_the_parallel_step_on_tbb(tmp_path):
    pytest.importorskip("numba")
    system = shutil.which("python3", path="/usr/bin:/bin")
    tbb = _tbb_file()
    if system is None or tbb is None or not sys.platform.startswith("linux"):
        pytest.skip("needs a system python3 and this environment's libtbb.so.12")
    version = subprocess.run([system, "-c", "import sys; print(sys.version_info[:2])"], capture_output=True,
                             text=True, timeout=60).stdout.strip()
    if version != str(sys.version_info[:2]):
        pytest.skip(f"the system python3 is {version}, not {sys.version_info[:2]}: this environment's packages")
    env = {k: v for k, v in os.environ.items() if k not in ("PYTHONPATH", "LD_LIBRARY_PATH", "NUMBA_THREADING_LAYER")}
    probe = [system, "-c", "import ctypes; ctypes.CDLL('libtbb.so.12')"]
    if subprocess.run(probe, capture_output=True, env=env, timeout=60).returncode == 0:
        pytest.skip("the system loader finds TBB by itself here: nothing to preload")
    venv = tmp_path / "venv"
    subprocess.run([system, "-m", "venv", "--without-pip", str(venv)], check=True, env=env, timeout=120)
    (venv / "lib").mkdir(exist_ok=True)
    os.symlink(tbb, venv / "lib" / batched.TBB_LIBRARY)  # where pip puts it in a venv
    site = next(venv.glob("lib/python*/site-packages"))
    paths = [str(ROOT)] + [p for p in (sysconfig.get_paths()["purelib"], sysconfig.get_paths()["platlib"])]
    (site / "outer.pth").write_text("\n".join(dict.fromkeys(paths)) + "\n")
    code = ("import numpy as np, gymnasium as gym, numba, pneunet_env\n"
            "from pneunet_env.physics import batched\n"
            "env = gym.make_vec('PneuNetGrasp-v1', num_envs=2048, parallel=True)\n"
            "env.reset(seed=0); env.step(np.zeros((2048, 1)))\n"
            "print(batched.TBB_LOADED, numba.threading_layer())\n")
    res = subprocess.run([str(venv / "bin" / "python"), "-c", code], capture_output=True, text=True, env=env,
                         cwd=tmp_path, timeout=600)
    assert res.returncode == 0, res.stderr[-2000:]
    loaded, layer = res.stdout.split()[-2:]
    assert layer == "tbb", res.stdout + res.stderr[-2000:]
    assert loaded == str(venv / "lib" / batched.TBB_LIBRARY)
