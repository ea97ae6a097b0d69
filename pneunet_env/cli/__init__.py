"""``pneunet-grasp``: the package's command line.

Each subcommand lives in its own module, imported only when it runs (or is asked for its ``--help``), so
``pneunet-grasp solve`` needs neither torch nor matplotlib and ``pneunet-grasp --help`` imports none of them.
A subcommand module provides ``add_arguments(parser)`` and ``run(args) -> int``. Commands whose name has two
words (``bench speed``) form a group (``bench``) that answers ``--help`` with its sub-commands.
``python -m pneunet_env.cli`` is the same as ``pneunet-grasp``.

**Errors.** Every command's errors end the same way: one line on stderr, ``pneunet-grasp CMD: error: MESSAGE``
naming the input, and exit status 2, without a traceback. That holds for argparse's own errors (an unknown option, a
value its ``type=`` refuses: :mod:`pneunet_env.arguments` checks numbers and output paths at parse time, before any
work), for a ``ValueError``, ``TypeError`` or ``OverflowError`` (``int(inf)``) a command raises from bad input, and
for a command's ``SystemExit`` with a message. Ctrl-C ends a command with one line, ``pneunet-grasp CMD:
interrupted``, and exit status 130; a reader of stdout that goes away (``| head``) with exit status 141, quietly.
An optional package that a command needs and that is not installed is named in one line with the extra that installs
it (:mod:`pneunet_env.extras`), exit status 2. A warning is one line too, ``pneunet-grasp CMD: warning: MESSAGE``
(:func:`pneunet_env.extras.warn`), and the command goes on. The first run after an install says, once, that numba is
compiling the physics (:data:`COMPILE_NOTICE`, where stderr is a terminal). Options are never abbreviated
(``--object`` is not ``--objects``).
Set the environment variable ``PNEUNET_DEBUG=1`` to see the full traceback of an error or an interruption instead
(for developers).
"""

from __future__ import annotations

import argparse
import contextlib
import difflib
import importlib
import os
import sys

from pneunet_env.extras import PROG, missing_extra, missing_line, require_extra
from pneunet_env.files import deferred_interrupt

__all__ = ["COMMANDS", "DEBUG_ENV", "GROUPS", "CommandError", "main", "require_extra"]

# name -> (module, one-line help)
COMMANDS: dict[str, tuple[str, str]] = {
    "demo": ("pneunet_env.cli.demo", "main job: evaluate the scripted pressure ramp across object stiffnesses"),
    "solve": ("pneunet_env.cli.solve", "print a quasi-static loading path for one object"),
    "render": ("pneunet_env.cli.render", "save rendered frames of an episode as PNG"),
    "figures": ("pneunet_env.paper.command", "regenerate the paper's figures (PNG + CSV) and check its statements"),
    "bench speed": ("pneunet_env.bench.speed", "speed benchmark against CartPole (table, JSON, PNG)"),
    "bench solvers": ("pneunet_env.bench.solvers", "solver study: speed vs accuracy, stability map"),
    "bench design": ("agents.bench.design", "what a design study costs: one design evaluation, and the batched "
                     "search against the episode loop"),
    "bench gpu": ("pneunet_env.bench.gpu", "the fused step's CUDA kernel on a GPU: agreement with the CPU, env-steps/s "
                  "at N = 2^16..2^22 (JSON, PNG; extra: gpu)"),
    "bench render": ("pneunet_env.bench.render_speed", "rgb_array frames/s (step + render) against CartPole"),
    "bench train": ("agents.bench.train", "PPO training steps/s on the env (the shipped config) against the same PPO "
                    "on CartPole"),
    "evaluate": ("agents.evaluation.evaluate_cli", "evaluate policies over a stiffness grid (table, JSON, PNGs)"),
    "train": ("agents.training.cli", "train an SB3 agent from a YAML config"),
    "train-skrl": ("agents.training.skrl_ppo", "train skrl's PPO on the torch backend, on its device (extra: skrl)"),
    "search": ("agents.search.cli", "tune the blind best-ramp (or rigid) schedule; --sensitivity runs the threshold "
               "study"),
    "design": ("agents.design", "design the actuator: which walls and elastomer let one blind ramp hold a use case "
               "(Optuna; extra: design)"),
    "map": ("agents.evaluation.map_cli", "chart success over object modulus x radius: oracle, best blind ramp, "
            "rigid jaw, with the regime boundary"),
}

