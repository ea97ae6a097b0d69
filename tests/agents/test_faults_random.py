"""A worker killed (SIGKILL, as the kernel's OOM killer or a cluster's pre-emption does) at a random moment of
``train --seeds 2 --jobs 2`` and of ``design --jobs 2``, 10 times each (issue 34). Every time: the command ends
within a bounded time with a named error (or had finished), no lock and no temporary file is left, and running the
same command again finishes with every seed (every trial, Table 1's among them) accounted for.

The commands run in one long-lived subprocess (a harness that calls the CLI's ``main``, as ``pneunet-grasp`` does),
so that the 40 runs pay torch's, SB3's and Optuna's imports once, and the workers are forked from one server; the
test finds the workers (the server's children, in ``/proc``) and kills one at a moment drawn uniformly over a clean
run's time. The harness's stderr goes to a file: what every process of a command printed is checked.
"""

from __future__ import annotations

import contextlib
import json
import os
import random
import re
import signal
import subprocess
import sys
import textwrap
import time
from pathlib import Path

import pytest

pytestmark = [pytest.mark.slow,
              pytest.mark.skipif(not Path("/proc/self/task").is_dir(), reason="finds the workers in /proc (Linux)")]

ROOT = Path(__file__).resolve().parents[2]
REPEATS = 10
BOUND_S = 60.0
"""How long a command may take to end after its worker was killed (it takes about a second; the machine may be
busy)."""

SEEDS = ["train", "--config", "ppo", "--seeds", "2", "--jobs", "2", "--timesteps", "128", "--n-envs", "2",
         "--eval-freq", "128", "--n-eval-episodes", "1", "--checkpoint-freq", "32", "--objects", "2", "--no-progress"]
DESIGN = ["design", "--trials", "4", "--jobs", "2", "--objects", "6", "--held-out", "4", "--top", "1", "--quiet",
          "--bound", "top_thickness_mm=1.5:2.5", "--bound", "chamber_height_mm=5:6"]

HARNESS = textwrap.dedent('''
    import json, os, signal, sys, traceback
    proto = os.fdopen(os.dup(1), "w", buffering=1)  # the protocol; every process's stdout goes to /dev/null
    os.dup2(os.open(os.devnull, os.O_WRONLY), 1)
    from pneunet_env.cli import main
    for name in sys.argv[1:]:
        __import__(name)  # imported once, before any timing
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    proto.write("ready\\n")
    for line in sys.stdin:
        argv = json.loads(line)
        proto.write("start\\n")
        try:
            try:
                signal.signal(signal.SIGINT, signal.default_int_handler)
                rc = main(argv)
            finally:
                signal.signal(signal.SIGINT, signal.SIG_IGN)
        except SystemExit as exc:
            rc = exc.code if isinstance(exc.code, int) else 1
        except BaseException:
            rc = "crash"
            traceback.print_exc()
        sys.stderr.flush()
        proto.write(json.dumps({"rc": rc}) + "\\n")
''')


