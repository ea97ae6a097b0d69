"""A lock on an output folder (or file) that one process writes at a time: a training run, a search's result.

:class:`RunLock` creates a lock file (``FOLDER/.lock``; ``DIR/.NAME.lock`` for a single output file) with
``O_CREAT | O_EXCL``, so that of two processes taking it at once exactly one succeeds. The file holds who holds it
(JSON: ``pid``, ``host``, ``started`` as an ISO time, ``command``), and is removed when the holder ends, whether it
finished, failed or was interrupted (Ctrl-C). A second process is refused with a :class:`ValueError` that names
the folder and the holder (its pid, host, start time and command).

A lock left by a process that was killed hard (``kill -9``, a power cut) is *stale*: its pid is dead on this host.
A stale lock is taken over, with a note on stderr. A lock from another host (a shared file system), or one whose
pid is alive (or was reused by another process), is taken over only with ``force=True`` (``--force``): the caller
then asserts that the other process is gone, or accepts that two writers share the folder. An empty or unreadable
lock file (a process killed while writing it) counts as held, with the same remedy.

A shared optimisation study (``pneunet-grasp design``'s Optuna storage) is multi-writer by design: it takes no lock.

:func:`deferred_interrupt` holds a Ctrl-C that arrives during a few lines that must run whole (a lock taken or
released, a file staged and renamed into place) and raises it when they are done: a Ctrl-C at any moment leaves
either the old state or the new one, and no temporary file or lock behind.
"""

from __future__ import annotations

import datetime
import json
import os
import socket
import sys
from pathlib import Path
from typing import Any

from pneunet_env.files import deferred_interrupt

__all__ = ["RunLock", "LOCK_NAME", "lock_path_for", "deferred_interrupt", "pid_alive", "release_dead", "release_held"]


LOCK_NAME = ".lock"
"""The lock file of a folder."""

_HELD: set[RunLock] = set()
"""The locks this process holds (a lock joins when it is taken, leaves when it is released)."""


def release_held() -> None:
    """Release every lock this process still holds: for the top of a command, after a Ctrl-C. A ``with RunLock``
    whose exit is interrupted at its very start (Python handles a signal on entering a function, before any of its
    own protection) leaves its lock file; by the time the interrupt reaches the command's top it has been delivered,
    so this runs whole. (Seen: about one random Ctrl-C in 1,200 to 3,000 left a 50 ms ``search``'s lock.)"""
    for lock in list(_HELD):
        lock.release()


def release_dead(target: str | os.PathLike, pid: int, *, file: bool = False) -> bool:
    """Remove the lock of ``target`` if the process ``pid`` of this host holds it and is gone; whether it did.

    For a parent whose worker process died (killed by the kernel's OOM killer, a scheduler's pre-emption): the
    worker's lock goes at once, where a later command would otherwise take it over as stale, with a note. A lock held
    by another process, or by ``pid`` still alive, is left as it is."""
    lock = RunLock(target, file=file)
    info = lock.holder()
    if (not info or info.get("pid") != pid or info.get("host") != socket.gethostname() or pid == os.getpid()
            or pid_alive(pid)):
        return False
    with deferred_interrupt():
        return lock._take_over(info)


def lock_path_for(target: str | os.PathLike, *, file: bool = False) -> Path:
    """The lock file of ``target``: ``target/.lock`` for a folder, ``DIR/.NAME.lock`` for the file ``DIR/NAME``."""
    target = Path(target)
    return target.with_name(f".{target.name}.lock") if file else target / LOCK_NAME


def pid_alive(pid: int) -> bool:
    """Whether a process ``pid`` exists on this host (POSIX; on Windows, where this is not checked, ``True``)."""
    if pid <= 0:
        return False
    if os.name == "nt":  # pragma: no cover  (no cheap check without a dependency: never called stale)
        return True
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:  # it exists, under another user
        return True
    except OSError:
        return True
    return True


