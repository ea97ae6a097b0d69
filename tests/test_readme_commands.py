"""Every command the README shows runs, and a test runs it; so does every command of the docs pages its sections
moved to in 0.14 (``tests/test_readme.py``'s ``PAGES``: results, usage, commands, ...).

README.md and those pages are read when the tests are collected (they keep changing), and every command they show is
taken from them (a command two pages show, once, from the first): inline code spans (which may wrap across a line
break) and the lines of ```bash blocks. Four kinds are kept:

- ``pneunet-grasp ...``: a *synopsis* (a usage line: ``[...]``, ``|``, ``...`` or a placeholder in capitals such as
  ``K``, ``N``, ``NAME_OR_MODEL``, ``YAML``) is checked, not run: its subcommand exists and every ``--flag`` it names
  (and every value it names for a flag with choices) is accepted by that subcommand's parser, built as
  ``pneunet_env.cli.main`` builds it. A *concrete* command is run, from the repository root, through
  ``pneunet_env.cli.main`` in-process (in a subprocess for the commands in :data:`SUBPROCESS`, whose torch threads,
  worker processes or global state would leak into the test session), and must exit 0 without a traceback.
- ``python -m rl_zoo3.train ...``: run in a subprocess when concrete; a synopsis's flags are checked against its
  ``--help``.
- ``pip install ...``: never run; every extra named in ``.[a,b]`` must exist in pyproject.toml.
- ``python -m pytest ...``: never run (it would run this file); its ``-m`` expression must name declared markers.

The repository stays untouched: every output path (``--out``, ``--export``, ``--run-dir``, ``--sheet``, ``--json``,
``--plot``, rl-zoo3's ``-f``; ``DIR`` and ``DIR/...`` placeholders; paths inside the repository alike) is moved into
pytest's ``tmp_path``, a command that writes into the repository by default gets its output flag pointed there
(:data:`DEFAULT_OUTPUT`), and the last test checks that ``git status --porcelain`` did not change.

The runs are kept small by :data:`SMOKE`: per subcommand, flags appended AFTER the README's own (argparse keeps the
last value). A concrete command whose subcommand has no entry there and is not in :data:`CHEAP` fails ("add a smoke
entry"): nothing is skipped silently. Each command's wall time is printed (``-s``; or see ``--durations``).
"""

from __future__ import annotations

import argparse
import functools
import importlib
import importlib.util
import os
import re
import shlex
import shutil
import subprocess
import sys
import tempfile
import time
from dataclasses import dataclass
from pathlib import Path

import pytest

pytestmark = pytest.mark.slow

ROOT = Path(__file__).resolve().parents[1]
README = ROOT / "README.md"
_spec = importlib.util.spec_from_file_location("readme_snippets", ROOT / "tests" / "test_readme.py")
_readme = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(_readme)
PAGES: tuple[Path, ...] = _readme.PAGES
FIRST_PAGES: frozenset[str] = frozenset(p.relative_to(ROOT).as_posix() for p in _readme.FIRST_PAGES)
"""The README and the pages its sections moved to: their commands run here; the other docs pages' commands run in
``tests/test_docs_commands.py``, a file of its own so that ``--dist loadfile`` runs the two halves side by side."""
"""The README and the docs pages its sections moved to (``tests/test_readme.py``'s, one list for both)."""
PYPROJECT = ROOT / "pyproject.toml"
PROG = "pneunet-grasp"

# --------------------------------------------------------------------------------------------------------------------
# What each subcommand needs to run small, and where it writes
# --------------------------------------------------------------------------------------------------------------------

SMOKE: dict[str, tuple[str, ...]] = {
    "demo": ("--objects", "8"),
    "evaluate": ("--stiffness-grid", "3", "--episodes", "1"),
    "search": ("--objects", "8", "--targets", "0.3", "0.6", "--durations", "20", "--refine", "0"),
    "train": ("--timesteps", "512", "--n-envs", "2", "--eval-freq", "256", "--n-eval-episodes", "2",
              "--checkpoint-freq", "256"),
    "train-skrl": ("--minutes", "0.02", "--num-envs", "16", "--eval-objects", "8", "--eval-every", "1"),
    "design": ("--trials", "2", "--objects", "8", "--held-out", "8", "--top", "1"),
    "map": ("--grid", "3", "2", "--density", "1000"),
    "render": ("--steps", "4", "--columns", "2", "--width", "240", "--height", "180"),
    "figures": ("--quick",),
    "bench speed": ("--quick",),
    "bench solvers": ("--quick",),
    "bench render": ("--frames", "5", "--repeats", "1"),
    "bench train": ("--steps", "512", "--threads", "1"),
    "bench design": ("--no-old", "--objects", "8", "--repeats", "1"),
    "bench gpu": ("--dry-run",),  # under numba-cuda's simulator, on the CPU (the gpu extra; no GPU needed)
}
"""Per subcommand: flags appended after the README's own to make the run small."""

