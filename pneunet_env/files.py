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

__all__ = ["atomic_write_bytes", "atomic_write_json", "atomic_write_many", "atomic_write_text", "deferred_interrupt",
           "save_figure", "stage_file"]


@contextlib.contextmanager
def deferred_interrupt() -> Iterator[None]:
    """Hold a Ctrl-C (SIGINT) that arrives inside the block until the block ends, then raise ``KeyboardInterrupt``.

    For a few lines that must run whole: a file written to a temporary name and renamed into place (between the
    temporary file's creation and the ``try`` that removes it on failure, an interrupt would leave it behind), a lock
    file created or removed. Only in the main thread under Python's default SIGINT handler (where Ctrl-C raises
    ``KeyboardInterrupt``); nested, the outermost block holds it; elsewhere the block runs as it is.
    """
    if (threading.current_thread() is not threading.main_thread()
            or signal.getsignal(signal.SIGINT) is not signal.default_int_handler):
        yield
        return
    caught: list[int] = []
    signal.signal(signal.SIGINT, lambda signum, frame: caught.append(signum))
    try:
        yield
    finally:
        signal.signal(signal.SIGINT, signal.default_int_handler)
        if caught:
            raise KeyboardInterrupt


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
    except BaseException:
        tmp.unlink(missing_ok=True)
        raise
    return tmp


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
    except BaseException:
        tmp.unlink(missing_ok=True)
        raise
    finally:
        if close:
            import matplotlib.pyplot as plt  # the caller made the figure: matplotlib is there

            plt.close(fig)
    return path
