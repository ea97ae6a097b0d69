"""A study's outputs: design configs with their ramps beside them, design.json's figures (Pareto, curves,
importance)."""

from __future__ import annotations

import json
import textwrap
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np

from agents.design.space import P_TILDE_MAX, RAMP_STEPS, WINDOW_POINTS, design_config
from agents.policies.scripted import jsonable
from pneunet_env.config import EnvConfig
from pneunet_env.yamlio import dump_yaml


def design_yaml(params: Mapping[str, Any], base: EnvConfig, note: str) -> str:
    """The env config of a design as YAML (the actuator, its pressure scale and the objects it was designed for)."""

    cfg = design_config(params, base)
    d = cfg.to_dict()
    body = {"actuator": d["actuator"],
            "objects": {"use_case": d["objects"]["use_case"], "class_weights": d["objects"]["class_weights"]},
            "task": {"max_pressure_kpa": d["task"]["max_pressure_kpa"],
                     "max_pressure_step_kpa": d["task"]["max_pressure_step_kpa"],
                     "grip_faces": d["task"]["grip_faces"]}}
    head = "".join(f"# {line}\n" for line in note.splitlines())
    return head + dump_yaml(body, sort_keys=False)


OUTSIDE_NOTE = " (OUTSIDE the stretch its material was fitted on: not buildable as scored)"
NO_DATA_NOTE = (" (the paper's own material, with no elastomer's data behind it: a requirement on the material, not a "
                "design to build)")


def write_design(path: Path, row: dict[str, Any], base: EnvConfig, study: str) -> Path:
    """``PATH.yaml`` (the design's env config) and ``PATH.best_ramp.json`` (its blind ramp, found on the search
    objects), both written atomically."""
    from agents.policies.scripted import LinearRamp
    from pneunet_env.files import atomic_write_bytes

    s, h = row["search"], row["held_out"]
    e = row["elastomer"]
    note = (f"A pneu-net designed by `pneunet-grasp design` (study {study!r}, trial {row['trial']}): "
            f"{row['label']}.\n"
            f"Elastomer: {e['name']} (mu {e['shear_modulus_kpa']:g} kPa, J {e['gent_limit']:g}; "
            f"pneunet_env/data/elastomers.yaml: {e['source']}).\n"
            f"Blind ramp beside it ({path.stem}.best_ramp.json): {s['pressure_kpa']:.1f} kPa over {RAMP_STEPS} "
            "steps.\n"
            f"Held-out objects ({h['objects']['all']}): force-controlled {h['blind']['force']:.1%}, "
            f"position-controlled {h['blind']['position']:.1%} (Table 1's labels); oracle "
            f"{h['oracle']['force']:.1%} / {h['oracle']['position']:.1%}; at the worst corner (walls, modulus, the "
            f"material's range, the regulator's +-{h.get('pressure_error_kpa', 0):g} kPa) "
            f"{h.get('worst_corner', {}).get('force', float('nan')):.1%} / "
            f"{h.get('worst_corner', {}).get('position', float('nan')):.1%}; largest wall stretch "
            f"{h.get('wall_stretch', float('nan')):.2f}"
            f"{OUTSIDE_NOTE if h.get('outside_data') else NO_DATA_NOTE if h.get('outside_data', 0) is None else ''}"
            ".\n"
            'Load with gym.make("PneuNetGrasp-v1", config="<this file>").')
    path.parent.mkdir(parents=True, exist_ok=True)
    atomic_write_bytes(path, design_yaml(row["params"], base, note).encode())
    cfg = design_config(row["params"], base)
    ramp = LinearRamp(s["target"], RAMP_STEPS, cfg)
    data = {**ramp.to_dict(), "gripper": "pneunet", "target_kpa": s["pressure_kpa"],
            # what target is a fraction of (agents.policies.scripted.ramp_target)
            "max_pressure_kpa": cfg.task.max_pressure_kpa,
            "search": {"by": "pneunet-grasp design", "study": study, "trial": row["trial"],
                       "objects": s["objects"]["all"]},
            "score": {"search": {k: s.get(k) for k in ("blind", "oracle", "robust", "worst_corner")},
                      "held_out": {k: h.get(k) for k in ("blind", "oracle", "robust", "worst_corner", "corners",
                                                          "wall_stretch", "outside_data")}}}
    atomic_write_bytes(path.with_suffix(".best_ramp.json"), (json.dumps(data, indent=1) + "\n").encode())
    return path


def write_outputs(spec, result: dict[str, Any], base: EnvConfig) -> None:
    """Every output of a study's report in ``spec.out`` (atomic writes)."""
    from pneunet_env.files import atomic_write_bytes

    out = spec.out
    for row in result["designs"]:
        write_design(out / "designs" / f"{row['label']}.yaml", row, base, spec.name)
    atomic_write_bytes(out / "design.json", (json.dumps(result, indent=1, default=jsonable) + "\n").encode())
    try:
        plt = _plt()
    except ImportError:
        return
    plot_pareto(result, out / "pareto.png", plt)
    plot_curves(result, base, out / "curves.png", plt)
    plot_importance(result, out / "importance.png", plt)


