"""``pneunet-grasp bench design``: what a design study costs, measured against CartPole and the old search path.

* **One design evaluation** (:func:`agents.design.evaluate_design`: ``--objects`` objects x the 60 candidate blind
  pressures, then the same schedule on the 8 perturbed actuators), after compilation: the median of
  ``--repeats`` runs, with its env-steps per second beside ``gym.make_vec("CartPole-v1", num_envs=N)``'s
  (``CartPoleVectorEnv``) at the same N, stepped with random actions in the same run.
* **The best-ramp search on the default task**: ``pneunet-grasp search``'s batched path (:mod:`agents.evaluation.batch`)
  and the single-env episode loop it replaced, both timed here, both on the old eight durations (the same work) and
  each as its command runs it (the batched search on :data:`agents.search.ramp.DURATIONS`).

Figures, never a pass/fail: machines are noisy. ``--json PATH`` keeps them.
"""

from __future__ import annotations

import argparse
import os
import platform
import sys
import time
from typing import Any

import numpy as np

from pneunet_env import arguments as checks
from pneunet_env.files import atomic_write_json


def _cartpole_rate(n: int, steps: int = 100, seed: int = 0) -> float:
    import gymnasium as gym

    env = gym.make_vec("CartPole-v1", num_envs=n)
    env.reset(seed=seed)
    rng = np.random.default_rng(seed)
    acts = rng.integers(0, 2, size=(steps, n))
    env.step(acts[0])
    t0 = time.perf_counter()
    for a in acts:
        env.step(a)
    dt = time.perf_counter() - t0
    env.close()
    return n * steps / dt


def bench_evaluation(objects: int = 200, repeats: int = 3) -> dict[str, Any]:
    """One design evaluation's wall time (Table 1's actuator), after a warm-up that compiles."""
    from agents.design import N_ERRORS, TARGETS, evaluate_design, reference_regimes, table1_design
    from agents.evaluation.batch import episode_seeds

    seeds = episode_seeds(objects)
    ref = reference_regimes(seeds)
    evaluate_design(table1_design(), seeds, ref)  # compiles (the loops are cached on disk too)
    times = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        evaluate_design(table1_design(), seeds, ref)
        times.append(time.perf_counter() - t0)
    n = objects * len(TARGETS)
    env_steps = (n + N_ERRORS * objects) * 100
    med = float(np.median(times))
    cp = _cartpole_rate(n)
    return {"objects": objects, "pressures": len(TARGETS), "perturbed_actuators": N_ERRORS, "seconds": times,
            "median_s": med, "env_steps": env_steps, "env_steps_per_s": env_steps / med,
            "cartpole_vector_env_steps_per_s": cp, "ratio_to_cartpole": env_steps / med / cp}


def bench_search(objects: int = 200, old: bool = True) -> dict[str, Any]:
    """The default task's best-ramp search: batched and episodic, timed in this run."""
    from agents.search.ramp import ALL_DURATIONS, DURATIONS, search_ramp
    from pneunet_env.config import EnvConfig

    cfg = EnvConfig()
    out: dict[str, Any] = {"objects": objects}
    search_ramp(cfg, n_objects=8, durations=(20,), refine=0, progress=False)  # compile
    for label, durations, batched in (("batched, 8 durations", ALL_DURATIONS, True),
                                      ("batched, as the command runs", DURATIONS, True),
                                      ("episodic, 8 durations (before 0.6)", ALL_DURATIONS, False)):
        if not batched and not old:
            continue
        t0 = time.perf_counter()
        best, cands = search_ramp(cfg, n_objects=objects, durations=durations, progress=False, batched=batched)
        out[label] = {"seconds": time.perf_counter() - t0, "candidates": len(cands),
                      "best_target_kpa": best.target * cfg.task.max_pressure_kpa, "best_steps": best.n_steps,
                      "success_rate": best.success_rate}
    if old:
        ep = out["episodic, 8 durations (before 0.6)"]["seconds"]
        out["speedup_same_work"] = ep / out["batched, 8 durations"]["seconds"]
        out["speedup_command"] = ep / out["batched, as the command runs"]["seconds"]
    return out


def run_benchmark(objects: int = 200, repeats: int = 3, old: bool = True) -> dict[str, Any]:
    res = {"machine": {"python": platform.python_version(), "cpus": os.cpu_count(), "processor": platform.processor()
                       or platform.machine()},
           "evaluation": bench_evaluation(objects, repeats), "search": bench_search(objects, old)}
    try:
        import numba

        res["machine"]["numba_threading_layer"] = numba.threading_layer()
    except (ImportError, ValueError):  # no numba, or no parallel region run yet
        res["machine"]["numba_threading_layer"] = None
    return res


def format_table(res: dict[str, Any]) -> str:
    e, s = res["evaluation"], res["search"]
    lines = [f"one design evaluation ({e['objects']} objects x {e['pressures']} pressures + {e['perturbed_actuators']} "
             f"perturbed actuators): median {e['median_s']:.2f} s of {', '.join(f'{x:.2f}' for x in e['seconds'])}; "
             f"{e['env_steps_per_s'] / 1e6:.2f} M env-steps/s = {e['ratio_to_cartpole']:.3f}x CartPoleVectorEnv at "
             f"N = {e['objects'] * e['pressures']}",
             f"best-ramp search, default task, {s['objects']} objects:"]
    for k, v in s.items():
        if isinstance(v, dict):
            lines.append(f"  {k:<36} {v['seconds']:8.1f} s  ({v['candidates']} ramps; best {v['best_target_kpa']:.1f} "
                         f"kPa over {v['best_steps']} steps, {v['success_rate']:.1%})")
    if "speedup_same_work" in s:
        lines.append(f"  speed-up: {s['speedup_same_work']:.0f}x for the same work, {s['speedup_command']:.0f}x as the "
                     "commands run")
    lines.append(f"machine: {res['machine']}")
    return "\n".join(lines)


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--objects", type=checks.integer(1, 100_000), default=200,
                        help="objects per evaluation and search (default 200)")
    parser.add_argument("--repeats", type=checks.integer(1, 1000), default=3,
                        help="timed design evaluations (default 3)")
    parser.add_argument("--no-old", action="store_true", help="skip the episodic search (minutes)")
    parser.add_argument("--json", type=checks.output_file, default=None,
                        help="also write the figures as JSON (checked before the benchmark; replaced whole)")


def run(args: argparse.Namespace) -> int:
    if args.objects < 1 or args.repeats < 1:
        raise SystemExit("pneunet-grasp bench design: --objects and --repeats must be >= 1")
    if args.json is not None:
        checks.check_output_file(args.json, "--json")
    res = run_benchmark(args.objects, args.repeats, not args.no_old)
    print(format_table(res))
    if args.json is not None:
        atomic_write_json(args.json, res)
        print(f"wrote {args.json}")
    return 0


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="pneunet-grasp bench design", description=__doc__.split("\n\n")[0])
    add_arguments(parser)
    return run(parser.parse_args(argv))


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
