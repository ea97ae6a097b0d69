"""The README's Python snippets run as written, and its relative links and images (and those of docs/) exist.

The README is a front door (at most :data:`MAX_README_LINES` lines, its set-up commands within its first
:data:`SETUP_WITHIN`); its other sections moved to docs/ pages in 0.14 (:data:`PAGES`). The snippets are the fenced
```python blocks of the README and of those pages: the Quick start, and "Use with ..." in ``docs/usage.md``. Each runs
with ``exec`` in a fresh namespace, in-process (torch and numba are imported once for all: about 10 s in all on the
2-core machine), in an empty folder (what a snippet saves stays out of the repository). A training snippet shows the
size it was measured at; it runs here at smoke size (:func:`smoke`). The rl-zoo3 command line of "Use with ..." is a
bash block: the slow ``tests/agents/test_zoo.py`` runs it; ``tests/envs/test_sb3_examples.py`` runs the SB3 snippets
as a user would. ``tests/test_readme_commands.py`` runs the commands of the same pages.
"""

from __future__ import annotations

import importlib.util
import re
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
README = ROOT / "README.md"
DOCS = ROOT / "docs"
USAGE = DOCS / "usage.md"
"""The page of the env's spaces and of "Use with ..." (Gymnasium's vector API, SB3, rl-zoo3, the physics alone)."""
FIRST_PAGES = (README, DOCS / "results.md", USAGE, DOCS / "terms.md", DOCS / "speed.md", DOCS / "commands.md",
               DOCS / "bad-input.md", DOCS / "install.md", DOCS / "development.md")
"""The README and the pages its sections moved to in 0.14, in the order a reader meets them."""
PAGES = FIRST_PAGES + tuple(sorted(set(DOCS.glob("*.md")) - set(FIRST_PAGES)))
"""Every page a user reads: the README and every ``docs/*.md``. Their snippets (here) and commands
(``tests/test_readme_commands.py``) are run; a new page joins by being written."""
MAX_README_LINES = 250
SETUP_WITHIN = 60
"""The README's first screen: its two set-up commands (main job and tests) lie within its first lines."""

FENCE = re.compile(r"^```python\n(.*?)^```", re.S | re.M)
HEADING = re.compile(r"^(#{1,6}) (.+?)\s*$", re.M)
LINK = re.compile(r"!?\[(?:[^\]\[]|\[[^\]]*\])*\]\(([^)\s]+)(?:\s+\"[^\"]*\")?\)")
HTML_ANCHOR = re.compile(r"<a\s+(?:id|name)=\"([^\"]+)\"", re.I)
HAS_SB3 = importlib.util.find_spec("stable_baselines3") is not None
SIZE = re.compile(r"\btotal_timesteps=([\d_]+)")
SIZE_BY_POSITION = re.compile(r"(?<=\.learn\()[\d_]+(?=[,)])")
SMOKE_TIMESTEPS = 1
"""A training snippet's ``learn(total_timesteps=N)`` runs with this: one rollout and one update."""


def page_name(page: Path) -> str:
    """``README.md`` or ``docs/usage.md``: a page as messages name it."""
    return page.relative_to(ROOT).as_posix()


def section(text: str, title: str, page: str = "README.md") -> str:
    """The body of the ``## title`` section of a Markdown text (up to the next ``## `` heading)."""
    m = re.search(rf"^## {re.escape(title)}\s*$", text, re.M)
    assert m, f"{page} has no '## {title}' section"
    end = re.search(r"^## ", text[m.end():], re.M)
    return text[m.end(): m.end() + end.start() if end else len(text)]


def sections(text: str) -> list[tuple[str, str]]:
    """``(title, body)`` of every ``## `` section of a Markdown text, in order (the text before the first: ``""``)."""
    heads = list(re.finditer(r"^## (.+?)\s*$", text, re.M))
    out = [("", text[: heads[0].start() if heads else len(text)])]
    for i, m in enumerate(heads):
        out.append((m.group(1), text[m.end(): heads[i + 1].start() if i + 1 < len(heads) else len(text)]))
    return out


def snippets() -> list[tuple[str, str]]:
    """``(id, code)`` of every Python block of :data:`PAGES`, in order; the id names the page (but the README's) and
    the section (``quick-0``, ``usage/use-2``)."""
    out = []
    for page in PAGES:
        prefix = "" if page == README else page.stem + "/"
        for title, body in sections(page.read_text(encoding="utf-8")):
            for i, code in enumerate(FENCE.findall(body)):
                out.append((f"{prefix}{(title.split() or ['top'])[0].lower()}-{i}", code))
    return out


def smoke(code: str) -> str:
    """The snippet at smoke size: every ``total_timesteps=N``, and a ``.learn(N)`` given its size by position, becomes
    :data:`SMOKE_TIMESTEPS`."""
    return SIZE_BY_POSITION.sub(str(SMOKE_TIMESTEPS), SIZE.sub(f"total_timesteps={SMOKE_TIMESTEPS}", code))


