"""``pneunet-grasp``: every command answers ``--help``, unknown ones exit 2, and the one progress-bar helper."""

from __future__ import annotations

import ast
import io
import os
import subprocess
import sys
from pathlib import Path

import pytest

from pneunet_env.cli import COMMANDS, GROUPS, main
from pneunet_env.progress import NoBar, add_progress_argument, progress, progress_enabled

ROOT = Path(__file__).resolve().parents[2]
LONG_COMMANDS = ("render", "evaluate", "search", "figures", "bench speed", "bench solvers", "demo")


# ------------------------------------------------------------------------------------------------ --help
@pytest.mark.parametrize("flag", ["--help", "-h"])
def test_top_level_help(flag, cli):
    rc, out, _ = cli([flag])
    assert rc == 0
    assert out.startswith("usage: pneunet-grasp")
    for name in COMMANDS:
        assert name in out


@pytest.mark.parametrize("flag", ["--help", "-h"])
@pytest.mark.parametrize("group", list(GROUPS))
def test_group_help_lists_its_sub_commands(group, flag, cli):
    rc, out, _ = cli([group, flag])
    assert rc == 0
    assert out.startswith(f"usage: pneunet-grasp {group}")
    subs = [name.split(" ", 1)[1] for name in COMMANDS if name.startswith(group + " ")]
    assert subs and all(f"  {s} " in out for s in subs)
    if group == "bench":
        assert {"speed", "solvers"} <= set(subs)


@pytest.mark.parametrize("flag", ["--help", "-h"])
@pytest.mark.parametrize("name", list(COMMANDS))
def test_every_command_answers_help(name, flag, cli):
    rc, out, err = cli([*name.split(), flag])
    assert rc == 0, err
    assert out.startswith(f"usage: pneunet-grasp {name}")
    assert COMMANDS[name][1] in " ".join(out.split())  # the one-line help is the description (argparse wraps it)
    if name in LONG_COMMANDS:
        assert "--no-progress" in out


def test_version(cli):
    from pneunet_env import __version__

    rc, out, _ = cli(["--version"])
    assert rc == 0 and out.strip() == f"pneunet-grasp {__version__}"


# ---------------------------------------------------------------------------------------------- errors
@pytest.mark.parametrize(("argv", "message"), [
    (["no-such-command"], "unknown command 'no-such-command'"),
    (["rendr"], "did you mean 'render'"),
    (["--no-such-option"], "unknown option"),
    (["bench"], "needs a sub-command"),
    (["bench", "no-such-sub"], "unknown bench sub-command 'no-such-sub'"),
    (["bench", "sped"], "did you mean 'speed'"),
])
def test_unknown_commands_exit_2(argv, message, cli):
    rc, out, err = cli(argv)
    assert rc == 2
    assert message in err and "usage: pneunet-grasp" in err
    assert out == ""


def test_a_bad_option_exits_2(cli):
    rc, _, err = cli(["solve", "--no-such-option"])
    assert rc == 2 and "unrecognized arguments" in err


# ----------------------------------------------------------------------------------------- subprocess
def _python(*args: str) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, *args], capture_output=True, text=True, timeout=60, cwd=ROOT,
                          env={**os.environ, "PYTHONPATH": str(ROOT)})


def test_python_dash_m_bench_help():
    res = _python("-m", "pneunet_env.cli", "bench", "--help")
    assert res.returncode == 0, res.stderr
    assert "speed" in res.stdout and "solvers" in res.stdout


def test_help_imports_no_command_module_nor_heavy_dependency():
    heavy = ["torch", "matplotlib", "stable_baselines3", "tqdm"]
    code = (
        "import sys\n"
        "from pneunet_env.cli import COMMANDS, main\n"
        "assert main(['--help']) == 0 and main(['bench', '--help']) == 0 and main(['nope']) == 2\n"
        f"bad = [m for m in {heavy!r} + [mod for mod, _ in COMMANDS.values()] if m in sys.modules]\n"
        "print('imported:', bad)\n"
    )
    res = _python("-c", code)
    assert res.returncode == 0, res.stderr
    assert res.stdout.strip().endswith("imported: []"), res.stdout


# ------------------------------------------------------------------------------------- progress helper
class _Terminal(io.StringIO):
    def isatty(self) -> bool:
        return True


def test_progress_is_a_passthrough_when_stderr_is_not_a_terminal(monkeypatch):
    monkeypatch.setattr(sys, "stderr", io.StringIO())
    assert not progress_enabled()
    bar = progress([1, 2, 3], desc="x")
    assert isinstance(bar, NoBar) and bar.total == 3
    assert list(bar) == [1, 2, 3]
    manual = progress(total=5, desc="y")  # the interface the commands use, all no-ops
    manual.set_description_str("z")
    manual.set_postfix_str("w")
    manual.update(2)
    manual.total += 1
    manual.refresh()
    manual.close()
    assert isinstance(manual, NoBar) and manual.total == 6
    assert sys.stderr.getvalue() == ""


