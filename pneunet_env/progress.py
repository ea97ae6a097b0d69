"""The one progress bar helper of the command line (and of the long jobs it runs).

:func:`progress` returns a ``tqdm`` bar on stderr, or a :class:`NoBar` passthrough with the same small
interface (iterate, ``update``, ``set_description_str``, ``set_postfix_str``, ``refresh``, ``close``, ``write``,
``total``) so that callers never test for ``None``. The bar is shown when

* ``enabled`` is ``True`` (forced on), or ``enabled`` is ``None`` (auto) and stderr is a terminal, and
* ``tqdm`` is installed (it comes with the ``plot`` and ``rl`` extras, not with the core package).

``enabled=False`` (``--no-progress``) always turns it off. Only the command line and the jobs below it
(``pneunet_env.bench``, ``pneunet_env.paper.command``, ``agents``) use this module; the library
(``pneunet_env.envs``, ``physics``, ``task``) never does.
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Iterable, Iterator
from typing import Any

__all__ = ["NoBar", "add_progress_argument", "progress", "progress_enabled"]


def progress_enabled(enabled: bool | None = None) -> bool:
    """Whether a bar would be drawn: ``enabled`` if given, else whether stderr is a terminal (tqdm aside)."""
    if enabled is not None:
        return bool(enabled)
    isatty = getattr(sys.stderr, "isatty", None)
    try:
        return bool(isatty()) if isatty is not None else False
    except ValueError:  # a closed stream
        return False


class NoBar:
    """A do-nothing stand-in for a tqdm bar: iterates over ``iterable`` (if any), ignores every update."""

    def __init__(self, iterable: Iterable | None = None, total: float | None = None, **_: Any) -> None:
        self.iterable = iterable
        if total is None and iterable is not None:
            try:
                total = len(iterable)  # type: ignore[arg-type]
            except TypeError:
                total = None
        self.total = total
        self.n = 0

    def __iter__(self) -> Iterator:
        if self.iterable is None:
            raise TypeError("this progress bar has no iterable; call update() instead")
        return iter(self.iterable)

    def __len__(self) -> int:
        return int(self.total or 0)

    def __enter__(self) -> NoBar:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def update(self, n: float = 1) -> None:
        self.n += n

    def set_description(self, desc: str | None = None, refresh: bool = True) -> None:
        pass

    def set_description_str(self, desc: str | None = None, refresh: bool = True) -> None:
        pass

    def set_postfix(self, *args: Any, **kwargs: Any) -> None:
        pass

    def set_postfix_str(self, s: str = "", refresh: bool = True) -> None:
        pass

    def refresh(self) -> None:
        pass

    def close(self) -> None:
        pass

    @staticmethod
    def write(s: str, file: Any = None, end: str = "\n") -> None:
        """Print ``s`` (to stdout by default), as ``tqdm.write`` does without clobbering a bar."""
        print(s, file=sys.stdout if file is None else file, end=end)


def progress(iterable: Iterable | None = None, total: float | None = None, desc: str | None = None,
             enabled: bool | None = None, unit: str = "it", leave: bool = False, **kwargs: Any):
    """A tqdm bar over ``iterable`` (or a manual one, ``iterable=None``, driven by ``update``) on stderr.

    Args:
        enabled: ``None`` (default): on when stderr is a terminal; ``True``: on; ``False``: off.
        leave: keep the finished bar on screen (default: erase it).
        kwargs: passed on to ``tqdm``.

    Returns a :class:`NoBar` passthrough when the bar is off or tqdm is not installed.
    """
    if progress_enabled(enabled):
        try:
            from tqdm import tqdm
        except ImportError:  # tqdm comes with the plot/rl extras
            pass
        else:
            return tqdm(iterable, total=total, desc=desc, unit=unit, leave=leave, file=sys.stderr, **kwargs)
    return NoBar(iterable, total=total)


def add_progress_argument(parser: argparse.ArgumentParser, *aliases: str) -> None:
    """Add ``--no-progress`` (and ``aliases``): ``args.progress`` is ``False`` with it, else ``None`` (auto)."""
    parser.add_argument("--no-progress", *aliases, dest="progress", action="store_const", const=False, default=None,
                        help="no progress bar (default: one on stderr when it is a terminal)")
