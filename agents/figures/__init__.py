"""The figures of ``agents``: each takes the data a command computed (rows, traces, a record) and draws it.

* :mod:`~agents.figures.style`: matplotlib (Agg), imported only when a figure is drawn, and the policies' styles;
* :mod:`~agents.figures.evaluation`: ``success_vs_stiffness.png``, ``schedules.png`` (``pneunet-grasp evaluate``);
* :mod:`~agents.figures.training`: ``training.png``, ``learning_curves.png`` (``pneunet-grasp train [--seeds]``);
* :mod:`~agents.figures.search`: the search's ``--plot`` and ``sensitivity.png`` (``pneunet-grasp search``);
* :mod:`~agents.figures.maps`: ``map.png`` (``pneunet-grasp map``).

A new figure goes here, in the module of its command, as ``plot_x(data, path, ...) -> Path``.

May import: :mod:`agents.common` (the task in words, the regime labels, the map's record) and ``pneunet_env``;
never a module that computes the data it draws (no episode runs here).
"""
