"""The Stable-Baselines3 examples (docs/usage.md, "Use with ..." > "Stable-Baselines3") train as the project trains, say
what they reach, and run as a user runs them.

- Their PPO and env settings are ``configs/train/ppo.yaml``'s (what ``pneunet-grasp train`` uses), read from the
  code (:mod:`ast`) and compared key by key. Up to 0.12 the examples used PPO's defaults, with which PPO here stalls
  (0 % of 200 objects after 20,000 steps, issue 32).
- Each says, after its block, the size it was measured at (its ``total_timesteps``, written out: ``200,000 steps``)
  and what it reached (a success rate).
- Each runs as a script in an empty folder at smoke size (``tests/test_readme.py``'s :func:`smoke`), and the
  page's scoring command (``pneunet-grasp demo ... --policy MODEL.zip:action=setpoint``, ``MODEL`` the name the
  example saves) scores the model it saved (slow: two fresh interpreters for each, about 25 s on 2 cores).
"""

from __future__ import annotations

import ast
import importlib.util
import inspect
import os
import re
import shlex
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
_spec = importlib.util.spec_from_file_location("readme_snippets", ROOT / "tests" / "test_readme.py")
readme = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(readme)

SUBSECTION = "Stable-Baselines3"
"""The ``### `` heading, inside docs/usage.md's "Use with ..." section, whose Python blocks are checked here."""
SCORE = re.compile(r"`(pneunet-grasp demo [^`]*MODEL\.zip:action=setpoint[^`]*)`")
"""The page's command that scores an example's model (``MODEL``: the name the example saves)."""
HAS_SB3 = readme.HAS_SB3


def subsection() -> str:
    """The text of the ``### Stable-Baselines3`` subsection (up to the next ``### `` heading)."""
    body = readme.section(readme.USAGE.read_text(encoding="utf-8"), "Use with ...", readme.page_name(readme.USAGE))
    m = re.search(rf"^### {re.escape(SUBSECTION)}\s*$", body, re.M)
    assert m, f"docs/usage.md's 'Use with ...' has no '### {SUBSECTION}'"
    end = re.search(r"^### ", body[m.end():], re.M)
    return body[m.end(): m.end() + end.start() if end else len(body)]


def examples() -> list[tuple[str, str]]:
    """``(code, prose)`` of each Python block of the subsection; ``prose``: the text after it, up to the next
    block."""
    text = subsection()
    blocks = list(readme.FENCE.finditer(text))
    return [(b.group(1), text[b.end(): blocks[i + 1].start() if i + 1 < len(blocks) else len(text)])
            for i, b in enumerate(blocks)]


EXAMPLES = examples()
IDS = [f"example-{i + 1}" for i in range(len(EXAMPLES))]


def test_both_examples_are_found():
    """A lost fence would check nothing: the batched env's example and SB3's ``make_vec_env`` one, each training."""
    assert len(EXAMPLES) == 2, [code[:60] for code, _ in EXAMPLES]
    assert all("PPO(" in code and ".learn(" in code for code, _ in EXAMPLES)


class Name(str):
    """A plain name in the code (``wrapper_class=PressureSetpoint``), not a literal string."""


def _value(node: ast.AST):
    """A literal, ``dict(key=literal, ...)``, or a plain name (:class:`Name`)."""
    if isinstance(node, ast.Name):
        return Name(node.id)
    if isinstance(node, ast.Call) and isinstance(node.func, ast.Name) and node.func.id == "dict" and not node.args:
        return {kw.arg: _value(kw.value) for kw in node.keywords}
    return ast.literal_eval(node)


def _calls(tree: ast.AST, name: str) -> list[ast.Call]:
    return [n for n in ast.walk(tree) if isinstance(n, ast.Call) and isinstance(n.func, ast.Name) and n.func.id == name]


def _keywords(call: ast.Call) -> dict:
    return {kw.arg: _value(kw.value) for kw in call.keywords}


def _size(code: str) -> int:
    sizes = readme.SIZE.findall(code)
    assert len(sizes) == 1, f"one learn(total_timesteps=N) expected, found {sizes}"
    return int(sizes[0].replace("_", ""))


@pytest.mark.parametrize(("code", "prose"), EXAMPLES, ids=IDS)
def test_example_states_its_size_and_what_it_reaches(code, prose):
    """The examples (usage.md) learn at the size they show, and say what they reach there (issue 32: at 20,000 steps
    the earlier ones held nothing, and the README said neither how many steps they need nor what they reach)."""
    n = _size(code)
    assert f"{n:,} steps" in prose, f"the text after the example does not state its size, '{n:,} steps'"
    assert re.search(r"\d+(\.\d+)? %", prose), "the text after the example does not state a success rate"