SMOKE_IF: dict[tuple[str, str], tuple[str, ...]] = {
    ("train", "--seeds"): ("--seeds", "2", "--objects", "8", "--jobs", "1"),  # one process: no spawn from pytest
    ("search", "--sensitivity"): ("--grid", "3"),
    # torch.compile's first compilation of the solver's round takes minutes on a CPU (266 s on the 2-core CI machine;
    # docs/performance.md says it had no figure for that reason): the smoke run takes the sweep's CPU backends, with
    # --compile accepted; the compiled round itself is what a lent GPU measures (``bench gpu``, issue 35)
    ("bench speed", "--compile"): ("--backend", "numba", "numpy", "--num-envs", "256"),
}
"""(subcommand, a flag the README's command has): more flags appended after :data:`SMOKE`'s."""

SMOKE_INSTEAD: dict[tuple[str, str], tuple[str, ...]] = {
    ("demo", "--task"): ("--episodes", "1", "--bins", "2"),  # the paper's task draws by stiffness bin, not --objects
}
"""(subcommand, a flag the page's command has): the smoke flags that replace :data:`SMOKE`'s."""

OK_STATUS: dict[tuple[str, str], tuple[int, ...]] = {
    # On smoke-size objects the findings are noise: exit 1 ("a finding is not as expected") is a result, not a crash.
    # The full-size run (200 objects, about 85 s on 2 cores) is what decides the findings.
    ("design", "--checks"): (0, 1),
}
"""(subcommand, a flag the README's command has): the exit statuses that count as having run."""

CHEAP: frozenset[str] = frozenset({"solve"})
"""Subcommands that run small as they are: no smoke entry needed."""

SUBPROCESS: frozenset[str] = frozenset({"train-skrl", "design"})
"""Subcommands run as a subprocess: skrl seeds every global RNG; design spawns worker processes (which re-import the
main module) and keeps SQLite state. The others run in-process (torch's thread count and matplotlib's figures are
restored after each)."""

OUTPUT_FLAGS: frozenset[str] = frozenset({"--out", "--export", "--run-dir", "--sheet", "--json", "--plot",
                                          "-f", "--log-folder"})
"""Flags whose value is a path written to: always moved into tmp_path."""

DEFAULT_OUTPUT: dict[str, tuple[str, str]] = {
    "search": ("--out", "search/best_ramp.json"),
    "map": ("--out", "map"),
    "evaluate": ("--out", "evaluation"),
    "design": ("--out", "design"),
    "train": ("--run-dir", "runs"),
    "train-skrl": ("--out", "skrl"),
    "bench speed": ("--out", "bench_speed"),
    "bench solvers": ("--out", "bench_solvers"),
    "rl_zoo3": ("-f", "logs"),
}
"""Subcommands that write into the repository unless told otherwise: (flag, path under tmp_path) appended when the
README's command does not give the flag. Not here: commands whose output flag is required (``figures --out``;
``render --out`` or ``--sheet``), so that a README command without it fails as it would for a user."""

PREREQUISITES: dict[tuple[str, str], tuple[str, ...]] = {
    ("figures", "--table-only"): ("figures", "--quick"),
}
"""(subcommand, a flag the page's command has): the run that makes what it reads (the CSVs), into the same output
folder first: a page shows them one after the other."""
SHIPPED_OUTPUTS: dict[tuple[str, str], tuple[str, ...]] = {
    ("bench speed", "--plot-only"): ("docs/img/performance/speed.json",),
}
"""(subcommand, a flag): what it reads from its output folder, copied there from the repository's own record (the
chart's run, a real ``bench speed --out`` record) instead of measuring again."""


def _fruit_catalogue(dest: Path) -> None:
    """``docs/env.md``'s worked example, as its reader writes it: the YAML block with the packaged apple copied in
    where the page writes ``apple: {...}``."""
    from pneunet_env.yamlio import dump_yaml, load_yaml

    text = (ROOT / "docs" / "env.md").read_text(encoding="utf-8")
    block = next(m.group(2) for m in FENCE.finditer(text)
                 if m.group(1).strip() == "yaml" and "my_kiwi" in m.group(2))
    data = load_yaml(block.replace("{...}", "null"), "docs/env.md's fruit bowl")
    packaged = load_yaml((ROOT / "pneunet_env" / "data" / "objects.yaml").read_bytes(), "objects.yaml")
    data["classes"]["apple"] = packaged["classes"]["apple"]
    dest.write_text(dump_yaml(data, sort_keys=False), encoding="utf-8")


