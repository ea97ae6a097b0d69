"""The layout's rules, checked on the import graph (every import, at module level or inside a function).

* the physics imports nothing from the Gym layer (nor gymnasium itself);
* below the CLI, the library imports nothing from ``agents``; the library never depends on ``paper`` or ``bench``;
* no import cycle between the package's modules, nor between those of ``agents``;
* ``agents`` in layers (``docs/architecture.md``): ``common`` imports nothing from ``agents``; ``policies`` and
  ``figures`` only ``common`` (a figure takes data: it imports no module that computes it); ``evaluation`` nothing
  above it; no package imports ``bench``, and no module imports a command's CLI module but that command's own;
* no module of either package is over 800 lines;
* ``import pneunet_env`` needs neither torch, numba nor matplotlib, and registers every env id.
"""

from __future__ import annotations

import ast
import subprocess
import sys
from pathlib import Path

import gymnasium as gym

import pneunet_env

ROOT = Path(pneunet_env.__file__).resolve().parent


def _module_name(path: Path) -> str:
    rel = path.relative_to(ROOT.parent).with_suffix("")
    parts = list(rel.parts)
    if parts[-1] == "__init__":
        parts = parts[:-1]
    return ".".join(parts)


def _imports(path: Path) -> set[str]:
    """Every module ``path`` imports (absolute names; relative imports resolved), at any depth in the file."""
    tree = ast.parse(path.read_text())
    pkg = _module_name(path).split(".")
    if path.name != "__init__.py":
        pkg = pkg[:-1]
    out: set[str] = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            out.update(a.name for a in node.names)
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                base = pkg[: len(pkg) - node.level + 1]
                mod = ".".join(base + ([node.module] if node.module else []))
            else:
                mod = node.module or ""
            out.add(mod)
            out.update(f"{mod}.{a.name}" for a in node.names)  # `from pkg import module`
    return out


def _graph(root: Path = ROOT) -> dict[str, set[str]]:
    modules = {_module_name(p): p for p in root.rglob("*.py")}
    graph = {}
    for name, path in modules.items():
        deps = {m for m in _imports(path) if m in modules and m != name}
        # `from pkg import submodule` depends on the submodule; the package's __init__ runs first in any case
        graph[name] = {d for d in deps if not any(x.startswith(d + ".") for x in deps)}
    return graph


GRAPH = _graph()
AGENTS = ROOT.parent / "agents"
AGENTS_GRAPH = _graph(AGENTS)


def _imported(prefix: str) -> dict[str, set[str]]:
    return {m: deps for m, deps in GRAPH.items() if m == prefix or m.startswith(prefix + ".")}


def test_physics_imports_nothing_from_the_gym_layer():
    for mod, path in ((m, p) for p in ROOT.joinpath("physics").rglob("*.py") for m in [_module_name(p)]):
        deps = _imports(path)
        assert not any(d.split(".")[0] == "gymnasium" for d in deps), mod
        inside = {d for d in deps if d.startswith("pneunet_env.") and not d.startswith("pneunet_env.physics")}
        assert not inside, (mod, inside)


def test_only_the_cli_reaches_into_agents():
    for p in ROOT.rglob("*.py"):
        mod = _module_name(p)
        uses_agents = {d for d in _imports(p) if d == "agents" or d.startswith("agents.")}
        if mod.startswith("pneunet_env.cli"):
            continue
        assert not uses_agents, (mod, uses_agents)


def test_agents_bench_and_paper_do_not_import_the_cli():
    """The CLI sits on top: ``agents``, ``pneunet_env.bench`` and ``pneunet_env.paper`` take progress bars, the
    extras check and the atomic writer from below it (``pneunet_env.progress``, ``.extras``, ``.files``)."""
    files = [*ROOT.parent.joinpath("agents").rglob("*.py"), *ROOT.joinpath("bench").rglob("*.py"),
             *ROOT.joinpath("paper").rglob("*.py")]
    assert len(files) > 20
    for p in files:
        bad = {d for d in _imports(p) if d == "pneunet_env.cli" or d.startswith("pneunet_env.cli.")}
        assert not bad, (p, bad)


def test_the_library_does_not_depend_on_paper_or_bench():
    for mod, deps in GRAPH.items():
        if mod.startswith(("pneunet_env.paper", "pneunet_env.bench", "pneunet_env.cli")):
            continue
        bad = {d for d in deps if d.startswith(("pneunet_env.paper", "pneunet_env.bench"))}
        assert not bad, (mod, bad)


def _find_cycle(graph: dict[str, set[str]]) -> list[str] | None:
    """An import cycle of ``graph`` (its modules, the first repeated at the end), or ``None``: a depth-first search
    for a back edge."""
    state: dict[str, int] = {}
    stack: list[str] = []

    def visit(m: str) -> list[str] | None:
        state[m] = 1
        stack.append(m)
        for d in sorted(graph[m]):
            if state.get(d) == 1:
                return stack[stack.index(d):] + [d]
            if d not in state and (cycle := visit(d)):
                return cycle
        stack.pop()
        state[m] = 2
        return None

    for m in sorted(graph):
        if m not in state and (cycle := visit(m)):
            return cycle
    return None


def test_no_import_cycle():
    cycle = _find_cycle(GRAPH)
    assert cycle is None, f"import cycle: {' -> '.join(cycle)}"