def _plt():
    from agents.figures.style import _matplotlib

    return _matplotlib()


def _save(fig, path: Path, plt) -> Path:
    """Save a figure atomically (:func:`pneunet_env.files.save_figure`) and close it."""
    from pneunet_env.files import save_figure

    return save_figure(fig, path, dpi=120)


def _wrap(text: str, width_in: float, fontsize: float) -> str:
    """``text`` broken into lines no wider than ``width_in`` inches at ``fontsize`` points, its own line breaks kept:
    a long list of class weights must not run off the figure (tight_layout moves the axes, never shortens a title).
    A character is taken as 0.62 em wide (DejaVu Sans averages about 0.55)."""
    chars = max(20, int(width_in * 72.0 / (0.62 * fontsize)))
    return "\n".join(textwrap.fill(line, chars) for line in text.splitlines())


def _title_and_layout(fig, ax, text: str, fontsize: float) -> None:
    """``ax``'s title, wrapped to the axes' width (a title is centred on its axes, not on the figure), then
    ``tight_layout``: laid out once to find that width, and again with the title."""
    fig.tight_layout()
    ax.set_title(_wrap(text, ax.get_position().width * fig.get_figwidth(), fontsize), fontsize=fontsize)
    fig.tight_layout()


def _use_case_title(result: dict[str, Any]) -> str:
    st = result["settings"]
    return st["use_case"] if st["class_weights"] is None else "class weights " + ", ".join(
        f"{k} {v:g}" for k, v in st["class_weights"].items())


def _table1(result: dict[str, Any]) -> dict[str, Any] | None:
    """The study's Table 1 row (``None`` without one)."""
    return next((row for row in result["designs"] if row["label"] == "table1"), None)


def _is_table1(row: dict[str, Any], table1: dict[str, Any] | None) -> bool:
    """Whether a ranked design is Table 1's actuator itself (its trial, or the same parameters): a small study's best
    may be."""
    return table1 is not None and row is not table1 and row["params"] == table1["params"]


def plot_pareto(result: dict[str, Any], path: Path, plt) -> Path:
    """Blind success on force- against position-controlled objects (Table 1's labels), every design of the study;
    colour: the worse regime at the worst corner (the third objective); the Pareto front ringed; Table 1 and the best
    marked."""
    return _save(pareto_figure(result, plt), path, plt)


def pareto_figure(result: dict[str, Any], plt):
    """:func:`plot_pareto`'s figure (not saved)."""
    pts = result["all"]
    x = np.array([p["objectives"][0] for p in pts])
    y = np.array([p["objectives"][1] for p in pts])
    c = np.array([p["objectives"][2] for p in pts])
    front = np.array([p["pareto"] for p in pts])
    fig, ax = plt.subplots(figsize=(6.4, 5.0))
    sc = ax.scatter(x, y, c=c, cmap="viridis", vmin=0, vmax=1, s=22, alpha=0.85, lw=0)
    ax.scatter(x[front], y[front], s=70, facecolors="none", edgecolors="black", lw=0.9, label="Pareto front")
    for row in result["designs"]:
        s = row["search"]
        if row["label"] == "table1":
            ax.plot(s["blind"]["force"], s["blind"]["position"], "*", ms=16, color="#d62728", mec="black",
                    label=f"Table 1 actuator ({s['pressure_kpa']:.1f} kPa)")
        elif row["label"] == "rank-1":  # drawn over Table 1's star (smaller): both show if they are one design
            what = "Table 1 itself" if _is_table1(row, _table1(result)) else row["params"]["elastomer"]
            ax.plot(s["blind"]["force"], s["blind"]["position"], "D", ms=9, color="#ff7f0e", mec="black",
                    label=f"best design ({what}, {s['pressure_kpa']:.1f} kPa)")
    fig.colorbar(sc, ax=ax, label="worse regime at the worst corner")
    ax.set_xlabel("blind success, force-controlled objects")
    ax.set_ylabel("blind success, position-controlled objects")
    ax.set_xlim(-0.03, 1.03)
    ax.set_ylim(-0.03, 1.03)
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize=7.5, loc="lower left")
    _title_and_layout(fig, ax, f"Actuator designs for {_use_case_title(result)}: one blind ramp each\n"
                      f"({result['scored']} designs, {result['objects']} search objects; regimes by Table 1's "
                      "labels)", 9)
    return fig


def free_curve(params: Mapping[str, Any], base: EnvConfig, n: int = 121) -> tuple[np.ndarray, np.ndarray]:
    """The free actuator's pressure-curvature curve of a design: ``(p~, kappa~)`` from rest to ``p~ = 1.2``."""
    from pneunet_env.physics.solver import load_path

    cfg = design_config(params, base)
    ps = np.linspace(0.0, P_TILDE_MAX, n)
    lp = load_path(ps, 0.0, 0.02, cfg.actuator_params, cfg.solver)
    return ps, lp.curvature


TABLE1_COLOUR = "#d62728"
"""Table 1's colour in the design figures (red); its curves are dashed and drawn over the designs'."""