def test_progress_is_a_tqdm_bar_on_stderr_when_forced_on(monkeypatch):
    tqdm = pytest.importorskip("tqdm").tqdm
    err = io.StringIO()
    monkeypatch.setattr(sys, "stderr", err)
    bar = progress(range(4), desc="forced", enabled=True)
    assert isinstance(bar, tqdm)
    assert list(bar) == [0, 1, 2, 3]
    assert "forced" in err.getvalue()


def test_progress_follows_the_terminal_and_no_progress_wins(monkeypatch):
    tqdm = pytest.importorskip("tqdm").tqdm
    monkeypatch.setattr(sys, "stderr", _Terminal())
    assert progress_enabled()
    bar = progress(total=2)
    assert isinstance(bar, tqdm)
    bar.close()
    assert isinstance(progress(total=2, enabled=False), NoBar)


def test_progress_without_tqdm_is_a_passthrough(monkeypatch):
    monkeypatch.setitem(sys.modules, "tqdm", None)  # `import tqdm` raises ImportError
    monkeypatch.setattr(sys, "stderr", _Terminal())
    bar = progress([1, 2], enabled=True)
    assert isinstance(bar, NoBar) and list(bar) == [1, 2]


def test_no_progress_flag():
    import argparse

    parser = argparse.ArgumentParser()
    add_progress_argument(parser, "--quiet")
    assert parser.parse_args([]).progress is None  # auto: on when stderr is a terminal
    assert parser.parse_args(["--no-progress"]).progress is False
    assert parser.parse_args(["--quiet"]).progress is False


def _imported_modules(path: Path) -> set[str]:
    out: set[str] = set()
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.Import):
            out.update(a.name for a in node.names)
        elif isinstance(node, ast.ImportFrom) and node.module:
            out.add(node.module)
    return out


def test_the_library_below_the_cli_draws_no_bars():
    lib = ROOT / "pneunet_env"
    files = [*lib.joinpath("envs").rglob("*.py"), *lib.joinpath("physics").rglob("*.py"), lib / "task.py"]
    for path in files:
        bad = {m for m in _imported_modules(path) if m.startswith(("pneunet_env.cli", "tqdm"))}
        assert not bad, (path, bad)


def test_tqdm_is_imported_only_by_the_helper():
    allowed = {ROOT / "pneunet_env/progress.py"}
    for path in [*ROOT.joinpath("pneunet_env").rglob("*.py"), *ROOT.joinpath("agents").rglob("*.py")]:
        if path not in allowed:
            assert not any(m.split(".")[0] == "tqdm" for m in _imported_modules(path)), path


def test_a_closed_pipe_ends_a_command_quietly(tmp_path):
    # `pneunet-grasp demo | head -1`: the reader goes away; the command stops with 128 + SIGPIPE, not a traceback
    code = ("import sys\nimport pneunet_env.cli.render as r\n"
            "r.run = lambda args: [print('x' * 99) for _ in range(100_000)] and 0\n"
            "from pneunet_env.cli import main\n"
            f"sys.exit(main(['render', '--out', {str(tmp_path)!r}]))\n")
    proc = subprocess.Popen([sys.executable, "-c", code], stdout=subprocess.PIPE, stderr=subprocess.PIPE)
    assert proc.stdout.readline() == b"x" * 99 + b"\n"
    proc.stdout.close()  # the reader goes away; the writer has megabytes left to write
    err = proc.stderr.read().decode()
    assert proc.wait(timeout=60) == 141 and "Traceback" not in err, err


def test_a_broken_pipe_that_is_not_stdout_is_an_error(monkeypatch, tmp_path):
    from pneunet_env.cli import render

    def run(args):
        raise BrokenPipeError(32, "Broken pipe")

    monkeypatch.setattr(render, "run", run)
    monkeypatch.setattr(sys, "stdout", io.StringIO())  # stdout is fine (and has no file descriptor)
    with pytest.raises(BrokenPipeError):
        main(["render", "--out", str(tmp_path)])
    with open(tmp_path / "file", "w") as out:  # stdout is a file, which a reader cannot close
        monkeypatch.setattr(sys, "stdout", out)
        with pytest.raises(BrokenPipeError):
            main(["render", "--out", str(tmp_path)])


def test_demo_rates_do_not_hide_a_miss():
    from pneunet_env.cli.demo import _rate

    assert [_rate(x) for x in (1.0, 0.995, 0.9996, 0.5, 0.004, 0.0004, 0.0)] == [
        "100%", "99.5%", ">99.9%", "50%", "0.4%", "<0.1%", "0%"]


def test_demo_names_models_by_stem_unless_stems_collide():
    from pneunet_env.cli.demo import _short_names

    names = ("best-ramp", "agents/models/ppo_kitchen.zip", "runs/a/best_model.zip", "runs/b/best_model.zip")
    short = _short_names(iter(names))  # any iterable, as the demo passes a generator
    assert [short[n] for n in names] == ["best-ramp", "ppo_kitchen", "runs/a/best_model.zip", "runs/b/best_model.zip"]
