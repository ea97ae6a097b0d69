"""pneunet_env: a soft pneumatic (pneu-net) grasping environment with a quasi-static energy-minimising step."""

from .params import ActuatorParams
from .solver import Equilibrium, LoadPath, SolverOptions, load_path, solve_equilibrium

__version__ = "0.1.0"

__all__ = ["ActuatorParams", "Equilibrium", "LoadPath", "SolverOptions", "load_path", "solve_equilibrium", "__version__"]
