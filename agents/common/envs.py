"""The env ids the policies drive.
"""

from __future__ import annotations

from pneunet_env.files import atomic_write_bytes, stage_file  # noqa: F401  (re-exported: the one atomic writer)

__all__ = ["PNEUNET_ENV", "RIGID_ENV"]


PNEUNET_ENV = "PneuNetGrasp-v1"


RIGID_ENV = "RigidGrasp-v1"
