"""``pneunet-grasp evaluate``: policies against object stiffness, with fixed seeds, on the active task.

``pneunet-grasp evaluate --policy NAME_OR_MODEL_PATH [--policy ...] --stiffness-grid N --episodes M --out DIR``

For every policy (:mod:`agents.policies`: ``ramp``, ``step``, ``best-ramp``, ``oracle``, ``rigid`` or a
stable-baselines3 ``.zip``) it runs episodes across ``N`` log-spaced values of the object stiffness ``k~``. How
depends on where the task's objects come from (:func:`task_description`):

* **objects from the catalogue** (the default task, ``PneuNetGrasp-v1``: its *kitchen* use case): ``N`` log-spaced
  ``k~`` bins span the use case's classes (:func:`catalogue_stiffness_range`; 1.6e-3 to 37 for the kitchen), and
  each bin holds ``M`` objects *drawn by the env* whose ``k~`` falls in it (:func:`draw_bins`: real apples, gels,
  ..., nothing pinned; seeds ``GRID_SEED + seed * 1_000_003 + j``). Pinning a ``k~`` onto a catalogue draw would
  give an apple the modulus of a gel but keep its failure stress: not an object of the task.
* **objects from ranges** (the paper's task, ``PneuNetGrasp-Paper-v0``: its 250 mm ring): ``N`` log-spaced ``k~``
  spanning the ranges (``k~`` of ``object_shear_modulus_kpa`` at the middle object size: 6.8e-6 to 0.10), ``M``
  episodes each with ``k~`` pinned (``reset(seed=..., options={"object_stiffness": k})``, seed
  ``seed * 1_000_003 + 1000 i + e``).

Seeds are fixed and shared by every policy, so the policies face the same objects. It then

* prints the task (its objects, its damage rule in words, its slip rule) and, per policy, success / damage / slip
  by stiffness decade and by regime, read off the mechanics (:mod:`pneunet_env.physics.regimes`:
  force-controlled or position-controlled); on the catalogue also by class; on the paper's ring also by the
  paper's own ``k~`` bins, soft (``k~ < 1e-4``) and stiff (``k~ >= 1e-3``), which mean nothing at hand scale;
* writes ``DIR/evaluation.json``: a list of rows ``{policy, object_stiffness, success_rate, damage_rate,
  slip_rate}`` (plus ``label``, ``episodes``, ``mean_return``, ``mean_peak_traction_kpa``,
  ``object_shear_modulus_kpa``, ``solver_failures``, ``by_regime``; drawn objects: ``k_range``, ``by_class``), and
  ``DIR/evaluation_summary.json`` (the task, per policy and regime, the config and seeds);
* writes ``DIR/success_vs_stiffness.png``: every policy on one chart, with the regimes (on the ring: the paper's
  ``k~`` bins, and the stiffness below which no state both holds and spares the object under the crush-fraction
  rule, :func:`agents.policies.oracle.feasible_stiffness`);
* with ``--objects N``, runs N objects drawn from the env's own distribution (held-out seeds) and reports each
  policy's overall success rate (the number the best-ramp search maximises, on objects it did not see);
* writes ``DIR/schedules.png``: the pressure (or jaw closure) each policy actually applied, step by step, for
  objects from soft to stiff (``--schedule-stiffness``; on the catalogue, the drawn object nearest each ``k~``).

``--config`` and ``--set KEY=VALUE`` change the environment (e.g. ``--set object_density_kg_m3=30`` for a
sensitivity run, ``--set use_case=null --set damage_rule=crush_fraction`` for the paper's task); the defaults are
the env's physically justified thresholds (``docs/env.md``). The PNGs need matplotlib (extra ``plot``), checked
before any episode runs; ``--no-plots`` does without.
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

import numpy as np

from agents.common.cli import add_catalogue, parse_overrides, usage_error
from agents.common.regimes import SOFT_MAX, STIFF_MIN
from agents.common.words import damage_rule_text, rate_parts, regime_text, slip_rule_text, task_description
from agents.evaluation.batch import HELD_OUT_SEED
from agents.evaluation.evaluate import evaluate_distribution, evaluate_policies, record_schedules
from agents.evaluation.objects import GRID_SEED, nearest_drawn, stiffness_bins, stiffness_grid
from agents.evaluation.summaries import decade_table, regime_summary
from agents.figures.evaluation import plot_schedules, plot_success
from agents.policies.registry import default_model
from pneunet_env import arguments as checks
from pneunet_env.config import load_config
from pneunet_env.files import atomic_write_text
from pneunet_env.progress import add_progress_argument

__all__ = ["add_arguments", "run"]


DEFAULT_POLICIES = ("best-ramp", "oracle", "rigid")


PAPER_SCHEDULE_STIFFNESS = (1e-5, 3e-4, 1.2e-3, 1e-2)
"""The ``k~`` of ``schedules.png`` on the paper's ring (on the catalogue: four across the grid)."""


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--policy", action="append", default=None, metavar="NAME_OR_MODEL_PATH",
                        help="a policy (repeatable): ramp, step, best-ramp, oracle, rigid (optionally "
                             "NAME:key=value,...), or an SB3 model .zip. Default: best-ramp, oracle, rigid, and the "
                             "task's PPO model if present (agents/models/ppo_kitchen.zip on the default task, "
                             "ppo_pneunet.zip on the paper's)")
    parser.add_argument("--stiffness-grid", type=checks.integer(1, 10_000, "the stiffness grid size"), default=25,
                        help="log-spaced k~ values (default 25): on the catalogue, bins of drawn objects")
    parser.add_argument("--episodes", type=checks.count, default=2,
                        help="episodes per policy and k~ (default 2): on the catalogue, objects per bin")
    parser.add_argument("--out", type=checks.output_dir, default="evaluation",
                        help="output folder, checked before any episode; files in it are replaced (default "
                             "./evaluation)")
    parser.add_argument("--seed", type=checks.seed, default=0, help="base seed (default 0)")
    parser.add_argument("--k-min", type=checks.positive, default=None,
                        help="smallest k~ (default: the task's objects' range)")
    parser.add_argument("--k-max", type=checks.positive, default=None,
                        help="largest k~ (default: the task's objects' range)")
    parser.add_argument("--schedule-stiffness", type=checks.positive, nargs="+", default=None,
                        help="k~ of the episodes drawn in schedules.png (default: on the paper's ring 1e-5 3e-4 "
                             "1.2e-3 1e-2; on the catalogue four across the grid, each the drawn object nearest it)")
    parser.add_argument("--config", default=None, help="environment config YAML (default: the env's defaults)")
    parser.add_argument("--set", dest="overrides", action="append", default=[], metavar="KEY=VALUE",
                        help="override an environment config key (repeatable; VALUE is YAML); the paper's task: "
                             "--set use_case=null --set damage_rule=crush_fraction")
    add_catalogue(parser)
    parser.add_argument("--objects", type=checks.integer(0, checks.MAX_COUNT), default=0,
                        help="also run N objects drawn from the env's own distribution (held-out seeds) and report "
                             "each policy's overall success rate (default 0: none)")
    parser.add_argument("--no-plots", action="store_true", help="skip the PNGs (and matplotlib)")
    add_progress_argument(parser, "--quiet")


