"""Ctrl-C at a random moment of ``train``, ``search`` and ``map``, 20 times each: every time, either a run that
resumes (resumed once here, to the end) or a clean absence of output; never a cut file, a temporary file or a lock
left behind (issue 21).

The commands run in one long-lived subprocess (a harness that calls the CLI's ``main``, as ``pneunet-grasp`` does),
so that the 60 runs pay torch's and SB3's import once: SIGINT is sent to that process at a moment drawn uniformly
over the command's measured run time, and the harness reports the command's exit status and stderr. One fresh
``python -m pneunet_env.cli train`` process is interrupted too, for the real entry point's exit status (130) and its
one line.
"""

from __future__ import annotations

import json
import os
import random
import signal
import subprocess
import sys
import textwrap
import time
import zipfile
from pathlib import Path

import numpy as np
import pytest

pytestmark = pytest.mark.slow

ROOT = Path(__file__).resolve().parents[2]
REPEATS = 20
TRAIN = ["train", "--config", "ppo", "--timesteps", "256", "--n-envs", "2", "--eval-freq", "128",
         "--n-eval-episodes", "1", "--checkpoint-freq", "128", "--no-progress"]
SEARCH = ["search", "--objects", "8", "--targets", "0.3", "0.6", "--durations", "20", "--refine", "0", "--quiet"]
MAP = ["map", "--grid", "3", "2", "--density", "1000", "--no-progress"]
"""The smoke sizes of ``tests/test_readme_commands.py``'s table (train's a little smaller still)."""

HARNESS = textwrap.dedent('''
    import contextlib, io, json, os, signal, sys
    proto = os.fdopen(os.dup(1), "w", buffering=1)  # the protocol; the commands' own output goes to /dev/null
    devnull = open(os.devnull, "w")
    from pneunet_env.cli import main
    import agents.evaluation.map_cli, agents.search.cli, agents.training.cli  # noqa  (imported once, before any timing)
    import stable_baselines3  # noqa
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    proto.write("ready\\n")
    for line in sys.stdin:
        argv = json.loads(line)
        err = io.StringIO()
        rc, where = None, "command"
        try:
            try:
                with contextlib.redirect_stdout(devnull), contextlib.redirect_stderr(err):
                    signal.signal(signal.SIGINT, signal.default_int_handler)
                    proto.write("start\\n")
                    rc = main(argv)
            finally:
                signal.signal(signal.SIGINT, signal.SIG_IGN)  # a SIGINT after the command ended is ignored
        except KeyboardInterrupt as exc:  # it escaped the command (or came before it began: the harness's frame)
            rc, where = "KeyboardInterrupt", ("harness" if exc.__traceback__.tb_next is None else "command")
        except SystemExit as exc:
            rc = exc.code if isinstance(exc.code, int) else 1
        except Exception:  # a crash: reported, not fatal to the harness
            import traceback
            rc = "crash"
            err.write(traceback.format_exc())
        proto.write(json.dumps({"rc": rc, "where": where, "err": err.getvalue()[-3000:]}) + "\\n")
''')


class Harness:
    def __init__(self, cwd: Path) -> None:
        env = {**os.environ, "PYTHONPATH": str(ROOT) + os.pathsep + os.environ.get("PYTHONPATH", ""),
               "MPLBACKEND": "Agg"}
        self.proc = subprocess.Popen([sys.executable, "-c", HARNESS], cwd=cwd, env=env, stdin=subprocess.PIPE,
                                     stdout=subprocess.PIPE, text=True, bufsize=1)
        assert self._line() == "ready"

    def _line(self) -> str:
        line = self.proc.stdout.readline()
        assert line, f"the harness died (exit status {self.proc.poll()})"
        return line.strip()

    def run(self, argv: list[str], kill_after: float | None = None) -> dict:
        """Run ``pneunet-grasp ARGV``; send SIGINT ``kill_after`` seconds after it starts (if it is still running)."""
        self.proc.stdin.write(json.dumps(argv) + "\n")
        self.proc.stdin.flush()
        assert self._line() == "start"
        t0 = time.monotonic()
        if kill_after is not None:
            time.sleep(kill_after)
            self.proc.send_signal(signal.SIGINT)
        result = json.loads(self._line())
        result["wall_s"] = time.monotonic() - t0
        return result

    def close(self) -> None:
        self.proc.stdin.close()
        self.proc.wait(timeout=60)


