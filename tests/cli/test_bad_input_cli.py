"""Bad input on the command line: every command, every option. A bad value ends the command with ONE line on
stderr (``pneunet-grasp CMD: error: ...``), exit status 2, no traceback, and before the work starts; a value the
command accepts reaches its work. Outputs (``--out``, ``--json``, ``--sheet``) are checked before the work, and
every file a command writes goes through :mod:`pneunet_env.files`.

The sweep runs each command in this process through :func:`pneunet_env.cli.main`, with the command's heavy work
(:data:`WORK`) replaced by a stand-in that raises :class:`WorkStarted`: so a case takes milliseconds, and "the work
started" is observed, not guessed. The whole sweep is ``slow``; the quick suite runs a representative subset.
"""

from __future__ import annotations

import argparse
import ast
import contextlib
import importlib
import io
from pathlib import Path

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from pneunet_env.cli import COMMANDS, DEBUG_ENV, CommandError, main

ROOT = Path(__file__).resolve().parents[2]

# ------------------------------------------------------------------------------------------------ the harness


class WorkStarted(BaseException):  # noqa: N818 (not an error: the signal that validation passed)
    """Raised by the stand-in of a command's heavy work: every check before it passed."""


WORK: dict[str, list[tuple[str, str]]] = {
    "demo": [("agents.evaluation.batch", "policy_episodes"), ("agents.evaluation.episodes", "run_episode")],
    "solve": [("pneunet_env.cli.solve", "load_path")],
    "render": [("gymnasium", "make")],
    "figures": [("pneunet_env.paper.command", "generate"), ("pneunet_env.paper.command", "load_tables")],
    "bench speed": [("pneunet_env.bench.speed", "run_benchmark"), ("pneunet_env.bench.backends", "run_sweep"),
                    ("pneunet_env.bench.speed", "plot")],
    "bench solvers": [("pneunet_env.bench.solvers", "run_study")],
    "bench design": [("agents.bench.design", "run_benchmark")],
    "bench render": [("pneunet_env.bench.render_speed", "bench_render")],
    "bench train": [("agents.bench.train", "bench_train")],
    "bench gpu": [("pneunet_env.bench.gpu", "run_check")],
    "evaluate": [("agents.evaluation.evaluate_cli", "evaluate_policies")],
    "train": [("agents.training.cli", "train"), ("agents.training.seeds", "run_seeds")],
    "train-skrl": [("agents.training.skrl_ppo", "train")],
    "search": [("agents.search.cli", "search_ramp"), ("agents.search.cli", "sensitivity_study")],
    "design": [("agents.design.cli", "run_study"), ("agents.design.cli", "work"), ("agents.design.cli", "report"),
               ("agents.design.checks", "run_design_checks")],
    "map": [("agents.evaluation.map_cli", "success_map")],
}
"""Each command's heavy work: the functions the sweep replaces (a command that is not here fails the sweep)."""


def _base(name: str, tmp: Path) -> list[str]:
    """The options a command needs to run at all (its required ones; cheap policies), before the swept option."""
    return {"render": ["--out", str(tmp / "frames")], "figures": ["--out", str(tmp / "figures")],
            "train": ["--config", "ppo", "--run-dir", str(tmp / "run")],
            "evaluate": ["--policy", "ramp"]}.get(name, [])


def _stub(*args, **kwargs):
    raise WorkStarted


@contextlib.contextmanager
def _no_work(names):
    with pytest.MonkeyPatch.context() as mp:
        for name in names:
            for module, attr in WORK[name]:
                mp.setattr(importlib.import_module(module), attr, _stub)
        mp.setenv("MPLBACKEND", "Agg")
        mp.delenv(DEBUG_ENV, raising=False)
        yield mp


def _call(argv: list[str]) -> tuple[str, int | None, str]:
    """``main(argv)`` with its output captured: ``("work", None, err)`` where the work started, else
    ``("exit", status, err)``. Any other exception propagates (a traceback: the test fails)."""
    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        try:
            rc = main(argv)
        except WorkStarted:
            return "work", None, err.getvalue()
        except SystemExit as exc:
            rc = exc.code if isinstance(exc.code, int) else 1
    return "exit", rc, err.getvalue()