class Harness:
    def __init__(self, cwd: Path, modules: list[str]) -> None:
        env = {**os.environ, "PYTHONPATH": str(ROOT) + os.pathsep + os.environ.get("PYTHONPATH", ""),
               "MPLBACKEND": "Agg"}
        env.pop("PNEUNET_DEBUG", None)
        self.err_path = cwd / "stderr.txt"
        self.err = open(self.err_path, "w")
        self.proc = subprocess.Popen([sys.executable, "-c", HARNESS, *modules], cwd=cwd, env=env,
                                     stdin=subprocess.PIPE, stdout=subprocess.PIPE, stderr=self.err, text=True,
                                     bufsize=1)
        assert self._line() == "ready"

    def _line(self, timeout: float | None = None) -> str:
        if timeout is not None:
            import select

            ready, _, _ = select.select([self.proc.stdout], [], [], timeout)
            assert ready, f"the command did not end within {timeout:g} s: {self.err_path.read_text()[-3000:]}"
        line = self.proc.stdout.readline()
        assert line, f"the harness died (exit status {self.proc.poll()}): {self.err_path.read_text()[-3000:]}"
        return line.strip()

    def workers(self) -> list[int]:
        """The pids of the worker processes alive now: the children of the harness's forkserver, or its children
        started by ``spawn``."""
        out = []
        for child in _children(self.proc.pid):
            try:
                cmdline = Path(f"/proc/{child}/cmdline").read_text()
            except OSError:
                continue
            if "forkserver" in cmdline:
                out += _children(child)
            elif "spawn_main" in cmdline:
                out.append(child)
        return out

    def run(self, argv: list[str], kill_after: float | None = None, rng: random.Random | None = None,
            watch: bool = False) -> dict:
        """Run ``pneunet-grasp ARGV``; ``kill_after`` seconds after its first worker is seen, SIGKILL one of its
        workers (drawn by ``rng``) if one is alive. Returns ``rc``, ``err`` (what every process printed on stderr),
        ``killed`` (the pid or None), ``after_kill_s``, ``wall_s`` and (``watch``) ``workers_s``: when workers were
        first and last seen alive (seconds from the start)."""
        start = self.err_path.stat().st_size
        self.proc.stdin.write(json.dumps(argv) + "\n")
        self.proc.stdin.flush()
        assert self._line() == "start"
        t0 = time.monotonic()
        killed, t_kill = None, None
        seen: list[float] = []
        if watch:
            import threading

            def look() -> None:
                while not done:
                    if self.workers():
                        seen.append(time.monotonic() - t0)
                    time.sleep(0.01)

            done = False
            watcher = threading.Thread(target=look, daemon=True)
            watcher.start()
        if kill_after is not None:  # counted from the moment the first worker is seen
            while not self.workers() and time.monotonic() - t0 < BOUND_S and self.proc.poll() is None:
                time.sleep(0.005)
            time.sleep(kill_after)
            alive = self.workers()
            if alive:
                killed = rng.choice(alive)
                try:
                    os.kill(killed, signal.SIGKILL)
                    t_kill = time.monotonic()
                except ProcessLookupError:  # it ended just then
                    killed = None
        result = json.loads(self._line(timeout=None if t_kill is None else BOUND_S))
        result["wall_s"] = time.monotonic() - t0
        if watch:
            done = True
            watcher.join()
            result["workers_s"] = (seen[0], seen[-1]) if seen else None
        result["after_kill_s"] = None if t_kill is None else time.monotonic() - t_kill
        result["killed"] = killed
        self.err.flush()
        with open(self.err_path) as fh:
            fh.seek(start)
            result["err"] = fh.read()
        return result

    def close(self) -> None:
        """End the harness: at once if a command hangs (a failed test), its workers with it."""
        self.proc.stdin.close()
        try:
            self.proc.wait(timeout=120 if self.proc.stdout.readable() else 5)
        except subprocess.TimeoutExpired:
            for pid in [*self.workers(), *_children(self.proc.pid)]:
                with contextlib.suppress(OSError):
                    os.kill(pid, signal.SIGKILL)
            self.proc.kill()
            self.proc.wait()
        self.err.close()


def _children(pid: int) -> list[int]:
    out = []
    for task in Path(f"/proc/{pid}/task").glob("*"):
        try:
            out += [int(c) for c in (task / "children").read_text().split()]
        except OSError:
            pass
    return out


def _workers_span(h: Harness, argv) -> float:
    """Three quarters of how long a clean run's workers live (seconds, from the first one seen to the last): the
    second of two runs (the first compiles and warms up)."""
    for k in range(2):
        warm = h.run(argv(k), watch=True)
        assert warm["rc"] == 0 and warm["workers_s"], warm["err"][-3000:]
    first, last = warm["workers_s"]
    return 0.75 * (last - first)  # the last quarter is often past the end of a resumed (shorter) run's workers


def _leftovers(folder: Path) -> list[str]:
    return sorted(str(p) for p in folder.rglob("*") if p.name.endswith((".tmp", ".lock")) or ".tmp." in p.name)


def _check_ended(res: dict, what: str) -> str | None:
    """The command ended in time, with a finished run or a one-line named error; returns that line (or None)."""
    assert res["rc"] in (0, 2), f"{what}: exit status {res['rc']}: {res['err'][-3000:]}"
    if res["after_kill_s"] is not None:
        assert res["after_kill_s"] < BOUND_S, res
    assert "Traceback" not in res["err"] and "Exception ignored" not in res["err"], res["err"][-3000:]
    if res["rc"] == 0:
        return None
    lines = [line for line in res["err"].splitlines() if line.startswith(f"pneunet-grasp {what}: error: ")]
    assert len(lines) == 1, res["err"][-3000:]
    assert "run the same command again" in lines[0], lines[0]
    if res["killed"] is not None:
        assert f"(pid {res['killed']}) was killed by SIGKILL" in lines[0], (lines[0], res["killed"])
    return lines[0]


def _kill_runs(h: Harness, folders, argv_for, span: float, rng: random.Random, what: str, check) -> int:
    """``REPEATS`` runs, each with a worker killed at a random moment, in chains: each run after a kill is the same
    command again (it resumes), until one finishes; a chain whose last run was killed is then run once more, to the
    end, and ``check(folder, argv, line)`` accounts for every seed or trial after each run. Returns how many kills
    hit a worker that had not finished."""
    hits = kills = 0
    while kills < REPEATS:
        folder = next(folders)
        argv = argv_for(folder)
        while kills < REPEATS:
            res = h.run(argv, kill_after=rng.uniform(0.0, span), rng=rng)
            kills += 1
            line = _check_ended(res, what)
            assert not _leftovers(folder), _leftovers(folder)
            check(folder, argv, line)
            hits += line is not None
            if line is None:
                break
        if line is not None:
            again = h.run(argv)
            assert again["rc"] == 0, again["err"][-3000:]
            assert not _leftovers(folder), _leftovers(folder)
            check(folder, argv, None)
    return hits


