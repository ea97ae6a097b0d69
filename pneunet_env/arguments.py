"""The command line's value checks: argparse ``type=`` callables that refuse a bad value at parse time, before any
work, with a message naming what the option takes and what it got.

argparse prints the message as ``pneunet-grasp CMD: error: argument --seed: MESSAGE`` and exits with status 2.
The commands of ``pneunet_env``, ``pneunet_env.bench``, ``pneunet_env.paper`` and ``agents`` import them from here
(below the CLI: nothing of theirs imports :mod:`pneunet_env.cli`).

* Numbers: :func:`integer` (a whole number in a range: ``1e3``, ``nan`` and ``x`` are refused), :data:`count`,
  :data:`seed` (``0 <= seed < 2**32``), :func:`real` (a *finite* number in a range: ``nan``, ``inf`` and ``1e400``,
  which overflows to ``inf``, are refused), :data:`positive`, :data:`non_negative`.
* Outputs, checked before the work, so that a run never ends by failing to write what it computed:
  :func:`output_dir` (an existing folder, or one that can be created: not an existing file, nothing under a file,
  a place this process can write) and :func:`output_file` (a file that can be written there; an existing file is
  replaced atomically, through :mod:`pneunet_env.files`, as the command's docs say; a folder or a device is
  refused). Their ``check_*`` twins check a path that did not come through argparse (a default computed later).
  A path too long for the file system is refused by both (``ENAMETOOLONG`` would come only at the first write).
* Inputs: :func:`check_input_path` (``--config``): a FIFO, a device, a folder or a too-long path is refused before
  anything opens it (:func:`pneunet_env.yamlio.check_input_file`, which every YAML and JSON file read goes through).
* Errors of the file system: :func:`os_error_line`, the command line's one line for a full disk, a quota, a
  read-only file system, a too-long path.
"""

from __future__ import annotations

import argparse
import errno
import math
import os
import tempfile
from collections.abc import Callable
from pathlib import Path

from pneunet_env.yamlio import check_input_file, path_too_long, short_repr

__all__ = ["MAX_COUNT", "MAX_SEED", "check_input_path", "check_output_dir", "check_output_file", "count", "integer",
           "non_negative", "os_error_line", "output_dir", "output_file", "positive", "real", "seed"]

MAX_COUNT = 1_000_000
"""The largest count an option takes by default (objects, episodes, steps): more would run for days or exhaust
memory before the first episode."""
MAX_SEED = 2**32 - 1
"""The largest seed (numpy's legacy range): seeds are offset and multiplied into 64-bit integers downstream."""


def _named(func: Callable, name: str) -> Callable:
    func.__name__ = func.__qualname__ = name
    return func


def integer(minimum: int | None = None, maximum: int | None = None, what: str | None = None) -> Callable[[str], int]:
    """A ``type=`` reading a whole number (``12``, ``-3``; not ``1e3``, ``2.0``, ``nan``) in
    ``[minimum, maximum]`` (``None``: no bound); ``what`` names the value in the message (``"the grid size"``)."""

    def parse(text: str) -> int:
        message = f"{what + ' must be' if what else 'needs'} a whole number{_range(minimum, maximum)}, got {text!r}"
        try:
            value = int(str(text).strip(), 10)
        except ValueError:
            raise argparse.ArgumentTypeError(message) from None
        if (minimum is not None and value < minimum) or (maximum is not None and value > maximum):
            raise argparse.ArgumentTypeError(message)
        return value

    return _named(parse, "integer")


def real(minimum: float | None = None, maximum: float | None = None, *,
         above: bool = False) -> Callable[[str], float]:
    """A ``type=`` reading a finite number (``1e-3``, ``0.5``; not ``nan``, ``inf`` or ``1e400``) in
    ``[minimum, maximum]``; ``above``: strictly above ``minimum``."""

    def parse(text: str) -> float:
        want = f"a finite number{_range(minimum, maximum, above)}"
        try:
            value = float(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"needs {want}, got {text!r}") from None
        if not math.isfinite(value):
            raise argparse.ArgumentTypeError(f"needs {want}, got {text!r}"
                                             + (" (it overflows)" if "inf" not in str(text).lower()
                                                and "nan" not in str(text).lower() else ""))
        low = minimum is not None and (value <= minimum if above else value < minimum)
        if low or (maximum is not None and value > maximum):
            raise argparse.ArgumentTypeError(f"needs {want}, got {text!r}")
        return value

    return _named(parse, "number")


def _range(lo, hi, above: bool = False) -> str:
    fmt = lambda x: str(x) if isinstance(x, int) else f"{x:g}"  # noqa: E731
    if lo is not None and hi is not None:
        return f" in {'(' if above else '['}{fmt(lo)}, {fmt(hi)}]"
    if lo is not None:
        return f" {'>' if above else '>='} {fmt(lo)}"
    if hi is not None:
        return f" <= {fmt(hi)}"
    return ""


count = integer(1, MAX_COUNT)
"""A count of things to run (objects, episodes, steps): a whole number in ``[1, MAX_COUNT]``."""
seed = _named(integer(0, MAX_SEED), "seed")
"""A seed: a whole number in ``[0, 2**32 - 1]``."""
positive = real(0.0, above=True)
"""A finite number ``> 0``."""
non_negative = real(0.0)
"""A finite number ``>= 0``."""


