"""Odd but valid input ends in a named one-line error, or works (issue 37, item 6).

Before: ``--policy best-ramp:path=FIFO`` waited for a writer for ever; the oracle raised ``RuntimeError: the loading
path did not converge`` for a neo-Hookean material or a very soft one; a full disk, and a 5,000-character path, gave
``OSError`` tracebacks; normalisation statistics with a NaN mean, or of the wrong shape, failed inside torch or SB3
without naming the file; a 200 kB ``use_case`` was echoed whole in a 200,144-character error line.
"""

from __future__ import annotations

import errno
import json
import os
import shutil
import threading
from pathlib import Path

import numpy as np
import pytest

from pneunet_env import files
from pneunet_env.arguments import os_error_line
from pneunet_env.cli import DEBUG_ENV, main
from pneunet_env.config import load_config
from pneunet_env.yamlio import SHOWN_CHARS, cut_message, load_json_file, load_yaml_file, short_repr

ROOT = Path(__file__).resolve().parents[2]
LONG = "a" * 5000
"""A 5,000-character name: past any file system's NAME_MAX (255) and Linux's PATH_MAX (4,096)."""


@pytest.fixture(autouse=True)
def _no_debug(monkeypatch):
    monkeypatch.delenv(DEBUG_ENV, raising=False)
    monkeypatch.setenv("MPLBACKEND", "Agg")


def _run(argv, capsys) -> tuple[int, str]:
    """``main(argv)``: ``(status, stderr)``."""
    try:
        rc = main(argv)
    except SystemExit as exc:
        rc = exc.code
    return rc, capsys.readouterr().err


def _one_line(command: str, rc, err: str) -> str:
    """The one error line (status 2, no traceback), without its ``pneunet-grasp CMD: error:`` prefix."""
    lines = err.splitlines()
    assert rc == 2 and "Traceback" not in err and len(lines) == 1, (rc, err[-3000:])
    prefix = f"pneunet-grasp {command}: error: "
    assert lines[0].startswith(prefix), err
    return lines[0][len(prefix):]


# ------------------------------------------------------------------------------------------------ FIFOs and devices
@pytest.fixture
def fifo(tmp_path):
    """A FIFO with no writer. Should something open it to read (and so wait for a writer), a writer comes after
    15 s and goes at once: the reader then gets an empty file, and the test fails instead of hanging."""
    if not hasattr(os, "mkfifo"):
        pytest.skip("no FIFOs here")
    path = tmp_path / "ramp.fifo"
    os.mkfifo(path)
    done = threading.Event()

    def unblock():
        if not done.wait(15):
            try:  # succeeds only where a reader waits
                os.close(os.open(path, os.O_WRONLY | os.O_NONBLOCK))
            except OSError:
                pass

    threading.Thread(target=unblock, daemon=True).start()
    yield path
    done.set()


@pytest.mark.parametrize("option", ["--policy best-ramp:path=", "--config ",
                                    f"--policy {ROOT / 'agents' / 'models' / 'ppo_kitchen.zip'}:vecnormalize="])
def test_a_fifo_as_an_input_file_is_refused_by_name(fifo, option, capsys):
    if "vecnormalize" in option:  # a pickle, named: the one reader of pickled statistics
        pytest.importorskip("stable_baselines3")
    flag, _, prefix = option.partition(" ")
    line = _one_line("demo", *_run(["demo", "--objects", "1", flag, f"{prefix}{fifo}"], capsys))
    assert "a FIFO" in line and str(fifo) in line and "not a regular file" in line, line


@pytest.mark.skipif(not os.path.exists("/dev/zero"), reason="no /dev/zero")
@pytest.mark.parametrize("option", ["--policy best-ramp:path=", "--config "])
def test_a_device_as_an_input_file_is_refused_by_name(option, capsys):
    flag, _, prefix = option.partition(" ")
    line = _one_line("demo", *_run(["demo", "--objects", "1", flag, f"{prefix}/dev/zero"], capsys))
    assert "'/dev/zero': it is a character device, not a regular file" in line, line


