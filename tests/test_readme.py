"""The README's Python snippets run as written, and its relative links and images (and those of docs/) exist.

The snippets are the fenced ```python blocks of the "Quick start" and "Use with ..." sections. Each runs with
``exec`` in a fresh namespace, in-process (torch and numba are imported once for all: about 10 s in all on the
2-core machine), in an empty folder (what a snippet saves stays out of the repository). A training snippet shows
the size it was measured at; it runs here at smoke size (:func:`smoke`). The rl-zoo3 command line of "Use with ..."
is a bash block: the slow ``tests/agents/test_zoo.py`` runs it; ``tests/envs/test_sb3_examples.py`` runs the SB3
snippets as a user would.
"""

from __future__ import annotations

import importlib.util
import re
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
README = ROOT / "README.md"
DOCS = ROOT / "docs"
SECTIONS = ("Quick start", "Use with ...")
"""The README sections (``## `` headings) whose Python blocks are run."""

FENCE = re.compile(r"^```python\n(.*?)^```", re.S | re.M)
HEADING = re.compile(r"^(#{1,6}) (.+?)\s*$", re.M)
LINK = re.compile(r"!?\[(?:[^\]\[]|\[[^\]]*\])*\]\(([^)\s]+)(?:\s+\"[^\"]*\")?\)")
HAS_SB3 = importlib.util.find_spec("stable_baselines3") is not None
SIZE = re.compile(r"\btotal_timesteps=([\d_]+)")
SMOKE_TIMESTEPS = 1
"""A training snippet's ``learn(total_timesteps=N)`` runs with this: one rollout and one update."""


def section(text: str, title: str) -> str:
    """The body of the ``## title`` section of a Markdown text (up to the next ``## `` heading)."""
    m = re.search(rf"^## {re.escape(title)}\s*$", text, re.M)
    assert m, f"README.md has no '## {title}' section"
    end = re.search(r"^## ", text[m.end():], re.M)
    return text[m.end(): m.end() + end.start() if end else len(text)]


def snippets() -> list[tuple[str, str]]:
    """``(id, code)`` of every Python block of :data:`SECTIONS`, in order."""
    text = README.read_text(encoding="utf-8")
    out = []
    for title in SECTIONS:
        for i, code in enumerate(FENCE.findall(section(text, title))):
            out.append((f"{title.split()[0].lower()}-{i}", code))
    return out


def smoke(code: str) -> str:
    """The snippet at smoke size: every ``total_timesteps=N`` becomes :data:`SMOKE_TIMESTEPS`."""
    return SIZE.sub(f"total_timesteps={SMOKE_TIMESTEPS}", code)


def _params():
    params = []
    for name, code in snippets():
        marks = []
        if "stable_baselines3" in code:
            marks.append(pytest.mark.skipif(not HAS_SB3, reason="stable_baselines3 is not installed (the rl extra)"))
        params.append(pytest.param(code, id=name, marks=marks))
    return params


def test_the_snippets_are_found():
    """A renamed section or a lost fence would silently run nothing: the quick start and the four "Use with"
    snippets (vector API, SB3 batched, SB3 setpoint wrapper, the physics alone) must all be there."""
    names = [name for name, _ in snippets()]
    assert names.count("quick-0") == 1
    assert len([n for n in names if n.startswith("use-")]) >= 4, names


@pytest.mark.parametrize("code", _params())
def test_readme_snippet_runs(code, monkeypatch, tmp_path):
    monkeypatch.chdir(tmp_path)
    # SB3 logs a learn() given no logger (as the README's, like any user's) to $SB3_LOGDIR: here, the test's own folder
    monkeypatch.setenv("SB3_LOGDIR", str(tmp_path / "SB3"))
    namespace = {"__name__": "__readme__"}
    torch = importlib.import_module("torch") if importlib.util.find_spec("torch") else None
    threads = None if torch is None else torch.get_num_threads()
    try:
        exec(compile(smoke(code), "README.md", "exec"), namespace)
    finally:  # a snippet may set torch's threads (the SB3 ones do): the rest of the session keeps its own
        if threads is not None:
            torch.set_num_threads(threads)


def test_rl_zoo3_command_names_the_project_files():
    """The rl-zoo3 command line (run by the slow tests/agents/test_zoo.py) names a config that exists, the env id
    and the package that registers it."""
    body = section(README.read_text(encoding="utf-8"), "Use with ...")
    lines = [ln for ln in body.splitlines() if ln.startswith("python -m rl_zoo3.train ")]
    assert len(lines) == 1, lines
    argv = lines[0].split()
    opt = {argv[i]: argv[i + 1] for i in range(len(argv) - 1) if argv[i].startswith("-")}
    assert opt["--env"] == "PneuNetGrasp-v1" and opt["--gym-packages"] == "pneunet_env" and opt["--algo"] == "ppo"
    assert (ROOT / opt["--conf-file"]).is_file()


def _slug(heading: str) -> str:
    """GitHub's anchor for a heading: lower case, punctuation dropped (but ``-`` and ``_``), spaces to ``-``."""
    text = re.sub(r"`|\*|\[|\]\([^)]*\)", "", heading).strip().lower()
    return re.sub(r"[^\w\- ]", "", text).replace(" ", "-")


def _anchors(path: Path) -> set[str]:
    text = re.sub(r"^```.*?^```", "", path.read_text(encoding="utf-8"), flags=re.S | re.M)
    seen: dict[str, int] = {}
    out = set()
    for _, title in HEADING.findall(text):
        slug = _slug(title)
        n = seen.get(slug, 0)
        seen[slug] = n + 1
        out.add(slug if n == 0 else f"{slug}-{n}")
    return out


@pytest.mark.parametrize("page", [README, *sorted(DOCS.glob("*.md"))], ids=lambda p: p.relative_to(ROOT).as_posix())
def test_relative_links_and_images_exist(page):
    text = re.sub(r"^```.*?^```", "", page.read_text(encoding="utf-8"), flags=re.S | re.M)  # code is not links
    text = re.sub(r"`[^`\n]*`", "", text)
    missing = []
    for target in LINK.findall(text):
        if re.match(r"[a-z][a-z0-9+.-]*:", target):  # https:, mailto:, ...
            continue
        file, _, anchor = target.partition("#")
        dest = (page.parent / file).resolve() if file else page
        if not dest.exists():
            missing.append(target)
        elif anchor and dest.suffix == ".md" and anchor not in _anchors(dest):
            missing.append(target)
    assert not missing, f"{page.relative_to(ROOT)}: broken links {missing}"
