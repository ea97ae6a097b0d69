"""``pneunet-grasp demo``: the main job. The best blind pressure ramp against real objects, with the oracle (which
knows each object) and a blind rigid gripper beside it: success by regime and by object class, policy by policy.

**The default task** (``--task default``): ``--objects`` objects drawn by ``PneuNetGrasp-v1`` itself (the kitchen
use case of the object catalogue: apple, kiwifruit, soft cheese, gelatin), the same seeds for every policy. Each
object's regime is read off the mechanics (:mod:`pneunet_env.physics.regimes`: force-controlled when it yields
more than half of the free actuator's curvature beyond its surface at 60 kPa, position-controlled otherwise).

**The paper's task** (``--task paper``, ``PneuNetGrasp-Paper-v0``): its 250 mm ring, by object stiffness:
The stiffness axis ``k~ = k_obj w/mu`` is cut into log-spaced bins (``--k-min``, ``--k-max``, ``--bins``; default:
the four decades from 1e-5 to 1e-1). Each of ``--episodes`` episodes per bin draws its ``k~`` log-uniformly inside
its bin (from a generator seeded by ``--seed`` and the bin), pins it with ``reset(options={"object_stiffness":
k})``, and runs each policy on the same objects. These four options belong to the paper's task, and ``--objects``
to the default task: given to the other task, each is an error (exit status 2) that names the ``--task`` it needs.

* ``best-ramp``: the linear pressure ramp found by ``python -m agents.search`` (``agents/best_ramp.json``): one
  blind schedule, tuned once over the object distribution, the same for every object (the output names the file
  and what it was tuned on; a config whose objects no shipped schedule was tuned for gets a warning on stderr
  with the ``pneunet-grasp search`` command that tunes one for them);
* ``oracle``: knows the object and steps to the best constant pressure for it (:mod:`agents.policies.oracle`): the
  feasibility ceiling, not a blind policy;
* ``rigid``: a rigid, position-controlled gripper closing to a fixed indentation, tuned like best-ramp
  (``RigidGrasp-v1``, :mod:`pneunet_env.envs.rigid`).

``--targets-kpa`` adds plain linear ramps (to each target over ``--ramp-steps`` steps). Everything else is the
environment's config: the task's objects, the damage and slip thresholds of ``docs/env.md`` (the header prints
them: the damage rule is the config's ``damage_rule``, whichever the task); ``--config PATH`` and ``--set KEY=VALUE``
(repeatable, VALUE is YAML, on top of ``--config`` and of the paper task's settings) change it. A schedule shipped
beside the config file, ``DIR/NAME.best_ramp.json`` (``DIR/NAME.best_rigid.json`` for ``rigid``) beside
``DIR/NAME.yaml``, replaces the package's, with or without ``--set`` (:func:`agents.policies.registry.tuned_path`).
``--json`` saves every episode. ``pneunet-grasp evaluate`` makes the plots.
"""

from __future__ import annotations

import argparse
import json
import math
import time
from pathlib import Path

import numpy as np

from pneunet_env import arguments as checks
from pneunet_env.files import atomic_write_text
from pneunet_env.progress import add_progress_argument, progress

DEFAULT_POLICIES = ("best-ramp", "oracle", "rigid")
DEFAULT_OBJECTS = 100
"""Objects drawn on the default task."""
PAPER_OPTIONS = (("--k-min", 1e-5, "smallest k~"), ("--k-max", 1e-1, "largest k~"),
                 ("--bins", 4, "log-spaced stiffness bins (4: decades)"),
                 ("--episodes", 10, "episodes per bin and policy"))
"""The paper task's options: ``(flag, default, help)``; ``None`` until given, so that giving one is seen."""
PROG = "pneunet-grasp demo"