@pytest.fixture(scope="module")
def harness(tmp_path_factory):
    h = Harness(tmp_path_factory.mktemp("cwd"))
    yield h
    h.close()


def _ctrl_c_reaches_python() -> None:
    """In the child, before Python starts: SIGINT back to its default. A test run started in the background of a
    non-interactive shell inherits SIGINT ignored, and Python then leaves it ignored (as a user's `cmd &` is)."""
    signal.signal(signal.SIGINT, signal.SIG_DFL)


def _leftovers(folder: Path) -> list[str]:
    return sorted(str(p) for p in folder.rglob("*") if p.name.endswith((".tmp", ".lock")) or ".tmp." in p.name)


def _whole(path: Path) -> None:
    """Every file the commands write, whole: JSON parses, NPZ and ZIP read, PNG ends with its IEND chunk."""
    if path.suffix == ".json":
        json.loads(path.read_text())
    elif path.suffix == ".npz":
        with np.load(path) as data:
            [data[k] for k in data.files]
    elif path.suffix == ".zip":
        with zipfile.ZipFile(path) as zf:
            assert zf.testzip() is None and "data" in zf.namelist(), path
    elif path.suffix == ".png":
        assert path.read_bytes()[-12:-8] == b"\x00\x00\x00\x00" and path.read_bytes()[-8:-4] == b"IEND", path


def _check_interrupt_status(res: dict, prog: str) -> None:
    """A command interrupted ends with status 130 and one line (the CLI's), or it ended before the SIGINT came."""
    if res["rc"] == "KeyboardInterrupt":
        assert res["where"] == "harness", f"{prog}: the interrupt escaped the CLI: {res['err']}"
        return
    assert res["rc"] in (0, 130), f"{prog}: exit status {res['rc']}: {res['err']}"
    if res["rc"] == 130:
        assert f"pneunet-grasp {prog}: interrupted" in res["err"] and "Traceback" not in res["err"], res["err"]


def _timed(harness: Harness, argv: list[str], folder: Path) -> float:
    """The command's run time, uninterrupted: the second of two runs (the first compiles and warms up)."""
    times = []
    for k in range(2):
        res = harness.run([*argv, "--run-dir" if argv[0] == "train" else "--out", str(folder / f"warm{k}")])
        assert res["rc"] == 0, res["err"]
        times.append(res["wall_s"])
    return times[-1]


def test_ctrl_c_during_train_leaves_a_run_that_resumes_or_nothing(harness, tmp_path):
    from agents.training.train import latest_checkpoint

    rng = random.Random(21)
    span = 1.05 * _timed(harness, TRAIN, tmp_path)
    outcomes = {"nothing": 0, "resumed": 0, "finished first": 0}
    for i in range(REPEATS):
        run_dir = tmp_path / f"run{i}"
        res = harness.run([*TRAIN, "--run-dir", str(run_dir)], kill_after=rng.uniform(0.0, span))
        _check_interrupt_status(res, "train")
        assert not _leftovers(tmp_path), _leftovers(tmp_path)
        if not run_dir.exists():
            outcomes["nothing"] += 1
            continue
        for path in run_dir.rglob("*"):
            if path.is_file():
                _whole(path)
        record = json.loads((run_dir / "run.json").read_text())  # a run folder always has its record
        if record["state"] == "finished":
            outcomes["finished first"] += 1
            continue
        assert record["state"] == "interrupted", record["state"]
        assert latest_checkpoint(run_dir) is not None
        res = harness.run([*TRAIN, "--run-dir", str(run_dir), "--resume"])
        assert res["rc"] == 0, res["err"]
        record = json.loads((run_dir / "run.json").read_text())
        assert record["state"] == "finished" and record["timesteps"] >= 256
        assert record["invocations"][-2].get("interrupted") and not _leftovers(run_dir)
        outcomes["resumed"] += 1
    print(f"train, {REPEATS} random Ctrl-C: {outcomes}")
    assert outcomes["resumed"] > 0  # the draw does hit training (else this test proves little)


