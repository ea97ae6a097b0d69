"""Optional numba compilation of the scalar kernels.

numba is an optional extra (``pip install pneunet-env[fast]``): with it, the Newton solve runs as
compiled code (about a microsecond per solve instead of tens); without it the same functions run as
plain Python, with identical results up to floating-point round-off. Set ``PNEUNET_DISABLE_NUMBA=1``
to force the pure-Python path.
"""

from __future__ import annotations

import os

__all__ = ["HAVE_NUMBA", "njit"]

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
