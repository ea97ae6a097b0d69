"""``pneunet-grasp evaluate``: policies against a log-spaced grid of object stiffnesses, with fixed seeds.

``pneunet-grasp evaluate --policy NAME_OR_MODEL_PATH [--policy ...] --stiffness-grid N --episodes M --out DIR``

For every policy (:mod:`agents.policies`: ``ramp``, ``step``, ``best-ramp``, ``oracle``, ``rigid`` or a
stable-baselines3 ``.zip``) and every ``k~`` of an ``N``-point log-spaced grid spanning the config's object
range (``k~`` of ``object_shear_modulus_kpa`` at the middle object size: 6.8e-6 to 0.10 by default), it runs
``M`` episodes with ``k~`` pinned (``reset(seed=..., options={"object_stiffness": k})``). Seeds are fixed and
shared by every policy (episode ``e`` at grid point ``i`` uses seed ``seed * 1_000_003 + 1000 i + e``), so the
policies face the same objects. It then

* prints success / damage / slip by stiffness decade, and for the paper's two regimes: soft (``k~ < 1e-4``)
  and stiff (``k~ >= 1e-3``);
* writes ``DIR/evaluation.json``: a list of rows ``{policy, object_stiffness, success_rate, damage_rate,
  slip_rate}`` (plus ``label``, ``episodes``, ``mean_return``, ``mean_peak_traction_kpa``,
  ``object_shear_modulus_kpa``, ``solver_failures``), and ``DIR/evaluation_summary.json`` (per policy and
  regime, with the config and seeds);
* writes ``DIR/success_vs_stiffness.png``: every policy on one chart, the soft and stiff regimes shaded, and
  the stiffness below which no state both holds and spares the object (:func:`agents.oracle.feasible_stiffness`);
* with ``--objects N``, runs N objects drawn from the env's own distribution (held-out seeds) and reports each
  policy's overall success rate (the number the best-ramp search maximises, on objects it did not see);
* writes ``DIR/schedules.png``: the pressure (or jaw closure) each policy actually applied, step by step, for
  objects from soft to stiff (``--schedule-stiffness``), with each episode's outcome.

``--config`` and ``--set KEY=VALUE`` change the environment (e.g. ``--set object_density_kg_m3=30`` for a
sensitivity run); the defaults are the env's physically justified thresholds (``docs/env.md``).
"""

from __future__ import annotations

import argparse
import json
import math
import time
from pathlib import Path
from typing import Any

import numpy as np

from pneunet_env.cli.progress import add_progress_argument
from pneunet_env.cli.progress import progress as progress_bar
from pneunet_env.config import EnvConfig, load_config

__all__ = ["run_episode", "stiffness_grid", "evaluate_policies", "evaluate_distribution", "decade_table",
           "regime_summary", "object_regimes", "regime_rates", "use_case_regimes",
           "plot_success", "plot_schedules", "parse_overrides", "SOFT_MAX", "STIFF_MIN",
           "add_arguments", "run"]

SOFT_MAX = 1e-4
"""The paper's soft regime: ``k~ < 1e-4`` (a 1.5 kPa gel at the paper's object size)."""
STIFF_MIN = 1e-3
"""The paper's stiff regime: ``k~ >= 1e-3`` (a 15 kPa elastomer)."""

DEFAULT_POLICIES = ("best-ramp", "oracle", "rigid")
DEFAULT_MODEL = Path(__file__).resolve().parent / "models" / "ppo_kitchen.zip"
"""PPO trained on the default task (pressure only); ``models/ppo_pneunet.zip`` was trained on the paper's task."""


# ---------------------------------------------------------------------------------------------
# Episodes
# ---------------------------------------------------------------------------------------------


