"""``pneunet-grasp``: the package's command line.

Each subcommand lives in its own module, imported only when it runs (or is asked for its ``--help``), so
``pneunet-grasp solve`` needs neither torch nor matplotlib and ``pneunet-grasp --help`` imports none of them.
A subcommand module provides ``add_arguments(parser)`` and ``run(args) -> int``. Commands whose name has two
words (``bench speed``) form a group (``bench``) that answers ``--help`` with its sub-commands.
``python -m pneunet_env.cli`` is the same as ``pneunet-grasp``.
"""

from __future__ import annotations

import argparse
import difflib
import importlib
import os
import sys

from pneunet_env.extras import PROG, require_extra

__all__ = ["COMMANDS", "GROUPS", "main", "require_extra"]

# name -> (module, one-line help)
COMMANDS: dict[str, tuple[str, str]] = {
    "demo": ("pneunet_env.cli.demo", "main job: evaluate the scripted pressure ramp across object stiffnesses"),
    "solve": ("pneunet_env.cli.solve", "print a quasi-static loading path for one object"),
    "render": ("pneunet_env.cli.render", "save rendered frames of an episode as PNG"),
    "figures": ("pneunet_env.paper.command", "regenerate the paper's figures (PNG + CSV) and check its statements"),
    "bench speed": ("pneunet_env.bench.speed", "speed benchmark against CartPole (table, JSON, PNG)"),
    "bench solvers": ("pneunet_env.bench.solvers", "solver study: speed vs accuracy, stability map"),
    "bench design": ("agents.bench_design", "what a design study costs: one design evaluation, and the batched "
                     "search against the episode loop"),
    "bench render": ("pneunet_env.bench.render_speed", "rgb_array frames/s (step + render) against CartPole"),
    "bench train": ("agents.bench_train", "PPO training steps/s on the env (the shipped config) against the same PPO "
                    "on CartPole"),
    "evaluate": ("agents.evaluate", "evaluate policies over a stiffness grid (table, JSON, PNGs)"),
    "train": ("agents.train", "train an SB3 agent from a YAML config"),
    "train-skrl": ("agents.train_skrl", "train skrl's PPO on the torch backend, on its device (extra: skrl)"),
    "search": ("agents.search", "tune the blind best-ramp (or rigid) schedule; --sensitivity runs the threshold study"),
    "design": ("agents.design", "design the actuator: which walls and elastomer let one blind ramp hold a use case "
               "(Optuna; extra: design)"),
    "map": ("agents.maps", "chart success over object modulus x radius: oracle, best blind ramp, rigid jaw, "
            "with the regime boundary"),
}

# group -> one-line help; a group's sub-commands are the COMMANDS named "GROUP SUB"
GROUPS: dict[str, str] = {
    "bench": "benchmarks: the environment's speed and the equilibrium solvers' accuracy",
}

_HELP = ("-h", "--help")


def _subcommands(group: str) -> dict[str, str]:
    prefix = group + " "
    return {name[len(prefix):]: help_ for name, (_, help_) in COMMANDS.items() if name.startswith(prefix)}


def _top_level() -> list[str]:
    """The first words of the commands, in order: ``demo``, ..., ``bench``, ..."""
    return list(dict.fromkeys(name.split(" ", 1)[0] for name in COMMANDS))


def _table(rows: dict[str, str]) -> list[str]:
    width = max(len(n) for n in rows)
    return [f"  {name:<{width}}  {help_}" for name, help_ in rows.items()]


def _usage() -> str:
    lines = [f"usage: {PROG} [-h] [-V] COMMAND [options]", "",
             "Soft PneuNet gripper environment: demos, figures, benchmarks and agents.", "", "commands:"]
    lines += _table({name: help_ for name, (_, help_) in COMMANDS.items()})
    lines += ["", "options:", "  -h, --help     show this help and exit", "  -V, --version  print the version and exit",
              "", f"Run '{PROG} COMMAND --help' for a command's options."]
    return "\n".join(lines)


def _group_usage(group: str) -> str:
    subs = _subcommands(group)
    lines = [f"usage: {PROG} {group} [-h] {{{','.join(subs)}}} [options]", "", GROUPS.get(group, ""), "",
             "sub-commands:"]
    lines += _table(subs)
    lines += ["", "options:", "  -h, --help  show this help and exit", "",
              f"Run '{PROG} {group} SUB-COMMAND --help' for a sub-command's options."]
    return "\n".join(lines)


