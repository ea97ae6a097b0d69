"""Policies run on objects, and what their outcomes say: ``pneunet-grasp evaluate`` and ``pneunet-grasp map``.

* :mod:`~agents.evaluation.episodes`: one episode and its outcome (``run_episode``);
* :mod:`~agents.evaluation.batch`: many objects x many schedules as one vector env run (the batched runner);
* :mod:`~agents.evaluation.objects`: the stiffness grid and its bins, objects drawn by the env into them;
* :mod:`~agents.evaluation.evaluate`: policies over the grid and over the env's own distribution;
* :mod:`~agents.evaluation.summaries`: the rows by regime, by ``k~`` bin and by class; the printed tables;
* :mod:`~agents.evaluation.maps`: the success map over modulus x radius;
* :mod:`~agents.evaluation.evaluate_cli`, :mod:`~agents.evaluation.map_cli`: the two commands.

May import: :mod:`agents.common`, :mod:`agents.policies`; the ``*_cli`` modules also :mod:`agents.figures`.
"""