def _designed_rank1(dest: Path) -> None:
    """``designs/rank-1.yaml`` of a design study's output folder, as ``docs/design.md`` names it: the shipped
    kitchen design (what ``--export`` wrote from rank 1), with its ramp beside it."""
    src = ROOT / "configs" / "env" / "designed-kitchen.yaml"
    dest.parent.mkdir(parents=True, exist_ok=True)
    shutil.copyfile(src, dest)
    shutil.copyfile(src.with_suffix(".best_ramp.json"), dest.with_suffix(".best_ramp.json"))


INPUTS = {"fruit.yaml": _fruit_catalogue, "designs/rank-1.yaml": _designed_rank1}
"""Input files a page's command names that a reader makes first (by the page's own recipe): made in tmp_path,
and the command pointed there."""

NEEDS_CUDA = ("--device", "cuda")
"""A command that names a CUDA device runs only where torch sees one (the GPU figures of docs/speed.md); elsewhere
it is skipped by name, with its reason."""

ZOO_SMOKE = ("-n", "2048")
"""rl-zoo3: one rollout of the config's 16 envs x 128 steps."""

# --------------------------------------------------------------------------------------------------------------------
# Extraction
# --------------------------------------------------------------------------------------------------------------------

FENCE = re.compile(r"^```([^\n`]*)\n(.*?)^```[ \t]*$", re.S | re.M)
SPAN = re.compile(r"`([^`]+)`")
PLACEHOLDER = re.compile(r"^[A-Z][A-Z0-9_]*$")
PLACEHOLDER_SPLIT = re.compile(r"[/=:,.\s]+")
EXTRAS = re.compile(r"\[([^\]]*)\]")
CHAINS = frozenset({"&&", "||", ";"})


@dataclass(frozen=True)
class Command:
    kind: str  # "pneunet-grasp", "rl_zoo3", "pip" or "pytest"
    argv: tuple[str, ...]  # the words after the program (after "pip install", "python -m pytest", ...)
    text: str  # as the page shows it, whitespace normalised
    line: int  # the line of its page it starts on
    page: str = "README.md"  # the page that shows it: README.md or docs/NAME.md

    @property
    def where(self) -> str:
        """``README.md line 12``: where a message sends the reader."""
        return f"{self.page} line {self.line}"

    @property
    def synopsis(self) -> bool:
        return self.kind in (PROG, "rl_zoo3") and is_synopsis(self.argv)

    @property
    def name(self) -> str:
        """The subcommand (``bench speed``), or the kind for the others."""
        if self.kind != PROG:
            return self.kind
        from pneunet_env.cli import GROUPS

        if not self.argv:
            return ""
        if self.argv[0] in GROUPS and len(self.argv) > 1:
            return " ".join(self.argv[:2])
        return self.argv[0]


def _tokens(text: str) -> list[str]:
    try:
        return shlex.split(text, comments=True)
    except ValueError:  # an unbalanced quote in prose: plain words
        return text.split()


def _classify(words: list[str]) -> tuple[str, tuple[str, ...]] | None:
    if words[:1] == [PROG]:
        return PROG, tuple(words[1:])
    if words[:3] == ["python", "-m", "pneunet_env.cli"]:
        return PROG, tuple(words[3:])
    if words[:3] == ["python", "-m", "rl_zoo3.train"]:
        return "rl_zoo3", tuple(words[3:])
    if words[:2] == ["pip", "install"]:
        return "pip", tuple(words[2:])
    if words[:3] == ["python", "-m", "pytest"]:
        return "pytest", tuple(words[3:])
    return None


def _commands_in(text: str, line: int, page: str) -> list[Command]:
    """The commands of one bash line or inline span (``a && b`` gives two)."""
    out = []
    words: list[str] = []
    for tok in [*_tokens(text), "&&"]:
        if tok not in CHAINS:
            words.append(tok)
            continue
        kind_argv = _classify(words) if words else None
        if kind_argv is not None:
            out.append(Command(kind_argv[0], kind_argv[1], " ".join(words), line, page))
        words = []
    return out