def run_episode(env, policy, seed: int | None = None, options: dict[str, Any] | None = None,
                record: bool = False) -> dict[str, Any]:
    """One episode of ``policy`` on ``env``; its outcome.

    ``policy.begin_episode(info)`` (if present) is called with ``reset``'s info. With ``record``, the
    command applied at each step (``pressure_kpa``, or ``jaw_closure_mm`` for the rigid gripper) is kept,
    from the reset state (index 0) to the last step.

    Returns:
        ``{stiffness, shear_modulus_kpa, success, damaged, dropped, return, steps, peak_traction_kpa,
        solver_failed, commands}`` (``commands`` only with ``record``).
    """
    obs, info = env.reset(seed=seed, options=options)
    reset_info = info  # the object's constants are in the reset info
    begin = getattr(policy, "begin_episode", None)
    if begin is not None:
        begin(info)
    key = "jaw_closure_mm" if "jaw_closure_mm" in info else "pressure_kpa"
    commands = [float(info[key])] if record else None
    ret, steps, peak, failed = 0.0, 0, 0.0, False
    while True:
        obs, reward, terminated, truncated, info = env.step(policy(obs))
        ret += reward
        steps += 1
        peak = max(peak, float(info["contact_force_kpa"]))
        failed = failed or bool(info.get("solver_failed", False))
        if record:
            commands.append(float(info[key]))
        if terminated or truncated:
            break
    out = {
        "stiffness": float(reset_info["object_stiffness"]),
        "shear_modulus_kpa": float(reset_info["object_shear_modulus_kpa"]),
        "curvature": float(reset_info["object_curvature"]),
        "object_class": str(reset_info.get("object_class", "ranges")),
        "success": bool(info.get("is_success", False)),
        "damaged": bool(info["damaged"]),
        "dropped": bool(info["dropped"]),
        "return": float(ret),
        "steps": steps,
        "peak_traction_kpa": peak,
        "solver_failed": failed,
    }
    if record:
        out["commands"] = commands
    return out


def stiffness_grid(config: EnvConfig, n: int, k_min: float | None = None, k_max: float | None = None) -> np.ndarray:
    """``n`` log-spaced ``k~`` spanning the config's object range (``object_shear_modulus_kpa`` at the middle size)."""
    if int(n) != n or n < 1:
        raise ValueError(f"stiffness grid size must be an integer >= 1, got {n!r}")
    from pneunet_env.objects import stiffness_per_modulus

    oc = config.objects
    unit = float(stiffness_per_modulus(np.mean(oc.object_thickness_mm), np.mean(oc.object_curvature_per_m),
                                       config.scales))
    lo = unit * config.objects.object_shear_modulus_kpa[0] if k_min is None else float(k_min)
    hi = unit * config.objects.object_shear_modulus_kpa[1] if k_max is None else float(k_max)
    if not 0.0 < lo <= hi:
        raise ValueError(f"need 0 < k_min <= k_max, got {lo!r} and {hi!r}")
    if n == 1:
        return np.array([math.sqrt(lo * hi)])
    return np.logspace(math.log10(lo), math.log10(hi), int(n))


def episode_seed(seed: int, grid_index: int, episode: int) -> int:
    """The seed of episode ``episode`` at grid point ``grid_index`` (shared by every policy)."""
    return seed * 1_000_003 + 1000 * grid_index + episode


def evaluate_policies(entries, config: EnvConfig, grid, episodes: int, seed: int = 0,
                      progress: bool | None = None) -> list[dict[str, Any]]:
    """Rows ``{policy, label, object_stiffness, success_rate, damage_rate, slip_rate, ...}``: one per policy, ``k~``.

    ``progress``: a bar on stderr; ``None`` (default): when stderr is a terminal.
    """
    if int(episodes) != episodes or episodes < 1:
        raise ValueError(f"episodes must be an integer >= 1, got {episodes!r}")
    bar = progress_bar(total=len(entries) * len(grid) * episodes, desc="evaluate", unit="episode", enabled=progress)
    from agents.batch import policy_episodes

    rows = []
    for entry in entries:
        # every grid point and episode in one vector env run where the policy allows it (the same episodes)
        seeds = [episode_seed(seed, i, e) for i in range(len(grid)) for e in range(episodes)]
        ks = np.repeat(np.asarray(grid, dtype=float), episodes)
        done = policy_episodes(entry, config, seeds, {"object_stiffness": ks}, bar)
        for i, k in enumerate(grid):
            res = done[i * episodes:(i + 1) * episodes]
            rows.append({
                "policy": entry.name,
                "label": entry.label,
                "object_stiffness": float(k),
                "success_rate": float(np.mean([r["success"] for r in res])),
                "damage_rate": float(np.mean([r["damaged"] for r in res])),
                "slip_rate": float(np.mean([r["dropped"] for r in res])),
                "episodes": episodes,
                "mean_return": float(np.mean([r["return"] for r in res])),
                "mean_peak_traction_kpa": float(np.mean([r["peak_traction_kpa"] for r in res])),
                "object_shear_modulus_kpa": float(np.mean([r["shear_modulus_kpa"] for r in res])),
                "solver_failures": int(sum(r["solver_failed"] for r in res)),
            })
    bar.close()
    return rows


