"""The lowest layer of ``agents``: what every other package shares, importing nothing from ``agents``.

* :mod:`~agents.common.resources`: the files the package ships (named configs, trained models, ``AGENTS_DIR``);
* :mod:`~agents.common.workers`: worker processes watched by their parent (seed studies, design studies);
* :mod:`~agents.common.regimes`: the regime labels (the paper's ``k~`` bins, each object's regime off the mechanics);
* :mod:`~agents.common.words`: the active task in words, and the rate formats;
* :mod:`~agents.common.map_record`: the success map's record, read (its summary);
* :mod:`~agents.common.envs`: the env ids the policies drive;
* :mod:`~agents.common.cli`: the commands' shared argument helpers (``usage_error``, ``parse_overrides``).

May import: ``pneunet_env`` (below the CLI) and third-party packages; nothing from ``agents``.
"""
