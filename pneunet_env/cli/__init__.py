"""``pneunet-grasp``: the package's command line.

Each subcommand lives in its own module, imported only when it runs, so ``pneunet-grasp solve``
needs neither torch nor matplotlib. A subcommand module provides ``add_arguments(parser)`` and
``run(args) -> int``.
"""

from __future__ import annotations

import argparse
import importlib
import sys

__all__ = ["COMMANDS", "main"]

# name -> (module, one-line help)
COMMANDS: dict[str, tuple[str, str]] = {
    "demo": ("pneunet_env.cli.demo", "main job: evaluate the scripted pressure ramp across object stiffnesses"),
    "solve": ("pneunet_env.cli.solve", "print a quasi-static loading path for one object"),
    "render": ("pneunet_env.cli.render", "save rendered frames of an episode as PNG"),
    "figures": ("pneunet_env.paper.command", "regenerate the paper's figures (PNG + CSV) and check its statements"),
    "bench speed": ("pneunet_env.bench.speed", "speed benchmark against CartPole (table, JSON, PNG)"),
    "bench solvers": ("pneunet_env.bench.solvers", "solver study: speed vs accuracy, stability map"),
    "evaluate": ("agents.evaluate", "evaluate policies over a stiffness grid (table, JSON, PNGs)"),
    "train": ("agents.train", "train an SB3 agent from a YAML config"),
    "search": ("agents.search", "tune the blind best-ramp (or rigid) schedule; --sensitivity runs the threshold study"),
}


def _usage() -> str:
    width = max(len(n) for n in COMMANDS)
    lines = ["usage: pneunet-grasp COMMAND [options]", "", "commands:"]
    lines += [f"  {name:<{width}}  {help_}" for name, (_, help_) in COMMANDS.items()]
    lines += ["", "Run 'pneunet-grasp COMMAND --help' for a command's options."]
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    argv = list(sys.argv[1:] if argv is None else argv)
    if not argv or argv[0] in ("-h", "--help"):
        print(_usage())
        return 0
    if argv[0] in ("-V", "--version"):
        from pneunet_env import __version__

        print(f"pneunet-grasp {__version__}")
        return 0
    name = " ".join(argv[:2]) if " ".join(argv[:2]) in COMMANDS else argv[0]
    if name not in COMMANDS:
        print(f"pneunet-grasp: unknown command {' '.join(argv[:2])!r}\n\n{_usage()}", file=sys.stderr)
        return 2
    module_name, help_ = COMMANDS[name]
    try:
        module = importlib.import_module(module_name)
    except ModuleNotFoundError as exc:
        if exc.name and module_name.startswith(exc.name):
            print(f"pneunet-grasp: command {name!r} is not available in this version", file=sys.stderr)
            return 2
        print(f"pneunet-grasp {name}: missing dependency {exc.name!r}; install the package's extras "
              "(see README)", file=sys.stderr)
        return 2
    parser = argparse.ArgumentParser(prog=f"pneunet-grasp {name}", description=help_)
    module.add_arguments(parser)
    args = parser.parse_args(argv[len(name.split()):])
    return int(module.run(args) or 0)


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
