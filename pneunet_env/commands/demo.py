"""``pneunet-grasp demo``: the main job. A blind, scripted linear pressure ramp against objects from
gels to elastomers: success, damage and slip rates per object stiffness.

The stiffness axis ``k~ = k_obj w/mu`` is cut into log-spaced bins (default: 8 half-decades from 1e-5
to 1e-1). Each episode draws its ``k~`` log-uniformly inside its bin (from a generator seeded by
``--seed``, the bin and the episode), pins it with ``reset(options={"object_stiffness": k})``, and runs
:class:`agents.scripted.LinearRamp` from 0 to each target pressure (``--targets-kpa``) over
``--ramp-steps`` steps, then holds it. Everything else is the environment's config (the paper's
object size, water-like density; see ``configs/env/default.yaml``). For each target, a table gives, per
bin, the fraction of episodes held to the end (success), damaged, or dropped (slip), and the mean
peak traction in kPa. ``--json`` saves the numbers.
"""

from __future__ import annotations

import argparse
import json
import math
import time
from pathlib import Path

import numpy as np


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--targets-kpa", type=float, nargs="+", default=[20.0, 40.0, 60.0],
                        help="ramp targets in kPa, one table each (default 20 40 60)")
    parser.add_argument("--ramp-steps", type=int, default=40, help="steps from 0 to the target (default 40)")
    parser.add_argument("--k-min", type=float, default=1e-5, help="smallest k~ (default 1e-5)")
    parser.add_argument("--k-max", type=float, default=1e-1, help="largest k~ (default 1e-1)")
    parser.add_argument("--bins", type=int, default=8, help="log-spaced stiffness bins (default 8)")
    parser.add_argument("--episodes", type=int, default=5, help="episodes per bin and target (default 5)")
    parser.add_argument("--seed", type=int, default=0, help="base seed (default 0)")
    parser.add_argument("--config", default=None, help="environment config YAML (default: built-in defaults)")
    parser.add_argument("--json", type=Path, default=None, help="also write the results as JSON to this path")


def _progress(total: int):
    try:
        from tqdm import tqdm
    except ImportError:  # pragma: no cover - tqdm ships with the rl/plot extras
        return None
    return tqdm(total=total, desc="demo", unit="episode", leave=False)


def evaluate_ramp(env, policy, stiffness: float, seed: int) -> dict:
    """Run one episode with the object's ``k~`` pinned; return its outcome."""
    obs, info = env.reset(seed=seed, options={"object_stiffness": stiffness})
    peak, ret, steps = 0.0, 0.0, 0
    while True:
        obs, reward, terminated, truncated, info = env.step(policy(obs))
        ret += reward
        steps += 1
        peak = max(peak, info["contact_force_kpa"])
        if not info["solver_converged"]:
            raise RuntimeError(f"solver failed at k~={stiffness:g}, step {steps}: {info['solver_status']}")
        if terminated or truncated:
            break
    return {
        "stiffness": stiffness,
        "shear_modulus_kpa": info["object_shear_modulus_kpa"],
        "success": bool(info["is_success"]),
        "damaged": bool(info["damaged"]),
        "dropped": bool(info["dropped"]),
        "peak_traction_kpa": peak,
        "return": ret,
        "steps": steps,
    }