# group -> one-line help; a group's sub-commands are the COMMANDS named "GROUP SUB"
GROUPS: dict[str, str] = {
    "bench": "benchmarks: the environment's speed and the equilibrium solvers' accuracy",
}

_HELP = ("-h", "--help")

DEBUG_ENV = "PNEUNET_DEBUG"
"""Set it (``PNEUNET_DEBUG=1``) to see a command error's full traceback instead of its one line."""


class CommandError(SystemExit):
    """A command's error, already printed as one line on stderr: exit status 2. ``str()`` is the message (its
    ``code`` is the exit status, as for argparse's errors)."""

    def __init__(self, message: str) -> None:
        super().__init__(2)
        self.message = message

    def __str__(self) -> str:
        return self.message


class _Parser(argparse.ArgumentParser):
    """argparse, with its errors on one line: ``pneunet-grasp CMD: error: argument --x: MESSAGE``, exit status 2; and
    without argparse's prefix matching (``allow_abbrev=False``): ``demo --object 50`` is an unknown option, not
    ``--objects 50``."""

    def __init__(self, *args, **kwargs) -> None:
        kwargs.setdefault("allow_abbrev", False)
        super().__init__(*args, **kwargs)

    def error(self, message: str):  # type: ignore[override]
        _fail(self.prog, message)


def _debug() -> bool:
    return os.environ.get(DEBUG_ENV, "").strip().lower() not in ("", "0", "false", "no", "off")


def _one_line(message: str, prog: str) -> str:
    """``message`` on one line, without a ``PROG:`` prefix the command already put there (the line carries it)."""
    text = " ".join(str(message).split())
    for prefix in (f"{prog}: error: ", f"{prog}: ", f"{prog.removeprefix(PROG + ' ')}: "):
        text = text.removeprefix(prefix)
    return text


def _fail(prog: str, message: str):
    """Print ``PROG: error: MESSAGE`` (one line, its over-long values cut: :func:`pneunet_env.yamlio.cut_message`)
    and raise :class:`CommandError` (exit status 2)."""
    from pneunet_env.yamlio import cut_message

    line = cut_message(_one_line(message, prog))
    print(f"{prog}: error: {line}", file=sys.stderr)
    raise CommandError(line)


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
    """Run ``pneunet-grasp ARGV``; return the exit status (``--help`` and argument errors raise ``SystemExit``).

    A reader of stdout that goes away (``pneunet-grasp --help | head -1``) ends it quietly with status 141, wherever
    the output was cut: stdout is flushed here, inside the handler, not at the interpreter's exit (Python's recipe,
    "Note on SIGPIPE" in the :mod:`signal` docs)."""
    try:
        try:
            return _main(argv)
        finally:  # what is still buffered: written here, where a closed pipe is caught, not at the interpreter's exit
            with contextlib.suppress(AttributeError, ValueError):  # no stdout, or a closed one: nothing to write
                sys.stdout.flush()
    except BrokenPipeError:
        if not _stdout_closed():
            raise  # some other pipe: a real error
        return 141  # 128 + SIGPIPE, as a Unix command does