HELD_OUT_SEED = 1_000_000_000
"""Offset of the ``--objects`` episodes' seeds: disjoint from the search's (``seed * 1_000_003 + i``)."""


def evaluate_distribution(entries, config: EnvConfig, n_objects: int, seed: int = 0,
                          progress: bool | None = None) -> dict[str, dict[str, float]]:
    """Each policy on ``n_objects`` objects drawn from the env's own distribution (held-out seeds
    ``HELD_OUT_SEED + seed * 1_000_003 + i``): ``{policy: {success_rate, damage_rate, slip_rate, objects, ...}}``."""
    seeds = [HELD_OUT_SEED + seed * 1_000_003 + i for i in range(n_objects)]
    bar = progress_bar(total=len(entries) * n_objects, desc="distribution", unit="episode", enabled=progress)
    from agents.batch import policy_episodes

    out = {}
    for entry in entries:
        res = policy_episodes(entry, config, seeds, bar=bar)  # batched where the policy allows: the same episodes
        k = np.array([r["stiffness"] for r in res])
        ok = np.array([r["success"] for r in res])
        out[entry.name] = {
            "objects": n_objects,
            "success_rate": float(ok.mean()),
            "damage_rate": float(np.mean([r["damaged"] for r in res])),
            "slip_rate": float(np.mean([r["dropped"] for r in res])),
            **regime_rates(ok, k, [r["curvature"] for r in res], config),
            # the paper ring's k~ bins (every hand-scale object is above them)
            "success_rate_soft": float(ok[k < SOFT_MAX].mean()) if (k < SOFT_MAX).any() else math.nan,
            "success_rate_stiff": float(ok[k >= STIFF_MIN].mean()) if (k >= STIFF_MIN).any() else math.nan,
            "objects_soft": int((k < SOFT_MAX).sum()),
            "objects_stiff": int((k >= STIFF_MIN).sum()),
        }
    bar.close()
    return out


def record_schedules(entries, config: EnvConfig, stiffnesses, seed: int = 0) -> list[dict[str, Any]]:
    """One recorded episode per policy and stiffness: ``{policy, label, command, object_stiffness, ...outcome}``."""
    out = []
    for entry in entries:
        env = entry.make_env(config)
        for j, k in enumerate(stiffnesses):
            r = run_episode(env, entry.policy, episode_seed(seed, 10_000 + j, 0), {"object_stiffness": float(k)},
                            record=True)
            r.update(policy=entry.name, label=entry.label, command=entry.command)
            out.append(r)
        env.close()
    return out


# ---------------------------------------------------------------------------------------------
# Tables
# ---------------------------------------------------------------------------------------------


def _rates(rows) -> dict[str, float]:
    w = np.array([r["episodes"] for r in rows], dtype=float)
    if w.sum() == 0:
        return {"episodes": 0, "success_rate": math.nan, "damage_rate": math.nan, "slip_rate": math.nan}
    avg = lambda key: float(np.dot(w, [r[key] for r in rows]) / w.sum())  # noqa: E731
    return {"episodes": int(w.sum()), "success_rate": avg("success_rate"), "damage_rate": avg("damage_rate"),
            "slip_rate": avg("slip_rate")}


def regime_summary(rows) -> dict[str, dict[str, dict[str, float]]]:
    """``{policy: {"soft": rates, "intermediate": rates, "stiff": rates, "all": rates}}`` (episode-weighted)."""
    out: dict[str, dict[str, dict[str, float]]] = {}
    for name in dict.fromkeys(r["policy"] for r in rows):
        rs = [r for r in rows if r["policy"] == name]
        out[name] = {
            "soft": _rates([r for r in rs if r["object_stiffness"] < SOFT_MAX]),
            "intermediate": _rates([r for r in rs if SOFT_MAX <= r["object_stiffness"] < STIFF_MIN]),
            "stiff": _rates([r for r in rs if r["object_stiffness"] >= STIFF_MIN]),
            "all": _rates(rs),
        }
    return out


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


