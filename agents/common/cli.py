"""Helpers of the commands' argument handling, shared by every command of ``agents`` (and ``pneunet-grasp demo``).
"""

from __future__ import annotations

import sys
from typing import Any


def usage_error(prog: str, message: str) -> None:
    """An argument error, argparse's way: one line ``PROG: error: MESSAGE`` on stderr, exit status 2."""
    print(f"{prog}: error: {message}", file=sys.stderr)
    raise SystemExit(2)


def parse_overrides(items) -> dict[str, Any]:
    """``["KEY=VALUE", ...]`` -> a dict, each VALUE read as YAML exactly as in a config file
    (:func:`pneunet_env.yamlio.parse_value`: ``30``, ``5e1``, ``[30, 1000]``, ``true``); ``ValueError`` naming the
    item for a bad value. A key set twice takes its last value."""
    from pneunet_env.yamlio import parse_value

    out: dict[str, Any] = {}
    for item in items or []:
        key, eq, value = item.partition("=")
        if not eq or not key.strip():
            raise ValueError(f"--set needs KEY=VALUE, got {item!r}")
        out[key.strip()] = parse_value(value, f"--set {item!r}")
    return out