def plot_curves(result: dict[str, Any], base: EnvConfig, path: Path, plt) -> Path:
    """The best designs beside Table 1: (a) the free pressure-curvature curve, dimensionless as the paper's Fig. 3;
    (b) the same in kPa and 1/m, with the blind pressure and the objects' curvatures; (c) blind success against
    the blind pressure, with the window within 5 points of the best."""
    return _save(curves_figure(result, base, plt), path, plt)


def curves_figure(result: dict[str, Any], base: EnvConfig, plt):
    """:func:`plot_curves`' figure (not saved). Table 1 is red and dashed, drawn over the designs (``zorder``): a
    design identical to it (a small study's best may be Table 1's trial itself) shows through the dashes, and its
    legend entry says ``= Table 1``, instead of hiding Table 1's line under its own."""

    fig, axes = plt.subplots(1, 3, figsize=(15, 4.4))
    colours = iter(["#1f77b4", "#2ca02c", "#9467bd", "#ff7f0e", "#8c564b", "#17becf", "#7f7f7f", "#bcbd22"] * 4)
    table1 = _table1(result)
    for row in result["designs"]:
        is_t1 = row is table1
        col = TABLE1_COLOUR if is_t1 else next(colours)
        line = dict(color=col, lw=2.0, ls=(0, (5, 3)), zorder=3) if is_t1 else dict(color=col, lw=1.6, zorder=2)
        dot = dict(color=col, mec="black", ms=7, zorder=4 if is_t1 else 3)
        s = row["search"]
        mu = row["elastomer"]["shear_modulus_kpa"]
        w = row["params"]["width_mm"]
        ps, k = free_curve(row["params"], base)
        lab = ("Table 1" if is_t1 else row["label"]) + f" ({row['params']['elastomer']})"
        if _is_table1(row, table1):
            lab += " = Table 1"
        axes[0].plot(ps, k, label=lab, **line)
        axes[1].plot(ps * mu, k / (w * 1e-3), label=lab, **line)
        kb = np.interp(s["pressure_kpa"] / mu, ps, k) / (w * 1e-3)
        axes[1].plot(s["pressure_kpa"], kb, "o", **dot)
        axes[2].plot(s["pressures_kpa"], s["rate_vs_pressure"], label=lab, **line)
        axes[2].axvspan(*s["window_kpa"], color=col, alpha=0.12, lw=0)
        axes[2].plot(s["pressure_kpa"], s["blind"]["all"], "o", **dot)
    cfg = base
    radius = cfg.objects.table.radius_mm if cfg.objects.from_catalogue else None
    if radius is not None:
        lo, hi = 1e3 / float(np.max(radius[1])), 1e3 / float(np.min(radius[0]))
        axes[1].axhspan(lo, hi, color="#888888", alpha=0.15, lw=0,
                        label=f"objects' curvature (R {float(np.min(radius[0])):g}-{float(np.max(radius[1])):g} mm)")
    axes[0].set_xlabel("p~ = p / mu")
    axes[0].set_ylabel("kappa~ = w kappa (free actuator)")
    axes[0].set_title("(a) free actuator, dimensionless (the paper's Fig. 3)", fontsize=9)
    axes[1].set_xlabel("pressure (kPa)")
    axes[1].set_ylabel("curvature (1/m), free actuator")
    axes[1].set_xscale("log")
    axes[1].set_title("(b) in physical units; dot: the blind pressure", fontsize=9)
    axes[2].set_xlabel("blind ramp's pressure (kPa)")
    axes[2].set_ylabel("success, search objects")
    axes[2].set_xscale("log")
    axes[2].set_ylim(-0.03, 1.03)
    axes[2].set_title(f"(c) one blind pressure for all; band: within {WINDOW_POINTS:.0%} of the best", fontsize=9)
    for ax in axes:
        ax.grid(True, alpha=0.3)
        ax.legend(fontsize=7)
    fig.suptitle(_wrap(f"Why the design works ({_use_case_title(result)})", fig.get_figwidth(), 10), fontsize=10)
    fig.tight_layout()
    return fig


def plot_importance(result: dict[str, Any], path: Path, plt) -> Path:
    """Optuna's PED-ANOVA importance of each design parameter for the design score."""
    return _save(importance_figure(result, plt), path, plt)


def importance_figure(result: dict[str, Any], plt):
    """:func:`plot_importance`'s figure (not saved); its labels fit (the x label on two lines, the title wrapped)."""
    imp = result["importance"]
    fig, ax = plt.subplots(figsize=(6, 3.2))
    if imp:
        names = list(imp)[::-1]
        ax.barh(names, [imp[n] for n in names], color="#4c72b0")
        ax.set_xlabel("importance for the design score\n(PED-ANOVA: top designs against all)")
    else:
        ax.text(0.5, 0.5, _wrap(result.get("importance_note") or "too few designs for an importance estimate",
                                fig.get_figwidth(), 9), ha="center", va="center", fontsize=9)
        ax.set_axis_off()
    _title_and_layout(fig, ax, f"What matters for one blind schedule ({_use_case_title(result)}, "
                      f"{result['scored']} designs)", 9)
    return fig
