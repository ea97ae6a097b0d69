"""Worker processes that survive their faults: the ``--jobs`` of ``pneunet-grasp train --seeds`` and ``design``.

:func:`run_jobs` runs each job in a process of its own, forked from a fresh interpreter that imported the workers'
modules and did nothing else (``forkserver``: no numba, torch or SQLite state is forked, and a worker does not pay
torch's imports again; ``spawn`` where there is no fork), and watches every worker: its exit, through the process's
sentinel, and its result, through a pipe. A worker that dies (``SIGKILL`` from the kernel's OOM killer or a
cluster's pre-emption, a crash) is noticed at once, not when a pool next hands it work, and its job is named.

**One fault stops the study, cleanly.** When a worker dies, fails with an error or is interrupted, no other job
starts, and every worker still running is sent one SIGINT: it stops as a Ctrl-C stops a single run (a training
seed saves its model as a checkpoint; a design trial is marked failed, to be retried), reports, and exits. The
others are stopped rather than left to go on because the study's result needs every job (the seeds are scored
together; the design report needs its Table 1 reference), so it must be run again anyway; because a stopped worker
loses nothing (the same command resumes it from where it stopped) while a worker left running may be the next one
the same memory pressure or pre-emption kills, losing everything since its last checkpoint; and because the user
then learns of the fault within seconds, not hours later. A worker that has not stopped ``grace_s`` after its
SIGINT is killed.

**Ctrl-C.** The parent notes a SIGINT (it raises no ``KeyboardInterrupt`` mid-bookkeeping) and stops the workers
the same way; a worker takes only its first SIGINT (:func:`pneunet_env.files.interrupt_once`), so the terminal's
Ctrl-C, which reaches the whole process group, and the parent's forwarded one stop it once. A worker starts with
SIGINT blocked (the mask is inherited), so a Ctrl-C during its start-up waits until it can be handled as the job's
interrupt, never a traceback of its bootstrap.
"""

from __future__ import annotations

import os
import signal
import sys
import threading
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import Any

__all__ = ["Outcome", "Jobs", "run_jobs", "STOP_GRACE_S", "usable_cores", "available_memory", "check_jobs"]

STOP_GRACE_S = 120.0
"""How long a worker may take to stop after its SIGINT (save a checkpoint, record its state) before it is killed."""

def usable_cores() -> int:
    """The cores this process may run on (its CPU affinity, else ``os.cpu_count()``)."""
    try:
        return max(len(os.sched_getaffinity(0)), 1)
    except (AttributeError, OSError):  # no affinity on this platform
        return max(os.cpu_count() or 1, 1)


def available_memory() -> int | None:
    """The memory available to new processes (bytes: Linux's ``MemAvailable``), or ``None`` where it is not known."""
    try:
        with open("/proc/meminfo") as fh:
            for line in fh:
                if line.startswith("MemAvailable:"):
                    return int(line.split()[1]) * 1024
    except (OSError, ValueError, IndexError):
        pass
    return None