def extract(text: str, page: str = "README.md") -> list[Command]:
    """Every command of a Markdown text (the page ``page``), in order, each once (its first place)."""
    found: list[Command] = []
    prose = list(text)
    for m in FENCE.finditer(text):
        start_line = text.count("\n", 0, m.start(2)) + 1
        if m.group(1).strip().lower() in ("bash", "sh", "shell", "console"):
            body = m.group(2).replace("\\\n", " ")  # continuation lines
            for i, ln in enumerate(body.splitlines()):
                found += _commands_in(ln.removeprefix("$ "), start_line + i, page)
        for i in range(m.start(), m.end()):  # blank the block out of the prose, keeping the line numbers
            if prose[i] != "\n":
                prose[i] = " "
    prose_text = "".join(prose)
    for m in SPAN.finditer(prose_text):
        span = " ".join(m.group(1).replace("\\|", "|").split())  # a table's escaped pipe; wrapped lines
        found += _commands_in(span, prose_text.count("\n", 0, m.start()) + 1, page)
    seen: set[tuple[str, tuple[str, ...]]] = set()
    unique = []
    for cmd in sorted(found, key=lambda c: c.line):
        if (cmd.kind, cmd.argv) not in seen:
            seen.add((cmd.kind, cmd.argv))
            unique.append(cmd)
    return unique


def readme_commands() -> list[Command]:
    """Every command of :data:`PAGES`, page by page, each once (its first place)."""
    seen: set[tuple[str, tuple[str, ...]]] = set()
    out = []
    for page in PAGES:
        for cmd in extract(page.read_text(encoding="utf-8"), page.relative_to(ROOT).as_posix()):
            if (cmd.kind, cmd.argv) not in seen:
                seen.add((cmd.kind, cmd.argv))
                out.append(cmd)
    return out


def _is_placeholder(word: str) -> bool:
    return any(PLACEHOLDER.match(part) for part in PLACEHOLDER_SPLIT.split(word) if part)


def _is_dir_path(word: str) -> bool:
    """``DIR`` or ``DIR/...``: a folder the user names, moved into tmp_path when it is an output."""
    return word == "DIR" or word.startswith("DIR/")


def is_synopsis(argv: tuple[str, ...] | list[str]) -> bool:
    """A usage line rather than a command: brackets, alternatives, ellipses, or a placeholder in capitals (``DIR`` as
    an output path excepted: it is redirected)."""
    for i, word in enumerate(argv):
        if any(mark in word for mark in ("[", "]", "|", "...", "\u2026")):
            return True
        if _is_placeholder(word):
            flag = argv[i - 1].split("=")[0] if i else ""
            if not (flag in OUTPUT_FLAGS and _is_dir_path(word)):
                return True
    return False


def _param_id(cmd: Command, taken: set[str]) -> str:
    base = cmd.text.removeprefix(PROG + " ").removeprefix("python -m ")
    base = base if len(base) <= 90 else base[:87] + "..."
    pid, n = base, 2
    while pid in taken:
        pid, n = f"{base} #{n}", n + 1
    taken.add(pid)
    return pid


def _params(select) -> list:
    taken: set[str] = set()
    return [pytest.param(c, id=_param_id(c, taken)) for c in readme_commands() if select(c)]


def _run_params(first_pages: bool = True) -> list:
    """The concrete commands, each run once: two README commands that run the same argv once their outputs are
    moved (``bench speed`` and ``bench speed --out DIR``) are one case, whose id is the first and which names both.
    ``first_pages``: those first shown on :data:`FIRST_PAGES` (run here), else the others (``test_docs_commands``)."""
    taken: set[str] = set()
    groups: dict[tuple[str, ...], list[Command]] = {}
    for c in readme_commands():
        if c.kind in (PROG, "rl_zoo3") and not c.synopsis:
            groups.setdefault(run_key(c), []).append(c)
    return [pytest.param(cs[0], tuple(c.text for c in cs[1:]), id=_param_id(cs[0], taken)) for cs in groups.values()
            if (cs[0].page in FIRST_PAGES) == first_pages]


# --------------------------------------------------------------------------------------------------------------------
# Parsers
# --------------------------------------------------------------------------------------------------------------------


@functools.cache
def cli_parser(name: str) -> argparse.ArgumentParser:
    """The subcommand's parser, built as :func:`pneunet_env.cli.main` builds it."""
    from pneunet_env.cli import COMMANDS

    module_name, help_ = COMMANDS[name]
    module = importlib.import_module(module_name)
    parser = argparse.ArgumentParser(prog=f"{PROG} {name}", description=help_)
    module.add_arguments(parser)
    return parser