def decade_table(rows) -> str:
    """Success / damage / slip by stiffness decade, then by regime, one block per policy."""
    lines = []
    for name in dict.fromkeys(r["policy"] for r in rows):
        rs = [r for r in rows if r["policy"] == name]
        lines.append(f"{name}: {rs[0]['label']}")
        lines.append(f"  {'k~':>19}  {'episodes':>8}  {'success':>7}  {'damaged':>7}  {'slipped':>7}")
        decades = sorted({math.floor(math.log10(r["object_stiffness"]) + 1e-12) for r in rs})
        for d in decades:
            sub = [r for r in rs if math.floor(math.log10(r["object_stiffness"]) + 1e-12) == d]
            lines.append(_line(f"1e{d:+03d} - 1e{d + 1:+03d}", _rates(sub)))
        regimes = regime_summary(rs)[name]
        lines.append(_line("soft (< 1e-4)", regimes["soft"]))
        lines.append(_line("stiff (>= 1e-3)", regimes["stiff"]))
        lines.append(_line("all", regimes["all"]))
        lines.append("")
    return "\n".join(lines)


def _line(label: str, r: dict[str, float]) -> str:
    if r["episodes"] == 0:
        return f"  {label:>19}  {0:>8}  {'-':>7}  {'-':>7}  {'-':>7}"
    return (f"  {label:>19}  {r['episodes']:>8}  {r['success_rate']:7.0%}  {r['damage_rate']:7.0%}  "
            f"{r['slip_rate']:7.0%}")


# ---------------------------------------------------------------------------------------------
# Plots (matplotlib imported here only)
# ---------------------------------------------------------------------------------------------

# Policies often score the same: the widest lines are drawn first (underneath), so that each stays visible.
_STYLES = {
    "rigid": dict(color="#d62728", lw=7.5, alpha=0.35, zorder=2),
    "best-ramp": dict(color="#1f5fbf", lw=2.4, marker="o", ms=3.5, zorder=5),
    "oracle": dict(color="black", lw=1.3, ls="--", zorder=6),
    "ramp": dict(color="#7f7f7f", lw=1.4, ls=":", marker=".", zorder=4),
    "step": dict(color="#a0a0a0", lw=1.4, ls="-.", marker=".", zorder=4),
}
_MODEL_STYLE = dict(color="#2ca02c", lw=4.5, alpha=0.75, zorder=3)


def _style(name: str) -> dict:
    base = name.split(":")[0]
    if name.endswith(".zip"):
        return dict(_MODEL_STYLE)
    return dict(_STYLES.get(base, dict(lw=1.5, marker=".")))


def _matplotlib():
    import matplotlib

    matplotlib.use("Agg", force=False)
    import matplotlib.pyplot as plt

    return plt