def _nearest_existing(path: Path) -> Path:
    p = path.absolute()
    while not p.exists() and p != p.parent:
        p = p.parent
    return p


def _writable(folder: Path, shown: str) -> None:
    """Refuse unless a file can be created in ``folder`` (tried: permissions, a read-only file system, ``/proc``)."""
    try:
        fd, name = tempfile.mkstemp(dir=folder, prefix=".pneunet-write-check-")
    except OSError as exc:
        raise argparse.ArgumentTypeError(f"{shown}: cannot write in {str(folder)!r} ({exc.strerror or exc})") from None
    os.close(fd)
    os.unlink(name)


def check_output_dir(path: str | os.PathLike, option: str = "--out") -> Path:
    """``path`` as an output folder: an existing folder this process can write in, or one it can create.

    Raises:
        ValueError: naming ``option`` and ``path``: an empty path, an existing file, a path under a file, or a
            place that cannot be written.
    """
    try:
        return _output_dir(path, option)
    except argparse.ArgumentTypeError as exc:
        raise ValueError(str(exc)) from None


def _named_path(path, option: str) -> tuple[Path, str, str]:
    """``(path, its text, how a message names it)``; an empty path, or one too long for the file system
    (:func:`pneunet_env.yamlio.path_too_long`), refused."""
    text = os.fspath(path)
    shown = f"{option} {short_repr(text)}" if option else short_repr(text)
    if not str(text).strip():
        raise argparse.ArgumentTypeError(f"{shown}: an empty path")
    why = path_too_long(text)
    if why is not None:
        raise argparse.ArgumentTypeError(f"{shown}: the path is too long ({why})")
    return Path(text), str(text), shown


def _creatable_under(folder: Path, shown: str) -> None:
    """``folder`` (a path's nearest existing ancestor) is a folder this process can write in."""
    if not folder.is_dir():
        raise argparse.ArgumentTypeError(f"{shown}: cannot be created, {str(folder)!r} is a file, not a folder")
    _writable(folder, shown)


def _output_dir(path, option: str) -> Path:
    p, _, shown = _named_path(path, option)
    if p.exists():
        if not p.is_dir():
            raise argparse.ArgumentTypeError(f"{shown} exists and is not a folder (it would hold the outputs)")
        _writable(p, shown)
        return p
    _creatable_under(_nearest_existing(p), shown)
    return p


def check_output_file(path: str | os.PathLike, option: str = "--out") -> Path:
    """``path`` as an output file: a new file in a folder that exists or can be created, or an existing regular
    file (replaced atomically when written).

    Raises:
        ValueError: naming ``option`` and ``path``: an empty path, a folder, a device, a path under a file, or a
            place that cannot be written.
    """
    try:
        return _output_file(path, option)
    except argparse.ArgumentTypeError as exc:
        raise ValueError(str(exc)) from None


def _output_file(path, option: str) -> Path:
    p, text, shown = _named_path(path, option)
    if p.is_dir() or text.endswith(("/", os.sep)):
        raise argparse.ArgumentTypeError(f"{shown} is a folder; give a file name")
    if p.exists() and not p.is_file():
        raise argparse.ArgumentTypeError(f"{shown} exists and is not a regular file")
    _creatable_under(_nearest_existing(p.parent), shown)
    return p


def check_input_path(path: str | os.PathLike, option: str = "--config") -> None:
    """``path`` as an input file, before anything opens it (:func:`pneunet_env.yamlio.check_input_file`): a path too
    long for the file system, or one that exists and is a folder, a FIFO (its opening would wait for a writer for
    ever) or a device, is refused with a ``ValueError`` naming ``option``; a missing one passes (the caller may find
    it by another name, or say it is missing)."""
    check_input_file(path, f"{option} {short_repr(os.fspath(path))}")


_WRITE_ERRORS = {errno.ENOSPC: "no space left on the device", errno.EROFS: "a read-only file system",
                 errno.ENAMETOOLONG: "the path is too long for the file system"}
if hasattr(errno, "EDQUOT"):  # (not on Windows)
    _WRITE_ERRORS[errno.EDQUOT] = "the disk quota is exceeded"


def os_error_line(exc: OSError) -> str | None:
    """The one line that names an :class:`OSError` the user can act on, with its path, as the command line prints
    it: ``no space left on the device writing '/runs/a/run.json'`` (``ENOSPC``; ``EDQUOT``, ``EROFS`` alike), ``the
    path is too long for the file system: '/tmp/aaaa...' (5,005 characters)`` (``ENAMETOOLONG``); ``None`` for
    any other error (a bug, shown as such)."""
    what = _WRITE_ERRORS.get(getattr(exc, "errno", None))
    if what is None:
        return None
    name = exc.filename if exc.filename is not None else exc.filename2
    if exc.errno == errno.ENAMETOOLONG:
        return what + ("" if name is None else f": {short_repr(os.fsdecode(name))}")
    return what + (" (writing)" if name is None else f" writing {short_repr(os.fsdecode(name))}")


def output_dir(text: str) -> Path:
    """``type=`` of an output folder option: :func:`check_output_dir` at parse time."""
    return _output_dir(text, "")


def output_file(text: str) -> Path:
    """``type=`` of an output file option: :func:`check_output_file` at parse time."""
    return _output_file(text, "")
