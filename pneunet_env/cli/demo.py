"""``pneunet-grasp demo``: the main job. The best blind pressure ramp against real objects, with the oracle (which
knows each object) and a blind rigid gripper beside it: success by regime and by object class, policy by policy.

**The default task** (``--task default``): ``--objects`` objects drawn by ``PneuNetGrasp-v0`` itself (the kitchen
use case of the object catalogue: apple, kiwifruit, soft cheese, gelatin), the same seeds for every policy. Each
object's regime is read off the mechanics (:mod:`pneunet_env.physics.regimes`: force-controlled when it yields
more than half of the free actuator's curvature beyond its surface at 60 kPa, position-controlled otherwise).

**The paper's task** (``--task paper``, ``PneuNetGrasp-Paper-v0``): its 250 mm ring, by object stiffness:
The stiffness axis ``k~ = k_obj w/mu`` is cut into log-spaced bins (default: the four decades from 1e-5 to
1e-1). Each episode draws its ``k~`` log-uniformly inside its bin (from a generator seeded by ``--seed`` and
the bin), pins it with ``reset(options={"object_stiffness": k})``, and runs each policy on the same objects:

* ``best-ramp``: the linear pressure ramp found by ``python -m agents.search`` (``agents/best_ramp.json``): one
  blind schedule, tuned once over the object distribution, the same for every object;
* ``oracle``: knows the object and steps to the best constant pressure for it (:mod:`agents.oracle`): the
  feasibility ceiling, not a blind policy;
* ``rigid``: a rigid, position-controlled gripper closing to a fixed indentation, tuned like best-ramp
  (``RigidGrasp-v0``, :mod:`pneunet_env.envs.rigid`).

``--targets-kpa`` adds plain linear ramps (to each target over ``--ramp-steps`` steps). Everything else is the
environment's config: the paper's object size, water-like density, the damage and slip thresholds of
``docs/env.md``; ``--config PATH`` and ``--set KEY=VALUE`` (repeatable, VALUE is YAML, on top of ``--config`` and of
the paper task's settings) change it. A schedule shipped beside the config file, ``DIR/NAME.best_ramp.json``
(``DIR/NAME.best_rigid.json`` for ``rigid``) beside ``DIR/NAME.yaml``, replaces the package's, with or without
``--set`` (:func:`agents.policies.tuned_path`). ``--json`` saves every episode. ``pneunet-grasp evaluate`` makes
the plots.
"""

from __future__ import annotations

import argparse
import json
import math
import time
from pathlib import Path

import numpy as np

from pneunet_env.cli.progress import add_progress_argument, progress

DEFAULT_POLICIES = ("best-ramp", "oracle", "rigid")


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--task", choices=("default", "paper"), default="default",
                        help="default: objects drawn from the catalogue (by regime and class); paper: the paper's "
                             "250 mm ring, by stiffness bin")
    parser.add_argument("--objects", type=int, default=100, help="objects drawn (default task; default 100)")
    parser.add_argument("--policy", action="append", default=None, metavar="NAME",
                        help="policies to run (repeatable; default best-ramp, oracle, rigid; see agents.policies)")
    parser.add_argument("--targets-kpa", type=float, nargs="+", default=[],
                        help="also run plain linear ramps to these targets (kPa)")
    parser.add_argument("--ramp-steps", type=int, default=40, help="steps of those ramps from 0 to the target "
                        "(default 40)")
    parser.add_argument("--k-min", type=float, default=1e-5, help="smallest k~ (default 1e-5)")
    parser.add_argument("--k-max", type=float, default=1e-1, help="largest k~ (default 1e-1)")
    parser.add_argument("--bins", type=int, default=4, help="log-spaced stiffness bins (default 4: decades)")
    parser.add_argument("--episodes", type=int, default=10, help="episodes per bin and policy (default 10)")
    parser.add_argument("--seed", type=int, default=0, help="base seed (default 0)")
    parser.add_argument("--config", default=None, metavar="PATH",
                        help="environment config YAML (default: built-in defaults); best-ramp and rigid load "
                             "DIR/NAME.best_ramp.json and DIR/NAME.best_rigid.json where they lie beside DIR/NAME.yaml")
    parser.add_argument("--set", dest="overrides", action="append", default=[], metavar="KEY=VALUE",
                        help="override an environment config key, on top of --config (repeatable; VALUE is YAML), "
                             "e.g. --set max_pressure_kpa=40; a schedule beside --config still applies")
    parser.add_argument("--json", type=Path, default=None, help="also write the results as JSON to this path")
    add_progress_argument(parser)


