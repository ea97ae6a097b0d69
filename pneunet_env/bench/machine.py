"""The machine a benchmark ran on, as its JSON records it: versions, CPUs, numba's threads and threading layer, load."""

from __future__ import annotations

import os
import platform
from typing import Any

import numpy as np

__all__ = ["machine", "load_average"]


def load_average() -> list[float] | None:
    """The 1/5/15-minute load averages (other work on the machine makes every figure slower), if available."""
    try:
        return [round(x, 2) for x in os.getloadavg()]
    except (AttributeError, OSError):  # pragma: no cover - not on Windows
        return None


def machine() -> dict[str, Any]:
    """Python, numpy, Gymnasium and numba versions, the platform and CPUs, and (with numba) its threads, the threading
    layer the parallel loops ran on and where TBB was loaded from. Call it after the runs."""
    import gymnasium

    from pneunet_env.physics._jit import HAVE_NUMBA

    info = {
        "python": platform.python_version(),
        "numpy": np.__version__,
        "gymnasium": gymnasium.__version__,
        "numba": None,
        "platform": platform.platform(),
        "processor": platform.processor() or platform.machine(),
        "cpus": os.cpu_count(),
    }
    if HAVE_NUMBA:
        import numba

        from pneunet_env.physics.batched import TBB_LOADED

        info["numba"] = numba.__version__
        info["numba_threads"] = numba.get_num_threads()
        try:  # the layer the parallel loops ran on (after the runs: it is chosen at the first one)
            info["threading_layer"] = numba.threading_layer()
        except ValueError:
            info["threading_layer"] = None
        info["tbb_loaded"] = TBB_LOADED
    return info