def _check_task_options(args: argparse.Namespace) -> None:
    """Fill the task's defaults; an option of the other task, given, is an argument error naming ``--task``."""
    from agents.common.cli import usage_error

    paper = [flag for flag, _, _ in PAPER_OPTIONS if getattr(args, _dest(flag)) is not None]
    if args.task == "default" and paper:
        usage_error(PROG, f"{', '.join(paper)} {'applies' if len(paper) == 1 else 'apply'} to the paper's task "
                          "(its stiffness bins) only: add --task paper, or leave "
                          f"{'it' if len(paper) == 1 else 'them'} out (the default task draws --objects from the "
                          "catalogue)")
    if args.task == "paper" and args.objects is not None:
        usage_error(PROG, "--objects applies to the default task only: the paper's task runs --episodes objects in "
                          "each of --bins stiffness bins (drop --task paper to draw --objects from the catalogue)")
    for flag, default, _ in PAPER_OPTIONS:
        if getattr(args, _dest(flag)) is None:
            setattr(args, _dest(flag), default)
    if args.objects is None:
        args.objects = DEFAULT_OBJECTS


def _dest(flag: str) -> str:
    return flag.lstrip("-").replace("-", "_")


def add_arguments(parser: argparse.ArgumentParser) -> None:
    from agents.common.cli import add_catalogue

    parser.add_argument("--task", choices=("default", "paper"), default="default",
                        help="default: objects drawn from the catalogue (by regime and class); paper: the paper's "
                             "250 mm ring, by stiffness bin")
    parser.add_argument("--objects", type=checks.count, default=None,
                        help=f"objects drawn (the default task only; default {DEFAULT_OBJECTS})")
    parser.add_argument("--policy", action="append", default=None, metavar="NAME",
                        help="policies to run (repeatable; default best-ramp, oracle, rigid; see agents.policies)")
    parser.add_argument("--targets-kpa", type=checks.non_negative, nargs="+", default=[],
                        help="also run plain linear ramps to these targets (kPa)")
    parser.add_argument("--ramp-steps", type=checks.integer(1, 100_000), default=40,
                        help="steps of those ramps from 0 to the target (default 40)")
    for flag, default, help_ in PAPER_OPTIONS:
        kind = checks.integer(1, 10_000 if flag == "--bins" else checks.MAX_COUNT) if isinstance(default, int) \
            else checks.positive
        parser.add_argument(flag, type=kind, default=None, help=f"{help_} (--task paper only; default "
                            f"{default:g})")
    parser.add_argument("--seed", type=checks.seed, default=0, help="base seed (default 0)")
    parser.add_argument("--config", default=None, metavar="PATH",
                        help="environment config YAML (default: built-in defaults); best-ramp and rigid load "
                             "DIR/NAME.best_ramp.json and DIR/NAME.best_rigid.json where they lie beside DIR/NAME.yaml")
    parser.add_argument("--set", dest="overrides", action="append", default=[], metavar="KEY=VALUE",
                        help="override an environment config key, on top of --config (repeatable; VALUE is YAML), "
                             "e.g. --set max_pressure_kpa=40; a schedule beside --config still applies")
    add_catalogue(parser)
    parser.add_argument("--json", type=checks.output_file, default=None,
                        help="also write the results as JSON to this file (checked before the first episode; an "
                             "existing file is replaced whole)")
    add_progress_argument(parser)


