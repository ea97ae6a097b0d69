"""The evaluation's rows summarised: by regime, by the paper's ``k~`` bins and by class (:func:`regime_summary`),
the printed table by stiffness decade (:func:`decade_table`), and what a use case draws (:func:`use_case_regimes`).
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from agents.common.regimes import SOFT_MAX, STIFF_MIN, _paper_bins, object_regimes
from pneunet_env.config import load_config

__all__ = ["regime_summary", "use_case_regimes", "decade_table"]


def _rates(rows) -> dict[str, Any]:
    """Episode-weighted rates over ``rows``; ``None`` rates where there is no episode."""
    w = np.array([r["episodes"] for r in rows], dtype=float)
    if w.sum() == 0:
        return {"episodes": 0, "success_rate": None, "damage_rate": None, "slip_rate": None}
    avg = lambda key: float(np.dot(w, [r[key] for r in rows]) / w.sum())  # noqa: E731
    return {"episodes": int(w.sum()), "success_rate": avg("success_rate"), "damage_rate": avg("damage_rate"),
            "slip_rate": avg("slip_rate")}


def _count_rates(counts) -> dict[str, Any]:
    """Rates from summed ``{episodes, success, damaged, slipped}`` counts (``None`` where there is no episode)."""
    n = sum(c["episodes"] for c in counts)
    if n == 0:
        return {"episodes": 0, "success_rate": None, "damage_rate": None, "slip_rate": None}
    tot = lambda key: sum(c[key] for c in counts) / n  # noqa: E731
    return {"episodes": n, "success_rate": tot("success"), "damage_rate": tot("damaged"), "slip_rate": tot("slipped")}


def regime_summary(rows, paper_bins: bool | None = None) -> dict[str, dict[str, dict[str, float]]]:
    """``{policy: {group: rates}}``, episode-weighted: ``"all"``; the regimes read off the mechanics
    (``"force-controlled"``, ``"position-controlled"``, ``"unreachable"``: those with episodes, from the rows'
    ``by_regime``); with ``paper_bins`` (default: unless the rows are drawn from the catalogue) the paper's ``k~``
    bins ``"soft"`` (``< 1e-4``), ``"intermediate"`` and ``"stiff"`` (``>= 1e-3``); for drawn objects each class.
    An empty group's rates are ``None``."""
    from pneunet_env.physics.regimes import REGIMES

    paper_bins = _paper_bins(rows) if paper_bins is None else paper_bins
    out: dict[str, dict[str, dict[str, float]]] = {}
    for name in dict.fromkeys(r["policy"] for r in rows):
        rs = [r for r in rows if r["policy"] == name]
        groups: dict[str, dict[str, Any]] = {}
        for reg in REGIMES:
            counts = [r["by_regime"][reg] for r in rs if reg in r.get("by_regime", {})]
            if counts:
                groups[reg] = _count_rates(counts)
        if paper_bins:
            groups["soft"] = _rates([r for r in rs if r["object_stiffness"] < SOFT_MAX])
            groups["intermediate"] = _rates([r for r in rs if SOFT_MAX <= r["object_stiffness"] < STIFF_MIN])
            groups["stiff"] = _rates([r for r in rs if r["object_stiffness"] >= STIFF_MIN])
        classes = dict.fromkeys(c for r in rs for c in r.get("by_class", {}))
        for c in classes:
            groups[f"class {c}"] = _count_rates([r["by_class"][c] for r in rs if c in r.get("by_class", {})])
        groups["all"] = _rates(rs)
        out[name] = groups
    return out


def use_case_regimes(use_case: str, draws: int = 4000, seed: int = 0) -> dict[str, Any]:
    """What a catalogue use case draws, read off the mechanics (docs/env.md's table of use cases).

    ``draws`` objects from :func:`pneunet_env.task.sample_object` (``default_rng(seed)``), each classed by
    :func:`pneunet_env.physics.regimes.regime` at the config's maximum pressure. Returns the shares
    ``{"force", "position", "unreachable"}``, the largest ``k~`` drawn, and ``modulus_span_decades``:
    ``log10`` of the largest over the smallest Young's modulus of the classes with weight (their catalogue
    ranges, not the draws).
    """
    from pneunet_env.catalogue import load_catalogue, use_case_weights
    from pneunet_env.physics.regimes import FORCE, POSITION, UNREACHABLE
    from pneunet_env.task import sample_object

    cfg = load_config(use_case=use_case)
    obj = sample_object(np.random.default_rng(seed), cfg, size=draws)
    reg = object_regimes(obj.stiffness, obj.curvature, cfg)
    catalogue = load_catalogue()
    moduli = [catalogue[name].youngs_modulus_kpa for name, w in use_case_weights(use_case).items() if w > 0]
    return {"use_case": use_case, "draws": draws, "seed": seed,
            "force": float(np.mean(reg == FORCE)), "position": float(np.mean(reg == POSITION)),
            "unreachable": float(np.mean(reg == UNREACHABLE)), "max_stiffness": float(np.max(obj.stiffness)),
            "modulus_span_decades": math.log10(max(e[1] for e in moduli) / min(e[0] for e in moduli))}


def decade_table(rows, paper_bins: bool | None = None) -> str:
    """Success / damage / slip by stiffness decade, by regime (read off the mechanics), by the paper's ``k~`` bins
    (``paper_bins``, as :func:`regime_summary`) and by class (drawn objects), one block per policy. A group with no
    episode is left out."""
    paper_bins = _paper_bins(rows) if paper_bins is None else paper_bins
    lines = []
    summary = regime_summary(rows, paper_bins)
    for name in dict.fromkeys(r["policy"] for r in rows):
        rs = [r for r in rows if r["policy"] == name]
        lines.append(f"{name}: {rs[0]['label']}")
        lines.append(f"  {'k~':>19}  {'episodes':>8}  {'success':>7}  {'damaged':>7}  {'slipped':>7}")
        decades = sorted({math.floor(math.log10(r["object_stiffness"]) + 1e-12) for r in rs})
        for d in decades:
            sub = [r for r in rs if math.floor(math.log10(r["object_stiffness"]) + 1e-12) == d]
            lines.append(_line(f"1e{d:+03d} - 1e{d + 1:+03d}", _rates(sub)))
        groups = summary[name]
        labels = {"force-controlled": "force-controlled", "position-controlled": "position-controlled",
                  "unreachable": "unreachable", "soft": "soft (< 1e-4)", "stiff": "stiff (>= 1e-3)"}
        labels.update({g: g.removeprefix("class ").replace("_", " ") for g in groups if g.startswith("class ")})
        for g, label in labels.items():
            if g in groups and groups[g]["episodes"]:
                lines.append(_line(label, groups[g]))
        lines.append(_line("all", groups["all"]))
        lines.append("")
    return "\n".join(lines)


def _line(label: str, r: dict[str, Any]) -> str:
    if r["episodes"] == 0:
        return f"  {label:>19}  no objects"
    return (f"  {label:>19}  {r['episodes']:>8}  {r['success_rate']:7.0%}  {r['damage_rate']:7.0%}  "
            f"{r['slip_rate']:7.0%}")
