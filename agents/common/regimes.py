"""The regime labels that evaluation, the design study and the figures share: the paper's ``k~`` bins and each
object's regime read off the mechanics (:mod:`pneunet_env.physics.regimes`).
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from pneunet_env.config import EnvConfig

__all__ = ["SOFT_MAX", "STIFF_MIN", "object_regimes", "regime_rates"]


SOFT_MAX = 1e-4
"""The paper's soft regime on its ring: ``k~ < 1e-4`` (a 1.5 kPa gel at the paper's object size)."""


STIFF_MIN = 1e-3
"""The paper's stiff regime on its ring: ``k~ >= 1e-3`` (a 15 kPa elastomer)."""


def _paper_bins(rows) -> bool:
    """Whether the paper's ``k~`` bins apply: objects pinned on a ``k~`` grid (not drawn from the catalogue)."""
    return not any(r.get("objects") == "drawn" for r in rows)


def object_regimes(stiffness, curvature, config: EnvConfig) -> np.ndarray:
    """Each object's regime code (:data:`pneunet_env.physics.regimes.FORCE`, ``POSITION`` or ``UNREACHABLE``),
    read off the mechanics at ``config``'s maximum pressure, with its actuator and solver settings."""
    from pneunet_env.physics.regimes import regime

    return regime(stiffness, curvature, config.pressure_max, config.actuator_params, config.solver)


def regime_rates(success, stiffness, curvature, config: EnvConfig) -> dict[str, Any]:
    """``{success_rate_force, success_rate_position, objects_force, objects_position}``: success split by the
    objects' regimes (:func:`object_regimes`; NaN for an empty side)."""
    from pneunet_env.physics.regimes import FORCE, POSITION

    ok = np.asarray(success, dtype=bool)
    reg = object_regimes(stiffness, curvature, config)
    rate = lambda m: float(ok[m].mean()) if m.any() else math.nan  # noqa: E731
    return {"success_rate_force": rate(reg == FORCE), "success_rate_position": rate(reg == POSITION),
            "objects_force": int((reg == FORCE).sum()), "objects_position": int((reg == POSITION).sum())}