def test_train_learns_after_a_ctrl_c_left_gradients_off(tmp_path, monkeypatch):
    """A Ctrl-C raised inside ``torch.no_grad().__enter__`` leaves gradients off for the rest of the process (its
    ``__exit__`` never runs). CI met it: a resumed train in the harness's process failed in SB3's update with
    "element 0 of tensors does not require grad". ``train`` now learns with gradients on whatever the caller's mode,
    and leaves the caller's mode as it was."""
    torch = pytest.importorskip("torch")
    from pneunet_env.cli import main

    monkeypatch.chdir(tmp_path)
    before = torch.is_grad_enabled()
    torch.set_grad_enabled(False)
    try:
        rc = main([*TRAIN, "--run-dir", str(tmp_path / "run")])
        assert not torch.is_grad_enabled()
    finally:
        torch.set_grad_enabled(before)
    assert rc == 0
    assert json.loads((tmp_path / "run" / "run.json").read_text())["state"] == "finished"


def test_ctrl_c_during_search_leaves_the_result_whole_or_absent(harness, tmp_path):
    rng = random.Random(22)
    span = 1.05 * _timed(harness, SEARCH, tmp_path)
    written = 0
    for i in range(REPEATS):
        out = tmp_path / f"s{i}" / "best.json"
        res = harness.run([*SEARCH, "--out", str(out)], kill_after=rng.uniform(0.0, span))
        _check_interrupt_status(res, "search")
        assert not _leftovers(tmp_path), _leftovers(tmp_path)
        if out.exists():
            assert json.loads(out.read_text())["n_steps"] == 20
            written += 1
        else:
            assert not out.parent.exists()  # no empty folder either
    print(f"search, {REPEATS} random Ctrl-C: {written} finished first")


def test_ctrl_c_during_map_leaves_whole_files_or_none(harness, tmp_path):
    rng = random.Random(23)
    span = 1.05 * _timed(harness, MAP, tmp_path)
    finished = 0
    for i in range(REPEATS):
        out = tmp_path / f"m{i}"
        res = harness.run([*MAP, "--out", str(out)], kill_after=rng.uniform(0.0, span))
        _check_interrupt_status(res, "map")
        assert not _leftovers(tmp_path), _leftovers(tmp_path)
        files = sorted(p.name for p in out.iterdir()) if out.exists() else []
        for name in files:
            _whole(out / name)
        finished += files == ["map.json", "map.png"]
    print(f"map, {REPEATS} random Ctrl-C: {finished} finished first")


def test_ctrl_c_ends_the_real_command_with_130_and_one_line(tmp_path):
    """The entry point itself (a fresh process): SIGINT once training runs -> exit status 130, one line on stderr
    (and the train command's own note of where it saved the run), a run that resumes."""
    run_dir = tmp_path / "run"
    env = {**os.environ, "PYTHONPATH": str(ROOT) + os.pathsep + os.environ.get("PYTHONPATH", ""), "MPLBACKEND": "Agg"}
    argv = [sys.executable, "-m", "pneunet_env.cli", *TRAIN, "--timesteps", "100000", "--run-dir", str(run_dir)]
    proc = subprocess.Popen(argv, cwd=tmp_path, env=env, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE,
                            text=True, preexec_fn=_ctrl_c_reaches_python)
    deadline = time.monotonic() + 120
    while not list((run_dir / "checkpoints").glob("model_*_steps.zip")) and time.monotonic() < deadline:
        assert proc.poll() is None, proc.stderr.read()
        time.sleep(0.05)
    proc.send_signal(signal.SIGINT)
    _, err = proc.communicate(timeout=120)
    lines = [line for line in err.splitlines() if line.strip()]
    assert proc.returncode == 130, err
    assert lines[-1].startswith("pneunet-grasp train: interrupted at ") and "Traceback" not in err, err
    assert lines[-1].endswith("--resume goes on from there"), err
    record = json.loads((run_dir / "run.json").read_text())
    assert record["state"] == "interrupted" and not (run_dir / ".lock").exists()