def _main(argv: list[str] | None) -> int:
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
        known = missing_extra(exc)
        missing = (missing_line(name, known[0], known[1]) if known is not None else
                   f"{PROG} {name}: missing dependency {exc.name!r}; install the package's extras (see README)")
        if any(a in _HELP for a in args_in):  # still answer --help, without the options it cannot list
            print(f"usage: {PROG} {name} [options]\n\n{help_}\n\n{missing}")
            return 0
        print(missing, file=sys.stderr)
        return 2
    prog = f"{PROG} {name}"
    interrupt_seen, stop_noting = _NOT_NOTING
    try:  # everything from here on: a Ctrl-C at any point is the command's interrupt (status 130), never a traceback
        with deferred_interrupt():  # the noting set up whole (a Ctrl-C meanwhile is raised after the block)
            interrupt_seen, stop_noting = _note_interrupts()
        parser = _Parser(prog=prog, description=help_)
        module.add_arguments(parser)
        args = parser.parse_args(args_in)
        _resolve_config(args, name)
        with _compile_notice(prog):
            return int(module.run(args) or 0)
    except ModuleNotFoundError as exc:  # an optional package the command imports as it goes: one line naming its extra
        known = None if _debug() else missing_extra(exc)
        if known is None:
            raise
        print(missing_line(name, *known), file=sys.stderr)
        return 2
    except BrokenPipeError:
        if not _stdout_closed():
            raise  # some other pipe: a real error
        return 141  # the reader of stdout went away (``| head``): stop quietly, 128 + SIGPIPE, as a Unix command does
    except KeyboardInterrupt as exc:
        if _debug():
            raise
        return _interrupted(prog, " ".join(str(a) for a in exc.args if str(a).strip()))
    except (ValueError, TypeError, OverflowError) as exc:  # bad input, found by the command: one line naming it
        if not _debug() and interrupt_seen():
            # a Ctrl-C that compiled code turned into another error (matplotlib's drawing reports one that came
            # during its C call as ValueError('Invalid bounding box')): an interrupt all the same, not bad input
            return _interrupted(prog, "")
        if _debug():
            raise
        _fail(prog, str(exc) or type(exc).__name__)
    except OSError as exc:  # a full disk, a quota, a read-only file system, a too-long path: one line naming the path
        from pneunet_env.arguments import os_error_line

        line = None if _debug() else os_error_line(exc)
        if line is None:
            if not _debug() and interrupt_seen():
                return _interrupted(prog, "")
            raise
        _fail(prog, line)
    except Exception:
        if not _debug() and interrupt_seen():  # the same for any error (numba's compiler, cut by a Ctrl-C, raises
            return _interrupted(prog, "")  # RuntimeError('no compiled object yet ...')): an interrupt, not a bug
        raise
    except CommandError:
        raise
    except SystemExit as exc:
        if _debug() or exc.code is None or isinstance(exc.code, int):
            raise  # a status alone: the command printed its message (argparse's --help, require_extra)
        _fail(prog, str(exc.code))
    finally:
        stop_noting()


COMPILE_NOTICE = ("compiling the physics (numba; once per install, about 10-30 s; later runs load it from numba's "
                  "cache)...")
"""What a command says, once, on stderr, when numba compiles one of the package's disk-cached functions: the first run
after an install (or an upgrade, or on another CPU), when numba's cache is cold (:func:`_compile_notice`)."""


def _disk_cached(dispatcher) -> bool:
    """Whether numba keeps ``dispatcher``'s compiled code on disk (it was made with ``cache=True``)."""
    cache = getattr(dispatcher, "_cache", None)
    return cache is not None and type(cache).__name__ != "NullCache"