def plot_success(rows, path: str | Path, config: EnvConfig, title: str | None = None) -> Path:
    """Success (top) and damage / slip (bottom) vs ``k~`` for every policy; soft and stiff regimes shaded."""
    from agents.oracle import feasible_stiffness
    from pneunet_env.objects import stiffness_per_modulus

    plt = _matplotlib()
    ks = np.array([r["object_stiffness"] for r in rows])
    lo, hi = ks.min() / 1.3, ks.max() * 1.3
    fig, (ax, ax_d, ax_s) = plt.subplots(3, 1, figsize=(8.6, 7.4), sharex=True,
                                         gridspec_kw=dict(height_ratios=[2.4, 1, 1]))
    k_feas = feasible_stiffness(config)
    for a in (ax, ax_d, ax_s):
        a.axvspan(lo, SOFT_MAX, color="#4c9be8", alpha=0.12, lw=0)
        a.axvspan(STIFF_MIN, hi, color="#f0a030", alpha=0.14, lw=0)
        a.axvline(k_feas, color="#555555", ls=(0, (1, 2)), lw=1.4)
        a.set_xscale("log")
        a.set_xlim(lo, hi)
        a.grid(True, which="major", alpha=0.3)
    ax.text(k_feas / 1.12, 0.55, f"below k~ = {k_feas:.2g} no state\nholds the object and spares it:\n"
            "F = k_obj delta >= F_grip would\nneed delta > the crush depth", fontsize=7.5, color="#444444",
            va="center", ha="right")
    ax.text(math.sqrt(lo * SOFT_MAX), 1.06, "soft (k~ < 1e-4)", ha="center", fontsize=9, color="#1f5fbf")
    ax.text(math.sqrt(STIFF_MIN * hi), 1.06, "stiff (k~ >= 1e-3)", ha="center", fontsize=9, color="#b06000")
    for name in dict.fromkeys(r["policy"] for r in rows):
        rs = sorted((r for r in rows if r["policy"] == name), key=lambda r: r["object_stiffness"])
        k = [r["object_stiffness"] for r in rs]
        st = _style(name)
        ax.plot(k, [r["success_rate"] for r in rs], label=rs[0]["label"], **st)
        ax_d.plot(k, [r["damage_rate"] for r in rs], **st)
        ax_s.plot(k, [r["slip_rate"] for r in rs], **st)
    ax.set_ylim(-0.04, 1.13)
    ax.set_ylabel("success rate\n(held to the end, intact)")
    for a, what in ((ax_d, "damaged"), (ax_s, "slipped\n(dropped)")):
        a.set_ylim(-0.07, 1.07)
        a.set_ylabel(what)
    ax_s.set_xlabel("object stiffness k~ = k_obj w / mu")
    ax.legend(loc="lower center", bbox_to_anchor=(0.5, 1.1), ncol=2, fontsize=8, frameon=False)
    oc = config.objects
    unit = float(stiffness_per_modulus(np.mean(oc.object_thickness_mm), np.mean(oc.object_curvature_per_m),
                                       config.scales))
    top = ax.secondary_xaxis("top", functions=(lambda k: k / unit, lambda m: m * unit))
    top.set_xlabel("object shear modulus mu_obj (kPa)", fontsize=8)
    top.tick_params(labelsize=8)
    if title is None:
        oc, tc = config.objects, config.task
        title = (f"rho = {_fmt_range(oc.object_density_kg_m3)} kg/m^3, mu_f = {tc.friction_coefficient:g}, "
                 f"crushed at delta > {tc.crush_fraction:g} H, H = {_fmt_range(oc.object_thickness_mm)} mm")
    fig.suptitle(title, fontsize=9, y=0.995)
    fig.tight_layout()
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=130)
    plt.close(fig)
    return path


def _fmt_range(r) -> str:
    return f"{r[0]:g}" if r[0] == r[1] else f"{r[0]:g}-{r[1]:g}"


def plot_schedules(traces, path: str | Path, config: EnvConfig) -> Path:
    """One panel per policy: the command applied at each step, one line per object stiffness, outcome marked."""
    plt = _matplotlib()
    names = list(dict.fromkeys(t["policy"] for t in traces))
    ncol = min(3, len(names))
    nrow = math.ceil(len(names) / ncol)
    fig, axes = plt.subplots(nrow, ncol, figsize=(4.1 * ncol, 3.1 * nrow), squeeze=False)
    ks = sorted({t["object_stiffness"] for t in traces if "object_stiffness" in t} | {t["stiffness"] for t in traces})
    cmap = plt.get_cmap("viridis")
    colours = {k: cmap(0.9 * i / max(1, len(ks) - 1)) for i, k in enumerate(ks)}
    n_steps = config.episode_steps
    for ax, name in zip(axes.flat, names, strict=False):
        ts = [t for t in traces if t["policy"] == name]
        ax.axvspan(config.task.squeeze_steps + 0.5, n_steps, color="#dddddd", alpha=0.6, lw=0)
        # longest episode first and widest, so that the schedules, which often coincide, stay visible
        order = sorted(ts, key=lambda t: -len(t["commands"]))
        widths = np.linspace(5.0, 1.4, max(2, len(order)))
        for lw, t in zip(widths, order, strict=False):
            c = t["commands"]
            ax.plot(range(len(c)), c, color=colours[t["stiffness"]], lw=lw, alpha=0.85, solid_capstyle="butt",
                    label=f"k~ = {t['stiffness']:.2g}")
            if t["success"]:
                m, mc = "o", "#2ca02c"
            elif t["damaged"]:
                m, mc = "X", "#d62728"
            else:
                m, mc = "v", "#ff7f0e"
            ax.plot(len(c) - 1, c[-1], m, color=mc, ms=8, mec="black", mew=0.6, zorder=5)
        ax.set_title(ts[0]["label"], fontsize=8.5)
        ax.set_xlim(0, n_steps + 2)
        ax.set_xlabel("step")
        if ts[0]["command"] == "jaw":
            ax.set_ylabel("jaw closure (mm)")
        else:
            ax.set_ylabel("pressure (kPa)")
            ax.set_ylim(-1, config.task.max_pressure_kpa * 1.05)
        ax.text(0.5 * (config.task.squeeze_steps + n_steps), ax.get_ylim()[1] * 0.03, "hold", ha="center", fontsize=7.5,
                color="#555555")
        ax.grid(True, alpha=0.3)
    for ax in list(axes.flat)[len(names):]:
        ax.axis("off")
    handles, labels = axes.flat[0].get_legend_handles_labels()
    handles += [plt.Line2D([], [], ls="", marker=m, color=c, mec="black", mew=0.6, ms=7)
                for m, c in (("o", "#2ca02c"), ("X", "#d62728"), ("v", "#ff7f0e"))]
    labels += ["held to the end", "damaged", "slipped"]
    fig.legend(handles, labels, loc="lower center", ncol=len(labels), fontsize=8, frameon=False)
    fig.suptitle("the schedules applied (squeeze, then hold: shaded); marker = outcome", fontsize=9)
    fig.tight_layout(rect=(0, 0.07, 1, 0.97))
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=120)
    plt.close(fig)
    return path


