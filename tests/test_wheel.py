"""The built wheel is complete: installed from it (not editable), ``pneunet-grasp demo`` runs from any directory.

A plain ``pip install .`` ships only what ``[tool.setuptools]`` in ``pyproject.toml`` declares; the tuned ramps
(``agents/best_ramp.json``, ``agents/best_rigid.json``) and the trained model (``agents/models/``) are read next
to the code, so a wheel without them breaks the demo while every in-repo test still passes.

How the test keeps the repository out of the picture:

* the wheel is built from a snapshot of the source tree in a temporary folder, so no ``build/`` or
  ``*.egg-info`` lands in the repository, and none left there from an earlier build (``SOURCES.txt`` lists
  files that setuptools would ship again) can hide a missing declaration;
* the venv is made without ``--system-site-packages``; instead a ``.pth`` file in it lists this interpreter's
  package folders (minus the repository), so the dependencies (numpy, gymnasium, ...) are found while the
  ``.pth`` files in those folders are *not* run: the ``__editable__`` finder of a ``pip install -e .``, which
  would quietly serve any module missing from the wheel from the repository, is never installed. (It also works
  when the tests themselves run inside a venv, where ``--system-site-packages`` would see the base interpreter's
  packages, not this one's);
* every command runs in a fresh empty folder, without ``PYTHONPATH`` and without the user site;
* a venv inside the repository (``.venv``, where the README puts it) is this interpreter's, not the repository's
  source: its site-packages are listed like any other.

Slow (about 10-20 s: a wheel build, a venv and the demo): ``python -m pytest tests/test_wheel.py -m slow``.
"""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
import sysconfig
from pathlib import Path

import pytest

pytestmark = pytest.mark.slow

ROOT = Path(__file__).resolve().parents[1]
PACKAGES = ("pneunet_env", "agents")

# Mirrors .gitignore (plus .git): what a clean checkout does not have.
_IGNORE_ANYWHERE = {"__pycache__", "build", "dist", ".pytest_cache", ".ruff_cache", ".hypothesis", ".venv"}
_IGNORE_AT_ROOT = {".git", "out", "runs"}
_IGNORE_SUFFIXES = (".pyc", ".pyo", ".pyd", ".so", ".egg-info")

# Run by the venv's python (-I: no PYTHONPATH, no user site, no cwd on sys.path) from an empty folder.
_PROBE = r"""
import json, sys, sysconfig
from pathlib import Path

import agents
import agents.policies.registry
import agents.policies.sb3
import pneunet_env
import pneunet_env.cli
import pneunet_env.cli.demo

reg = agents.policies.registry
model = reg.DEFAULT_MODEL
vecnorm = agents.policies.sb3.vecnormalize_path(model)
data = [reg.BEST_RAMP_PATH, reg.BEST_RIGID_PATH, reg.BEST_RAMP_PAPER_PATH,
        model, model.with_suffix(".json")]
print(json.dumps({
    "purelib": sysconfig.get_paths()["purelib"],
    "pneunet_env": pneunet_env.__file__,
    "agents": agents.__file__,
    "data": {str(p): p.is_file() for p in data},
    "vecnormalize": None if vecnorm is None else str(vecnorm),
    "modules": {name: getattr(mod, "__file__", None) for name, mod in sys.modules.items()
                if name.split(".")[0] in ("pneunet_env", "agents")},
    "meta_path": [getattr(f, "__name__", type(f).__name__) for f in sys.meta_path],
    "sys_path": sys.path,
}))
"""


def _ignore(folder: str, names: list[str]) -> set[str]:
    at_root = Path(folder).resolve() == ROOT
    return {n for n in names
            if n in _IGNORE_ANYWHERE or n.endswith(_IGNORE_SUFFIXES) or (at_root and n in _IGNORE_AT_ROOT)}


def _clean_env() -> dict[str, str]:
    env = {k: v for k, v in os.environ.items() if k not in ("PYTHONPATH", "PYTHONHOME", "PYTHONUSERBASE",
                                                            "PYTHONSTARTUP", "PYTHONSAFEPATH", "VIRTUAL_ENV")}
    env["PYTHONNOUSERSITE"] = "1"
    env["PYTHONDONTWRITEBYTECODE"] = "1"
    env["PIP_DISABLE_PIP_VERSION_CHECK"] = "1"
    return env


def _run(cmd: list[str], *, cwd: Path, env: dict[str, str], timeout: float, what: str,
         check: bool = True) -> subprocess.CompletedProcess:
    cmd = [str(c) for c in cmd]
    try:
        res = subprocess.run(cmd, cwd=cwd, env=env, capture_output=True, text=True, timeout=timeout)
    except subprocess.TimeoutExpired as exc:
        pytest.fail(f"{what}: timed out after {timeout} s\n$ {' '.join(cmd)}\n"
                    f"--- stdout ---\n{exc.stdout or ''}\n--- stderr ---\n{exc.stderr or ''}")
    if check and res.returncode != 0:
        pytest.fail(_report(res, what))
    return res