class RunLock:
    """An exclusive lock on an output folder (``file=False``) or a single output file (``file=True``).

    Use it as a context manager (``with RunLock(run_dir, command=...):``), or :meth:`acquire` and :meth:`release`.
    The folder (or the file's folder) is created if missing.

    Args:
        target: the folder (or file) written by one process at a time.
        command: what the holder runs (recorded in the lock file and shown to a refused process); default the
            process's command line.
        force: take over any lock, even one whose holder looks alive or lives on another host.
        file: ``target`` is a single output file: the lock is ``DIR/.NAME.lock`` beside it.
        what: the noun used in messages (``"run folder"``, ``"output"``).

    Two locks on one target in the same process refuse each other too (the holder's pid is alive).
    """

    def __init__(self, target: str | os.PathLike, *, command: str | None = None, force: bool = False,
                 file: bool = False, what: str | None = None) -> None:
        self.target = Path(target)
        self.path = lock_path_for(self.target, file=file)
        self.command = " ".join(sys.argv) if command is None else str(command)
        self.force = bool(force)
        self.what = what or ("output" if file else "run folder")
        self.held = False
        self._created_folder = False
        self._info: dict[str, Any] = {}

    # -- the lock file --------------------------------------------------------------------------------------------

    def _create(self) -> bool:
        """Create the lock file with our details; ``False`` if it exists."""
        info = {"pid": os.getpid(), "host": socket.gethostname(),
                "started": datetime.datetime.now().astimezone().isoformat(timespec="seconds"), "command": self.command}
        try:
            fd = os.open(self.path, os.O_CREAT | os.O_EXCL | os.O_WRONLY, 0o644)
        except FileExistsError:
            return False
        try:
            with os.fdopen(fd, "w", encoding="utf-8") as fh:
                fh.write(json.dumps(info) + "\n")
                fh.flush()
                os.fsync(fh.fileno())
            self._info, self.held = info, True  # from here, release() removes it
            _HELD.add(self)
        except BaseException:  # an interrupt between the creation and the content: no empty lock left
            self.path.unlink(missing_ok=True)
            self.held = False
            raise
        return True

    def holder(self) -> dict[str, Any] | None:
        """The lock file's content (``{}`` if it is empty or unreadable), or ``None`` if there is no lock file."""
        try:
            text = self.path.read_text(encoding="utf-8")
        except FileNotFoundError:
            return None
        except (OSError, UnicodeDecodeError):
            return {}
        try:
            data = json.loads(text)
        except ValueError:
            return {}
        return data if isinstance(data, dict) else {}

    @staticmethod
    def is_stale(info: dict[str, Any]) -> bool:
        """Whether a holder is provably gone: it ran on this host and its pid is dead."""
        pid = info.get("pid")
        return (isinstance(pid, int) and info.get("host") == socket.gethostname() and pid != os.getpid()
                and not pid_alive(pid))

    @staticmethod
    def describe(info: dict[str, Any]) -> str:
        if not info:
            return "an unknown process (the lock file is empty or unreadable)"
        return (f"pid {info.get('pid')} on host {info.get('host')!r}, since {info.get('started')}"
                + (f": {info['command']}" if info.get("command") else ""))

    def _take_over(self, info: dict[str, Any]) -> bool:
        """Remove the lock file we judged from ``info``, unless another process replaced it meanwhile."""
        aside = self.path.with_name(f"{self.path.name}.{os.getpid()}.stale")
        try:
            os.replace(self.path, aside)
        except FileNotFoundError:
            return True  # its holder released it: try again
        try:
            try:
                now = json.loads(aside.read_text(encoding="utf-8"))
            except (OSError, ValueError):
                now = {}
            if isinstance(now, dict) and now != info:  # a fresh lock of another process: put it back
                try:
                    os.link(aside, self.path)
                except FileExistsError:
                    pass
                return False
            return True
        finally:
            aside.unlink(missing_ok=True)

    # -- acquire / release ----------------------------------------------------------------------------------------

    def acquire(self) -> RunLock:
        """Take the lock, or raise ``ValueError`` naming the folder and the process that holds it."""
        try:
            with deferred_interrupt():  # a Ctrl-C meanwhile is raised once the lock is taken...
                self._created_folder = not self.path.parent.exists()
                self.path.parent.mkdir(parents=True, exist_ok=True)
                try:
                    return self._acquire()
                except BaseException:
                    self._remove_folder()
                    raise
        except KeyboardInterrupt:  # ... and gives it back: nothing is left
            self.release()
            raise

    def _acquire(self) -> RunLock:
        for _ in range(5):
            if self._create():
                self.held = True
                return self
            info = self.holder()
            if info is None:
                continue  # released meanwhile
            if self.force or self.is_stale(info):
                why = "--force" if self.force and not self.is_stale(info) else "its process is gone"
                if self._take_over(info):
                    print(f"taking over the lock of {self.what} {str(self.target)!r} ({why}): held by "
                          f"{self.describe(info)}", file=sys.stderr)
                    continue
            raise ValueError(
                f"{self.what} {str(self.target)!r} is in use by {self.describe(info)} (lock file {str(self.path)!r}); "
                "wait for that process to end, use another folder, or pass --force to take the lock over if it is "
                "gone")
        raise ValueError(f"{self.what} {str(self.target)!r}: could not take the lock {str(self.path)!r} (other "
                         "processes keep taking it)")

    def release(self) -> None:
        """Remove the lock file if it is still ours (a process that took it over with ``--force`` keeps its own), and
        the folder :meth:`acquire` created for it if nothing else was written there (an interrupted command leaves
        no empty folder).

        A Ctrl-C that lands before the block that holds interrupts has begun (while :func:`deferred_interrupt` sets
        itself up) would skip the release: it is released then all the same, and the interrupt goes on. One that
        lands on entering this method is left to :func:`release_held`, at the command's top."""
        try:
            with deferred_interrupt():
                self._release()
        finally:
            if self.held:  # the interrupt came first
                with deferred_interrupt():
                    self._release()

    def _release(self) -> None:
        if not self.held:
            return
        self.held = False
        _HELD.discard(self)
        if self.holder() == self._info:
            self.path.unlink(missing_ok=True)
        self._remove_folder()

    def _remove_folder(self) -> None:
        if self._created_folder:
            try:
                self.path.parent.rmdir()
            except OSError:  # not empty: the command's outputs (or another process's lock)
                pass

    def __enter__(self) -> RunLock:
        return self.acquire()

    def __exit__(self, *exc: object) -> None:
        self.release()