# ---------------------------------------------------------------------------------------------
# Command line
# ---------------------------------------------------------------------------------------------


def parse_overrides(items) -> dict[str, Any]:
    """``["KEY=VALUE", ...]`` -> a dict, each VALUE read as YAML (``30``, ``[30, 1000]``, ``true``)."""
    import yaml

    out: dict[str, Any] = {}
    for item in items or []:
        key, eq, value = item.partition("=")
        if not eq or not key.strip():
            raise ValueError(f"--set needs KEY=VALUE, got {item!r}")
        try:
            out[key.strip()] = yaml.safe_load(value)
        except yaml.YAMLError as exc:
            msg = " ".join(str(exc).split())
            raise ValueError(f"--set {item!r}: the value is not valid YAML ({msg})") from None
    return out


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--policy", action="append", default=None, metavar="NAME_OR_MODEL_PATH",
                        help="a policy (repeatable): ramp, step, best-ramp, oracle, rigid (optionally "
                             "NAME:key=value,...), or an SB3 model .zip. Default: best-ramp, oracle, rigid, and "
                             "agents/models/ppo_kitchen.zip (PPO on the default task) if present")
    parser.add_argument("--stiffness-grid", type=int, default=25, help="log-spaced k~ values (default 25)")
    parser.add_argument("--episodes", type=int, default=2, help="episodes per policy and k~ (default 2)")
    parser.add_argument("--out", type=Path, default=Path("evaluation"), help="output directory (default ./evaluation)")
    parser.add_argument("--seed", type=int, default=0, help="base seed (default 0)")
    parser.add_argument("--k-min", type=float, default=None, help="smallest k~ (default: the config's range)")
    parser.add_argument("--k-max", type=float, default=None, help="largest k~ (default: the config's range)")
    parser.add_argument("--schedule-stiffness", type=float, nargs="+", default=[1e-5, 3e-4, 1.2e-3, 1e-2],
                        help="k~ of the episodes drawn in schedules.png (default 1e-5 3e-4 1.2e-3 1e-2)")
    parser.add_argument("--config", default=None, help="environment config YAML (default: the env's defaults)")
    parser.add_argument("--set", dest="overrides", action="append", default=[], metavar="KEY=VALUE",
                        help="override an environment config key (repeatable; VALUE is YAML)")
    parser.add_argument("--objects", type=int, default=0,
                        help="also run N objects drawn from the env's own distribution (held-out seeds) and report "
                             "each policy's overall success rate (default 0: none)")
    parser.add_argument("--no-plots", action="store_true", help="skip the PNGs")
    add_progress_argument(parser, "--quiet")