@functools.cache
def zoo_help() -> str:
    res = subprocess.run([sys.executable, "-m", "rl_zoo3.train", "--help"], cwd=ROOT, capture_output=True,
                         text=True, timeout=120)
    assert res.returncode == 0, res.stderr[-2000:]
    return res.stdout


def _synopsis_words(argv: tuple[str, ...]) -> list[str]:
    """The words of a usage line without its brackets, alternatives split (``a|b`` -> ``a``, ``b``)."""
    words = []
    for word in argv:
        for part in word.replace("[", " ").replace("]", " ").replace("|", " ").split():
            words.append(part)
    return words


def _flag(word: str) -> str | None:
    return word.split("=")[0] if re.match(r"^--?[A-Za-z]", word) else None


# --------------------------------------------------------------------------------------------------------------------
# Running
# --------------------------------------------------------------------------------------------------------------------

TIMES: list[tuple[str, float]] = []


def _redirect(argv: list[str], tmp_path: Path, dry: bool = False) -> list[str]:
    """Every output path into tmp_path: ``DIR`` -> tmp_path/DIR, ``docs/img/x`` -> tmp_path/docs/img/x (parents
    created, as they exist in the repository)."""
    out = list(argv)
    for i, word in enumerate(out):
        flag, eq, value = word.partition("=")
        if eq and flag in OUTPUT_FLAGS:
            out[i] = f"{flag}={_moved(value, tmp_path, dry)}"
        elif i and out[i - 1] in OUTPUT_FLAGS and not word.startswith("-"):
            out[i] = _moved(word, tmp_path, dry)
        elif _is_dir_path(word):
            out[i] = _moved(word, tmp_path, dry)
    return out


def _moved(value: str, tmp_path: Path, dry: bool = False) -> str:
    p = Path(value)
    rel = p.relative_to(ROOT) if p.is_absolute() and p.is_relative_to(ROOT) else p
    rel = rel.relative_to(rel.anchor) if rel.is_absolute() else rel  # /elsewhere/x -> tmp_path/out/elsewhere/x
    moved = tmp_path / "out" / rel
    if not dry:
        moved.parent.mkdir(parents=True, exist_ok=True)
    return str(moved)


def _has(argv, flag: str) -> bool:
    return any(w == flag or w.startswith(flag + "=") for w in argv)


def prepare(cmd: Command, tmp_path: Path, dry: bool = False) -> list[str]:
    """The argv that is run: outputs moved into tmp_path, then the smoke flags (``dry``: create no folder, fail on
    nothing)."""
    name = cmd.name
    argv = _redirect(list(cmd.argv), tmp_path, dry)
    for i, word in enumerate(argv):
        if word in INPUTS:
            made = tmp_path / "inputs" / word
            if not dry:
                made.parent.mkdir(parents=True, exist_ok=True)
                INPUTS[word](made)
            argv[i] = str(made)
    if name in DEFAULT_OUTPUT:
        flag, sub = DEFAULT_OUTPUT[name]
        if name == "search" and _has(argv, "--sensitivity"):
            sub = "sensitivity"
        if not _has(argv, flag):
            argv += [flag, str(tmp_path / "default" / sub)]
    if cmd.kind == "rl_zoo3":
        return argv + list(ZOO_SMOKE)
    instead = [more for (sub_name, flag), more in SMOKE_INSTEAD.items() if sub_name == name and _has(cmd.argv, flag)]
    if instead:
        argv += instead[0]
    elif name in SMOKE:
        argv += SMOKE[name]
    elif name not in CHEAP and name and not dry:
        pytest.fail(f"add a smoke entry for {name!r} to SMOKE in {Path(__file__).name} (or to CHEAP if it runs "
                    f"small as it is): {cmd.page} shows `{cmd.text}` (line {cmd.line})")
    for (sub_name, flag), more in SMOKE_IF.items():
        if sub_name == name and _has(cmd.argv, flag):
            argv += more
    return argv


def _has_words(argv, words: tuple[str, ...]) -> bool:
    n = len(words)
    return any(tuple(argv[i:i + n]) == words for i in range(len(argv) - n + 1))


def _cuda() -> bool:
    try:
        import torch
    except ImportError:
        return False
    return bool(torch.cuda.is_available())


def run_key(cmd: Command) -> tuple[str, ...]:
    """What :func:`prepare` runs, with every path under tmp_path written ``<tmp>``."""
    fake = Path("/readme-commands-tmp")
    words = prepare(cmd, fake, dry=True)
    return (cmd.kind, *(re.sub(rf"{re.escape(str(fake))}/\S*", "<tmp>", w) for w in words))


