"""Writing files so that nothing is ever half-written: the one atomic writer of the package.

Every file a command writes (a JSON record, a checkpoint, an exported model, an NPZ, a PNG) goes to a temporary
file in the same folder, is flushed to disk, and is then renamed onto its name (``os.replace``, atomic on POSIX and
Windows). A reader, an interrupted run or a crash half-way sees the old file or the new one, never a truncated one.
A temporary file left by a hard kill (``.NAME.*.tmp``) is never read by the package.
"""

from __future__ import annotations

import contextlib
import json
import os
import signal
import tempfile
import threading
from collections.abc import Iterator
from pathlib import Path
from typing import Any

__all__ = ["atomic_write_bytes", "atomic_write_json", "atomic_write_many", "atomic_write_text",
           "command_line_interrupts", "deferred_interrupt", "interrupt_once", "remove_temporary", "save_figure",
           "stage_file"]


def interrupt_once(signum: int, frame: Any) -> None:
    """A SIGINT handler that raises ``KeyboardInterrupt`` the first time and ignores SIGINT from then on.

    For a worker process that may be told to stop twice (the terminal's Ctrl-C reaches its process group, and its
    parent forwards the one it got): the second must not cut the checkpoint the first is saving.
    :func:`deferred_interrupt` holds it as it holds Python's own handler."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    raise KeyboardInterrupt


@contextlib.contextmanager
def deferred_interrupt() -> Iterator[None]:
    """Hold a Ctrl-C (SIGINT) that arrives inside the block until the block ends, then raise ``KeyboardInterrupt``.

    For a few lines that must run whole: a file written to a temporary name and renamed into place (between the
    temporary file's creation and the ``try`` that removes it on failure, an interrupt would leave it behind), a lock
    file created or removed. Only in the main thread under Python's default SIGINT handler (where Ctrl-C raises
    ``KeyboardInterrupt``) or :func:`interrupt_once`; nested, the outermost block holds it; elsewhere the block runs
    as it is.
    """
    handler = signal.getsignal(signal.SIGINT)
    if (threading.current_thread() is not threading.main_thread()
            or handler not in (signal.default_int_handler, interrupt_once)):
        yield
        return
    caught: list[int] = []
    signal.signal(signal.SIGINT, lambda signum, frame: caught.append(signum))
    try:
        yield
    finally:
        signal.signal(signal.SIGINT, handler)
        if caught:
            if handler is interrupt_once:
                signal.signal(signal.SIGINT, signal.SIG_IGN)  # its one interrupt is spent
            raise KeyboardInterrupt


_PROG = "pneunet-grasp"
"""The command line's name (as :data:`pneunet_env.extras.PROG`, which this module, imported first, cannot import)."""


def _is_command_line() -> bool:
    """Whether this process runs the command line: the ``pneunet-grasp`` script, or ``python -m pneunet_env.cli``."""
    import sys

    script = os.path.basename(sys.argv[0]) if sys.argv else ""
    if script.removesuffix(".exe").removesuffix("-script.py") == _PROG:
        return True
    argv = list(getattr(sys, "orig_argv", []))
    return any(a == "-m" and b in ("pneunet_env.cli", "pneunet_env.cli.__main__")
               for a, b in zip(argv, argv[1:], strict=False))


def command_line_interrupts() -> None:
    """In the command line's process, a Ctrl-C that no command handles ends in the command's one line,
    ``pneunet-grasp CMD: interrupted``, and exit status 130, as one inside the command does: one that comes while the
    package and the command's module are imported (start-up: half a second or more), before the command's own
    handling begins. Call it first thing in the package's ``__init__``; elsewhere (a library import, a test) it does
    nothing. Set ``PNEUNET_DEBUG=1`` for Python's traceback instead.

    A ``KeyboardInterrupt`` that a C callback could not raise (numba's compiler calls back into Python; Python
    prints it as "Exception ignored ...") is not printed but raised again (a SIGINT sent to this process), once the
    callback has returned; an error the callback's caller raises meanwhile is the command's interrupt all the same
    (the command line's ``main`` sees that a SIGINT came)."""
    import sys

    if not _is_command_line() or os.environ.get("PNEUNET_DEBUG", "").strip().lower() not in ("", "0", "false", "no",
                                                                                             "off"):
        return
    previous_hook, previous_unraisable = sys.excepthook, sys.unraisablehook

    def excepthook(kind, value, tb) -> None:
        if not issubclass(kind, KeyboardInterrupt):
            previous_hook(kind, value, tb)
            return
        words = [a for a in sys.argv[1:3] if a[:1].isalpha()]
        name = " ".join(words[:2] if words[:1] == ["bench"] else words[:1])
        try:
            sys.stdout.flush()
        except (OSError, ValueError):
            pass
        print(f"{_PROG}{' ' + name if name else ''}: interrupted", file=sys.stderr, flush=True)
        os._exit(130)  # 128 + SIGINT, as the command's own interrupt (no interpreter clean-up: nothing has begun)

    def unraisablehook(unraisable) -> None:
        if not isinstance(unraisable.exc_value, KeyboardInterrupt):
            previous_unraisable(unraisable)
        elif signal.getsignal(signal.SIGINT) is signal.default_int_handler:
            os.kill(os.getpid(), signal.SIGINT)  # the interrupt the callback swallowed, raised where it can be

    sys.excepthook, sys.unraisablehook = excepthook, unraisablehook


def _umask() -> int:
    mask = os.umask(0o022)
    os.umask(mask)
    return mask


