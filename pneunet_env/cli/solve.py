"""``pneunet-grasp solve``: print the quasi-static loading (and unloading) path for one object."""

from __future__ import annotations

import argparse

import numpy as np

from pneunet_env import arguments as checks
from pneunet_env.physics.params import ActuatorParams
from pneunet_env.physics.solver import load_path


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--stiffness", type=checks.non_negative, default=1e-4,
                        help="object stiffness k~ = k_obj w/mu, >= 0 (0: free)")
    parser.add_argument("--object-curvature", type=checks.positive, default=0.02,
                        help="w kappa_obj, > 0 (default 0.02)")
    parser.add_argument("--p-max", type=checks.positive, default=1.2,
                        help="largest pressure p~ = p/mu, > 0 (default 1.2)")
    parser.add_argument("--points", type=checks.integer(2, 100_000), default=13,
                        help="pressures on the way up, >= 2 (default 13)")
    parser.add_argument("--unload", action="store_true", help="also unload back to 0")
    parser.add_argument("--gent-limit", type=checks.positive, default=20.0, help="Gent J, > 0 (default 20)")


def run(args: argparse.Namespace) -> int:
    if args.points < 2:  # (a caller that built args without the parser)
        raise ValueError(f"--points must be >= 2, got {args.points}")
    up = np.linspace(0.0, args.p_max, args.points)
    ps = np.concatenate([up, up[-2::-1]]) if args.unload else up
    path = load_path(ps, args.stiffness, args.object_curvature, ActuatorParams(gent_limit=args.gent_limit))
    print(f"{'p~':>8} {'kappa~':>10} {'e_s':>10} {'F~':>11} {'iters':>6} {'|grad|':>9}  snapped")
    for i, p in enumerate(path.pressure):
        print(
            f"{p:8.4f} {path.curvature[i]:10.6f} {path.side_strain[i]:10.6f} {path.contact_force[i]:11.4e}"
            f" {path.iterations[i]:6d} {path.gradient_norm[i]:9.1e}  {'yes' if path.snapped[i] else ''}"
        )
    return 0 if path.converged.all() else 1