def _ok_status(cmd: Command) -> tuple[int, ...]:
    for (sub_name, flag), ok in OK_STATUS.items():
        if sub_name == cmd.name and _has(cmd.argv, flag):
            return ok
    return (0,)


def _exit_status(exc: SystemExit) -> tuple[int, str]:
    if exc.code is None:
        return 0, ""
    if isinstance(exc.code, int):
        return exc.code, ""
    return 1, f"\nSystemExit: {exc.code}"  # the interpreter would print it, with status 1


def _run_in_process(argv: list[str], capfd) -> tuple[int, str]:
    from pneunet_env.cli import main

    torch = sys.modules.get("torch")
    threads = torch.get_num_threads() if torch is not None else None
    message = ""
    try:
        status = main(argv)
    except SystemExit as exc:
        status, message = _exit_status(exc)
    finally:
        torch = sys.modules.get("torch")
        if torch is not None and threads is not None:
            torch.set_num_threads(threads)
        if "matplotlib.pyplot" in sys.modules:
            sys.modules["matplotlib.pyplot"].close("all")
    out, err = capfd.readouterr()
    sys.stdout.write(out[-4000:])  # shown with -s
    return status, out + err + message


def _run_subprocess(prefix: list[str], argv: list[str]) -> tuple[int, str]:
    # SB3's own log folder (rl-zoo3 gives learn() no logger) goes to a folder of the run's, removed after it: neither
    # $TMPDIR/SB3-<date> left behind nor the session's $SB3_LOGDIR, which conftest watches
    log_dir = tempfile.mkdtemp(prefix="sb3_log_")
    try:
        res = subprocess.run([*prefix, *argv], cwd=ROOT, capture_output=True, text=True, timeout=600,
                             env={**os.environ, "PYTHONUNBUFFERED": "1", "SB3_LOGDIR": log_dir})
    finally:
        shutil.rmtree(log_dir, ignore_errors=True)
    sys.stdout.write(res.stdout[-4000:])
    return res.returncode, res.stdout + res.stderr


# --------------------------------------------------------------------------------------------------------------------
# Tests
# --------------------------------------------------------------------------------------------------------------------


def _git_status() -> str | None:
    git = shutil.which("git")
    if git is None:
        return None
    res = subprocess.run([git, "status", "--porcelain", "--untracked-files=all"], cwd=ROOT, capture_output=True,
                         text=True, timeout=60)
    return res.stdout if res.returncode == 0 else None


@pytest.fixture(scope="module")
def status_before() -> str | None:
    """``git status --porcelain`` before the first command of this module ran."""
    return _git_status()


@pytest.fixture(autouse=True)
def _snapshot(status_before):  # every test takes it, so that it is taken before the first one
    return status_before


def test_the_commands_are_found():
    """A broken regex, a renamed marker or a lost fence would make this module vacuous: the main job, the test
    command (in the README), the rl-zoo3 line, the Commands table's usage lines and some concrete commands must all
    be found, and every page of :data:`PAGES` that shows commands contributes some."""
    text = README.read_text(encoding="utf-8")
    cmds = readme_commands()
    assert {c.page for c in cmds} >= {"README.md", "docs/results.md", "docs/usage.md", "docs/commands.md",
                                      "docs/speed.md"}, sorted({c.page for c in cmds})
    by_kind = {k: [c for c in cmds if c.kind == k] for k in (PROG, "rl_zoo3", "pip", "pytest")}
    in_readme = {k: [c for c in v if c.page == "README.md"] for k, v in by_kind.items()}
    main_line = text[:text.index("<!-- main-command -->")].count("\n") + 1
    test_line = text[:text.index("<!-- test-command -->")].count("\n") + 1
    assert any(c.argv == ("demo",) and 0 < c.line - main_line <= 3 for c in in_readme[PROG]), \
        f"the main command `pneunet-grasp demo` was not found after <!-- main-command -->: {by_kind[PROG]}"
    assert any(0 < c.line - test_line <= 3 for c in in_readme["pytest"]), \
        f"the test command (python -m pytest) was not found after <!-- test-command -->: {by_kind['pytest']}"
    assert any(0 < c.line - test_line <= 3 and "-e" in c.argv for c in in_readme["pip"]), "the test command's pip"
    assert by_kind["rl_zoo3"], "the rl-zoo3 command line"
    synopses = [c for c in by_kind[PROG] if c.synopsis]
    concrete = [c for c in by_kind[PROG] if not c.synopsis]
    assert len(synopses) >= 10 and len({c.name for c in synopses}) >= 8, [c.text for c in synopses]
    assert len(concrete) >= 5, [c.text for c in concrete]
    # a wrapped inline span is one command (the demo over five policies wraps in the README)
    assert any(c.argv.count("--policy") >= 3 for c in concrete), [c.text for c in concrete]
    print(f"\n{len(cmds)} commands: {len(concrete)} concrete and {len(synopses)} synopses of {PROG}, "
          f"{len(by_kind['rl_zoo3'])} rl-zoo3, {len(by_kind['pip'])} pip install, {len(by_kind['pytest'])} pytest")


