"""The layout's rules, checked on the import graph (every import, at module level or inside a function).

* the physics imports nothing from the Gym layer (nor gymnasium itself);
* below the CLI, the library imports nothing from ``agents``; the library never depends on ``paper`` or ``bench``;
* no import cycle between the package's modules;
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


def _graph() -> dict[str, set[str]]:
    modules = {_module_name(p): p for p in ROOT.rglob("*.py")}
    graph = {}
    for name, path in modules.items():
        deps = {m for m in _imports(path) if m in modules and m != name}
        # `from pkg import submodule` depends on the submodule; the package's __init__ runs first in any case
        graph[name] = {d for d in deps if not any(x.startswith(d + ".") for x in deps)}
    return graph


GRAPH = _graph()


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


def test_no_import_cycle():
    # Tarjan-free: a depth-first search for a back edge.
    state: dict[str, int] = {}
    stack: list[str] = []

    def visit(m: str) -> None:
        state[m] = 1
        stack.append(m)
        for d in sorted(GRAPH[m]):
            if state.get(d) == 1:
                cycle = stack[stack.index(d):] + [d]
                raise AssertionError(f"import cycle: {' -> '.join(cycle)}")
            if d not in state:
                visit(d)
        stack.pop()
        state[m] = 2

    for m in sorted(GRAPH):
        if m not in state:
            visit(m)


def test_core_imports_without_torch_numba_or_matplotlib_and_registers_every_env():
    code = (
        "import sys\n"
        "class Block:\n"
        "    def find_spec(self, name, path=None, target=None):\n"
        "        if name.split('.')[0] in ('torch', 'matplotlib', 'stable_baselines3', 'agents'):\n"
        "            raise ImportError('blocked: ' + name)\n"
        "sys.meta_path.insert(0, Block())\n"
        "import gymnasium as gym, pneunet_env\n"
        "env = gym.make('PneuNetGrasp-v0'); env.reset(seed=0); env.step([0.5])\n"
        "env = gym.make('RigidGrasp-v0'); env.reset(seed=0); env.step([0.5])\n"
        "print('ok')\n"
    )
    res = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120,
                         env={"PNEUNET_DISABLE_NUMBA": "1", "PATH": "/usr/bin:/bin"})
    assert res.returncode == 0 and res.stdout.strip() == "ok", res.stderr
    for env_id in ("PneuNetGrasp-v0", "RigidGrasp-v0"):
        assert env_id in gym.registry


def test_the_lowest_gymnasium_has_what_the_env_uses():
    """``AutoresetMode`` (gymnasium.vector) arrived in Gymnasium 1.1: the requirement says so."""
    import re

    text = (ROOT.parent / "pyproject.toml").read_text()
    m = re.search(r'"gymnasium>=(\d+)\.(\d+)', text)
    assert m and (int(m.group(1)), int(m.group(2))) >= (1, 1), "pyproject.toml must require gymnasium>=1.1"
    from gymnasium.vector import AutoresetMode  # noqa: F401
