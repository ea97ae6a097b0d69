"""Helpers of the commands' argument handling, shared by every command of ``agents`` (and ``pneunet-grasp demo``).
"""

from __future__ import annotations

import sys
from typing import Any


def usage_error(prog: str, message: str) -> None:
    """An argument error, argparse's way: one line ``PROG: error: MESSAGE`` on stderr, exit status 2."""
    print(f"{prog}: error: {message}", file=sys.stderr)
    raise SystemExit(2)


CATALOGUE_HELP = ("your own object catalogue, a YAML file in pneunet_env/data/objects.yaml's format (classes may lack "
                  "sources: then reported unsourced); --set use_case=NAME picks one of its use cases (default: its "
                  "default)")


def add_catalogue(parser) -> None:
    """The ``--catalogue PATH`` option of the commands that draw objects (read by :func:`parse_overrides`)."""
    parser.add_argument("--catalogue", default=None, metavar="PATH", help=CATALOGUE_HELP)


def parse_overrides(items, catalogue: str | None = None) -> dict[str, Any]:
    """``["KEY=VALUE", ...]`` -> a dict, each VALUE read as YAML exactly as in a config file
    (:func:`pneunet_env.yamlio.parse_value`: ``30``, ``5e1``, ``[30, 1000]``, ``true``); ``ValueError`` naming the
    item for a bad value. A key set twice takes its last value. ``catalogue`` (``--catalogue PATH``) adds the key
    ``catalogue``, and the file's default use case unless ``use_case`` or ``class_weights`` is set."""
    from pneunet_env.yamlio import parse_value

    out: dict[str, Any] = {}
    for item in items or []:
        key, eq, value = item.partition("=")
        if not eq or not key.strip():
            raise ValueError(f"--set needs KEY=VALUE, got {item!r}")
        out[key.strip()] = parse_value(value, f"--set {item!r}")
    return out if catalogue is None else with_catalogue(out, catalogue)


def with_catalogue(over: dict[str, Any], catalogue: str) -> dict[str, Any]:
    """``over`` (config keys) with the user's ``catalogue`` and, unless ``over`` names a use case or class weights,
    the file's default use case; ``ValueError`` naming the file if it is not a catalogue."""
    from pneunet_env.catalogue import default_use_case

    out = {**over, "catalogue": str(catalogue)}
    if "use_case" not in out and "class_weights" not in out:
        out["use_case"] = default_use_case(catalogue)
    return out