def run(args: argparse.Namespace) -> int:
    from agents.common.cli import parse_overrides, usage_error
    from agents.common.regimes import SOFT_MAX, STIFF_MIN
    from agents.common.words import damage_rule_text, rate_parts, slip_rule_text, task_description
    from agents.evaluation.episodes import run_episode
    from agents.policies.oracle import feasible_stiffness
    from agents.policies.registry import make_policy, tuned_schedules_text, warn_untuned
    from pneunet_env import PAPER_TASK
    from pneunet_env.config import load_config
    from pneunet_env.objects import stiffness_per_modulus

    _check_task_options(args)
    if args.bins < 1 or args.episodes < 1 or args.ramp_steps < 1 or args.objects < 1:
        usage_error(PROG, "--bins, --episodes, --objects and --ramp-steps must be >= 1")
    if not 0.0 < args.k_min < args.k_max:
        usage_error(PROG, f"need 0 < --k-min < --k-max, got {args.k_min:g} and {args.k_max:g}")
    if args.bins * args.episodes > checks.MAX_COUNT:  # their draws are made up front
        usage_error(PROG, f"--bins x --episodes is {args.bins * args.episodes} objects; at most {checks.MAX_COUNT}")
    try:
        overrides = parse_overrides(args.overrides, args.catalogue)
        cfg = load_config(args.config, **{**(PAPER_TASK if args.task == "paper" else {}), **overrides})
        specs = list(args.policy or DEFAULT_POLICIES)
        for t in args.targets_kpa:
            if not 0.0 <= t <= cfg.task.max_pressure_kpa:
                raise ValueError(f"--targets-kpa: {t} is outside [0, max_pressure_kpa = {cfg.task.max_pressure_kpa}]")
            specs.append(f"ramp:target_kpa={t:g},steps={args.ramp_steps}")
        entries = [make_policy(s, cfg, config_path=args.config) for s in specs]
    except ValueError as exc:
        raise SystemExit(f"pneunet-grasp demo: {exc}") from None
    # the paper's task is its settings on top of --config: a search for these objects needs them too
    paper_sets = [f"{k}={'null' if v is None else v}" for k, v in PAPER_TASK.items()] if args.task == "paper" else []
    warn_untuned(PROG, entries, args.config, paper_sets + list(args.overrides), args.catalogue)
    if args.task == "default":
        return _run_distribution(args, cfg, entries)
    edges = np.logspace(math.log10(args.k_min), math.log10(args.k_max), args.bins + 1)
    draws = [edges[b] * (edges[b + 1] / edges[b]) ** np.random.default_rng([args.seed, b]).random(args.episodes)
             for b in range(args.bins)]
    oc = cfg.objects
    unit_mu = float(stiffness_per_modulus(np.mean(oc.object_thickness_mm), np.mean(oc.object_curvature_per_m),
                                          cfg.scales))
    t0 = time.perf_counter()
    bar = progress(total=len(entries) * args.bins * args.episodes, desc="demo", unit="episode", enabled=args.progress)
    results = []
    for entry in entries:
        env = entry.make_env(cfg)
        for b, ks in enumerate(draws):
            for e, k in enumerate(ks):
                r = run_episode(env, entry.policy, seed=args.seed * 100_003 + b * 1_000 + e,
                                options={"object_stiffness": float(k)})
                if r["solver_failed"]:
                    raise RuntimeError(f"{entry.name}: the solver failed at k~={k:g}")
                r.update(policy=entry.name, bin=b)
                results.append(r)
                bar.update()
        env.close()
    bar.close()
    elapsed = time.perf_counter() - t0

    main = entries[0]
    print(f"PneuNetGrasp-Paper-v0 demo: blind grasps of {task_description(cfg)}; {cfg.task.squeeze_steps} squeeze + "
          f"{cfg.task.hold_steps} hold steps; {args.episodes} objects per k~ bin, the same for every policy")
    print(f"{damage_rule_text(cfg)}; {slip_rule_text(cfg)}")
    others = entries[1:]
    short = _short_names(e.name for e in entries)
    print(f"\n{main.name}: {main.label}")
    head = f"{'k~ bin':>19}  {'mu_obj (kPa)':>17}  {'success':>7}  {'damaged':>7}  {'slipped':>7}  {'peak F (kPa)':>12}"
    head += "".join(f"  {short[e.name][:16]:>16}" for e in others)
    print(head)
    rate = lambda rs, key: float(np.mean([r[key] for r in rs])) if rs else math.nan  # noqa: E731
    for b in range(args.bins):
        rb = [r for r in results if r["bin"] == b and r["policy"] == main.name]
        lo, hi = edges[b], edges[b + 1]
        line = (f"{lo:8.1e} - {hi:8.1e}  {lo / unit_mu:7.3g} - {hi / unit_mu:7.3g}  {rate(rb, 'success'):7.0%}  "
                f"{rate(rb, 'damaged'):7.0%}  {rate(rb, 'dropped'):7.0%}  {rate(rb, 'peak_traction_kpa'):12.3g}")
        for e in others:
            ro = [r for r in results if r["bin"] == b and r["policy"] == e.name]
            line += f"  {_outcome(ro):>16}"
        print(line)
    print()
    for e in entries:
        rs = [r for r in results if r["policy"] == e.name]
        soft = [r for r in rs if r["stiffness"] < SOFT_MAX]
        stiff = [r for r in rs if r["stiffness"] >= STIFF_MIN]
        bins = rate_parts([("soft (k~ < 1e-4)", rate(soft, "success"), len(soft)),
                           ("stiff (k~ >= 1e-3)", rate(stiff, "success"), len(stiff))])
        print(f"{short[e.name]:>16}: success {rate(rs, 'success'):4.0%} overall; the paper's k~ bins: {bins}   "
              f"[{e.label}]")
    if others:
        print("(other policies' columns: success, and the failures as d = damaged, s = slipped)")
    if tuned := tuned_schedules_text(entries):
        print(tuned)
    if cfg.task.damage_rule == "crush_fraction" and not cfg.objects.from_catalogue:  # the bound assumes this rule
        k_feas = feasible_stiffness(cfg)
        print(f"\nBelow k~ = {k_feas:.2g} (mu_obj = {k_feas / unit_mu:.3g} kPa) no state of any gripper both holds "
              "the object and spares it: the grip needs F = k_obj delta >= its grip traction, which takes an "
              "indentation past the crush depth. See docs/results-paper.md.")
    print(f"\n{len(results)} episodes in {elapsed:.1f} s")
    if args.json is not None:
        atomic_write_text(args.json, json.dumps({"args": {k: (str(v) if isinstance(v, Path) else v)
                                                          for k, v in vars(args).items() if k != "func"},
                                                 "policies": {e.name: e.label for e in entries},
                                                 "bin_edges": edges.tolist(), "episodes": results}, indent=1))
        print(f"wrote {args.json}")
    return 0