def _params():
    params = []
    for name, code in snippets():
        marks = []
        if "stable_baselines3" in code:
            marks.append(pytest.mark.skipif(not HAS_SB3, reason="stable_baselines3 is not installed (the rl extra)"))
        if ".learn(" in code:  # a training snippet: one rollout at least (64 envs x 2,048 steps: a minute), so slow
            marks.append(pytest.mark.slow)
        params.append(pytest.param(code, id=name, marks=marks))
    return params


def test_a_training_snippet_runs_at_smoke_size_whichever_way_it_gives_its_size():
    # a size given by position (docs/performance.md's PPO(...).learn(100_000)) was run at full size until 0.15
    assert smoke("PPO(p, v).learn(100_000)") == f"PPO(p, v).learn({SMOKE_TIMESTEPS})"
    assert smoke("m.learn(total_timesteps=2_000, progress_bar=True)") == \
        f"m.learn(total_timesteps={SMOKE_TIMESTEPS}, progress_bar=True)"
    assert smoke("m.learn(n)") == "m.learn(n)" and smoke("x = 100_000") == "x = 100_000"


def test_the_snippets_are_found():
    """A renamed section or a lost fence would silently run nothing: the quick start and the four "Use with"
    snippets (vector API, SB3 batched, SB3 setpoint wrapper, the physics alone) must all be there."""
    names = [name for name, _ in snippets()]
    assert names.count("quick-0") == 1
    assert len([n for n in names if n.startswith("usage/use-")]) >= 4, names
    assert len(names) == len(set(names)), names


def _setup_lines(text: str) -> list[int]:
    """The README lines (1-based) of its set-up commands: the ``pip install`` lines of its ```bash blocks."""
    out = []
    for m in re.finditer(r"^```bash\n(.*?)^```", text, re.S | re.M):
        first = text.count("\n", 0, m.start(1)) + 1
        out += [first + i for i, ln in enumerate(m.group(1).splitlines()) if ln.startswith("pip install ")]
    return out


def test_readme_is_a_front_door():
    """Issue 36: the README is at most :data:`MAX_README_LINES` lines, and its two set-up commands (the main job and
    the tests, each the line after its marker, which ``.ci/run`` and ``tests/test_readme_commands.py`` read) come
    within its first :data:`SETUP_WITHIN` lines. Before 0.14 it was 882 lines, "Set up" at line 209."""
    text = README.read_text(encoding="utf-8")
    lines = text.splitlines()
    assert len(lines) <= MAX_README_LINES, f"README.md is {len(lines)} lines, more than {MAX_README_LINES}: move a " \
                                           f"section to a docs/ page (and add the page to PAGES)"
    setup = _setup_lines(text)
    assert len(setup) == 2, f"README.md should show exactly two set-up commands (main job, tests): lines {setup}"
    for marker in ("<!-- main-command -->", "<!-- test-command -->"):
        assert text.count(marker) == 1, marker
        at = lines.index(marker) + 1  # 1-based line of the marker; the fence follows, then the command
        assert lines[at] == "```bash" and at + 2 in setup, f"{marker} (line {at}) is not followed by its command"
    assert max(setup) <= SETUP_WITHIN, f"README.md's set-up commands are at lines {setup}, past {SETUP_WITHIN}"


def test_readme_links_every_page_its_sections_moved_to():
    """A moved section stays findable from the front door: every page of :data:`FIRST_PAGES` exists and is linked
    from the README, and every other page of :data:`PAGES` is reached from it by links."""
    targets = {t.partition("#")[0] for t in LINK.findall(README.read_text(encoding="utf-8"))}
    missing = [page_name(p) for p in FIRST_PAGES[1:] if not p.is_file() or page_name(p) not in targets]
    assert not missing, f"README.md links none of {missing}"
    reached, todo = {README.resolve()}, [README]
    while todo:
        page = todo.pop()
        for target in LINK.findall(page.read_text(encoding="utf-8")):
            path = (page.parent / target.partition("#")[0]).resolve()
            if path.suffix == ".md" and path.is_file() and path not in reached:
                reached.add(path)
                todo.append(path)
    unreached = [page_name(p) for p in PAGES if p.resolve() not in reached]
    assert not unreached, f"no chain of links from README.md reaches {unreached}"


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
    body = section(USAGE.read_text(encoding="utf-8"), "Use with ...", page_name(USAGE))
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
    """The anchors of a page: its headings' (GitHub's slugs), and its ``<a id="...">`` (an anchor kept where a
    section moved away, for the pages that link to it)."""
    text = re.sub(r"^```.*?^```", "", path.read_text(encoding="utf-8"), flags=re.S | re.M)
    seen: dict[str, int] = {}
    out = set(HTML_ANCHOR.findall(text))
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