def stage_file(final: str | Path, content: bytes | Path, suffix: str = ".tmp") -> Path:
    """A temporary file beside ``final`` (same folder, so ``os.replace`` onto ``final`` is atomic) holding
    ``content`` (bytes, or the bytes of the file at that path), flushed to disk, with ``final``'s permissions (a new
    file's usual ones if ``final`` does not exist). The caller renames it into place or deletes it."""
    final = Path(final)
    final.parent.mkdir(parents=True, exist_ok=True)
    with deferred_interrupt():  # a Ctrl-C between mkstemp and the try would leave the temporary file behind
        fd, name = tempfile.mkstemp(dir=final.parent, prefix=f".{final.name}.", suffix=suffix)
        tmp = Path(name)
    try:
        with os.fdopen(fd, "wb") as out:
            if isinstance(content, Path):
                with open(content, "rb") as src:
                    while chunk := src.read(1 << 20):
                        out.write(chunk)
            else:
                out.write(content)
            out.flush()
            os.fsync(out.fileno())
        os.chmod(tmp, final.stat().st_mode & 0o7777 if final.exists() else 0o666 & ~_umask())
    except BaseException as exc:
        tmp.unlink(missing_ok=True)
        _name_the_file(exc, final)
        raise
    return tmp


def _name_the_file(exc: BaseException, path: Path) -> None:
    """An ``OSError`` of a write that does not name its file (a full disk's ``ENOSPC`` from ``write`` or ``fsync``)
    names ``path``, the file being written: the command line's one line says which (``no space left on the device
    writing PATH``)."""
    if isinstance(exc, OSError) and exc.filename is None and exc.errno is not None:  # not a bare OSError("text")
        exc.filename = str(path)


def _is_temporary(name: str) -> bool:
    """Whether ``name`` is one of this module's temporary files (``.NAME.XXXX.tmp``, a figure's
    ``.STEM.XXXX.tmp.png``)."""
    return name.startswith(".") and (name.endswith(".tmp") or ".tmp." in name)


def remove_temporary(folder: str | Path) -> list[Path]:
    """Remove the temporary files a hard-killed writer left in ``folder`` and its sub-folders (what
    :func:`stage_file` and :func:`save_figure` stage before renaming); returns them. Only for a folder whose writer is
    known to be gone (its process ended, its lock held by the caller): a live writer's staged file would vanish."""
    removed = []
    for path in sorted(Path(folder).rglob(".*")):
        if _is_temporary(path.name) and path.is_file():
            path.unlink(missing_ok=True)
            removed.append(path)
    return removed


def atomic_write_bytes(path: str | Path, data: bytes) -> Path:
    """Write ``data`` to ``path`` through a temporary file in the same folder and ``os.replace``: a reader (or a
    failure half-way) sees the old file or the new one, never a truncated one."""
    path = Path(path)
    with deferred_interrupt():  # staged and renamed whole: a Ctrl-C here waits the few milliseconds it takes
        tmp = stage_file(path, data)
        try:
            os.replace(tmp, path)
        except BaseException:
            tmp.unlink(missing_ok=True)
            raise
    return path


def atomic_write_many(outputs: list[tuple[str | Path, bytes | Path]]) -> list[Path]:
    """Several files written as one: each ``(path, content)`` staged beside its path (:func:`stage_file`), then all
    renamed into place. A failure while staging leaves every old file untouched and no temporary file; a Ctrl-C is
    held until every file is in place (or every temporary one removed). Returns the paths, in order."""
    staged: list[tuple[Path, Path]] = []
    with deferred_interrupt():
        try:
            for final, content in outputs:
                staged.append((stage_file(final, content), Path(final)))
            for tmp, final in staged:
                os.replace(tmp, final)
        finally:
            for tmp, _ in staged:
                tmp.unlink(missing_ok=True)
    return [Path(final) for final, _ in outputs]


def atomic_write_text(path: str | Path, text: str) -> Path:
    """:func:`atomic_write_bytes` of ``text`` in UTF-8."""
    return atomic_write_bytes(path, text.encode("utf-8"))


def atomic_write_json(path: str | Path, data: Any, *, indent: int | None = 1, default=None) -> Path:
    """``data`` as JSON (one trailing newline), written atomically. ``default`` is :func:`json.dumps`'."""
    return atomic_write_text(path, json.dumps(data, indent=indent, default=default) + "\n")


def save_figure(fig: Any, path: str | Path, *, dpi: int = 120, close: bool = True, **kwargs: Any) -> Path:
    """Save a matplotlib figure to ``path`` atomically (rendered into a temporary file of the same format in the
    same folder, then renamed), and close it unless ``close=False``. Returns ``path``.

    The one figure-save ending of the package's commands (evaluate, map, search, train, the seed study, the design
    study, the benchmarks and the paper's figures). matplotlib is imported by the caller, never here.
    """
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    with deferred_interrupt():  # a Ctrl-C between mkstemp and the try would leave the temporary file behind
        fd, name = tempfile.mkstemp(dir=path.parent, prefix=f".{path.stem}.", suffix=".tmp" + (path.suffix or ".png"))
        os.close(fd)
        tmp = Path(name)
    try:
        fig.savefig(tmp, dpi=dpi, format=(path.suffix.lstrip(".") or "png"), **kwargs)
        os.chmod(tmp, 0o666 & ~_umask())
        os.replace(tmp, path)
    except BaseException as exc:
        tmp.unlink(missing_ok=True)
        _name_the_file(exc, path)
        raise
    finally:
        if close:
            import matplotlib.pyplot as plt  # the caller made the figure: matplotlib is there

            plt.close(fig)
    return path
