"""The files the package ships, found by name: train configs (``--config ppo``), env configs
(``--config designed-kitchen``) and trained models (``--policy ppo_kitchen``).

A source checkout keeps the configs in ``configs/train/`` and ``configs/env/`` at the repository's root, where
users copy and edit them; a wheel ships the same files inside the package, as ``agents/configs/train/`` and
``agents/configs/env/`` (``setup.py`` copies them at build time), so that an installed package finds them from any
folder. A name is looked up only when no file of that name exists: a path always means the file it names.
"""

from __future__ import annotations

import os
from pathlib import Path

AGENTS_DIR = Path(__file__).resolve().parents[1]
"""The package's root, ``agents/``: the shipped schedules (``best_ramp.json``, ...), ``models/`` and (in a wheel)
``configs/`` lie there."""
MODELS_DIR = AGENTS_DIR / "models"
CONFIG_DIRS = (AGENTS_DIR / "configs", AGENTS_DIR.parent / "configs")
"""Where named configs are looked up: the wheel's copy, then a source checkout's ``configs/``."""

__all__ = ["AGENTS_DIR", "is_name", "config_names", "resolve_config", "model_names", "resolve_model", "MODELS_DIR"]


def is_name(value: str | os.PathLike) -> bool:
    """Whether ``value`` reads as a bare name (no folder, no suffix): ``ppo``, not ``ppo.yaml`` or ``x/ppo``."""
    text = os.fspath(value)
    return bool(text) and os.sep not in text and "/" not in text and not Path(text).suffix


def config_names(kind: str) -> list[str]:
    """The shipped configs of ``kind`` (``"train"`` or ``"env"``), by name (``ppo``, ``designed-kitchen``)."""
    names: set[str] = set()
    for root in CONFIG_DIRS:
        folder = root / kind
        if folder.is_dir():
            names.update(p.stem for p in folder.glob("*.yaml") if not p.stem.endswith(".project"))
    return sorted(names)


def resolve_config(value: str | os.PathLike | None, kind: str) -> str | Path | None:
    """``value`` as a config file: an existing path as it is; a bare name (no folder, no suffix) as the shipped
    ``configs/<kind>/<name>.yaml``; ``None`` stays ``None``.

    Raises:
        ValueError: a bare name that is no shipped config (the valid names listed), or a path that does not exist.
    """
    if value is None or isinstance(value, dict):
        return value
    path = Path(value)
    if path.is_file():
        return value
    if is_name(value):
        for root in CONFIG_DIRS:
            cand = root / kind / f"{os.fspath(value)}.yaml"
            if cand.is_file():
                return cand
        raise ValueError(f"--config {os.fspath(value)!r}: no such file, and no shipped {kind} config of that name; "
                         f"shipped: {', '.join(config_names(kind)) or 'none'}")
    raise ValueError(f"--config {os.fspath(value)!r}: no such file")


def model_names() -> list[str]:
    """The shipped trained models, by name (``ppo_kitchen``, ...)."""
    return sorted(p.stem for p in MODELS_DIR.glob("*.zip")) if MODELS_DIR.is_dir() else []


def resolve_model(name: str) -> Path | None:
    """The shipped model ``agents/models/<name>.zip`` for a bare name, else ``None``."""
    if not is_name(name):
        return None
    path = MODELS_DIR / f"{name}.zip"
    return path if path.is_file() else None