PROG = "pneunet-grasp evaluate"


def run(args: argparse.Namespace) -> int:
    from agents.policies.registry import make_policy, tuned_schedules_text, warn_untuned
    from pneunet_env.extras import require_extra

    if args.objects < 0:
        usage_error(PROG, f"--objects must be >= 0, got {args.objects}")
    if args.episodes < 1:
        usage_error(PROG, f"--episodes must be >= 1, got {args.episodes}")
    if args.stiffness_grid * args.episodes > checks.MAX_COUNT:  # every policy's objects are listed up front
        usage_error(PROG, f"--stiffness-grid x --episodes is {args.stiffness_grid * args.episodes}; at most "
                          f"{checks.MAX_COUNT}")
    if args.no_plots and args.schedule_stiffness is not None:
        usage_error(PROG, "--schedule-stiffness sets what schedules.png draws; it does nothing with --no-plots")
    if not args.no_plots:  # before any episode: not a traceback once the work is done
        require_extra("evaluate", "matplotlib", "plot", "the plots", skip="--no-plots")
    try:
        config = load_config(args.config, **parse_overrides(args.overrides, args.catalogue))
        model = default_model(config)
        if args.policy is None and model is not None:  # the default policies run the task's PPO model too
            require_extra("evaluate", "stable_baselines3", "rl", f"the default policies' PPO model ({model.name})",
                          skip=" ".join(f"--policy {p}" for p in DEFAULT_POLICIES))
        specs = args.policy or list(DEFAULT_POLICIES) + ([str(model)] if model is not None else [])
        entries = [make_policy(s, config, config_path=args.config) for s in specs]
        warn_untuned(PROG, entries, args.config, args.overrides, args.catalogue)
        drawn = config.objects.from_catalogue
        if drawn:
            grid, edges = stiffness_bins(config, args.stiffness_grid, args.k_min, args.k_max)
        else:
            grid, edges = stiffness_grid(config, args.stiffness_grid, args.k_min, args.k_max), None
        if args.schedule_stiffness is not None and min(args.schedule_stiffness) <= 0:
            raise ValueError(f"--schedule-stiffness must be > 0, got {args.schedule_stiffness}")
    except ValueError as exc:
        raise SystemExit(f"{PROG}: {exc}") from None
    names = [e.name for e in entries]
    if len(set(names)) != len(names):
        raise SystemExit(f"{PROG}: a policy is given twice: {names}")
    t0 = time.perf_counter()
    rows = evaluate_policies(entries, config, grid, args.episodes, args.seed, progress=args.progress, edges=edges)
    traces = []
    if not args.no_plots:
        if args.schedule_stiffness is not None:
            sched = list(args.schedule_stiffness)
        elif drawn:  # four across the grid, at 1/8, 3/8, 5/8 and 7/8 of its log range
            sched = list(np.exp(np.log(edges[0]) + np.log(edges[-1] / edges[0]) * np.array([1, 3, 5, 7]) / 8))
        else:
            sched = list(PAPER_SCHEDULE_STIFFNESS)
        seeds = nearest_drawn(config, sched, args.seed) if drawn else None
        traces = record_schedules(entries, config, sched, args.seed, seeds=seeds)
    dist = evaluate_distribution(entries, config, args.objects, args.seed, args.progress) if args.objects else None
    elapsed = time.perf_counter() - t0

    n_ep = sum(r["episodes"] for r in rows)
    print(f"{PROG}: {task_description(config)}")
    print(f"  {damage_rule_text(config)}")
    print(f"  {slip_rule_text(config)}")
    print(f"  {regime_text(config)}")
    if tuned := tuned_schedules_text(entries):
        print(f"  {tuned}")
    bins = sorted({r["object_stiffness"] for r in rows})
    if drawn:
        print(f"{len(entries)} policies x {len(bins)} k~ bins from {edges[0]:.2g} to {edges[-1]:.2g} x up to "
              f"{args.episodes} objects drawn by the env into each (nothing pinned; {n_ep // max(1, len(entries))} "
              f"objects, the same for every policy), seed {args.seed}")
        if len(bins) < len(grid):
            print(f"  ({len(grid) - len(bins)} of the {len(grid)} bins drew no object and are left out)")
    else:
        print(f"{len(entries)} policies x {len(grid)} stiffnesses (k~ {grid[0]:.2g} to {grid[-1]:.2g}, pinned) x "
              f"{args.episodes} episodes, seed {args.seed}")
    if drawn:
        print("  (every bin counts alike in 'all', not as the task draws its objects: --objects N gives the task's "
              "own rate)")
    print()
    print(decade_table(rows))
    if dist is not None:
        print(f"on {args.objects} objects from the env's own distribution (held-out seeds):")
        for name, d in dist.items():
            parts = rate_parts([("force-controlled", d["success_rate_force"], d["objects_force"]),
                                ("position-controlled", d["success_rate_position"], d["objects_position"])])
            if "objects_soft" in d:
                parts += "; the paper's k~ bins: " + rate_parts([("soft", d["success_rate_soft"], d["objects_soft"]),
                                                                 ("stiff", d["success_rate_stiff"],
                                                                  d["objects_stiff"])])
            print(f"  {name:>24}: success {d['success_rate']:6.1%} ({parts}), damaged {d['damage_rate']:.1%}, "
                  f"slipped {d['slip_rate']:.1%}")
        print()
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    atomic_write_text(out / "evaluation.json", json.dumps(rows, indent=1, allow_nan=False) + "\n")
    from agents.policies.oracle import feasible_stiffness

    paper_bins = not drawn
    summary = {
        "task": {"objects": task_description(config), "damage_rule": config.task.damage_rule,
                 "damage": damage_rule_text(config), "slip": slip_rule_text(config), "regimes": regime_text(config),
                 "grid": ("objects drawn by the env into log-spaced k~ bins (nothing pinned)" if drawn
                          else "k~ pinned on a log-spaced grid")},
        "policies": {e.name: {"label": e.label, "env_id": e.env_id, "blind": e.blind,
                              **({"tuned_on": e.tuned_on} if e.tuned_on else {})} for e in entries},
        "regimes": regime_summary(rows, paper_bins),
        "regime_bounds": ({"soft": f"k~ < {SOFT_MAX:g}", "stiff": f"k~ >= {STIFF_MIN:g}",
                           "note": "the paper's k~ bins, on its ring"} if paper_bins else None),
        "feasible_stiffness": (feasible_stiffness(config) if paper_bins and config.task.damage_rule == "crush_fraction"
                               else None),
        "distribution": dist,
        "distribution_seeds": f"{HELD_OUT_SEED} + seed * 1000003 + i" if dist else None,
        "stiffness_grid": [float(k) for k in grid],
        "stiffness_bin_edges": None if edges is None else [float(k) for k in edges],
        "episodes": args.episodes,
        "seed": args.seed,
        "episode_seeds": (f"the first objects of {GRID_SEED} + seed * 1000003 + j to fall in each bin" if drawn
                          else "seed * 1000003 + 1000 * grid_index + episode"),
        "config": config.to_dict(),
        "elapsed_s": elapsed,
    }
    atomic_write_text(out / "evaluation_summary.json", json.dumps(summary, indent=1, allow_nan=False) + "\n")
    print(f"wrote {out / 'evaluation.json'}, {out / 'evaluation_summary.json'}")
    if not args.no_plots:
        plot_success(rows, out / "success_vs_stiffness.png", config,
                     feasible_stiffness=summary["feasible_stiffness"])
        plot_schedules(traces, out / "schedules.png", config)
        print(f"wrote {out / 'success_vs_stiffness.png'}, {out / 'schedules.png'}")
    n = n_ep + len(traces) + (args.objects * len(entries))
    print(f"{n} episodes in {elapsed:.1f} s")
    return 0
