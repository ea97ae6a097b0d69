"""Shared fixtures."""

from __future__ import annotations

import os
import shutil
import sys
import tempfile

import pytest

from pneunet_env import ActuatorParams


@pytest.fixture
def params() -> ActuatorParams:
    """The paper's defaults (J = 20)."""
    return ActuatorParams()


@pytest.fixture
def python_ctrl_c():
    """Python's own Ctrl-C handler for the test (a run started in the background of a non-interactive shell inherits
    SIGINT ignored, and Python then leaves it so), restored afterwards."""
    import signal

    before = signal.signal(signal.SIGINT, signal.default_int_handler)
    yield
    signal.signal(signal.SIGINT, before)


@pytest.fixture(scope="session")
def _sb3_logdir():
    """``$SB3_LOGDIR`` for the session: a path of this process's own, absent until something logs there.

    SB3 logs a ``learn()`` given no logger there (without it: a new ``$TMPDIR/SB3-<date and time>`` folder per call,
    left behind). Per process, so that xdist's workers and other programs' SB3 folders never mix with it."""
    root = tempfile.mkdtemp(prefix="pneunet-tests-sb3-")
    path = os.path.join(root, "SB3")
    before = os.environ.get("SB3_LOGDIR")
    os.environ["SB3_LOGDIR"] = path
    yield path
    if before is None:
        os.environ.pop("SB3_LOGDIR", None)
    else:
        os.environ["SB3_LOGDIR"] = before
    shutil.rmtree(root, ignore_errors=True)


@pytest.fixture(autouse=True)
def _no_sb3_log_folder(_sb3_logdir):
    """Fail a test that leaves an SB3 log folder: a model's ``learn()`` with no logger (give it
    ``agents.training.train.no_folder_logger()``), which would have left ``$TMPDIR/SB3-<date and time>`` behind."""
    yield
    if os.path.lexists(_sb3_logdir):
        shutil.rmtree(_sb3_logdir, ignore_errors=True)
        pytest.fail("the test made an SB3 log folder (a learn() with no logger: without $SB3_LOGDIR it would be left "
                    "in $TMPDIR as SB3-<date and time>); set the model's logger, e.g. "
                    "agents.training.train.no_folder_logger()",
                    pytrace=False)


@pytest.fixture
def cli(capsys):
    """``cli(argv)``: ``pneunet-grasp ARGV`` run in this process, as ``(exit status, stdout, stderr)``. A
    ``SystemExit`` counts as a return: its status (0 for none; 1 for a message, which is printed on stderr, as Python
    prints it)."""
    from pneunet_env.cli import main

    def run(argv: list[str]) -> tuple[int, str, str]:
        try:
            rc = main(argv)
        except SystemExit as exc:
            rc = 0 if exc.code is None else exc.code if isinstance(exc.code, int) else 1
            if not isinstance(exc.code, int) and exc.code is not None:
                print(exc.code, file=sys.stderr)
        out, err = capsys.readouterr()
        return rc, out, err

    return run