def check_jobs(jobs: int, worker_bytes: int, flag: str = "--jobs") -> None:
    """Refuse ``jobs`` worker processes (a ``ValueError`` naming ``flag``, in one line) beyond what this machine can
    run at once: one per usable core, and ``worker_bytes`` of available memory each."""
    cores = usable_cores()
    memory = available_memory()
    most = cores if memory is None else max(min(cores, memory // max(worker_bytes, 1)), 1)
    if jobs > most:
        gib = f", {memory / 2**30:.1f} GiB of memory available at {worker_bytes / 2**30:.1f} GiB a worker" \
            if memory is not None else ""
        raise ValueError(f"{flag} must be at most {most} on this machine ({cores} usable core(s){gib}), got {jobs}")


_POLL_S = 0.2
"""How often the parent looks at its SIGINT flag while it waits (seconds)."""


@dataclass
class Outcome:
    """How one job ended.

    ``state``: ``"done"`` (``value`` is what the job returned), ``"interrupted"`` (``value``: the interrupt's note,
    or ``""``), ``"error"`` (``value``: the exception), ``"died"`` (the process ended without a result: ``exitcode``
    says how; ``value`` is ``None``) or ``"not started"``."""

    index: int
    state: str = "not started"
    value: Any = None
    pid: int | None = None
    exitcode: int | None = None
    started: float | None = None
    """``time.monotonic()`` when the worker was started."""
    killed_by_parent: bool = False

    @property
    def signal_name(self) -> str | None:
        """The signal that ended the worker (``"SIGKILL"``), or ``None``."""
        if self.exitcode is None or self.exitcode >= 0:
            return None
        try:
            return signal.Signals(-self.exitcode).name
        except ValueError:
            return f"signal {-self.exitcode}"

    def cause(self) -> str:
        """Why a worker ended without a result, in words: ``"its worker process (pid 123) was killed by SIGKILL"``."""
        who = f"its worker process (pid {self.pid})"
        if self.killed_by_parent:
            return f"{who} did not stop within {STOP_GRACE_S:g} s of its interrupt and was killed"
        if self.signal_name is not None:
            return f"{who} was killed by {self.signal_name}"
        return f"{who} exited with status {self.exitcode} without a result"


@dataclass
class Jobs:
    """The outcomes of :func:`run_jobs`, in the order of the jobs, and whether the parent itself was interrupted."""

    outcomes: list[Outcome] = field(default_factory=list)
    interrupted: bool = False

    def by_state(self, *states: str) -> list[Outcome]:
        return [o for o in self.outcomes if o.state in states]

    @property
    def clean(self) -> bool:
        """Every job done, and no Ctrl-C."""
        return not self.interrupted and all(o.state == "done" for o in self.outcomes)


def _child(target: Callable[[Any], Any], job: Any, conn) -> None:  # a worker process: module-level, so it pickles
    from pneunet_env.files import interrupt_once

    signal.signal(signal.SIGINT, interrupt_once)  # SIGINT is still blocked here (inherited from the parent's start)
    previous_unraisable = sys.unraisablehook

    def unraisablehook(unraisable) -> None:
        # a KeyboardInterrupt that a C callback could not raise (numba's compiler calls back into Python: llvmlite's
        # object-cache notice) would be printed as "Exception ignored ..." with its traceback, and lost (the worker's
        # one interrupt spent): raised again, quietly, once the callback has returned, as the command line's own
        # process does (pneunet_env.files.command_line_interrupts)
        if not isinstance(unraisable.exc_value, KeyboardInterrupt):
            previous_unraisable(unraisable)
            return
        signal.signal(signal.SIGINT, interrupt_once)
        # sent from another thread a moment later: sent here, it would be raised inside this hook and swallowed
        # again (one that lands in a callback once more comes back here, until Python code raises it)
        timer = threading.Timer(0.01, os.kill, (os.getpid(), signal.SIGINT))
        timer.daemon = True
        timer.start()

    sys.unraisablehook = unraisablehook
    try:
        _unblock_sigint()  # a Ctrl-C that came during start-up is raised here, inside the try
        value = target(job)
        signal.signal(signal.SIGINT, signal.SIG_IGN)
        message = ("done", value)
    except KeyboardInterrupt as exc:
        signal.signal(signal.SIGINT, signal.SIG_IGN)
        message = ("interrupted", " ".join(str(a) for a in exc.args if str(a).strip()))
    except BaseException as exc:  # the job's error, for the parent to name (a SystemExit with a message too)
        spent = signal.getsignal(signal.SIGINT) is signal.SIG_IGN  # only interrupt_once sets it: a SIGINT came
        signal.signal(signal.SIGINT, signal.SIG_IGN)
        # an interrupt that compiled code turned into another error (numba reports one that came while it compiled
        # as RuntimeError('no compiled object yet ...')) is an interrupt all the same
        message = ("interrupted", "") if spent else ("error", exc)
    try:
        conn.send(message)
    except Exception:  # an exception that does not pickle: its type and message
        exc = message[1]
        conn.send(("error", RuntimeError(f"{type(exc).__name__}: {exc}")))
    conn.close()


def _block_sigint():
    """Block SIGINT in this thread (a pending one waits); returns the mask to restore, or ``None`` where signals
    cannot be masked (Windows, another thread)."""
    if not hasattr(signal, "pthread_sigmask") or threading.current_thread() is not threading.main_thread():
        return None
    return signal.pthread_sigmask(signal.SIG_BLOCK, {signal.SIGINT})


def _unblock_sigint() -> None:
    if hasattr(signal, "pthread_sigmask"):
        signal.pthread_sigmask(signal.SIG_UNBLOCK, {signal.SIGINT})


class _Running:
    def __init__(self, index: int, process, reader) -> None:
        self.index, self.process, self.reader = index, process, reader
        self.message: tuple[str, Any] | None = None
        self.eof = False  # its pipe closed without a message: it died (its sentinel says how)
        self.signalled = False
        self.kill_at: float | None = None


def _context(preload: Sequence[str]):
    """``forkserver`` (a server process imports ``preload`` once and forks each worker from it: a fresh
    interpreter's state, without each worker paying torch's imports again), where there is one; else ``spawn``."""
    import multiprocessing as mp

    if "forkserver" not in mp.get_all_start_methods():  # pragma: no cover  (Windows)
        return mp.get_context("spawn")
    ctx = mp.get_context("forkserver")
    ctx.set_forkserver_preload(list(preload))  # where the server runs already (an earlier study), as it is
    return ctx


def _helpers_running(ctx) -> None:
    """multiprocessing's resource tracker started (it unblocks SIGINT in the thread that starts it, which would undo
    :func:`_block_sigint`), and, for ``forkserver``, the server started with SIGINT blocked, so that every worker it
    forks inherits the mask."""
    from multiprocessing import resource_tracker

    resource_tracker.ensure_running()
    if ctx.get_start_method() == "forkserver":
        from multiprocessing import forkserver

        mask = _block_sigint()
        try:
            forkserver.ensure_running()
        finally:
            if mask is not None:
                signal.pthread_sigmask(signal.SIG_SETMASK, mask)


def run_jobs(target: Callable[[Any], Any], jobs: Sequence[Any], processes: int, *,
             on_end: Callable[[Outcome], bool] | None = None, grace_s: float = STOP_GRACE_S,
             preload: Sequence[str] = ()) -> Jobs:
    """Run ``target(job)`` for each job, at most ``processes`` at once, each in a process of its own.

    Args:
        target: a module-level function (it is pickled to the worker).
        jobs: the jobs' arguments (each pickled to its worker).
        processes: how many workers run at once (>= 1).
        on_end: called in the parent as each worker ends, with its :class:`Outcome` (whatever its state), before any
            other job starts: where the caller releases a dead worker's lock and records its fault. It returns
            whether the job's work is whole (a worker that died after its run finished); ``False`` (or a state other
            than ``"done"`` with no ``on_end``) stops the others.
        grace_s: how long a worker may take to stop after its SIGINT before it is killed (seconds).
        preload: modules the workers' server imports once (``forkserver``), for the workers to start with.

    Returns:
        every job's outcome, and whether the parent was interrupted (a SIGINT came: the caller raises
        ``KeyboardInterrupt`` once it has reported). Every worker has ended when this returns, whatever happened.
    """
    from multiprocessing.connection import wait

    if processes < 1:
        raise ValueError(f"processes must be >= 1, got {processes!r}")
    ctx = _context(preload)
    result = Jobs([Outcome(i) for i in range(len(jobs))])
    queue = list(range(len(jobs)))
    running: dict[int, _Running] = {}
    noted: list[int] = []
    previous = signal.getsignal(signal.SIGINT)
    own = threading.current_thread() is threading.main_thread() and previous is signal.default_int_handler
    if own:  # a Ctrl-C is noted, and handled between two steps of the bookkeeping below
        signal.signal(signal.SIGINT, lambda signum, frame: noted.append(signum))
    stopping = False

    def stop() -> None:
        nonlocal stopping
        stopping = True
        for run in running.values():
            if not run.signalled:
                run.signalled, run.kill_at = True, time.monotonic() + grace_s
                try:
                    os.kill(run.process.pid, signal.SIGINT)
                except (ProcessLookupError, OSError):  # it has just ended: its sentinel says so
                    pass

    def start(index: int) -> None:
        reader, writer = ctx.Pipe(duplex=False)
        process = ctx.Process(target=_child, args=(target, jobs[index], writer), daemon=False,
                              name=f"job-{index}")
        _helpers_running(ctx)
        mask = _block_sigint()  # the worker inherits SIGINT blocked: a Ctrl-C during its start-up waits for it
        try:
            process.start()
        finally:
            if mask is not None:
                signal.pthread_sigmask(signal.SIG_SETMASK, mask)
            writer.close()
        running[index] = _Running(index, process, reader)
        out = result.outcomes[index]
        out.pid, out.started, out.state = process.pid, time.monotonic(), "running"

    def end(run: _Running) -> None:
        run.process.join()
        if run.message is None and not run.eof:
            try:
                if run.reader.poll():
                    run.message = run.reader.recv()
            except (EOFError, OSError):
                pass
        run.reader.close()
        del running[run.index]
        out = result.outcomes[run.index]
        out.exitcode = run.process.exitcode
        if run.message is None:
            out.state = "died"
            out.killed_by_parent = run.kill_at is not None and time.monotonic() >= run.kill_at
        else:
            out.state, out.value = run.message
        if not (on_end(out) if on_end is not None else out.state == "done"):
            stop()

    try:
        while queue or running:
            if noted and not stopping:
                result.interrupted = True
                stop()
            while queue and not stopping and len(running) < processes:
                start(queue.pop(0))
            if not running:
                break
            ready = wait([r.process.sentinel for r in running.values()]
                         + [r.reader for r in running.values() if r.message is None and not r.eof], timeout=_POLL_S)
            for run in list(running.values()):
                if run.message is None and not run.eof and run.reader in ready:
                    try:
                        run.message = run.reader.recv()
                    except (EOFError, OSError):  # it died without a word: its sentinel says how
                        run.eof = True
                if run.process.sentinel in ready:
                    end(run)
            now = time.monotonic()
            for run in list(running.values()):
                if run.kill_at is not None and now >= run.kill_at and run.process.is_alive():
                    run.process.kill()
    finally:
        try:
            if running:  # the parent's own error: no worker is left behind
                stop()
                for run in list(running.values()):
                    run.process.join(max(0.0, (run.kill_at or 0.0) - time.monotonic()))
                    if run.process.is_alive():
                        run.process.kill()
                    end(run)
        finally:
            if own:
                signal.signal(signal.SIGINT, previous)
    result.interrupted = result.interrupted or bool(noted)
    for out in result.outcomes:
        if out.state == "running":  # pragma: no cover  (every started worker was ended above)
            out.state = "died"
    return result
