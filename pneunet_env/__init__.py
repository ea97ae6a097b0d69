"""pneunet_env: a soft pneumatic (pneu-net) grasping environment with a quasi-static energy-minimising step."""

import gymnasium as _gym

from .config import EnvConfig, load_config
from .env import PneuNetGraspEnv
from .params import ActuatorParams
from .solver import Equilibrium, LoadPath, SolverOptions, load_path, solve_equilibrium

__version__ = "0.1.0"

__all__ = [
    "ActuatorParams",
    "EnvConfig",
    "Equilibrium",
    "LoadPath",
    "PneuNetGraspEnv",
    "SolverOptions",
    "load_config",
    "load_path",
    "solve_equilibrium",
    "__version__",
]

ENV_ID = "PneuNetGrasp-v0"
if ENV_ID not in _gym.registry:
    _gym.register(
        id=ENV_ID,
        entry_point="pneunet_env.env:PneuNetGraspEnv",
        vector_entry_point="pneunet_env.vector_env:PneuNetGraspVectorEnv",
        max_episode_steps=EnvConfig().episode_steps,
    )
