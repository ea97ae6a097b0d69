"""Learned policies: ``pneunet-grasp train`` (stable-baselines3) and ``pneunet-grasp train-skrl``.

* :mod:`~agents.training.config`: the train config (rl-zoo3's file and the project's keys), read and checked;
* :mod:`~agents.training.envs`: the vec envs and callbacks of a run;
* :mod:`~agents.training.train`: the training loop, the saved models and the run's record (``run.json``);
* :mod:`~agents.training.export`: ``--export``;
* :mod:`~agents.training.seeds`: ``--seeds N``, one config over seeds;
* :mod:`~agents.training.skrl_ppo`: skrl's PPO on the torch backend (its own command);
* :mod:`~agents.training.cli`: ``pneunet-grasp train``'s command line.

A new training option goes in ``config.py`` (a project key: ``PROJECT_KEYS``, ``DEFAULTS``) and, as a flag, in
``cli.py``. torch and stable-baselines3 are imported only inside functions.

May import: :mod:`agents.common`, :mod:`agents.policies`, :mod:`agents.evaluation`, :mod:`agents.figures`.
"""
