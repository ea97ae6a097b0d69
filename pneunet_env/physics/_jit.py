"""Optional numba compilation of the scalar kernels.

numba is an optional extra (``pip install pneunet-env[fast]``): with it, the Newton solve runs as
compiled code (about a microsecond per solve instead of tens); without it the same functions run as
plain Python, with identical results up to floating-point round-off. Set ``PNEUNET_DISABLE_NUMBA=1``
to force the pure-Python path.
"""

from __future__ import annotations

import inspect
import os
from collections.abc import Callable, Mapping
from typing import Any

__all__ = ["HAVE_NUMBA", "njit", "python_entry"]

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


def python_entry(fn: Callable, record: type, nested: Mapping[str, type] | None = None) -> Callable:
    """``fn`` (compiled, returning the NamedTuple ``record``) as Python should call it: a twin compiled to return a
    plain tuple of numbers, from which Python builds the same ``record`` (``nested`` names the fields that are
    records themselves, with their types). Compiled callers keep calling ``fn``; without numba this is ``fn``.

    Why: numba turns a returned NamedTuple into a Python object by running Python code (it unpickles the class), and
    a signal that came during the compiled call is handled there, first. A Ctrl-C's ``KeyboardInterrupt`` raised
    at that moment makes numba call NULL: a segmentation fault instead of the interrupt (numba 0.68; numba issue
    #2324). A tuple of numbers is built by C alone, so the interrupt is raised after the call returns, as usual.
    """
    if not HAVE_NUMBA:
        return fn
    nested = dict(nested or {})
    names = list(inspect.signature(fn.py_func).parameters)

    def fields(expr: str, rec: type) -> str:
        parts = [fields(f"{expr}.{f}", nested[f]) if f in nested else f"{expr}.{f}" for f in rec._fields]
        return "(" + ", ".join(parts) + ",)"

    args = ", ".join(names)
    namespace: dict[str, Any] = {"fn": fn}
    exec(f"def plain({args}):\n    r = fn({args})\n    return {fields('r', record)}\n", namespace)  # noqa: S102
    plain = _numba.njit(namespace["plain"], cache=False, fastmath=False, nogil=True)
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
    entry.__name__ = entry.__qualname__ = getattr(fn, "__name__", "entry")
    entry.__doc__ = fn.__doc__
    entry.compiled = fn  # the compiled function itself, for compiled callers
    return entry