def test_extraction_rules():
    """The rules on a made-up page: wrapped spans, chains, bash comments, escaped table pipes, synopses, DIR."""
    page = ("Run `pneunet-grasp demo --objects\n  400` or `pneunet-grasp map --out DIR` (`--set K=V` alone is no\n"
            "command).\n\n```bash\npip install -e \".[rl]\" && pneunet-grasp solve --stiffness 1e-3  # a comment\n"
            "```\n\n| `pneunet-grasp x [--a b\\|c]` | `pneunet-grasp y --n N` |\n\n```python\n"
            "# `pneunet-grasp not-this`\n```\n")
    cmds = extract(page)
    assert [(c.kind, c.argv, c.synopsis) for c in cmds] == [
        (PROG, ("demo", "--objects", "400"), False),
        (PROG, ("map", "--out", "DIR"), False),
        ("pip", ("-e", ".[rl]"), False),
        (PROG, ("solve", "--stiffness", "1e-3"), False),
        (PROG, ("x", "[--a", "b|c]"), True),
        (PROG, ("y", "--n", "N"), True),
    ]
    assert cmds[0].line == 1 and cmds[3].line == 6


@pytest.mark.parametrize("cmd", _params(lambda c: c.kind == PROG and c.synopsis))
def test_synopsis_matches_the_parser(cmd: Command):
    from pneunet_env.cli import COMMANDS

    assert cmd.name in COMMANDS, f"`{cmd.text}` ({cmd.where}): no subcommand {cmd.name!r} in {PROG}"
    parser = cli_parser(cmd.name)
    actions = parser._option_string_actions
    words = _synopsis_words(cmd.argv[len(cmd.name.split()):])
    problems = []
    for i, word in enumerate(words):
        flag = _flag(word)
        if flag is None:
            continue
        if flag not in actions:
            problems.append(f"{flag} is not an option of `{PROG} {cmd.name}`")
            continue
        choices = actions[flag].choices
        if choices is None:
            continue
        values = [word.partition("=")[2]] if "=" in word else []
        for value in words[i + 1:]:
            if _flag(value) is not None:
                break
            values.append(value)
        for value in values:
            if value and not _is_placeholder(value) and value not in ("...", "\u2026") and value not in choices:
                problems.append(f"{flag} {value}: not one of {sorted(choices)}")
    assert not problems, f"`{cmd.text}` ({cmd.where}): " + "; ".join(problems)


@pytest.mark.parametrize("cmd", _params(lambda c: c.kind == "rl_zoo3" and c.synopsis))
def test_rl_zoo3_synopsis_matches_its_help(cmd: Command):
    pytest.importorskip("rl_zoo3")
    help_text = zoo_help()
    missing = [f for f in map(_flag, _synopsis_words(cmd.argv)) if f is not None and
               not re.search(rf"(?<![\w-]){re.escape(f)}(?![\w-])", help_text)]
    assert not missing, f"`{cmd.text}` ({cmd.where}): rl_zoo3.train has no {missing}"


@pytest.mark.parametrize("cmd", _params(lambda c: c.kind == "pip"))
def test_pip_install_names_existing_extras(cmd: Command):
    import tomllib

    declared = set(tomllib.loads(PYPROJECT.read_text(encoding="utf-8"))["project"].get("optional-dependencies", {}))
    for word in cmd.argv:
        if word.startswith("-"):
            continue
        target, _, _ = word.partition("[")
        if target not in (".", "./") and not word.startswith(".["):
            continue  # a package from the index (torch==...): not this project
        for m in EXTRAS.finditer(word):
            extras = {e.strip() for e in m.group(1).split(",") if e.strip()}
            assert extras <= declared, (f"`{cmd.text}` ({cmd.where}) names extras "
                                        f"{sorted(extras - declared)} that pyproject.toml does not declare "
                                        f"({sorted(declared)})")