def _report(res: subprocess.CompletedProcess, what: str) -> str:
    return (f"{what}: exit code {res.returncode}\n$ {' '.join(res.args)}\n"
            f"--- stdout (last 6000 chars) ---\n{res.stdout[-6000:]}\n"
            f"--- stderr (last 6000 chars) ---\n{res.stderr[-6000:]}")


def _dependency_paths() -> list[str]:
    """This interpreter's package folders (site-packages and what its .pth files add), minus the repository."""
    stdlib = {Path(sysconfig.get_paths()[k]).resolve() for k in ("stdlib", "platstdlib")}
    prefix = Path(sys.prefix).resolve()  # this interpreter's own folders: a venv at ROOT/.venv, as the README puts it
    out: list[str] = []
    for entry in sys.path:
        if not entry or not Path(entry).is_dir():
            continue
        p = Path(entry).resolve()
        in_repo = p == ROOT or (ROOT in p.parents and not (p == prefix or prefix in p.parents))
        if in_repo or p in stdlib or (p.parent in stdlib and p.name == "lib-dynload"):
            continue
        if str(p) not in out:
            out.append(str(p))
    return out


def _under(path: str | None, folder: Path) -> bool:
    return path is not None and folder in Path(path).resolve().parents


def _files(folder: Path) -> set[str]:
    return {p.relative_to(folder).as_posix() for p in folder.rglob("*")
            if p.is_file() and "__pycache__" not in p.parts and not p.name.endswith((".pyc", ".pyo"))}


@pytest.fixture(scope="module")
def installed(tmp_path_factory: pytest.TempPathFactory) -> dict:
    """Build the wheel from a snapshot of the repo, install it (no deps) into a fresh venv."""
    tmp = tmp_path_factory.mktemp("wheel")
    env = _clean_env()
    src = tmp / "src"
    shutil.copytree(ROOT, src, ignore=_ignore)
    wheelhouse = tmp / "wheelhouse"
    _run([sys.executable, "-m", "pip", "wheel", src, "--no-deps", "--no-build-isolation", "--no-index",
          "-w", wheelhouse], cwd=tmp, env=env, timeout=300, what="building the wheel")
    wheels = sorted(wheelhouse.glob("pneunet_env-*.whl"))
    assert len(wheels) == 1, f"expected one pneunet_env wheel in {wheelhouse}, found {[w.name for w in wheels]}"

    venv = tmp / "venv"
    _run([sys.executable, "-m", "venv", "--without-pip", venv], cwd=tmp, env=env, timeout=120,
         what="creating the venv")
    bindir = venv / ("Scripts" if os.name == "nt" else "bin")
    python = bindir / ("python.exe" if os.name == "nt" else "python")
    res = _run([python, "-I", "-c", "import sysconfig; print(sysconfig.get_paths()['purelib'])"], cwd=tmp, env=env,
               timeout=60, what="asking the venv for its site-packages")
    purelib = Path(res.stdout.strip()).resolve()
    assert purelib.is_dir() and venv.resolve() in purelib.parents, res.stdout
    # Plain paths in a .pth file are appended to sys.path; the .pth files inside them are not executed.
    (purelib / "_pneunet_test_dependencies.pth").write_text("\n".join(_dependency_paths()) + "\n")

    _run([python, "-I", "-m", "pip", "install", "--no-deps", "--no-index", wheels[0]], cwd=tmp, env=env,
         timeout=300, what="installing the wheel into the venv")
    return {"tmp": tmp, "src": src, "wheel": wheels[0], "python": python, "bindir": bindir, "purelib": purelib,
            "env": env}


def test_installed_modules_come_from_the_wheel(installed: dict, tmp_path: Path) -> None:
    res = _run([installed["python"], "-I", "-c", _PROBE], cwd=tmp_path, env=installed["env"], timeout=120,
               what="importing the installed package")
    info = json.loads(res.stdout.strip().splitlines()[-1])
    purelib = installed["purelib"]
    assert Path(info["purelib"]).resolve() == purelib
    context = (f"\npurelib: {purelib}\nsys.meta_path: {info['meta_path']}\nsys.path: {info['sys_path']}"
               f"\nstderr: {res.stderr[-3000:]}")
    for pkg in PACKAGES:
        assert _under(info[pkg], purelib), f"{pkg} imported from {info[pkg]}, not from the installed wheel" + context
    outside = {name: f for name, f in info["modules"].items() if f is not None and not _under(f, purelib)}
    assert not outside, f"modules imported from outside the installed wheel: {outside}" + context
    missing = [p for p, ok in info["data"].items() if not ok]
    assert not missing, f"runtime data files missing from the installed package: {missing}" + context
    for p in info["data"]:
        assert _under(p, purelib), p
    assert info["vecnormalize"] is not None and _under(info["vecnormalize"], purelib), info["vecnormalize"]