def _assert_one_line_error(name: str, argv: list[str], what: str, rc, err: str) -> None:
    assert what == "exit" and rc == 2, (argv, what, rc, err)
    assert "Traceback" not in err, (argv, err)
    lines = err.splitlines()
    assert len(lines) == 1 and lines[0].startswith(f"pneunet-grasp {name}: error: "), (argv, err)


def _assert_clean(name: str, argv: list[str], what: str, rc, err: str) -> None:
    """Either the command refused the input (one line, status 2) or it reached its work; never a traceback."""
    assert "Traceback" not in err, (argv, err)
    if what == "exit":
        _assert_one_line_error(name, argv, what, rc, err)


# ------------------------------------------------------------------------------------------------ the values
INT_BAD = ["-1", "0", "nan", "inf", "1e400", "x", "9" * 30]
FLOAT_BAD = ["-1", "0", "nan", "inf", "-inf", "1e400", "x", "1e308"]
ALWAYS_BAD_NUMBERS = {"nan", "inf", "-inf", "1e400", "x"}
"""No number option takes these (no option means 'unbounded' by inf)."""
STRING_BAD = ["", "x", "/", "ramp:steps=inf", "x=["]
UNWRITABLE = "/proc/no-such-folder/out"
"""A place no process can create a file in, root included (the tests may run as root, where permissions do not
stop a write)."""
PATH_OPTIONS = {"--out", "--json", "--sheet", "--plot", "--export", "--run-dir"}
FILE_OPTIONS = {"--json", "--sheet", "--plot", "--export", "search --out"}
"""Options naming a file written (``search --out``: the schedule's JSON); the other PATH_OPTIONS name a folder."""


def _parser(name: str) -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog=name)
    importlib.import_module(COMMANDS[name][0]).add_arguments(parser)
    return parser


def _options(name: str):
    """``(flag, action)`` of every option of ``name`` that takes a value."""
    for action in _parser(name)._actions:
        if action.option_strings and action.nargs != 0 and not isinstance(action, argparse._HelpAction):
            yield action.option_strings[-1], action


def _is_number(action) -> tuple[bool, bool]:
    """``(int-like, float-like)`` from the option's ``type=`` (plain ``int``/``float`` or a
    :mod:`pneunet_env.arguments` check)."""
    t = action.type
    if t is int:
        return True, False
    if t is float:
        return False, True
    name = getattr(t, "__name__", "")
    return name in ("integer", "seed", "count"), name in ("number",) or (
        name not in ("integer", "seed", "count") and _probe_float(t))


def _probe_float(t) -> bool:
    if t is None or getattr(t, "__name__", "") in ("output_dir", "output_file", "Path"):
        return False
    try:
        return isinstance(t("0.5"), float)
    except (argparse.ArgumentTypeError, ValueError, TypeError):
        return False


def _values(name: str, flag: str, action, tmp: Path) -> list[str]:
    is_int, is_float = _is_number(action)
    if action.choices is not None:
        return ["wrong"]
    if is_int:
        return INT_BAD
    if is_float:
        return FLOAT_BAD
    if flag in PATH_OPTIONS or action.type in (Path,) or getattr(action.type, "__name__", "") in (
            "output_dir", "output_file"):
        return [str(tmp / "a_folder"), str(tmp / "a_file"), str(tmp / "a_file" / "under"), UNWRITABLE, ""]
    return STRING_BAD


def _cases(names=None, tmp: Path | None = None):
    tmp = tmp or Path("/nonexistent-tmp")
    for name in names or COMMANDS:
        for flag, action in _options(name):
            for value in _values(name, flag, action, tmp):
                n = action.nargs if isinstance(action.nargs, int) else 1
                yield name, flag, [value] * n