def _compile_notice(prog: str):
    """A context in which numba's first compilation of a disk-cached function (``cache=True``: the package's step,
    solver and draws) prints ``PROG: COMPILE_NOTICE`` on stderr, once, so that a first run's half minute of compiling
    is not silent. numba raises its ``numba:compile`` event only where its cache had nothing to load (a cold cache),
    and a function compiled in every process (no disk cache) is passed over: a warm run says nothing. Shown where a
    progress bar would be (:func:`pneunet_env.progress.progress_enabled`: stderr is a terminal), so that a log or a
    test that reads stderr gets the same lines on a cold cache as on a warm one; nothing where numba is not imported
    (not installed, or disabled: ``PNEUNET_DISABLE_NUMBA``)."""
    from pneunet_env.physics._jit import HAVE_NUMBA
    from pneunet_env.progress import progress_enabled

    if not HAVE_NUMBA or "numba" not in sys.modules or not progress_enabled(None):
        return contextlib.nullcontext()
    try:
        from numba.core import event
    except ImportError:  # pragma: no cover - numba without its event API (older than 0.53; the floor is newer)
        return contextlib.nullcontext()

    class Notice(event.Listener):
        said = False

        def on_start(self, ev) -> None:
            data = ev.data if isinstance(ev.data, dict) else {}
            if not self.said and _disk_cached(data.get("dispatcher")):
                self.said = True
                from pneunet_env.extras import _line

                _line(f"{prog}: {COMPILE_NOTICE}")

        def on_end(self, ev) -> None:
            pass

    return event.install_listener("numba:compile", Notice())


_NOT_NOTING = (lambda: False), (lambda: None)
"""What :func:`_note_interrupts` returns where it notes nothing: ``(seen, stop)``."""


def _note_interrupts():
    """Start noting the signals that reach Python during the command (``signal.set_wakeup_fd``: the interpreter
    writes each signal's number to a pipe, whatever its handler does); returns ``(seen, stop)``: ``seen()`` tells
    whether a SIGINT came since, ``stop()`` ends the noting. The handlers are left as they are (``deferred_interrupt``
    holds a Ctrl-C only under Python's own). Only in the main thread, and where no wakeup fd is set already (an event
    loop's): elsewhere ``seen()`` is always false."""
    import signal
    import threading

    nothing = _NOT_NOTING
    if threading.current_thread() is not threading.main_thread():
        return nothing
    r, w = os.pipe()
    os.set_blocking(r, False)
    os.set_blocking(w, False)
    try:
        previous = signal.set_wakeup_fd(w, warn_on_full_buffer=False)
    except (ValueError, OSError):
        os.close(r)
        os.close(w)
        return nothing
    if previous != -1:  # someone else's: theirs again
        signal.set_wakeup_fd(previous)
        os.close(r)
        os.close(w)
        return nothing
    noted = bytearray()

    def seen() -> bool:
        try:
            while chunk := os.read(r, 512):
                noted.extend(chunk)
        except BlockingIOError:
            pass
        return signal.SIGINT in noted

    def stop() -> None:
        signal.set_wakeup_fd(-1)
        os.close(r)
        os.close(w)

    return seen, stop


def _interrupted(prog: str, note: str) -> int:
    """A command stopped by Ctrl-C: ``PROG CMD: interrupted [note]`` on stderr, status 130."""
    from pneunet_env.locks import release_held

    release_held()  # a lock whose with-statement's exit the interrupt cut at its start
    print(f"{prog}: interrupted" + (f" {note}" if note else ""), file=sys.stderr)
    return 130  # 128 + SIGINT, as a shell reports it


def _resolve_config(args: argparse.Namespace, name: str) -> None:
    """``--config`` as a file: a shipped config by name (``ppo``, ``designed-kitchen``) becomes its path; a folder
    or a missing file is an error naming it, before the command runs."""
    config = getattr(args, "config", None)
    if not isinstance(config, str) or os.path.isfile(config):
        return
    if os.path.isdir(config):
        raise ValueError(f"--config {config!r} is a folder, not a config file")
    from pneunet_env.arguments import check_input_path

    check_input_path(config, "--config")  # a FIFO, a device, a too-long path: refused by name, not "no such file"
    from agents.common.resources import is_name, resolve_config

    if is_name(config):
        args.config_given = config
    args.config = str(resolve_config(config, "train" if name == "train" else "env"))


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
