"""Policies, studies and commands above the Gym layer of ``pneunet_env``, in packages by concern and in layers (no
import goes up a layer; ``tests/test_architecture.py`` checks it, and ``docs/architecture.md`` draws it):

====================  ======================================================================================
``common``            what every package shares: shipped files, worker processes, regime labels, the task in
                      words, the commands' argument helpers. Imports nothing from ``agents``.
``policies``          scripted ramps, the oracle, the rigid jaw, SB3 models, and the registry of specs.
``figures``           the PNGs: take data, compute none (matplotlib imported only when drawing).
``evaluation``        episodes, the batched runner, objects and bins, policy evaluation, summaries, the map.
``search``            the best-ramp search and the threshold sensitivity study.
``training``          SB3 training (config, envs, export, seed studies) and skrl's PPO.
``design``            the actuator design study (Optuna).
``bench``             benchmarks of the study layers.
====================  ======================================================================================

Each command's CLI module sits beside its work (``evaluation.evaluate_cli``, ``search.cli``, ...) and is the top of
its package. Importing this package needs neither torch nor stable-baselines3.
"""

from agents.policies.scripted import LinearRamp, StepPolicy

__all__ = ["LinearRamp", "StepPolicy"]