@pytest.mark.parametrize("cmd", _params(lambda c: c.kind == "pytest"))
def test_pytest_command_names_declared_markers(cmd: Command):
    import tomllib

    ini = tomllib.loads(PYPROJECT.read_text(encoding="utf-8"))["tool"]["pytest"]["ini_options"]
    declared = {m.split(":")[0].strip() for m in ini.get("markers", [])}
    argv = list(cmd.argv)
    for i, word in enumerate(argv[:-1]):
        if word == "-m":
            names = set(re.findall(r"[A-Za-z_]\w*", argv[i + 1])) - {"and", "or", "not"}
            assert names <= declared, f"`{cmd.text}` ({cmd.where}): undeclared markers {names - declared}"


@pytest.mark.parametrize(("cmd", "also"), _run_params())
def test_command_runs(cmd: Command, also: tuple[str, ...], tmp_path, capfd, monkeypatch):
    run_command(cmd, also, tmp_path, capfd, monkeypatch)


def run_command(cmd: Command, also: tuple[str, ...], tmp_path, capfd, monkeypatch) -> None:
    """Run one page's command as :data:`SMOKE` and the rest say, and check it exits as it should, without a
    traceback (the body of :func:`test_command_runs` and of ``test_docs_commands``'s)."""
    if cmd.kind == "rl_zoo3":
        pytest.importorskip("rl_zoo3")
    else:
        from pneunet_env.cli import COMMANDS

        assert cmd.name in COMMANDS or not cmd.argv, f"`{cmd.text}` ({cmd.where}): no such subcommand"
    argv = prepare(cmd, tmp_path)
    monkeypatch.chdir(ROOT)
    if _has_words(cmd.argv, NEEDS_CUDA) and not _cuda():
        pytest.skip(f"`{cmd.text}` ({cmd.where}) needs a CUDA GPU (torch sees none here)")
    for (sub_name, flag), files in SHIPPED_OUTPUTS.items():
        if sub_name == cmd.name and _has(cmd.argv, flag):
            out_dir = Path(argv[argv.index("--out") + 1])
            out_dir.mkdir(parents=True, exist_ok=True)
            for f in files:
                shutil.copyfile(ROOT / f, out_dir / Path(f).name)
    for (sub_name, flag), before in PREREQUISITES.items():
        if sub_name == cmd.name and _has(cmd.argv, flag):
            out_flag = argv.index("--out") + 1
            first = [*before, "--out", argv[out_flag]]
            status, output = _run_in_process(first, capfd)
            assert status == 0, f"`{cmd.text}` ({cmd.where}): its prerequisite `{shlex.join(first)}` failed\n{output}"
    t0 = time.perf_counter()
    if cmd.kind == "rl_zoo3":
        status, output = _run_subprocess([sys.executable, "-m", "rl_zoo3.train"], argv)
    elif cmd.name in SUBPROCESS:
        status, output = _run_subprocess([sys.executable, "-m", "pneunet_env.cli"], argv)
    else:
        status, output = _run_in_process(argv, capfd)
    wall = time.perf_counter() - t0
    TIMES.append((cmd.text, wall))
    print(f"\n[{wall:6.1f} s] {cmd.text}\n          ran as: {shlex.join(argv)}"
          + "".join(f"\n          (the same run as: {t})" for t in also))
    where = f"`{cmd.text}` ({cmd.where}), run as `{shlex.join(argv)}`"
    assert status in _ok_status(cmd), f"{where}: exit status {status}\n{output[-4000:]}"
    assert "Traceback (most recent call last)" not in output, f"{where}: printed a traceback\n{output[-4000:]}"


def test_the_repository_is_untouched(status_before):
    """Last (tests run in file order): no command wrote into the repository."""
    check_untouched(status_before, "README")


def check_untouched(status_before: str | None, what: str) -> None:
    """Print the commands' times and check that ``git status --porcelain`` is what it was before the first ran."""
    if TIMES:
        print(f"\n{len(TIMES)} {what} commands ran in {sum(t for _, t in TIMES):.1f} s:")
        for text, wall in sorted(TIMES, key=lambda x: -x[1]):
            print(f"  {wall:6.1f} s  {text}")
    after = _git_status()
    if status_before is None or after is None:
        pytest.skip("git (or a git checkout) is not available: the repository's state was not checked")
    before_lines, after_lines = set(status_before.splitlines()), set(after.splitlines())
    changed = sorted(after_lines ^ before_lines)
    assert not changed, (
        f"the {what} commands changed the repository (git status --porcelain; an edit made by someone else in this "
        "working tree while the tests ran shows up here too):\n"
        + "\n".join(("+ " if ln in after_lines else "- ") + ln for ln in changed))
