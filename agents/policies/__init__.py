"""Policies for the envs: a name (or a model file) -> a policy and the env it drives.

* :mod:`~agents.policies.scripted`: blind pressure schedules (``LinearRamp``, ``StepPolicy``) and their JSON files;
* :mod:`~agents.policies.oracle`: the oracle, which knows the object (the feasibility ceiling);
* :mod:`~agents.policies.registry`: the policy registry and specs (``ramp``, ``step``, ``best-ramp``, ``oracle``,
  ``rigid``: the rigid jaw's ramp, ``PATH.zip``), the tuned schedules' files and the shipped PPO models;
* :mod:`~agents.policies.sb3`: stable-baselines3 models as policies, with their normalisation statistics as numbers.

A new policy goes here: its class in a module of its own (or beside its kin), and its spec in ``registry.REGISTRY``.

May import: :mod:`agents.common` (and ``pneunet_env``). Importing it needs neither torch nor stable-baselines3.
"""
