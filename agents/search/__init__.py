"""The best-ramp search (``pneunet-grasp search``, ``python -m agents.search``): one blind schedule, tuned once.

* :mod:`~agents.search.ramp`: the grid search over a ramp's target and duration, and the saved result;
* :mod:`~agents.search.sensitivity`: the threshold sensitivity study of the paper's task (``--sensitivity``);
* :mod:`~agents.search.cli`: the command.

May import: :mod:`agents.common`, :mod:`agents.policies`, :mod:`agents.evaluation`, :mod:`agents.figures`.
"""
