"""pneunet_env: a soft pneumatic (pneu-net) grasping environment with a quasi-static energy-minimising step."""

import pneunet_env._start  # noqa: F401  (first: a Ctrl-C while pneunet-grasp imports ends in its one line, 130)

# isort: split
import gymnasium as _gym

from pneunet_env.config import EnvConfig, load_config
from pneunet_env.envs.grasp import PneuNetGraspEnv
from pneunet_env.physics.params import ActuatorParams
from pneunet_env.physics.solver import Equilibrium, LoadPath, SolverOptions, load_path, solve_equilibrium

__version__ = "0.16.0"

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
    "PAPER_TASK",
    "__version__",
]

ENV_ID = "PneuNetGrasp-v1"
PAPER_ENV_ID = "PneuNetGrasp-Paper-v0"
RIGID_ENV_ID = "RigidGrasp-v1"
SLAB_HOLD = {"hold_rule": "slab"}
"""The ``v0`` envs' hold rule (until 0.14): a slab of depth ``H``, not the object's weight (``docs/env.md``)."""
PAPER_TASK = {"use_case": None, "class_weights": None, "damage_rule": "crush_fraction", "shape": "ring", **SLAB_HOLD}
"""The paper's task: its 250 mm ring (the objects section's ranges), the crush-fraction damage rule, and the slab
hold rule. Its ring (an annulus of thickness ``H`` as tall as the finger is wide: 154 g) cannot be lifted by two
90 mm fingers at any pressure up to ``p_max`` (the weight rule's grip ratio is at most 0.16 there: ``docs/env.md``),
so the paper's task, a study of the two regimes rather than of lifting, keeps the slab rule and its id."""

_GRASP = "pneunet_env.envs.grasp:PneuNetGraspEnv"
_GRASP_VECTOR = "pneunet_env.envs.grasp_vector:PneuNetGraspVectorEnv"
# env id -> (entry point, vector entry point, kwargs): every env the package registers, in one table
_RIGID = "pneunet_env.envs.rigid:RigidGraspEnv"
_ENVS = {
    ENV_ID: (_GRASP, _GRASP_VECTOR, {}),
    PAPER_ENV_ID: (_GRASP, _GRASP_VECTOR, PAPER_TASK),
    RIGID_ENV_ID: (_RIGID, None, {}),
    # the v0 envs, kept to reproduce results of 0.13 and earlier: the slab hold rule
    "PneuNetGrasp-v0": (_GRASP, _GRASP_VECTOR, SLAB_HOLD),
    "RigidGrasp-v0": (_RIGID, None, SLAB_HOLD),
}
for _id, (_entry, _vector, _kwargs) in _ENVS.items():
    if _id not in _gym.registry:
        _gym.register(id=_id, entry_point=_entry, vector_entry_point=_vector,
                      max_episode_steps=EnvConfig().episode_steps, kwargs=dict(_kwargs))