def test_every_yaml_and_json_reader_refuses_a_fifo_before_opening_it(fifo, tmp_path):
    for read in (load_json_file, load_yaml_file):
        with pytest.raises(ValueError, match=r"it is a FIFO \(a named pipe: reading it would wait for a writer\)"):
            read(fifo)
    with pytest.raises(ValueError, match="it is a folder, not a regular file"):
        load_json_file(tmp_path)


# ------------------------------------------------------------------------------------------------ the oracle
@pytest.mark.parametrize("override", [{"gent_limit": 1e9}, {"shear_modulus_kpa": 0.1}])
def test_the_oracle_plans_on_a_loading_path_that_ends_below_the_maximum(override):
    """A neo-Hookean material (its actuator balloons past p~ ~ 0.5: no stiffening) and a very soft one (60 kPa is
    600 mu): the loading path ends below ``max_pressure_kpa``; the oracle picks among the pressures it reaches, and
    its episode runs without a failed solve."""
    import gymnasium as gym

    from agents.evaluation.episodes import run_episode
    from agents.policies.oracle import Oracle

    config = load_config(**override)
    oracle = Oracle(config)
    env = gym.make("PneuNetGrasp-v1", config=config)
    try:
        result = run_episode(env, oracle, seed=0)
    finally:
        env.close()
    plan = oracle.plan
    assert 0.0 < plan["reached_kpa"] < config.task.max_pressure_kpa, plan
    assert 0.0 <= plan["pressure_kpa"] <= plan["reached_kpa"], plan
    assert not result["solver_failed"], result
    if "shear_modulus_kpa" in override:  # soft, but its path reaches the object: held
        assert plan["feasible"] and result["success"], (plan, result)


def test_the_oracle_runs_on_a_neo_hookean_config_from_the_command_line(tmp_path, capsys):
    config = tmp_path / "neo.yaml"
    config.write_text("actuator:\n  gent_limit: 1e9\n")
    rc, err = _run(["demo", "--objects", "2", "--policy", "oracle", "--config", str(config)], capsys)
    assert rc == 0 and "Traceback" not in err, err


# ------------------------------------------------------------------------------------------------ a full disk
class _FullDisk:
    """``os`` as :mod:`pneunet_env.files` sees it, on a full disk: every ``fsync`` (the staged file's, after its
    write) fails with ``ENOSPC``, as a write on a full disk does."""

    def __init__(self, code: int = errno.ENOSPC) -> None:
        self.code = code

    def __getattr__(self, name: str):
        return getattr(os, name)

    def fsync(self, fd: int) -> None:
        raise OSError(self.code, os.strerror(self.code))


def _files_in(folder: Path) -> list[str]:
    return sorted(str(p.relative_to(folder)) for p in folder.rglob("*") if p.is_file())


def test_a_write_on_a_full_disk_names_its_file_and_leaves_nothing(tmp_path, monkeypatch):
    old = tmp_path / "old.json"
    old.write_text('{"kept": true}\n')
    monkeypatch.setattr(files, "os", _FullDisk())
    first = tmp_path / "first.bin"
    for path in (tmp_path / "new.json", old):
        for write, args, named in ((files.atomic_write_json, (path, {"a": 1}), path),
                                   (files.atomic_write_text, (path, "a"), path),
                                   (files.atomic_write_many, ([(first, b"1"), (path, b"2")],), first)):
            with pytest.raises(OSError) as info:
                write(*args)
            assert info.value.errno == errno.ENOSPC and info.value.filename == str(named), info.value
            assert _files_in(tmp_path) == ["old.json"] and old.read_text() == '{"kept": true}\n'