def run(args: argparse.Namespace) -> int:
    from agents.evaluate import SOFT_MAX, STIFF_MIN, parse_overrides, run_episode
    from agents.oracle import feasible_stiffness
    from agents.policies import make_policy
    from pneunet_env import PAPER_TASK
    from pneunet_env.config import load_config
    from pneunet_env.objects import stiffness_per_modulus

    if args.bins < 1 or args.episodes < 1 or args.ramp_steps < 1 or args.objects < 1:
        raise SystemExit("--bins, --episodes, --objects and --ramp-steps must be >= 1")
    if not 0.0 < args.k_min < args.k_max:
        raise SystemExit(f"need 0 < --k-min < --k-max, got {args.k_min} and {args.k_max}")
    try:
        overrides = parse_overrides(args.overrides)
        cfg = load_config(args.config, **{**(PAPER_TASK if args.task == "paper" else {}), **overrides})
        specs = list(args.policy or DEFAULT_POLICIES)
        for t in args.targets_kpa:
            if not 0.0 <= t <= cfg.task.max_pressure_kpa:
                raise ValueError(f"--targets-kpa: {t} is outside [0, max_pressure_kpa = {cfg.task.max_pressure_kpa}]")
            specs.append(f"ramp:target_kpa={t:g},steps={args.ramp_steps}")
        entries = [make_policy(s, cfg, config_path=args.config) for s in specs]
    except ValueError as exc:
        raise SystemExit(f"pneunet-grasp demo: {exc}") from None
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
    print(f"PneuNetGrasp-v0 demo: blind grasps of objects from gels to elastomers; {cfg.task.squeeze_steps} squeeze + "
          f"{cfg.task.hold_steps} hold steps; {args.episodes} objects per bin, the same for every policy")
    print(f"object: H = {_fmt(oc.object_thickness_mm)} mm, kappa_obj = {_fmt(oc.object_curvature_per_m)} /m, "
          f"rho = {_fmt(oc.object_density_kg_m3)} kg/m^3, failure strain {_fmt(oc.object_failure_strain)}; "
          f"friction {cfg.task.friction_coefficient:g}, {cfg.task.grip_faces} faces")
    print(f"damage: traction > 3 eps_f mu_obj, or indentation > {cfg.task.crush_fraction:g} H;  "
          "slip (hold phase): traction < rho g H / (faces mu_f)")
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
        print(f"{short[e.name]:>16}: success {rate(rs, 'success'):4.0%} overall; soft (k~ < 1e-4) "
              f"{_pct(rate(soft, 'success'))}, stiff (k~ >= 1e-3) {_pct(rate(stiff, 'success'))}   [{e.label}]")
    if others:
        print("(other policies' columns: success, and the failures as d = damaged, s = slipped)")
    k_feas = feasible_stiffness(cfg)
    print(f"\nBelow k~ = {k_feas:.2g} (mu_obj = {k_feas / unit_mu:.3g} kPa) no state of any gripper both holds the "
          "object and spares it: the grip needs F = k_obj delta >= rho g H / (faces mu_f), which takes an "
          "indentation past the crush depth. See docs/results-paper.md.")
    print(f"\n{len(results)} episodes in {elapsed:.1f} s")
    if args.json is not None:
        args.json.parent.mkdir(parents=True, exist_ok=True)
        args.json.write_text(json.dumps({"args": {k: (str(v) if isinstance(v, Path) else v)
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
    from agents.batch import policy_episodes
    from agents.evaluate import HELD_OUT_SEED, object_regimes
    from pneunet_env.physics.regimes import REGIMES

    short = _short_names(e.name for e in entries)
    # held-out objects: not the seeds the blind schedules were searched on (agents.search uses seed * 1000003 + i)
    seeds = [HELD_OUT_SEED + args.seed * 1_000_003 + i for i in range(args.objects)]
    t0 = time.perf_counter()
    bar = progress(total=len(entries) * len(seeds), desc="demo", unit="episode", enabled=args.progress)
    results: dict[str, list[dict]] = {}
    for entry in entries:  # batched where the policy allows (agents.batch): the same episodes
        results[entry.name] = policy_episodes(entry, cfg, seeds, bar=bar)
    bar.close()
    first = results[entries[0].name]
    reg = object_regimes([r["stiffness"] for r in first], [r["curvature"] for r in first], cfg)
    classes = [r["object_class"] for r in first]
    elapsed = time.perf_counter() - t0
    print(f"PneuNetGrasp-v0 demo: {len(seeds)} objects drawn by the env (use case {cfg.objects.use_case!r}, damage "
          f"rule {cfg.task.damage_rule}), the same for every policy; {cfg.task.squeeze_steps} squeeze + "
          f"{cfg.task.hold_steps} hold steps")
    print("regime at 60 kPa, from the mechanics: force-controlled (the object yields) or position-controlled "
          "(it blocks the actuator)\n")
    cols = [(REGIMES[0], reg == 0), (REGIMES[1], reg == 1), ("all", np.ones(len(reg), bool))]
    print(f"{'policy':>18}" + "".join(f"  {name + f' ({int(m.sum())})':>26}" for name, m in cols))
    summary = {}
    for e in entries:
        ok = np.array([r["success"] for r in results[e.name]])
        cells = [_rate_cell(ok, m) for _, m in cols]
        summary[e.name] = {name: (float(ok[m].mean()) if m.any() else math.nan) for name, m in cols}
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
    print(f"\n{len(entries) * len(seeds)} episodes in {elapsed:.1f} s")
    if args.json is not None:
        args.json.parent.mkdir(parents=True, exist_ok=True)
        args.json.write_text(json.dumps({"task": "default", "use_case": cfg.objects.use_case, "summary": summary,
                                         "regime": reg.tolist(), "classes": classes,
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