def run(args: argparse.Namespace) -> int:
    import gymnasium as gym

    import pneunet_env  # noqa: F401  (registers the environment)
    from agents.scripted import LinearRamp

    from ..objects import stiffness_per_modulus

    if args.bins < 1 or args.episodes < 1 or args.ramp_steps < 1:
        raise SystemExit("--bins, --episodes and --ramp-steps must be >= 1")
    if not 0.0 < args.k_min < args.k_max:
        raise SystemExit(f"need 0 < --k-min < --k-max, got {args.k_min} and {args.k_max}")
    env = gym.make("PneuNetGrasp-v0", config=args.config)
    cfg = env.unwrapped.config
    for t in args.targets_kpa:
        if not 0.0 <= t <= cfg.max_pressure_kpa:
            raise SystemExit(f"--targets-kpa: {t} is outside [0, max_pressure_kpa = {cfg.max_pressure_kpa}]")
    edges = np.logspace(math.log10(args.k_min), math.log10(args.k_max), args.bins + 1)
    unit_mu = stiffness_per_modulus(
        np.mean(cfg.object_thickness_mm), np.mean(cfg.object_curvature_per_m), cfg.scales
    )
    t0 = time.perf_counter()
    bar = _progress(len(args.targets_kpa) * args.bins * args.episodes)
    results = []
    for target in args.targets_kpa:
        policy = LinearRamp.from_kpa(target, args.ramp_steps, cfg)
        for b in range(args.bins):
            rng = np.random.default_rng([args.seed, b])
            ks = edges[b] * (edges[b + 1] / edges[b]) ** rng.random(args.episodes)
            for e, k in enumerate(ks):
                r = evaluate_ramp(env, policy, float(k), seed=args.seed * 100_003 + b * 1_000 + e)
                r.update(target_kpa=target, bin=b)
                results.append(r)
                if bar is not None:
                    bar.update()
    if bar is not None:
        bar.close()
    env.close()
    elapsed = time.perf_counter() - t0

    print(f"PneuNetGrasp-v0 demo: linear ramp 0 -> target over {args.ramp_steps} steps, then held; "
          f"{cfg.squeeze_steps} squeeze + {cfg.hold_steps} hold steps; {args.episodes} episodes per bin")
    print(f"object: H = {cfg.object_thickness_mm} mm, kappa_obj = {cfg.object_curvature_per_m} /m, "
          f"rho = {cfg.object_density_kg_m3} kg/m^3, failure strain {cfg.object_failure_strain}; "
          f"friction {cfg.friction_coefficient}, {cfg.grip_faces} faces")
    print("damage: traction > 3 eps_f mu_obj, or indentation > "
          f"{cfg.crush_fraction:g} H;  slip (hold phase): traction < rho g H / (faces mu_f)")
    for target in args.targets_kpa:
        rows = [r for r in results if r["target_kpa"] == target]
        print(f"\nramp to {target:g} kPa (p~ = {target / cfg.shear_modulus_kpa:.2f})")
        print(f"{'k~ bin':>19}  {'mu_obj (kPa)':>17}  {'success':>7}  {'damaged':>7}  {'slipped':>7}  "
              f"{'peak F (kPa)':>12}")
        for b in range(args.bins):
            rb = [r for r in rows if r["bin"] == b]
            lo, hi = edges[b], edges[b + 1]
            rate = lambda key: np.mean([r[key] for r in rb])  # noqa: B023
            peak = np.mean([r["peak_traction_kpa"] for r in rb])
            print(f"{lo:8.1e} - {hi:8.1e}  {lo / unit_mu:7.3g} - {hi / unit_mu:7.3g}  {rate('success'):7.0%}  "
                  f"{rate('damaged'):7.0%}  {rate('dropped'):7.0%}  {peak:12.3g}")
        print(f"{'all':>19}  {'':>17}  {np.mean([r['success'] for r in rows]):7.0%}  "
              f"{np.mean([r['damaged'] for r in rows]):7.0%}  {np.mean([r['dropped'] for r in rows]):7.0%}")
    print(f"\n{len(results)} episodes in {elapsed:.1f} s")
    if args.json is not None:
        args.json.parent.mkdir(parents=True, exist_ok=True)
        args.json.write_text(json.dumps({"args": {k: (str(v) if isinstance(v, Path) else v)
                                                  for k, v in vars(args).items() if k != "func"},
                                         "bin_edges": edges.tolist(), "episodes": results}, indent=1))
        print(f"wrote {args.json}")
    return 0