def test_wheel_ships_every_file_of_the_packages(installed: dict) -> None:
    """Every module and data file under pneunet_env/ and agents/ in the source tree is installed."""
    for pkg in PACKAGES:
        source = _files(installed["src"] / pkg)
        if pkg == "agents":  # configs/ ships inside agents/ (setup.py): a wheel-only user finds them by name
            source |= {f"configs/{f}" for f in _files(installed["src"] / "configs")
                       if f.endswith((".yaml", ".best_ramp.json"))}
        shipped = _files(installed["purelib"] / pkg)
        missing = sorted(source - shipped)
        assert not missing, (f"{pkg}: files in the source tree but not in {installed['wheel'].name} (declare them in "
                             f"[tool.setuptools.package-data] or [tool.setuptools.packages.find]): {missing}")


def test_demo_runs_from_the_installed_wheel(installed: dict, tmp_path: Path) -> None:
    script = installed["bindir"] / ("pneunet-grasp.exe" if os.name == "nt" else "pneunet-grasp")
    assert script.is_file(), f"no console script {script}"
    res = _run([script, "demo"], cwd=tmp_path, env=installed["env"], timeout=600, what="pneunet-grasp demo",
               check=False)
    assert res.returncode == 0, _report(res, "pneunet-grasp demo (installed wheel)")
    assert "best-ramp" in res.stdout, _report(res, "pneunet-grasp demo printed no best-ramp row")
    assert not any(tmp_path.iterdir()), f"demo wrote into its working directory: {list(tmp_path.iterdir())}"


def test_shipped_model_loads(installed: dict, tmp_path: Path) -> None:
    """The trained PPO model in agents/models/ loads, with its VecNormalize statistics, from the installed copy."""
    probe = ("import json, agents.policies.registry as pol\n"
             "e = pol.make_policy(str(pol.DEFAULT_MODEL))\n"
             "print(json.dumps({'path': str(e.policy.path), 'vecnormalize': str(e.policy.vecnormalize_path),"
             " 'normalized': e.policy._norm is not None}))")
    find = _run([installed["python"], "-I", "-c", "import importlib.util as u; "
                 "print(all(u.find_spec(m) for m in ('stable_baselines3', 'torch')))"],
                cwd=tmp_path, env=installed["env"], timeout=60, what="looking for stable-baselines3")
    if find.stdout.strip() != "True":
        pytest.skip("stable-baselines3 / torch not installed (the rl extra)")
    res = _run([installed["python"], "-I", "-c", probe], cwd=tmp_path, env=installed["env"], timeout=300,
               what="loading the shipped PPO model")
    info = json.loads(res.stdout.strip().splitlines()[-1])
    purelib = installed["purelib"]
    assert _under(info["path"], purelib) and _under(info["vecnormalize"], purelib), info
    assert info["normalized"], info


def test_train_and_evaluate_from_the_installed_wheel(installed: dict, tmp_path: Path) -> None:
    """A user with the wheel alone trains from the shipped config by name, in an empty folder, and evaluates the
    result and a shipped model by name: 2,000 steps (a smoke run: that it works, not how well)."""
    find = _run([installed["python"], "-I", "-c", "import importlib.util as u; "
                 "print(all(u.find_spec(m) for m in ('stable_baselines3', 'torch', 'matplotlib')))"],
                cwd=tmp_path, env=installed["env"], timeout=60, what="looking for stable-baselines3")
    if find.stdout.strip() != "True":
        pytest.skip("stable-baselines3 / torch / matplotlib not installed (the rl and plot extras)")
    script = installed["bindir"] / ("pneunet-grasp.exe" if os.name == "nt" else "pneunet-grasp")
    res = _run([script, "train", "--config", "ppo", "--timesteps", "2048", "--n-envs", "4", "--eval-freq", "1024",
                "--n-eval-episodes", "4", "--run-dir", "run", "--export", "models/mine", "--no-progress"],
               cwd=tmp_path, env=installed["env"], timeout=600, what="pneunet-grasp train --config ppo")
    assert (tmp_path / "models" / "mine.zip").is_file(), _report(res, "no exported model")
    assert "exported the best evaluation's model" in res.stdout, res.stdout[-2000:]
    record = json.loads((tmp_path / "run" / "run.json").read_text())
    assert _under(record["config_path"], installed["purelib"]), record["config_path"]
    res = _run([script, "demo", "--objects", "8", "--policy", "models/mine.zip", "--policy", "ppo_kitchen"],
               cwd=tmp_path, env=installed["env"], timeout=600, what="pneunet-grasp demo with the trained model")
    assert "mine.zip" in res.stdout and "ppo_kitchen.zip" in res.stdout, res.stdout[-3000:]