@pytest.mark.skipif(not HAS_SB3, reason="stable_baselines3 is not installed (the rl extra)")
@pytest.mark.parametrize(("code", "prose"), EXAMPLES, ids=IDS)
def test_example_trains_with_ppo_yaml(code, prose):
    """The example's PPO, vec env size, reward normalisation and action are ``configs/train/ppo.yaml``'s: every
    algorithm key of the file, given in the example or left at PPO's default, has the file's value, and the example
    sets nothing else but ``seed``."""
    from stable_baselines3 import PPO

    from agents.training.config import _algo_kwargs, load_train_config

    hp = load_train_config(ROOT / "configs" / "train" / "ppo.yaml")
    tree = ast.parse(code)
    (ppo,) = _calls(tree, "PPO")
    given = _keywords(ppo)
    assert _value(ppo.args[0]) == hp["policy"]
    assert given.pop("policy_kwargs", None) == hp["policy_kwargs"], "policy_kwargs differ from ppo.yaml's"
    assert set(given) - set(_algo_kwargs(hp)) == {"seed"}, "the example sets PPO keys that ppo.yaml does not"
    defaults = {k: p.default for k, p in inspect.signature(PPO).parameters.items()}
    for key, want in _algo_kwargs(hp).items():
        assert given.get(key, defaults[key]) == want, f"PPO's {key}: the example's differs from ppo.yaml's {want!r}"

    envs = [_keywords(c) for c in (*_calls(tree, "SB3VecEnv"), *_calls(tree, "make_vec_env"))]
    assert len(envs) == 1 and envs[0].get("num_envs", envs[0].get("n_envs")) == hp["n_envs"], envs
    (norm,) = _calls(tree, "VecNormalize")
    norm_kw = _keywords(norm)
    want_norm = {"norm_obs": True, "norm_reward": True, **hp["normalize"]}
    assert {k: norm_kw.get(k, True) for k in ("norm_obs", "norm_reward")} == want_norm
    assert norm_kw.get("gamma") == hp["gamma"], "VecNormalize's return discount is not PPO's gamma"

    assert hp["env_wrapper"] == "pneunet_env.wrappers.PressureSetpoint"
    wrapped = [kw.get("wrapper_class") for kw in envs]
    setpoint = _calls(tree, "PressureSetpointVecEnv") or [w for w in wrapped if isinstance(w, Name)
                                                          and w == "PressureSetpoint"]
    assert setpoint, "the example's action is not ppo.yaml's pressure setpoint"
    imported = {a.name for n in ast.walk(tree) if isinstance(n, ast.ImportFrom) and n.module == "pneunet_env.wrappers"
                for a in n.names}
    assert imported & {"PressureSetpoint", "PressureSetpointVecEnv"}


def test_the_scoring_command_is_shown():
    """docs/usage.md names the command that scores an example's model, with ``MODEL`` for the name it saves."""
    assert len(SCORE.findall(" ".join(subsection().split()))) == 1


@pytest.mark.slow
@pytest.mark.skipif(not HAS_SB3, reason="stable_baselines3 is not installed (the rl extra)")
@pytest.mark.parametrize(("code", "prose"), EXAMPLES, ids=IDS)
def test_example_runs_as_a_user_runs_it(code, prose, tmp_path):
    """The example, at smoke size, as a script run by a fresh interpreter in an empty folder; then the page's
    scoring command on the model it saved, which must be scored on every object (a row with its name)."""
    saved = re.findall(r"""model\.save\(["']([^"']+)["']\)""", code)
    assert len(saved) == 1, "the example saves no model (model.save('NAME')) for the scoring command"
    script = tmp_path / "example.py"
    script.write_text(readme.smoke(code), encoding="utf-8")
    env = {**os.environ, "SB3_LOGDIR": str(tmp_path / "SB3")}  # SB3's log of a learn() with no logger: kept here
    run = subprocess.run([sys.executable, str(script)], cwd=tmp_path, env=env, capture_output=True, text=True,
                         timeout=600)
    assert run.returncode == 0, run.stderr[-3000:]
    assert (tmp_path / f"{saved[0]}.zip").is_file()

    (command,) = SCORE.findall(" ".join(subsection().split()))
    argv = [w.replace("MODEL", saved[0]) for w in shlex.split(command)[1:]]
    argv += ["--objects", "4", "--no-progress"]  # argparse keeps the last value: 4 objects
    run = subprocess.run([sys.executable, "-m", "pneunet_env.cli", *argv], cwd=tmp_path, env=env,
                         capture_output=True, text=True, timeout=600)
    assert run.returncode == 0, run.stderr[-3000:]
    rows = [ln.split() for ln in run.stdout.splitlines()]
    row = next((r for r in rows if r[:1] == [saved[0]]), None)
    assert row is not None and row[-1].endswith("%"), run.stdout
