"""Optional packages a command needs: :func:`require_extra` checks one before the work starts.

The command line, ``agents``, ``pneunet_env.bench`` and ``pneunet_env.paper`` import it from here (below the CLI),
so that nothing imports :mod:`pneunet_env.cli` but the entry point itself.
"""

from __future__ import annotations

import importlib
import sys

__all__ = ["EXTRA_OF", "PROG", "missing_extra", "missing_line", "require_extra", "warn"]

PROG = "pneunet-grasp"
"""The command line's program name, as error lines print it."""


def require_extra(command: str, module: str, extra: str, what: str = "", skip: str | None = None) -> None:
    """Exit now (status 2, one line on stderr) unless ``module`` imports: a command checks the optional packages it
    will need before it does its work, not after. The line names the extra that installs ``module``.

    Args:
        command: the command, as the user typed it after ``pneunet-grasp`` (``"evaluate"``).
        module: the module to import (``"matplotlib"``).
        extra: the package extra that provides it (``"plot"``).
        what: what needs it (``"the plots"``); default: ``"this command"``.
        skip: an option that does without it (``"--no-plots"``), named in the message.
    """
    try:
        importlib.import_module(module)
    except ImportError:
        print(missing_line(command, module, extra, what, skip), file=sys.stderr)
        raise SystemExit(2) from None


EXTRA_OF = {"stable_baselines3": "rl", "sb3_contrib": "rl", "torch": "rl", "rich": "rl", "rl_zoo3": "zoo",
            "skrl": "skrl", "matplotlib": "plot", "tqdm": "plot", "optuna": "design", "numba": "fast"}
"""The optional packages by their top-level module, and the extra of ``pyproject.toml`` that installs each (``torch``
is in ``rl`` and ``skrl``: ``rl``, the one the SB3 commands need; ``train-skrl`` checks its own)."""


def missing_line(command: str, module: str, extra: str, what: str = "", skip: str | None = None) -> str:
    """The one line :func:`require_extra` prints: ``pneunet-grasp COMMAND: MODULE is not installed and is needed for
    WHAT: pip install -e ".[EXTRA]" (or pip install "pneunet-env[EXTRA]")[, or pass SKIP to do without]``."""
    hint = f", or pass {skip} to do without" if skip else ""
    return (f"{PROG} {command}: {module} is not installed and is needed for {what or 'this command'}: "
            f"pip install -e \".[{extra}]\" (or pip install \"pneunet-env[{extra}]\"){hint}")


def missing_extra(exc: ImportError) -> tuple[str, str] | None:
    """``(module, extra)`` where ``exc`` is the import of an optional package (:data:`EXTRA_OF`) that is not installed
    (not a package that is there but broken: its top-level module is then found); else ``None``."""
    import importlib.util

    name = getattr(exc, "name", None)
    if not isinstance(name, str) or not name:
        return None
    top = name.partition(".")[0]
    if top not in EXTRA_OF:
        return None
    try:
        found = importlib.util.find_spec(top) is not None
    except (ImportError, ValueError):  # a half-imported module: treat as found (a real error, not a missing extra)
        found = True
    return None if found else (top, EXTRA_OF[top])


def warn(prog: str, message: str) -> None:
    """A command's warning: one line on stderr, ``PROG: warning: MESSAGE`` (the form of its error lines; the command
    goes on). Written above a progress bar that is being drawn (``tqdm.write``), not through it.

    Args:
        prog: the command as its lines name it (``"pneunet-grasp demo"``).
        message: the warning (whitespace, newlines included, is folded to single spaces: one line).
    """
    _line(f"{prog}: warning: {' '.join(str(message).split())}")


def _line(text: str) -> None:
    """``text`` and a newline on stderr, now (above a tqdm bar being drawn, where there is one)."""
    bar = getattr(sys.modules.get("tqdm"), "tqdm", None)
    if bar is not None and getattr(bar, "_instances", None):
        bar.write(text, file=sys.stderr)
    else:
        print(text, file=sys.stderr, flush=True)