def test_no_import_cycle_in_agents():
    """Every import of ``agents`` at any depth (inside functions too): none may close a circle."""
    assert len(AGENTS_GRAPH) > 30
    cycle = _find_cycle(AGENTS_GRAPH)
    assert cycle is None, f"import cycle: {' -> '.join(cycle)}"


def test_the_cycle_finder_finds_a_cycle_and_the_graph_sees_imports_inside_functions(tmp_path):
    assert _find_cycle({"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": set()}) == ["a", "b", "c", "a"]
    assert _find_cycle({"a": {"b"}, "b": set()}) is None
    # batch reaches run_episode inside a function: the walk sees it
    assert "agents.evaluation.episodes" in AGENTS_GRAPH["agents.evaluation.batch"]


_LAYERS: dict[str, tuple[str, ...]] = {
    # package -> the packages of agents it may import (besides itself)
    "agents.common": (),
    "agents.policies": ("agents.common",),
    "agents.figures": ("agents.common",),
    "agents.evaluation": ("agents.common", "agents.policies", "agents.figures"),
    "agents.search": ("agents.common", "agents.policies", "agents.figures", "agents.evaluation"),
    "agents.training": ("agents.common", "agents.policies", "agents.figures", "agents.evaluation"),
    "agents.design": ("agents.common", "agents.policies", "agents.figures", "agents.evaluation"),
    "agents.bench": ("agents.common", "agents.policies", "agents.figures", "agents.evaluation", "agents.search",
                     "agents.training", "agents.design"),
}


def _package(module: str) -> str:
    return ".".join(module.split(".")[:2])


def _is_command_cli(module: str) -> bool:
    """A command's CLI module (``agents.search.cli``, ``agents.evaluation.map_cli``); ``agents.common.cli`` holds the
    helpers every command shares."""
    last = module.rsplit(".", 1)[-1]
    return (last == "cli" or last.endswith("_cli")) and _package(module) != "agents.common"


def test_agents_is_in_layers():
    packages = {_package(m) for m in AGENTS_GRAPH if m != "agents"}
    assert packages == set(_LAYERS), "a new package of agents needs its place in _LAYERS and docs/architecture.md"
    for mod, deps in AGENTS_GRAPH.items():
        if mod == "agents":
            continue
        own = _package(mod)
        bad = {d for d in deps if _package(d) != own and _package(d) not in _LAYERS[own] and d != "agents"}
        assert not bad, (mod, bad)
        # a command's CLI module is the top of its package: only that package's __main__ imports it
        bad = {d for d in deps if _is_command_cli(d) and not mod.endswith("__main__")
               and not (own == "agents.design" and d.startswith("agents.design."))}
        assert not bad, (mod, bad)


def test_the_agents_layer_rule_catches_an_upward_import():
    """The rule above fails on a figure that imports the module that computes its data."""
    graph = {**AGENTS_GRAPH, "agents.figures.maps": AGENTS_GRAPH["agents.figures.maps"] | {"agents.evaluation.maps"}}
    own = "agents.figures"
    assert any(_package(d) not in _LAYERS[own] and _package(d) != own for d in graph["agents.figures.maps"])


MAX_LINES = 800
"""The house size of a module ("A house a newcomer can change")."""


def test_no_module_is_over_the_house_size():
    long = {}
    for path in [*ROOT.rglob("*.py"), *AGENTS.rglob("*.py")]:
        n = len(path.read_text().splitlines())
        if n > MAX_LINES:
            long[str(path.relative_to(ROOT.parent))] = n
    assert not long, f"modules over {MAX_LINES} lines: {long}"


def test_core_imports_without_torch_numba_or_matplotlib_and_registers_every_env():
    code = (
        "import sys\n"
        "class Block:\n"
        "    def find_spec(self, name, path=None, target=None):\n"
        "        if name.split('.')[0] in ('torch', 'matplotlib', 'stable_baselines3', 'agents'):\n"
        "            raise ImportError('blocked: ' + name)\n"
        "sys.meta_path.insert(0, Block())\n"
        "import gymnasium as gym, pneunet_env\n"
        "env = gym.make('PneuNetGrasp-v1'); env.reset(seed=0); env.step([0.5])\n"
        "env = gym.make('RigidGrasp-v1'); env.reset(seed=0); env.step([0.5])\n"
        "print('ok')\n"
    )
    res = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120,
                         env={"PNEUNET_DISABLE_NUMBA": "1", "PATH": "/usr/bin:/bin"})
    assert res.returncode == 0 and res.stdout.strip() == "ok", res.stderr
    for env_id in ("PneuNetGrasp-v1", "RigidGrasp-v1"):
        assert env_id in gym.registry


def test_the_lowest_gymnasium_has_what_the_env_uses():
    """``AutoresetMode`` (gymnasium.vector) arrived in Gymnasium 1.1: the requirement says so."""
    import re

    text = (ROOT.parent / "pyproject.toml").read_text()
    m = re.search(r'"gymnasium>=(\d+)\.(\d+)', text)
    assert m and (int(m.group(1)), int(m.group(2))) >= (1, 1), "pyproject.toml must require gymnasium>=1.1"
    from gymnasium.vector import AutoresetMode  # noqa: F401