def _random_kills(h: Harness, argv_for, tmp_path: Path, seed: int, what: str, check) -> int:
    """:func:`_kill_runs` at moments drawn over a clean run's workers' lifetime (``tmp_path/warm1`` is that run's
    folder); how many kills hit a worker at work, which must be some (the draw proves little otherwise; a run on a
    busy machine may outlast the clean one's, so not every kill hits)."""
    span = _workers_span(h, lambda k: argv_for(tmp_path / f"warm{k}"))
    hits = _kill_runs(h, (tmp_path / f"k{i}" for i in range(REPEATS)), argv_for, span, random.Random(seed), what,
                      check)
    assert hits >= 3
    return hits


def test_a_seed_worker_killed_at_a_random_moment(tmp_path):
    pytest.importorskip("stable_baselines3")

    def check(run_dir: Path, argv: list[str], line: str | None) -> None:
        if line is None:  # finished: every seed to the end, scored
            result = json.loads((run_dir / "seeds.json").read_text())
            assert result["seeds"] == [0, 1] and all(result["finished"].values()), result["finished"]
            for s in (0, 1):
                data = json.loads((run_dir / f"seed-{s}" / "run.json").read_text())
                assert data["state"] == "finished" and data["timesteps"] >= 128, data
            return
        seed = int(re.search(r"seed (\d+): its worker process", line).group(1))
        record = run_dir / f"seed-{seed}" / "run.json"
        if record.exists():  # a worker killed before it made its folder leaves nothing to mark
            data = json.loads(record.read_text())
            assert data["state"] == "failed" and data["exit_signal"] == "SIGKILL", data
        for other in run_dir.glob("seed-*/run.json"):
            assert json.loads(other.read_text())["state"] in ("failed", "interrupted", "finished"), other

    h = Harness(tmp_path, ["agents.training.seeds", "agents.training.train", "stable_baselines3"])
    try:
        hits = _random_kills(h, lambda d: [*SEEDS, "--run-dir", str(d)], tmp_path, 34, "train", check)
        print(f"train --seeds 2 --jobs 2: {hits} of {REPEATS} random kills hit a training worker")
    finally:
        h.close()


def test_a_design_worker_killed_at_a_random_moment(tmp_path):
    optuna = pytest.importorskip("optuna")

    def check(out: Path, argv: list[str], line: str | None) -> None:
        study = optuna.load_study(study_name="design-kitchen", storage=f"sqlite:///{out / 'study.db'}")
        trials = study.get_trials(deepcopy=False)
        states = [t.state.name for t in trials]
        assert "RUNNING" not in states, states  # a killed worker's trial is marked failed at once
        if line is not None:
            return
        assert "WAITING" not in states, states
        retries = [t.user_attrs["retry_of"] for t in trials if "retry_of" in t.user_attrs]
        failed = [t.number for t in trials if t.state.name == "FAIL"]
        assert sorted(retries) == failed, (retries, failed)  # each failed trial retried once, never twice
        assert sum(t.user_attrs.get("table1", False) and t.state.name == "COMPLETE" for t in trials) == 1
        assert sum(s in ("COMPLETE", "PRUNED") for s in states) >= int(argv[argv.index("--trials") + 1])
        result = json.loads((out / "design.json").read_text())
        assert result["designs"][0]["label"] == "table1", [d["label"] for d in result["designs"]]

    h = Harness(tmp_path, ["agents.design.study", "optuna"])
    try:
        hits = _random_kills(h, lambda d: [*DESIGN, "--out", str(d)], tmp_path, 35, "design", check)
        print(f"design --jobs 2: {hits} of {REPEATS} random kills hit a working worker")
        # the study goes on to more designs, PED-ANOVA's importance computed: none of Optuna's notes on what the
        # study uses knowingly is printed (issue 32)
        argv = [*DESIGN, "--out", str(tmp_path / "warm1")]
        argv[argv.index("--trials") + 1] = "9"
        more = h.run(argv)
        res = json.loads((tmp_path / "warm1" / "design.json").read_text())
        # computed, or said why not (the designs' scores tie: most hold nothing at their worst corner)
        assert more["rc"] == 0 and (res["importance"] or res["importance_note"])
        for text in ("ExperimentalWarning", "low `target`", "Warning"):
            assert text not in more["err"], more["err"][-3000:]
    finally:
        h.close()