def run(args: argparse.Namespace) -> int:
    from agents.policies import make_policy

    try:
        config = load_config(args.config, **parse_overrides(args.overrides))
        specs = args.policy or list(DEFAULT_POLICIES) + ([str(DEFAULT_MODEL)] if DEFAULT_MODEL.is_file() else [])
        entries = [make_policy(s, config, config_path=args.config) for s in specs]
        grid = stiffness_grid(config, args.stiffness_grid, args.k_min, args.k_max)
        if args.episodes < 1:
            raise ValueError(f"--episodes must be >= 1, got {args.episodes}")
    except ValueError as exc:
        raise SystemExit(f"pneunet-grasp evaluate: {exc}") from None
    names = [e.name for e in entries]
    if len(set(names)) != len(names):
        raise SystemExit(f"pneunet-grasp evaluate: a policy is given twice: {names}")
    t0 = time.perf_counter()
    rows = evaluate_policies(entries, config, grid, args.episodes, args.seed, progress=args.progress)
    traces = record_schedules(entries, config, args.schedule_stiffness, args.seed)
    if args.objects < 0:
        raise SystemExit(f"pneunet-grasp evaluate: --objects must be >= 0, got {args.objects}")
    dist = evaluate_distribution(entries, config, args.objects, args.seed, args.progress) if args.objects else None
    elapsed = time.perf_counter() - t0

    print(f"pneunet-grasp evaluate: {len(entries)} policies x {len(grid)} stiffnesses "
          f"(k~ {grid[0]:.2g} to {grid[-1]:.2g}) x {args.episodes} episodes, seed {args.seed}")
    print(f"thresholds: slip when F < rho g H / ({config.task.grip_faces} mu_f), rho = "
          f"{_fmt_range(config.objects.object_density_kg_m3)} kg/m^3, mu_f = {config.task.friction_coefficient:g}; "
          "damage when "
          f"delta > {config.task.crush_fraction:g} H or F > 3 eps_f mu_obj\n")
    print(decade_table(rows))
    if dist is not None:
        print(f"on {args.objects} objects from the env's own distribution (held-out seeds):")
        for name, d in dist.items():
            print(f"  {name:>24}: success {d['success_rate']:6.1%}  (force-controlled {d['success_rate_force']:.0%} "
                  f"of {d['objects_force']}, position-controlled {d['success_rate_position']:.0%} of "
                  f"{d['objects_position']}; the paper's k~ bins: soft {d['success_rate_soft']:.0%} of "
                  f"{d['objects_soft']}, stiff {d['success_rate_stiff']:.0%} of {d['objects_stiff']}), damaged "
                  f"{d['damage_rate']:.1%}, slipped {d['slip_rate']:.1%}")
        print()
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    (out / "evaluation.json").write_text(json.dumps(rows, indent=1) + "\n")
    from agents.oracle import feasible_stiffness

    summary = {
        "policies": {e.name: {"label": e.label, "env_id": e.env_id, "blind": e.blind} for e in entries},
        "regimes": regime_summary(rows),
        "regime_bounds": {"soft": f"k~ < {SOFT_MAX:g}", "stiff": f"k~ >= {STIFF_MIN:g}"},
        "feasible_stiffness": feasible_stiffness(config),
        "distribution": dist,
        "distribution_seeds": f"{HELD_OUT_SEED} + seed * 1000003 + i" if dist else None,
        "stiffness_grid": [float(k) for k in grid],
        "episodes": args.episodes,
        "seed": args.seed,
        "episode_seeds": "seed * 1000003 + 1000 * grid_index + episode",
        "config": config.to_dict(),
        "elapsed_s": elapsed,
    }
    (out / "evaluation_summary.json").write_text(json.dumps(summary, indent=1) + "\n")
    print(f"wrote {out / 'evaluation.json'}, {out / 'evaluation_summary.json'}")
    if not args.no_plots:
        plot_success(rows, out / "success_vs_stiffness.png", config)
        plot_schedules(traces, out / "schedules.png", config)
        print(f"wrote {out / 'success_vs_stiffness.png'}, {out / 'schedules.png'}")
    n = len(rows) * args.episodes + len(traces) + (args.objects * len(entries))
    print(f"{n} episodes in {elapsed:.1f} s")
    return 0
