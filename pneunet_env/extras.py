"""Optional packages a command needs: :func:`require_extra` checks one before the work starts.

The command line, ``agents``, ``pneunet_env.bench`` and ``pneunet_env.paper`` import it from here (below the CLI),
so that nothing imports :mod:`pneunet_env.cli` but the entry point itself.
"""

from __future__ import annotations

import importlib
import sys

__all__ = ["PROG", "require_extra"]

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
        hint = f", or pass {skip} to do without" if skip else ""
        print(f"{PROG} {command}: {module} is not installed and is needed for {what or 'this command'}: "
              f"pip install -e \".[{extra}]\" (or pip install \"pneunet-env[{extra}]\"){hint}", file=sys.stderr)
        raise SystemExit(2) from None