def test_a_figure_on_a_full_disk_names_its_file_and_leaves_nothing(tmp_path):
    class Figure:
        def savefig(self, path, **kwargs):
            Path(path).write_bytes(b"half a PNG")
            raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))

    with pytest.raises(OSError) as info:
        files.save_figure(Figure(), tmp_path / "plot.png", close=False)
    assert info.value.errno == errno.ENOSPC and info.value.filename == str(tmp_path / "plot.png")
    assert _files_in(tmp_path) == []


def test_demo_json_on_a_full_disk_is_one_line_naming_the_file(tmp_path, monkeypatch, capsys):
    out = tmp_path / "o" / "demo.json"
    monkeypatch.setattr(files, "os", _FullDisk())
    line = _one_line("demo", *_run(["demo", "--objects", "1", "--policy", "ramp", "--json", str(out)], capsys))
    assert line == f"no space left on the device writing {str(out)!r}", line
    assert _files_in(tmp_path) == []


@pytest.mark.slow  # SB3 and torch, then a design trial: seconds each
@pytest.mark.parametrize("argv", [
    ["train", "--config", "ppo", "--timesteps", "256", "--n-envs", "2", "--eval-freq", "128", "--n-eval-episodes", "1",
     "--no-progress", "--run-dir"],
    ["design", "--trials", "1", "--objects", "4", "--held-out", "4", "--top", "1", "--quiet", "--bound",
     "top_thickness_mm=1.5:2.5", "--bound", "chamber_height_mm=5:6", "--out"]])
def test_train_and_design_on_a_full_disk_are_one_line_naming_the_file(argv, tmp_path, monkeypatch, capsys):
    pytest.importorskip("stable_baselines3" if argv[0] == "train" else "optuna")
    out = tmp_path / "out"
    monkeypatch.setattr(files, "os", _FullDisk())
    line = _one_line(argv[0], *_run([*argv, str(out)], capsys))
    assert line.startswith(f"no space left on the device writing '{out}{os.sep}"), line
    assert not [f for f in _files_in(tmp_path) if ".tmp" in f], _files_in(tmp_path)


def test_a_quota_a_read_only_disk_and_other_errors():
    path = "/runs/a/run.json"
    assert os_error_line(OSError(errno.EROFS, "Read-only file system", path)) == \
        f"a read-only file system writing {path!r}"
    if hasattr(errno, "EDQUOT"):
        assert os_error_line(OSError(errno.EDQUOT, "Disk quota exceeded", path)) == \
            f"the disk quota is exceeded writing {path!r}"
    assert os_error_line(OSError(errno.ENOSPC, "No space left on device")) == "no space left on the device (writing)"
    assert os_error_line(OSError(errno.EACCES, "Permission denied", path)) is None  # not this kind: a bug, shown


# ------------------------------------------------------------------------------------------------ too-long paths
@pytest.mark.parametrize("argv", [
    ["demo", "--objects", "1", "--config", "{long}"],
    ["demo", "--objects", "1", "--json", "{long}"],
    ["demo", "--objects", "1", "--policy", "best-ramp:path={long}"],
    ["demo", "--objects", "1", "--policy", "{long}.zip"],
    ["evaluate", "--policy", "ramp", "--no-plots", "--out", "{long}"],
    ["train", "--config", "ppo", "--run-dir", "{long}"],
])
def test_a_path_too_long_for_the_file_system_is_one_short_line(argv, tmp_path, capsys):
    long = str(tmp_path / LONG)
    line = _one_line(argv[0], *_run([a.replace("{long}", long) for a in argv], capsys))
    assert "too long" in line and "(5,0" in line and len(line) < 600, line


def test_a_too_long_output_path_is_refused_before_the_work(tmp_path):
    from pneunet_env.arguments import check_output_dir, check_output_file

    for check in (check_output_dir, check_output_file):
        with pytest.raises(ValueError, match=r"the path is too long \(a name in it is 5,000 bytes long; the file "
                                             r"system takes at most \d+\)"):
            check(tmp_path / "missing" / LONG, "--out")