def _setup(tmp: Path) -> None:
    (tmp / "a_folder").mkdir(exist_ok=True)
    (tmp / "a_file").write_text("an existing file\n")


def _check_case(name: str, flag: str, values: list[str], tmp: Path) -> None:
    argv = [*name.split(), *_base(name, tmp), f"{flag}={values[0]}" if len(values) == 1 else flag,
            *([] if len(values) == 1 else values)]
    what, rc, err = _call(argv)
    _assert_clean(name, argv, what, rc, err)
    value = values[0]
    action = dict(_options(name))[flag]
    is_int, is_float = _is_number(action)
    if (is_int or is_float) and value in ALWAYS_BAD_NUMBERS:
        _assert_one_line_error(name, argv, what, rc, err)  # never accepted
    if flag == "--seed" and value == "-1":
        _assert_one_line_error(name, argv, what, rc, err)
    if flag in PATH_OPTIONS and value:
        wants_file = flag in FILE_OPTIONS or f"{name} {flag}" in FILE_OPTIONS
        refused = (value.endswith("a_folder") and wants_file) or (value.endswith("a_file") and not wants_file) \
            or value.endswith("under") or value == UNWRITABLE
        if refused:  # a folder for a file, a file for a folder, a path under a file, no write: refused first
            _assert_one_line_error(name, argv, what, rc, err)


# ------------------------------------------------------------------------------------------------ the sweep
def test_every_command_has_its_work_named():
    assert set(WORK) == set(COMMANDS)


MINE = ("demo", "solve", "render", "figures", "bench speed", "bench design", "bench train", "evaluate", "design",
        "map")
"""The commands whose every option the quick suite sweeps (the others: the slow sweep)."""
QUICK = {"evaluate": {"--seed", "--out", "--stiffness-grid", "--k-min", "--policy", "--set"},
         "map": {"--out", "--grid", "--seed", "--e-range"},
         "render": {"--width", "--sheet", "--out", "--target"},
         "solve": {"--stiffness", "--points"},
         "demo": {"--json", "--bins", "--targets-kpa", "--task"},
         "bench speed": {"--num-envs", "--out", "--backend"},
         "figures": {"--out", "--only"},
         "design": {"--export", "--trials"},
         "bench design": {"--json"},
         "bench train": {"--steps"}}
"""A representative subset for the quick suite: numbers, paths, choices and strings of the author's commands."""


def _sweep(names, tmp: Path, flags=None) -> list[str]:
    """Every case of ``names`` (only ``flags`` where given): the failures, one line each."""
    failures = []
    with _no_work(names):
        for name, flag, values in _cases(names, tmp):
            if flags is not None and flag not in flags[name]:
                continue
            try:
                _check_case(name, flag, values, tmp)
            except (AssertionError, Exception) as exc:  # collect them all: one report per command
                failures.append(f"{name} {flag} {values}: {type(exc).__name__}: {str(exc)[:300]}")
    return failures


