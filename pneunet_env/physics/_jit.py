"""Optional numba compilation of the scalar kernels.

numba is an optional extra (``pip install pneunet-env[fast]``): with it, the Newton solve runs as
compiled code (about a microsecond per solve instead of tens); without it the same functions run as
plain Python, with identical results up to floating-point round-off. Set ``PNEUNET_DISABLE_NUMBA=1``
to force the pure-Python path.
"""

from __future__ import annotations

import hashlib
import os
from collections.abc import Callable, Mapping
from pathlib import Path
from typing import Any

__all__ = ["HAVE_NUMBA", "njit", "njit_cached", "python_entry", "source_stamp"]

HAVE_NUMBA = False
if not os.environ.get("PNEUNET_DISABLE_NUMBA"):
    try:
        import numba as _numba

        HAVE_NUMBA = True
    except ImportError:  # pragma: no cover - depends on the install
        pass


def njit(fn):
    """``numba.njit(fn)`` when numba is available (and not disabled), else ``fn`` unchanged."""
    if HAVE_NUMBA:
        return _numba.njit(fn, cache=False, fastmath=False, nogil=True)
    return fn


def source_stamp(modules) -> int | None:
    """A hash of the sources of ``modules`` (numba's disk cache only watches a function's own file); ``None`` if they
    cannot be read (then nothing built on it is cached)."""
    h = hashlib.sha256()
    try:
        for module in modules:
            h.update(Path(module.__file__).read_bytes())
    except (OSError, TypeError):
        return None
    return int(h.hexdigest()[:15], 16)


def njit_cached(make: Callable[[int], Callable], modules, **options: Any) -> Callable:
    """``numba.njit(make(stamp), cache=True, nogil=True, **options)``, ``stamp`` being :func:`source_stamp` of
    ``modules``: compiled once and loaded from numba's disk cache in later processes, recompiled after an edit of any
    of those sources. ``make`` builds the function with ``stamp`` as a closure variable that the function reads (it
    is part of the cache's key). The solver's own closures cannot be cached (numba keys them by their pickled
    closure, which differs in every process); a cached function that calls them carries their code, compiled in.
    Without numba: ``make(0)``, plain Python."""
    if not HAVE_NUMBA:
        return make(0)
    stamp = source_stamp(modules)
    return _numba.njit(make(stamp or 0), nogil=True, cache=stamp is not None, **options)


def python_entry(plain: Callable, record: type, nested: Mapping[str, type] | None = None) -> Callable:
    """A compiled function that returns a record's fields as a plain tuple of numbers (``nested``: the fields that
    are records themselves, by name, with their types), as Python calls it: the same call, returning the
    ``record``, built in Python.

    Why: numba turns a returned NamedTuple into a Python object by running Python code (it unpickles the class), and
    a signal that came during the compiled call is handled there, first. A Ctrl-C's ``KeyboardInterrupt`` raised
    at that moment makes numba call NULL: a segmentation fault instead of the interrupt (numba 0.68; numba issue
    #2324). A tuple of numbers is built by C alone, so the interrupt is raised after the call returns, as usual.
    """
    make = record._make
    if not nested:
        def entry(*a):
            return make(plain(*a))
    else:
        where = [(i, nested[f]._make) for i, f in enumerate(record._fields) if f in nested]

        def entry(*a):
            t = list(plain(*a))
            for i, build in where:
                t[i] = build(t[i])
            return make(t)
    entry.__name__ = entry.__qualname__ = getattr(plain, "__name__", "entry")
    entry.__doc__ = plain.__doc__
    entry.plain = plain  # the compiled function itself
    return entry