# ------------------------------------------------------------------------------------------------ statistics
def _stats(mean, var=None, count=10.0) -> dict:
    data = json.loads((ROOT / "agents" / "models" / "ppo_kitchen_vecnormalize.json").read_text())
    data.update(norm_obs=True, obs_rms={"mean": mean, "var": [1.0] * len(mean) if var is None else var,
                                        "count": count})
    return data


@pytest.mark.parametrize("stats, why", [
    (_stats([float("nan")]), "must be finite numbers"), (_stats([0.1], [-1.0]), "the variance >= 0"),
    (_stats([0.1], count=float("inf")), "the count must be a finite number"),
    ({**_stats([0.1]), "gamma": 2.0}, "gamma must be in"), ({**_stats([0.1]), "epsilon": float("nan")}, "epsilon")])
def test_bad_statistics_are_refused_naming_the_file(stats, why):
    from agents.policies.sb3 import NormalizationStats

    with pytest.raises(ValueError, match=f"^stats.json: malformed statistics.*{why}"):
        NormalizationStats.from_dict(stats, "stats.json")


@pytest.mark.parametrize("mean, why", [([float("nan")], "must be finite numbers"),
                                       ([0.1, 0.2], r"have shape \(2,\), but the model observes shape \(1,\)")])
def test_a_model_with_bad_statistics_beside_it_names_the_file(mean, why, tmp_path):
    pytest.importorskip("stable_baselines3")
    from agents.policies.sb3 import SB3Policy

    for name in ("ppo_kitchen.zip", "ppo_kitchen.json"):
        shutil.copy(ROOT / "agents" / "models" / name, tmp_path / name)
    stats = tmp_path / "ppo_kitchen_vecnormalize.json"
    stats.write_text(json.dumps(_stats(mean)))
    with pytest.raises(ValueError, match=why) as info:
        SB3Policy(tmp_path / "ppo_kitchen.zip")
    assert str(stats) in str(info.value)


# ------------------------------------------------------------------------------------------------ long values
def test_a_200_kb_use_case_is_cut_in_its_error_line(tmp_path, capsys):
    value = "x" * 200_000
    config = tmp_path / "c.yaml"
    config.write_text(f"objects:\n  use_case: {value}\n")
    for argv in (["demo", "--objects", "1", "--set", f"use_case={value}"],
                 ["demo", "--objects", "1", "--config", str(config)]):
        line = _one_line("demo", *_run(argv, capsys))
        assert line.startswith("config key 'use_case' must be one of") and len(line) < 600, line[:600]
        assert line.endswith(f"got '{'x' * (SHOWN_CHARS - 4)}... (200,000 characters)"), line
    with pytest.raises(ValueError) as info:  # the library's error, too
        load_config(use_case=value)
    assert len(str(info.value)) < 600 and "(200,000 characters)" in str(info.value)


def test_cut_message_cuts_values_only():
    prose = "the model's sidecar 'a.json' says the env's action is 'rate'"
    assert cut_message(prose) == prose
    long = "y" * 1000
    cut = cut_message(f"got {long!r} and the env's {long}")
    assert cut == (f"got '{'y' * (SHOWN_CHARS - 4)}... (1,000 characters) and the env's {'y' * (SHOWN_CHARS - 3)}... "
                   f"(1,000 characters)")
    assert cut_message(cut) == cut  # cut again (a library's message, then the command line's): unchanged
    quoted = "it's " + repr("a b " * 300)
    assert cut_message(quoted) == "it's " + repr("a b " * 300)[:SHOWN_CHARS - 3] + "... (1,200 characters)"
    many = "got [" + ", ".join(["1"] * 100_000) + "]"
    cut = cut_message(many)
    assert len(cut) < 4100 and cut.endswith(f"(the message cut: {len(many):,} characters)")
    assert short_repr("z" * 5) == "'zzzzz'" and short_repr(np.arange(3)) == repr(np.arange(3))