def _did_you_mean(word: str, choices) -> str:
    close = difflib.get_close_matches(word, list(choices), n=1)
    return f"; did you mean {close[0]!r}?" if close else f" (choose from {', '.join(choices)})"


def _error(message: str, usage: str) -> int:
    """argparse's way: the usage line, the error, a pointer to the full help; exit status 2."""
    first = usage.splitlines()[0]
    help_cmd = first.removeprefix("usage: ").split(" [-h]")[0]
    print(f"{first}\n{PROG}: error: {message}\nRun '{help_cmd} --help' for usage.", file=sys.stderr)
    return 2


def main(argv: list[str] | None = None) -> int:
    """Run ``pneunet-grasp ARGV``; return the exit status (``--help`` and argument errors raise ``SystemExit``)."""
    argv = list(sys.argv[1:] if argv is None else argv)
    if not argv or argv[0] in _HELP:
        print(_usage())
        return 0
    if argv[0] in ("-V", "--version"):
        from pneunet_env import __version__

        print(f"{PROG} {__version__}")
        return 0
    head = argv[0]
    if head in GROUPS:
        rest = argv[1:]
        if not rest:
            return _error(f"'{head}' needs a sub-command ({', '.join(_subcommands(head))})", _group_usage(head))
        if rest[0] in _HELP:
            print(_group_usage(head))
            return 0
        name = f"{head} {rest[0]}"
        if name not in COMMANDS:
            return _error(f"unknown {head} sub-command {rest[0]!r}{_did_you_mean(rest[0], _subcommands(head))}",
                          _group_usage(head))
    elif head in COMMANDS:
        name = head
    elif head.startswith("-"):
        return _error(f"unknown option {head!r}", _usage())
    else:
        return _error(f"unknown command {head!r}{_did_you_mean(head, _top_level())}", _usage())
    module_name, help_ = COMMANDS[name]
    args_in = argv[len(name.split()):]
    try:
        module = importlib.import_module(module_name)
    except ModuleNotFoundError as exc:
        if exc.name and module_name.startswith(exc.name):
            print(f"{PROG}: command {name!r} is not available in this version", file=sys.stderr)
            return 2
        missing = (f"{PROG} {name}: missing dependency {exc.name!r}; install the package's extras "
                   "(see README)")
        if any(a in _HELP for a in args_in):  # still answer --help, without the options it cannot list
            print(f"usage: {PROG} {name} [options]\n\n{help_}\n\n{missing}")
            return 0
        print(missing, file=sys.stderr)
        return 2
    parser = argparse.ArgumentParser(prog=f"{PROG} {name}", description=help_)
    module.add_arguments(parser)
    args = parser.parse_args(args_in)
    config = getattr(args, "config", None)
    if isinstance(config, str) and not os.path.isfile(config):  # a shipped config by name: ppo, designed-kitchen
        from agents.resources import is_name, resolve_config

        if is_name(config):
            try:
                args.config_given = config
                args.config = str(resolve_config(config, "train" if name == "train" else "env"))
            except ValueError as exc:
                raise SystemExit(f"{PROG} {name}: {exc}") from None
    try:
        return int(module.run(args) or 0)
    except BrokenPipeError:
        if not _stdout_closed():
            raise  # some other pipe: a real error
        return 141  # the reader of stdout went away (``| head``): stop quietly, 128 + SIGPIPE, as a Unix command does


def _stdout_closed() -> bool:
    """Whether stdout is a pipe whose reader has gone away (``poll`` reports an error on its write end); if so,
    stdout is pointed at ``os.devnull``, so that the interpreter's final flush does not raise again."""
    try:
        fd = sys.stdout.fileno()
    except (AttributeError, OSError, ValueError):  # no file descriptor: the broken pipe was not stdout
        return False
    try:
        import select

        poller = select.poll()
        poller.register(fd, select.POLLOUT)
        closed = any(event & select.POLLERR for _, event in poller.poll(0))
    except (AttributeError, OSError):  # no poll (Windows): assume stdout, as Python's own recipe does
        closed = True
    if closed:
        devnull = os.open(os.devnull, os.O_WRONLY)
        try:
            os.dup2(devnull, fd)
        finally:
            os.close(devnull)
    return closed


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