def _short_names(names) -> dict[str, str]:
    """Each policy's name in a table: a model's file stem (``agents/models/ppo_kitchen.zip`` -> ``ppo_kitchen``),
    or its whole name where another has the same stem (``runs/a/best_model.zip``, ``runs/b/...``)."""
    names = list(names)
    stem = {n: Path(n.split(".zip:")[0]).stem if ".zip" in n else n for n in names}
    taken = [stem[n] for n in names]
    return {n: n if taken.count(stem[n]) > 1 else stem[n] for n in names}


def _fmt(r) -> str:
    return f"{r[0]:g}" if r[0] == r[1] else f"{r[0]:g}-{r[1]:g}"


def _pct(x: float) -> str:
    return "   -" if math.isnan(x) else f"{x:4.0%}"


def _outcome(rs) -> str:
    """``"40% (d60 s0)"``: success, then the damaged and slipped percentages."""
    if not rs:
        return "-"
    s = np.mean([r["success"] for r in rs])
    d = np.mean([r["damaged"] for r in rs])
    sl = np.mean([r["dropped"] for r in rs])
    return f"{s:.0%} (d{d * 100:.0f} s{sl * 100:.0f})"


def _run_distribution(args: argparse.Namespace, cfg, entries) -> int:
    """The default task: objects drawn by the env; success by regime and by class, policy by policy."""
    from agents.common.regimes import object_regimes
    from agents.common.words import damage_rule_text, regime_text, slip_rule_text, task_description
    from agents.evaluation.batch import HELD_OUT_SEED, policy_episodes
    from agents.policies.registry import tuned_schedules_text
    from pneunet_env.physics.regimes import REGIMES

    short = _short_names(e.name for e in entries)
    # held-out objects: not the seeds the blind schedules were searched on (agents.search uses seed * 1000003 + i)
    seeds = [HELD_OUT_SEED + args.seed * 1_000_003 + i for i in range(args.objects)]
    t0 = time.perf_counter()
    bar = progress(total=len(entries) * len(seeds), desc="demo", unit="episode", enabled=args.progress)
    results: dict[str, list[dict]] = {}
    for entry in entries:  # batched where the policy allows (agents.evaluation.batch): the same episodes
        results[entry.name] = policy_episodes(entry, cfg, seeds, bar=bar)
    bar.close()
    first = results[entries[0].name]
    reg = object_regimes([r["stiffness"] for r in first], [r["curvature"] for r in first], cfg)
    classes = [r["object_class"] for r in first]
    elapsed = time.perf_counter() - t0
    print(f"PneuNetGrasp-v1 demo: {len(seeds)} objects drawn by the env from {task_description(cfg)}, the same "
          f"for every policy; {cfg.task.squeeze_steps} squeeze + {cfg.task.hold_steps} hold steps")
    print(f"{damage_rule_text(cfg)}; {slip_rule_text(cfg)}")
    print(f"{regime_text(cfg)}\n")
    cols = [(REGIMES[code], reg == code) for code in range(len(REGIMES)) if (reg == code).any()]
    cols.append(("all", np.ones(len(reg), bool)))
    print(f"{'policy':>18}" + "".join(f"  {name + f' ({int(m.sum())})':>26}" for name, m in cols))
    summary = {}
    for e in entries:
        ok = np.array([r["success"] for r in results[e.name]])
        cells = [_rate_cell(ok, m) for _, m in cols]
        summary[e.name] = {name: float(ok[m].mean()) for name, m in cols}  # only groups with objects
        print(f"{short[e.name]:>18}" + "".join(f"  {c:>26}" for c in cells))
    print("\nby object class (share of draws, share force-controlled), success:")
    names = list(dict.fromkeys(classes))
    widths = [max(9, len(short[e.name])) for e in entries]
    heads = "".join(f"  {short[e.name]:>{w}}" for e, w in zip(entries, widths, strict=True))
    print(f"{'class':>14}  {'draws':>5}  {'force':>5}" + heads)
    cls = np.array(classes)
    for n in names:
        m = cls == n
        line = f"{n:>14}  {m.mean():5.0%}  {np.mean(reg[m] == 0):5.0%}"
        for e, w in zip(entries, widths, strict=True):
            ok = np.array([r["success"] for r in results[e.name]])
            line += f"  {_rate(float(ok[m].mean())):>{w}}"
        print(line)
    print("\n" + "; ".join(f"{short[e.name]}: {e.label}" for e in entries))
    if tuned := tuned_schedules_text(entries):
        print(tuned)
    print(f"\n{len(entries) * len(seeds)} episodes in {elapsed:.1f} s")
    if args.json is not None:
        atomic_write_text(args.json, json.dumps({"task": "default", "use_case": cfg.objects.use_case,
                                                 "summary": summary, "regime": reg.tolist(), "classes": classes,
                                                 "episodes": {k: v for k, v in results.items()}}, indent=1))
        print(f"wrote {args.json}")
    return 0


def _rate_cell(ok: np.ndarray, mask: np.ndarray) -> str:
    return "-" if not mask.any() else _rate(float(ok[mask].mean()))


def _rate(x: float) -> str:
    """A success rate in whole per cent, with one decimal where whole per cent would hide a miss or a hit
    (``0.995`` is ``99.5%``, not ``100%``)."""
    whole = f"{x:.0%}"
    if whole == "100%" and x < 1.0:
        return f"{x:.1%}" if f"{x:.1%}" != "100.0%" else ">99.9%"
    if whole == "0%" and x > 0.0:
        return f"{x:.1%}" if f"{x:.1%}" != "0.0%" else "<0.1%"
    return whole