@pytest.mark.parametrize("name", list(QUICK))
def test_bad_values_are_one_line_before_the_work(name, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    _setup(tmp_path)
    failures = _sweep([name], tmp_path, QUICK)
    assert not failures, "\n".join(failures)


@pytest.mark.slow  # every option of every command: about a thousand cases, some seconds
@pytest.mark.parametrize("name", list(COMMANDS))
def test_every_option_of_every_command_refuses_bad_values_in_one_line(name, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    _setup(tmp_path)
    failures = _sweep([name], tmp_path)
    assert not failures, "\n".join(failures)


def test_the_quick_subset_names_real_options():
    for name, flags in QUICK.items():
        assert flags <= {flag for flag, _ in _options(name)}, name


# ------------------------------------------------------------------------------------------------ the cases
@pytest.fixture
def work(tmp_path, monkeypatch):
    """Run in ``tmp_path``, every command's work replaced (:class:`WorkStarted`)."""
    monkeypatch.chdir(tmp_path)
    _setup(tmp_path)
    with _no_work(list(COMMANDS)):
        yield tmp_path


@pytest.mark.parametrize("name", ["evaluate", "map", "bench speed", "render", "figures", "design"])
def test_an_existing_file_as_the_output_folder_is_refused_before_the_work(name, work):
    # evaluate and map used to run every episode and then fail with FileExistsError: every result lost
    argv = [*name.split(), "--out", str(work / "a_file")]
    what, rc, err = _call(argv)
    _assert_one_line_error(name, argv, what, rc, err)
    assert "a_file" in err and "not a folder" in err
    assert (work / "a_file").read_text() == "an existing file\n"  # untouched


@pytest.mark.parametrize(("argv", "named"), [
    (["demo", "--json"], "is a folder"), (["render", "--sheet"], "is a folder"),
    (["bench", "design", "--json"], "is a folder"), (["bench", "train", "--json"], "is a folder")])
def test_a_folder_as_an_output_file_is_refused_before_the_work(argv, named, work):
    argv = [*argv, str(work / "a_folder")]
    what, rc, err = _call(argv)
    _assert_one_line_error(" ".join(argv[:2]) if argv[0] == "bench" else argv[0], argv, what, rc, err)
    assert named in err and "a_folder" in err


def test_an_existing_output_file_is_accepted_and_replaced_whole(work):
    # the documented behaviour of --json/--sheet: an existing file is replaced (atomically), not refused
    what, _, err = _call(["demo", "--json", str(work / "a_file")])
    assert what == "work" and err == ""


@pytest.mark.parametrize("argv", [["evaluate", "--seed", "-1"], ["map", "--seed", "-1"], ["demo", "--seed", "-1"],
                                  ["render", "--out", "o", "--seed", "-1"], ["design", "--seed", "-1"]])
def test_a_negative_seed_is_refused_before_the_work(argv, work):
    what, rc, err = _call(argv)  # evaluate used to start its episodes first
    _assert_one_line_error(argv[0], argv, what, rc, err)
    assert "seed" in err


@pytest.mark.parametrize(("argv", "named"), [
    (["render", "--out", "o", "--width", "10"], "--width 10"),  # a right message, but as a raw SystemExit (status 1)
    (["solve", "--stiffness", "-1"], "--stiffness"),  # a right message, but as a traceback
    (["solve", "--points", "1"], "--points"),
    (["evaluate", "--policy", "ramp:steps=inf"], "steps='inf'"),  # OverflowError, as a traceback
    (["demo", "--policy", "ramp:steps=inf"], "steps='inf'"),
    (["evaluate", "--set", "x=["], "x=["),
    (["evaluate", "--config", "."], "--config '.' is a folder"),
    (["solve", "--no-such-option"], "unrecognized arguments"),  # argparse's usage block is gone: one line
])
def test_bad_input_is_one_line_with_status_2(argv, named, work):
    what, rc, err = _call(argv)
    _assert_one_line_error(argv[0], argv, what, rc, err)
    assert named in err


def test_figures_table_only_needs_an_existing_folder(tmp_path):
    what, rc, err = _call(["figures", "--table-only", "--out", str(tmp_path / "none")])
    _assert_one_line_error("figures", [], what, rc, err)
    assert "--table-only" in err and "none" in err
    what, rc, err = _call(["figures", "--table-only", "--out", str(tmp_path)])  # a folder without the CSVs
    _assert_one_line_error("figures", [], what, rc, err)
    assert "missing" in err and ".csv" in err


# ------------------------------------------------------------------------------------------------ the entry point
def _raising(exc: BaseException):
    def run(args):
        raise exc

    return run


@pytest.mark.parametrize("exc", [ValueError("--points 3: too few"), TypeError("--points must be a number"),
                                 SystemExit("pneunet-grasp solve: --points 3: too few")])
def test_an_error_from_a_command_is_one_line_with_status_2(exc, monkeypatch):
    from pneunet_env.cli import solve

    monkeypatch.delenv(DEBUG_ENV, raising=False)
    monkeypatch.setattr(solve, "run", _raising(exc))
    what, rc, err = _call(["solve"])
    _assert_one_line_error("solve", ["solve"], what, rc, err)
    assert err.count("pneunet-grasp solve") == 1 and "--points" in err  # the command's own prefix is not doubled
    with pytest.raises(CommandError) as caught:  # argparse's way: SystemExit(2), its str() the message
        with contextlib.redirect_stderr(io.StringIO()):
            main(["solve"])
    assert caught.value.code == 2 and "--points" in str(caught.value)


def test_debug_shows_the_traceback(monkeypatch):
    from pneunet_env.cli import solve

    monkeypatch.setattr(solve, "run", _raising(ValueError("--points 3: too few")))
    monkeypatch.setenv(DEBUG_ENV, "1")
    with pytest.raises(ValueError, match="too few"):
        main(["solve"])
    monkeypatch.setattr(solve, "run", _raising(KeyboardInterrupt()))
    with pytest.raises(KeyboardInterrupt):
        main(["solve"])
    monkeypatch.setenv(DEBUG_ENV, "0")  # off
    assert _call(["solve"])[1] == 130


def test_ctrl_c_is_one_line_with_status_130(monkeypatch):
    from pneunet_env.cli import solve

    monkeypatch.delenv(DEBUG_ENV, raising=False)
    monkeypatch.setattr(solve, "run", _raising(KeyboardInterrupt()))
    what, rc, err = _call(["solve"])
    assert (what, rc, err) == ("exit", 130, "pneunet-grasp solve: interrupted\n")


def _self_interrupt():
    """Send this process a SIGINT and let its handler run (a system call after the kill: the handler runs by then)."""
    import os
    import signal

    os.kill(os.getpid(), signal.SIGINT)
    signal.pthread_sigmask(signal.SIG_BLOCK, [])


def test_a_ctrl_c_turned_into_another_error_is_still_an_interrupt(monkeypatch, python_ctrl_c):
    """A SIGINT that compiled code swallowed and reported as another error (matplotlib's drawing raises
    ``ValueError('Invalid bounding box')`` for one that came during its C call; CI's interrupt test met it once) is
    reported as the interrupt it was, status 130; the same error with no Ctrl-C is bad input, status 2. The SIGINT
    handler is left as it was."""
    import signal

    from pneunet_env.cli import solve

    def run(args):
        try:
            _self_interrupt()
        except KeyboardInterrupt:
            raise ValueError("Invalid bounding box") from None

    monkeypatch.delenv(DEBUG_ENV, raising=False)
    monkeypatch.setattr(solve, "run", run)
    assert _call(["solve"]) == ("exit", 130, "pneunet-grasp solve: interrupted\n")
    assert signal.getsignal(signal.SIGINT) is signal.default_int_handler
    assert signal.set_wakeup_fd(-1) == -1  # the noting ended with the command
    monkeypatch.setattr(solve, "run", _raising(ValueError("Invalid bounding box")))
    what, rc, err = _call(["solve"])
    assert rc == 2 and "Invalid bounding box" in err


def test_a_ctrl_c_while_the_command_is_set_up_is_its_interrupt(monkeypatch, python_ctrl_c):
    """A Ctrl-C that comes while the command's arguments are being declared (before its run begins) ends it as an
    interrupt, status 130, not as a traceback out of ``main`` (CI's interrupt test met one 0.03 s into a search)."""
    from pneunet_env.cli import solve

    declare = solve.add_arguments

    def add_arguments(parser):
        declare(parser)
        _self_interrupt()

    monkeypatch.delenv(DEBUG_ENV, raising=False)
    monkeypatch.setattr(solve, "add_arguments", add_arguments)
    try:
        result = _call(["solve"])
    except KeyboardInterrupt:
        pytest.fail("the Ctrl-C escaped main() as a KeyboardInterrupt")
    assert result == ("exit", 130, "pneunet-grasp solve: interrupted\n")


def test_a_command_still_holds_a_ctrl_c_in_its_deferred_blocks(monkeypatch, python_ctrl_c):
    """Inside a command, ``deferred_interrupt`` still holds a Ctrl-C until its block is done (the CLI notes interrupts
    without a handler of its own, which would have turned the holding off)."""
    from pneunet_env.cli import solve
    from pneunet_env.files import deferred_interrupt

    done = []

    def run(args):
        with deferred_interrupt():
            _self_interrupt()
            done.append("the block finished whole")

    monkeypatch.delenv(DEBUG_ENV, raising=False)
    monkeypatch.setattr(solve, "run", run)
    assert _call(["solve"]) == ("exit", 130, "pneunet-grasp solve: interrupted\n")
    assert done == ["the block finished whole"]


def test_a_status_without_a_message_passes_through(monkeypatch):
    from pneunet_env.cli import solve

    monkeypatch.setattr(solve, "run", _raising(SystemExit(3)))
    assert _call(["solve"]) == ("exit", 3, "")


# ------------------------------------------------------------------------------------------------ outputs
WRITER_FILES = sorted(str(p.relative_to(ROOT)) for p in [*ROOT.joinpath("agents").rglob("*.py"),
                        *ROOT.joinpath("pneunet_env").rglob("*.py")] if p.name != "files.py")
"""Every module of the package and of ``agents``; ``pneunet_env/files.py`` is the writer itself."""
WRITERS = {"write_text", "write_bytes", "savefig", "dump", "save", "savez", "savez_compressed", "to_csv"}
ALLOWED_WRITES = {
    ("agents/training/train.py", "model.save"),  # into an in-memory buffer, then written atomically
    ("agents/training/train.py", "NormalizationStats.from_vecnormalize(vn).save"),  # NormalizationStats.save is atomic
    ("agents/policies/sb3.py", "NormalizationStats.from_vecnormalize(load_pickled_vecnormalize(pickle_path)).save"),
    ("pneunet_env/yamlio.py", "yaml.dump"),  # to a string
}
"""Calls named like a writer that do not write a file in place (each checked by hand)."""


@pytest.mark.parametrize("path", WRITER_FILES)
def test_every_module_writes_through_the_atomic_writer(path):
    """Every file the package's commands write (JSON, NPZ, PNG, CSV, models) goes through :mod:`pneunet_env.files`
    (or :func:`pneunet_env.envs.render.save_png`, which does): never in place, so that an interrupted or failed
    write leaves the old file or the new one, never a truncated one."""
    tree = ast.parse((ROOT / path).read_text())
    bad = []
    for node in ast.walk(tree):
        if isinstance(node, ast.Call):
            f = node.func
            if isinstance(f, ast.Attribute) and f.attr in WRITERS and (path, ast.unparse(f)) not in ALLOWED_WRITES:
                bad.append(f"{ast.unparse(f)} at line {node.lineno}")
            if isinstance(f, ast.Name) and f.id == "open" and any(
                    isinstance(a, ast.Constant) and isinstance(a.value, str) and ("w" in a.value or "a" in a.value)
                    for a in node.args[1:2]):
                bad.append(f"open(..., 'w') at line {node.lineno}")
    assert not bad, (path, bad)


def test_the_figures_import_matplotlib_only_when_they_draw():
    figures = sorted((ROOT / "agents/figures").glob("*.py"))
    assert len(figures) >= 5
    for path in figures:
        assert "matplotlib" not in {n.split(".")[0] for n in _top_level_imports(path)}, path


def _top_level_imports(path: Path) -> set[str]:
    out: set[str] = set()
    for node in ast.parse(path.read_text()).body:
        if isinstance(node, ast.Import):
            out |= {a.name for a in node.names}
        elif isinstance(node, ast.ImportFrom) and node.module:
            out.add(node.module)
    return out


# ------------------------------------------------------------------------------------------------ the checks
def test_output_checks(tmp_path):
    from pneunet_env import arguments as checks

    tmp = tmp_path
    with pytest.raises(ValueError, match=r"--out '/dev/null' exists and is not a folder"):
        checks.check_output_dir("/dev/null")
    with pytest.raises(ValueError, match=r"--json '/dev/null' exists and is not a regular file"):
        checks.check_output_file("/dev/null", "--json")
    with pytest.raises(ValueError, match=r"cannot be created, '/dev/null' is a file"):
        checks.check_output_dir("/dev/null/x")
    with pytest.raises(ValueError, match="cannot write in '/proc'"):  # a place no one can write, root included
        checks.check_output_dir("/proc/no-such-folder/x")
    with pytest.raises(ValueError, match="is a folder; give a file name"):
        checks.check_output_file(tmp)
    with pytest.raises(ValueError, match="an empty path"):
        checks.check_output_dir("")
    assert checks.check_output_dir(tmp / "new" / "deeper") == tmp / "new" / "deeper"
    assert not (tmp / "new").exists() or (tmp / "new").is_dir()  # checked, not created
    assert not list(tmp.glob(".pneunet-write-check-*"))  # the write probe leaves nothing


@pytest.mark.parametrize(("check", "text", "message"), [
    ("count", "0", r"in \[1, 1000000\]"), ("count", "1e3", "whole number"), ("count", "nan", "whole number"),
    ("seed", "-1", r"\[0, 4294967295\]"), ("seed", "4294967296", "4294967295"),
    ("positive", "0", "> 0"), ("positive", "nan", "finite"), ("positive", "inf", "finite"),
    ("positive", "1e400", "overflows"), ("non_negative", "-1e-9", ">= 0"), ("positive", "x", "got 'x'")])
def test_number_checks_name_what_they_want_and_got(check, text, message):
    from pneunet_env import arguments as checks

    with pytest.raises(argparse.ArgumentTypeError, match=message):
        getattr(checks, check)(text)


def test_number_checks_accept_good_values():
    from pneunet_env import arguments as checks

    assert checks.count("12") == 12 and checks.seed("0") == 0 and checks.seed(str(2**32 - 1)) == 2**32 - 1
    assert checks.positive("1e-3") == 1e-3 and checks.non_negative("0") == 0.0 and checks.real(0, 1)("1") == 1.0


# ------------------------------------------------------------------------------------------------ hypothesis
FUZZED = ("solve", "render", "evaluate", "map", "demo", "bench speed", "figures")
_SPECIAL = ["nan", "inf", "-inf", "1e400", "-1", "0", "", "x", "=", "x=[", "ramp:steps=inf", "a_file", "a_folder",
            "a_file/under", "/", "--", "-", "9" * 25, "1e-320"]


@st.composite
def _argv(draw):
    name = draw(st.sampled_from(FUZZED))
    flags = [flag for flag, _ in _options(name)]
    token = st.one_of(st.sampled_from(flags), st.sampled_from(_SPECIAL),
                      st.integers(-(10**12), 10**12).map(str),
                      st.floats(allow_nan=True, allow_infinity=True).map(repr),
                      st.text(alphabet=st.characters(codec="utf-8", exclude_categories=("Cs",)), max_size=8))
    return name, draw(st.lists(token, max_size=6))


@settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(case=_argv())
def test_random_arguments_never_give_a_traceback(case, tmp_path_factory):
    name, tokens = case
    tmp = tmp_path_factory.getbasetemp() / "fuzz"  # one folder for every example: a fresh one each is slower
    tmp.mkdir(exist_ok=True)
    _setup(tmp)
    argv = [*name.split(), *_base(name, tmp), *tokens]  # evaluate: a cheap policy (not the PPO model's import)
    with _no_work(list(FUZZED)), contextlib.chdir(tmp):
        what, rc, err = _call(argv)  # an exception other than the work's start would fail here
    assert "Traceback" not in err, (argv, err)
    if what == "exit" and rc != 0:  # refused: one line, status 2 (0: --help)
        _assert_one_line_error(name, argv, what, rc, err)
