"""What a newcomer meets in the first hour is never silent nor a traceback (issue 32, items 4 and 5): the tuned
schedule named with what it was tuned on (and a warning where no shipped one fits the config's objects), the first
run's compiling said once, a missing extra named in one line, ``| head`` quiet, options never abbreviated."""

from __future__ import annotations

import contextlib
import io
import os
import subprocess
import sys
import threading
from pathlib import Path

import pytest

from pneunet_env.cli import COMMANDS, COMPILE_NOTICE, _compile_notice

ROOT = Path(__file__).resolve().parents[2]

FRUIT = ("objects:\n  use_case: null\n  object_shear_modulus_kpa: [10, 300]\n  object_thickness_mm: [3, 6]\n"
         "  object_curvature_per_m: [50, 100]\n")
"""A config with its own objects (R 10-20 mm, from ranges): no shipped schedule was tuned for them."""


@pytest.fixture
def fruit(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    path = tmp_path / "fruit.yaml"
    path.write_text(FRUIT)
    return path


# ------------------------------------------------------------------------------------------------ 4a: the ramp named
def test_demo_names_the_ramp_and_what_it_was_tuned_on_and_warns_where_none_fits(fruit, cli):
    """Before: ``best-ramp (42 kPa over 50 steps)``, the paper's 250 mm ring's ramp on 10-20 mm fruit, unsaid."""
    rc, out, err = cli(["demo", "--config", "fruit.yaml", "--objects", "2"])
    assert rc == 0
    assert ("tuned schedules: best-ramp: agents/best_ramp_paper.json, tuned on the paper's task (its 250 mm ring); "
            "rigid: agents/best_rigid_paper.json, tuned on the paper's task (its 250 mm ring)") in out
    lines = err.splitlines()
    assert len(lines) == 1, err  # one warning line, on stderr
    line = lines[0]
    assert line.startswith("pneunet-grasp demo: warning: no shipped schedule was tuned for this config's objects: ")
    assert "best-ramp runs agents/best_ramp_paper.json" in line and "rigid runs agents/best_rigid_paper.json" in line
    # the command that tunes one, written beside the config, where demo then finds it
    assert "pneunet-grasp search --config fruit.yaml --out fruit.best_ramp.json" in line
    assert "pneunet-grasp search --gripper rigid --config fruit.yaml --out fruit.best_rigid.json" in line


def test_demo_on_the_objects_its_ramp_was_tuned_on_names_it_and_does_not_warn(tmp_path, monkeypatch, cli):
    monkeypatch.chdir(tmp_path)
    rc, out, err = cli(["demo", "--objects", "1", "--policy", "best-ramp"])
    assert rc == 0 and err == ""
    assert ("tuned schedules: best-ramp: agents/best_ramp.json, tuned on the default task (the catalogue's "
            "'kitchen' use case)") in out
    rc, out, err = cli(["demo", "--task", "paper", "--bins", "1", "--episodes", "1", "--policy", "best-ramp"])
    assert rc == 0 and err == ""
    assert "best-ramp: agents/best_ramp_paper.json, tuned on the paper's task (its 250 mm ring)" in out


def test_demo_on_the_papers_task_with_other_objects_suggests_the_papers_settings(tmp_path, monkeypatch, cli):
    monkeypatch.chdir(tmp_path)
    rc, _, err = cli(["demo", "--task", "paper", "--bins", "1", "--episodes", "1", "--policy", "best-ramp", "--set",
                       "object_curvature_per_m=20"])
    assert rc == 0 and len(err.splitlines()) == 1
    assert ("pneunet-grasp search --set use_case=null --set class_weights=null --set damage_rule=crush_fraction "
            "--set shape=ring --set hold_rule=slab --set object_curvature_per_m=20 --out best_ramp.json") in err
    assert "then pass --policy best-ramp:path=best_ramp.json" in err  # no config file to put it beside


def test_evaluate_names_the_ramp_and_warns_as_the_demo_does(fruit, cli):
    rc, out, err = cli(["evaluate", "--config", "fruit.yaml", "--policy", "best-ramp", "--stiffness-grid", "1",
                         "--episodes", "1", "--no-plots", "--out", "ev"])
    assert rc == 0
    assert "tuned schedules: best-ramp: agents/best_ramp_paper.json, tuned on the paper's task" in out
    assert err.startswith("pneunet-grasp evaluate: warning: no shipped schedule") and len(err.splitlines()) == 1
    assert "pneunet-grasp search --config fruit.yaml --out fruit.best_ramp.json" in err
    summary = (fruit.parent / "ev" / "evaluation_summary.json").read_text()
    assert "tuned on the paper's task" in summary  # the policies' record says it too


def test_schedule_origin_beside_a_config_and_by_path(tmp_path):
    import json

    from agents.policies.registry import BEST_RAMP_PATH, make_policy
    from pneunet_env.config import load_config

    cfg_path = tmp_path / "soft.yaml"
    cfg_path.write_text(FRUIT)
    ramp = {"kind": "linear_ramp", "target": 0.5, "n_steps": 10}
    (tmp_path / "soft.best_ramp.json").write_text(json.dumps(ramp))
    entry = make_policy("best-ramp", load_config(cfg_path), config_path=cfg_path)
    assert entry.tuned_on == "soft.best_ramp.json, tuned for the config soft.yaml (beside it)"
    assert entry.fits_objects is True
    # other objects on top of the config (--set): that schedule was not tuned for them
    moved = load_config(cfg_path, object_curvature_per_m=[40, 60])
    assert make_policy("best-ramp", moved, config_path=cfg_path).fits_objects is False
    # a file given by path=: what it was tuned on is not known, so no warning either way
    other = make_policy(f"best-ramp:path={tmp_path / 'soft.best_ramp.json'}", load_config())
    assert other.fits_objects is None and "given by path=" in other.tuned_on
    packaged = make_policy(f"best-ramp:path={BEST_RAMP_PATH}", load_config(use_case="lab_bench"))
    assert packaged.fits_objects is False and "tuned on the default task" in packaged.tuned_on
    # the label itself is unchanged (plots' legends)
    assert entry.label == "best-ramp (30 kPa over 10 steps; from soft.best_ramp.json)"
    assert make_policy("oracle").tuned_on == "" and make_policy("oracle").fits_objects is None


# ------------------------------------------------------------------------------------------------ 4b: compiling, said
class _Terminal(io.StringIO):
    def isatty(self) -> bool:
        return True


def test_a_cold_numba_cache_is_said_once_and_a_warm_one_not(tmp_path, monkeypatch):
    """The notice fires on numba's compilation of a disk-cached function (a cold cache), once per command; a function
    loaded from the cache, or one without a disk cache, says nothing."""
    numba = pytest.importorskip("numba")
    from pneunet_env.physics import _jit

    if not _jit.HAVE_NUMBA:
        pytest.skip("numba is disabled")
    (tmp_path / "cold_module_for_notice.py").write_text(
        "import numba\n\n@numba.njit(cache=True)\ndef f(x):\n    return x + 1\n\n"
        "@numba.njit(cache=True)\ndef g(x):\n    return x * 2\n\n@numba.njit\ndef h(x):\n    return x - 1\n")
    monkeypatch.syspath_prepend(str(tmp_path))
    monkeypatch.setattr(numba.config, "CACHE_DIR", str(tmp_path / "cache"))  # (if NUMBA_CACHE_DIR is set)
    import cold_module_for_notice as m

    err = _Terminal()
    with contextlib.redirect_stderr(err), _compile_notice("pneunet-grasp demo"):
        m.h(1)  # compiled in every process: not the cache
        assert err.getvalue() == ""
        m.f(1)
        m.g(1)  # a second cold one: said once
    assert err.getvalue() == f"pneunet-grasp demo: {COMPILE_NOTICE}\n"
    warm = _Terminal()
    with contextlib.redirect_stderr(warm), _compile_notice("pneunet-grasp demo"):
        again = numba.njit(cache=True)(m.f.py_func)  # a new process's dispatcher: loads f from the disk cache
        assert again(1) == 2 and sum(again.stats.cache_hits.values()) == 1
    assert warm.getvalue() == ""
    quiet = io.StringIO()  # not a terminal (a log, a test reading stderr): no notice, as no progress bar
    with contextlib.redirect_stderr(quiet), _compile_notice("pneunet-grasp demo"):
        numba.njit(cache=True)(lambda x: x)(1)
    assert quiet.getvalue() == ""
    after = _Terminal()
    with contextlib.redirect_stderr(after):
        numba.njit(cache=True)(lambda x: x + 2)(1)  # outside a command: the listener is gone
    assert after.getvalue() == ""


def _read_all(fd: int, into: list[bytes]) -> None:
    while True:
        try:
            chunk = os.read(fd, 4096)
        except OSError:  # the pty's other end closed
            return
        if not chunk:
            return
        into.append(chunk)


def _demo_on_a_terminal(env) -> tuple[int, str]:
    """``pneunet-grasp demo`` (one object) in a subprocess whose stderr is a terminal (a pty); its stderr."""
    import pty

    master, slave = pty.openpty()
    got: list[bytes] = []
    reader = threading.Thread(target=_read_all, args=(master, got), daemon=True)
    reader.start()
    try:
        proc = subprocess.run([sys.executable, "-m", "pneunet_env.cli", "demo", "--objects", "1", "--policy",
                               "best-ramp"], stdout=subprocess.DEVNULL, stderr=slave, env=env, cwd=ROOT,
                              timeout=300)
    finally:
        os.close(slave)
    reader.join(10)
    os.close(master)
    return proc.returncode, b"".join(got).decode(errors="replace")


@pytest.mark.slow
@pytest.mark.skipif(sys.platform == "win32", reason="a pty")
def test_the_first_demo_says_it_is_compiling_and_the_second_does_not(tmp_path):
    """Before: the first ``demo`` spent 13-25 s compiling, silently. With a fresh numba cache: the notice, once; the
    same command again (the cache warm): none. (This also holds every disk-cached function to its cache: one that
    missed it in every process, the streams' draw did, would say it again.)"""
    pytest.importorskip("numba")
    env = {**os.environ, "NUMBA_CACHE_DIR": str(tmp_path / "numba"), "PNEUNET_DISABLE_NUMBA": ""}
    env.pop("PNEUNET_DISABLE_NUMBA")
    rc, err = _demo_on_a_terminal(env)
    assert rc == 0 and err.count(COMPILE_NOTICE) == 1, err
    rc, err = _demo_on_a_terminal(env)
    assert rc == 0 and COMPILE_NOTICE not in err, err


# ------------------------------------------------------------------------------------------------ 4c: extras, named
@pytest.mark.parametrize("missing", ["stable_baselines3", "torch"])
def test_train_without_the_rl_extra_names_it_in_one_line_before_any_work(missing, tmp_path, monkeypatch, cli):
    """Before: a 14-line ``ModuleNotFoundError`` traceback."""
    import agents.training.cli

    def no_work(*a, **k):
        raise AssertionError("the config was read before the check")

    monkeypatch.setattr(agents.training.cli, "load_train_config", no_work)
    monkeypatch.setitem(sys.modules, missing, None)  # `import <missing>` raises ImportError
    rc, out, err = cli(["train", "--config", "ppo", "--run-dir", str(tmp_path / "run")])
    assert rc == 2 and out == "" and "Traceback" not in err
    assert err.count("\n") == 1 and err.startswith(f"pneunet-grasp train: {missing} is not installed")
    assert '".[rl]"' in err and "pneunet-env[rl]" in err
    assert not (tmp_path / "run").exists()


@pytest.mark.parametrize("argv", [["evaluate", "--policy", "ppo_kitchen"], ["demo", "--policy", "ppo_kitchen"]])
def test_a_model_policy_without_the_rl_extra_names_it_in_one_line(argv, tmp_path, monkeypatch, cli):
    monkeypatch.chdir(tmp_path)
    monkeypatch.setitem(sys.modules, "stable_baselines3", None)
    rc, out, err = cli([*argv, *(["--no-plots", "--out", "ev"] if argv[0] == "evaluate" else [])])
    assert rc == 2 and out == "" and "Traceback" not in err
    assert err.count("\n") == 1 and err.startswith(f"pneunet-grasp {argv[0]}: stable_baselines3 is not installed")
    assert '".[rl]"' in err


def test_evaluate_by_default_without_the_rl_extra_says_how_to_do_without(tmp_path, monkeypatch, cli):
    from agents.policies.registry import DEFAULT_MODEL

    if not DEFAULT_MODEL.is_file():
        pytest.skip("no shipped model")
    monkeypatch.chdir(tmp_path)
    monkeypatch.setitem(sys.modules, "stable_baselines3", None)
    rc, out, err = cli(["evaluate", "--no-plots", "--out", "ev"])
    assert rc == 2 and err.count("\n") == 1 and "Traceback" not in err
    assert "needed for the default policies' PPO model (ppo_kitchen.zip)" in err
    assert "or pass --policy best-ramp --policy oracle --policy rigid to do without" in err
    assert not (tmp_path / "ev" / "evaluation.json").exists()


def test_a_missing_extra_found_at_import_is_named_with_its_extra(monkeypatch, cli):
    """A command module whose import needs an optional package names the extra (before: "install the package's
    extras (see README)")."""
    import importlib

    real = importlib.import_module

    def fake(name, *a, **k):
        if name == "agents.bench.train":
            raise ModuleNotFoundError("No module named 'torch'", name="torch")
        return real(name, *a, **k)

    monkeypatch.setattr(importlib, "import_module", fake)
    monkeypatch.setitem(sys.modules, "torch", None)
    rc, out, err = cli(["bench", "train"])
    assert rc == 2 and err.count("\n") == 1
    assert err.startswith("pneunet-grasp bench train: torch is not installed") and '".[rl]"' in err


def test_a_broken_package_is_not_taken_for_a_missing_extra(monkeypatch):
    from pneunet_env.extras import missing_extra

    assert missing_extra(ModuleNotFoundError("x", name="stable_baselines3.no_such_part")) is None  # it is installed
    assert missing_extra(ModuleNotFoundError("x", name="no_such_package_at_all")) is None  # not an extra's
    monkeypatch.setitem(sys.modules, "optuna", None)
    assert missing_extra(ModuleNotFoundError("x", name="optuna")) == ("optuna", "design")


# ------------------------------------------------------------------------------------------------ 5a: | head, quiet
@pytest.mark.parametrize("argv", [["--help"], ["--version"], ["bench", "--help"], ["demo", "--help"], ["nonsense"]])
def test_a_reader_of_stdout_that_went_away_ends_it_quietly(argv):
    """``pneunet-grasp --help | head -1`` ended in a ``BrokenPipeError`` traceback. Here the pipe's reader is gone
    before the first write, every time: exit status 141 (128 + SIGPIPE), nothing on stderr."""
    read, write = os.pipe()
    os.close(read)
    try:
        proc = subprocess.run([sys.executable, "-m", "pneunet_env.cli", *argv], stdout=write,
                              stderr=subprocess.PIPE, text=True, cwd=ROOT, timeout=120)
    finally:
        os.close(write)
    if argv == ["nonsense"]:  # an error goes to stderr, which is open: said, status 2
        assert proc.returncode == 2 and "unknown command 'nonsense'" in proc.stderr
        return
    # (argparse's own help, longer than the buffer, is written at once and its OSError dropped by argparse: status 0)
    assert proc.stderr == "" and proc.returncode in ((0, 141) if argv == ["demo", "--help"] else (141,))


# ------------------------------------------------------------------------------------------------ 5d: no abbreviations
@pytest.mark.parametrize(("argv", "typed"), [
    (["demo", "--object", "50"], "--object"),  # was taken as --objects 50
    (["demo", "--polic", "oracle"], "--polic"),
    (["evaluate", "--episode", "1", "--no-plots"], "--episode"),
    (["search", "--target", "0.5"], "--target"),
])
def test_an_abbreviated_option_is_refused(argv, typed, tmp_path, monkeypatch, cli):
    monkeypatch.chdir(tmp_path)
    rc, out, err = cli(argv)
    assert rc == 2 and out == ""
    assert err.count("\n") == 1 and f"unrecognized arguments: {typed}" in err


def test_no_command_parser_abbreviates(monkeypatch):
    import importlib

    from pneunet_env.cli import _Parser

    for name, (module, help_) in COMMANDS.items():
        try:
            mod = importlib.import_module(module)
        except ImportError:  # an extra that is not installed
            continue
        parser = _Parser(prog=name, description=help_)
        mod.add_arguments(parser)
        assert parser.allow_abbrev is False, name
