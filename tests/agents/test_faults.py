"""Studies that survive their faults (issue 34): a worker that dies, an interrupted trial, a storage that is not one,
Ctrl-C during start-up, and the vector env's seed message. The random-moment kills of a seed study's and a design
study's workers are ``test_faults_random.py`` (slow)."""

from __future__ import annotations

import contextlib
import json
import os
import signal
import socket
import sqlite3
import subprocess
import sys
import threading
import time
import zipfile
from pathlib import Path

import pytest

from pneunet_env.cli import main

ROOT = Path(__file__).resolve().parents[2]
SMALL = ["--objects", "4", "--held-out", "4", "--top", "1", "--quiet", "--bound", "top_thickness_mm=1.5:2.5",
         "--bound", "chamber_height_mm=5:6"]


def _dead_pid() -> int:
    proc = subprocess.Popen([sys.executable, "-c", "pass"])
    proc.wait()
    return proc.pid


def _leftovers(folder: Path) -> list[str]:
    return sorted(str(p) for p in folder.rglob("*") if p.name.endswith((".tmp", ".lock")) or ".tmp." in p.name)


# ---------------------------------------------------------------------------------------------------------------------
# The seed message of the vector env
# ---------------------------------------------------------------------------------------------------------------------


def test_the_vector_seed_message_names_the_value_and_its_type():
    import gymnasium as gym

    import pneunet_env  # noqa: F401  (registers the env)

    env = gym.make_vec("PneuNetGrasp-v1", num_envs=4)
    try:
        for bad, shown in [("abc", "'abc' (str)"), ("abcd", "'abcd' (str)"), (b"ab", "b'ab' (bytes)"),
                           (3.5, "3.5 (float)"), ([1, 2], "[1, 2] (list of 2)")]:
            with pytest.raises(ValueError) as err:
                env.reset(seed=bad)
            assert str(err.value).endswith(f"got {shown}"), str(err.value)  # not "got 3", the string's length
    finally:
        env.close()


# ---------------------------------------------------------------------------------------------------------------------
# Worker processes (agents.common.workers): a death noticed, the others stopped cleanly, Ctrl-C
# ---------------------------------------------------------------------------------------------------------------------
# The jobs are Python expressions run by ``eval`` (a builtin: it pickles by name to the worker; the test module does
# not, under pytest's importlib mode).

SLEEP = "__import__('time').sleep(60)"
DIE = "__import__('os').kill(__import__('os').getpid(), 9)"


def test_a_dead_worker_is_noticed_and_the_others_are_stopped_cleanly():
    from agents.common.workers import run_jobs

    ended = []
    t0 = time.monotonic()
    ran = run_jobs(eval, [SLEEP, DIE, SLEEP], 2, on_end=lambda out: ended.append(out.state) or out.state == "done")
    took = time.monotonic() - t0
    states = [o.state for o in ran.outcomes]
    assert states == ["interrupted", "died", "not started"], states
    died = ran.outcomes[1]
    assert died.signal_name == "SIGKILL" and "killed by SIGKILL" in died.cause() and str(died.pid) in died.cause()
    assert sorted(ended) == ["died", "interrupted"] and not ran.interrupted and not ran.clean
    assert took < 30, took  # not the 60 s the sleeping worker had left: stopped within seconds of the death


# A worker's SIGINT that lands where Python cannot raise it (a finaliser here; numba's compiler calls back into Python
# the same way, from llvmlite's object cache) is swallowed: without the worker's unraisable hook it printed "Exception
# ignored ..." with a traceback, and the worker, its one interrupt spent, slept on.
SWALLOWED = ("((type('D', (), {'__del__': lambda self: (__import__('os').kill(__import__('os').getpid(), 2), "
             "__import__('time').sleep(0.5))})(), 0)[1], __import__('time').sleep(20))")


def test_an_interrupt_a_callback_swallowed_is_raised_again_quietly(capfd):
    from agents.common.workers import run_jobs

    t0 = time.monotonic()
    ran = run_jobs(eval, [SWALLOWED], 1)
    took = time.monotonic() - t0
    err = capfd.readouterr().err
    assert [o.state for o in ran.outcomes] == ["interrupted"], (ran.outcomes, err)
    assert took < 15, took  # not the 20 s sleep: the interrupt was raised again once the finaliser returned
    assert "Exception ignored" not in err and "Traceback" not in err, err


def test_ctrl_c_in_the_parent_stops_every_worker_and_is_reported(python_ctrl_c):
    from agents.common.workers import run_jobs

    threading.Timer(2.0, os.kill, (os.getpid(), signal.SIGINT)).start()
    t0 = time.monotonic()
    ran = run_jobs(eval, [SLEEP, SLEEP, SLEEP], 2)
    assert ran.interrupted and time.monotonic() - t0 < 30
    assert [o.state for o in ran.outcomes] == ["interrupted", "interrupted", "not started"]
    assert signal.getsignal(signal.SIGINT) is signal.default_int_handler  # the parent's handler given back


def test_a_worker_takes_one_interrupt_only(python_ctrl_c):
    """The terminal's Ctrl-C and the parent's forwarded one both reach a worker: the second must not cut the
    checkpoint the first is saving (interrupt_once), and a deferred block holds it as it holds Python's own."""
    from pneunet_env.files import deferred_interrupt, interrupt_once

    signal.signal(signal.SIGINT, interrupt_once)
    try:
        with pytest.raises(KeyboardInterrupt):
            with deferred_interrupt():
                os.kill(os.getpid(), signal.SIGINT)
                time.sleep(0.05)  # held: the block runs whole
                done = True
        assert done and signal.getsignal(signal.SIGINT) is signal.SIG_IGN  # spent: a second one is ignored
        os.kill(os.getpid(), signal.SIGINT)
        time.sleep(0.05)
    finally:
        signal.signal(signal.SIGINT, signal.default_int_handler)


def _model_zip(path: Path) -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    with zipfile.ZipFile(path, "w") as zf:
        zf.writestr("data", "{}")


def test_a_seed_whose_worker_died_is_marked_failed_its_lock_released_and_its_temporary_files_removed(tmp_path):
    from agents.common.workers import Outcome
    from agents.training.seeds import _done, _mark_died

    run = tmp_path / "seed-3"
    _model_zip(run / "checkpoints" / "model_128_steps.zip")
    _model_zip(run / "checkpoints" / "model_256_steps.zip")
    (run / "checkpoints" / ".model_384_steps.zip.x1y2.tmp").write_bytes(b"cut")  # a write the kill cut short
    (run / ".training.ab12.tmp.png").write_bytes(b"cut")
    pid = _dead_pid()
    (run / "run.json").write_text(json.dumps({"seed": 3, "state": "running", "timesteps": 128,
                                              "invocations": [{"start_timesteps": 0, "end_timesteps": 128,
                                                               "wall_s": 2.0}]}))
    (run / ".lock").write_text(json.dumps({"pid": pid, "host": socket.gethostname(), "started": "x",
                                           "command": "pneunet-grasp train"}))
    out = Outcome(0, state="died", pid=pid, exitcode=-9, started=time.monotonic() - 5)
    assert _mark_died(run, 3, out) is False
    record = json.loads((run / "run.json").read_text())
    assert record["state"] == "failed" and record["exit_signal"] == "SIGKILL" and record["timesteps"] == 256
    assert f"pid {pid}" in record["failed"] and "SIGKILL" in record["failed"]
    last = record["invocations"][-1]
    assert last["failed"] == record["failed"] and last["start_timesteps"] == 128 and last["exit_signal"] == "SIGKILL"
    assert not _leftovers(tmp_path), _leftovers(tmp_path)  # the lock and the cut files gone
    assert not _done(run, {"n_timesteps": 256})  # a failed seed resumes
    # a worker that died once its run had finished: the record is kept
    (run / "run.json").write_text(json.dumps({"seed": 3, "state": "finished", "timesteps": 256}))
    assert _mark_died(run, 3, out) is True
    assert json.loads((run / "run.json").read_text())["state"] == "finished"
    assert _mark_died(tmp_path / "seed-9", 9, out) is False and not (tmp_path / "seed-9").exists()


def test_a_dead_process_lock_is_released_and_a_live_one_kept(tmp_path):
    from pneunet_env.locks import RunLock, release_dead

    pid = _dead_pid()
    (tmp_path / ".lock").write_text(json.dumps({"pid": pid, "host": socket.gethostname()}))
    assert not release_dead(tmp_path, pid + 1) and (tmp_path / ".lock").exists()  # another process's
    assert release_dead(tmp_path, pid) and not (tmp_path / ".lock").exists()
    with RunLock(tmp_path / "live"):
        assert not release_dead(tmp_path / "live", os.getpid()) and (tmp_path / "live" / ".lock").exists()


# ---------------------------------------------------------------------------------------------------------------------
# Storages: checked before anything is written; the user's file left byte for byte
# ---------------------------------------------------------------------------------------------------------------------

def _refused(argv: list[str], capsys, *names: str) -> str:
    from pneunet_env.cli import CommandError

    with pytest.raises(CommandError):
        main(["design", *argv])
    err = capsys.readouterr().err.strip()
    assert "\n" not in err and err.startswith("pneunet-grasp design: error: --"), err
    for name in names:
        assert name in err, err
    assert "Traceback" not in err
    return err


def _storage_case(case: str, tmp_path: Path) -> tuple[list[str], Path]:
    """The arguments of a storage that is not one, and the path it names (to be left as it was)."""
    if case == "a text file as the journal":  # the issue's: 14 bytes, and Optuna appended 132
        path = tmp_path / "garbage.log"
        path.write_bytes(b"not a journal\n")
        return ["--storage", f"journal:{path}"], path
    if case in ("a folder as the journal", "a folder as the SQLite file"):
        path = tmp_path / "afolder"
        path.mkdir()
        (path / "keep.txt").write_text("mine")
        return ["--storage", f"journal:{path}" if "journal" in case else f"sqlite:///{path}"], path
    if case == "a journal in a missing folder":
        return ["--storage", f"journal:{tmp_path / 'missing' / 'j.log'}"], tmp_path / "missing"
    if case == "/dev/null as the journal":
        return ["--storage", "journal:/dev/null"], Path("/dev/null")
    if case == "a text file as the SQLite file":
        path = tmp_path / "notes.db"
        path.write_bytes(b"my notes, not a database\n")
        return ["--storage", f"sqlite:///{path}"], path
    if case == "another program's SQLite database":
        path = tmp_path / "other.db"
        with contextlib.closing(sqlite3.connect(path)) as con:
            con.execute("CREATE TABLE mine (x INTEGER)")
            con.execute("INSERT INTO mine VALUES (1)")
            con.commit()
        return ["--storage", f"sqlite:///{path}"], path
    assert case == "a text file as the default OUT/study.db"
    (tmp_path / "out").mkdir()
    path = tmp_path / "out" / "study.db"
    path.write_bytes(b"a file of mine")
    return [], path


def _state(path: Path):
    """What must not change: a file's bytes, a folder's listing, a device's kind, or its absence."""
    if path.is_dir():
        return sorted((p.name, p.read_bytes()) for p in path.iterdir())
    if path.is_char_device():
        return "device"
    return path.read_bytes() if path.exists() else None


@pytest.mark.parametrize("case", ["a text file as the journal", "a folder as the journal",
                                  "a journal in a missing folder", "/dev/null as the journal",
                                  "a text file as the SQLite file", "another program's SQLite database",
                                  "a folder as the SQLite file", "a text file as the default OUT/study.db"])
def test_a_storage_that_is_not_one_is_refused_by_name_and_left_byte_for_byte(tmp_path, capsys, case):
    pytest.importorskip("optuna")
    argv, path = _storage_case(case, tmp_path)
    before = _state(path)
    _refused([*argv, "--trials", "1", "--out", str(tmp_path / "out"), *SMALL], capsys, str(path))
    assert _state(path) == before
    assert not (tmp_path / "out" / "design.json").exists()


def test_a_new_or_empty_journal_and_a_real_one_are_taken(tmp_path):
    pytest.importorskip("optuna")
    from agents.design.storage import check_storage

    empty = tmp_path / "empty.log"
    empty.write_bytes(b"")
    check_storage(f"journal:{empty}", tmp_path)
    check_storage(f"journal:{tmp_path / 'new.log'}", tmp_path)
    assert not (tmp_path / "new.log").exists()  # checked, not made
    real = tmp_path / "real.log"
    real.write_text(json.dumps({"op_code": 0, "worker_id": "w", "study_name": "s", "directions": [1]}) + "\n")
    check_storage(f"journal:{real}", tmp_path)
    check_storage(f"sqlite:///{tmp_path / 'new.db'}", tmp_path)


def test_an_rdb_server_that_does_not_answer_is_refused_within_the_time_limit(tmp_path, monkeypatch):
    optuna = pytest.importorskip("optuna")
    from agents.design import storage

    calls = []

    def hangs(url, **kwargs):  # a server that accepts the connection and never answers
        calls.append(kwargs)
        time.sleep(30)

    monkeypatch.setattr(optuna.storages, "RDBStorage", hangs)
    monkeypatch.setattr(storage, "STORAGE_TIMEOUT_S", 0.5)
    t0 = time.monotonic()
    with pytest.raises(ValueError, match=r"postgresql://u@10\.255\.255\.1/db.*no answer within 0\.5 s"):
        storage.make_storage("postgresql://u@10.255.255.1/db", tmp_path)
    assert time.monotonic() - t0 < 5
    assert calls[0]["engine_kwargs"]["connect_args"] == {"connect_timeout": 0}  # the driver gives up too
    assert not list(tmp_path.iterdir())  # no partial study


def test_an_rdb_url_without_its_driver_is_named_at_once(tmp_path, capsys):
    pytest.importorskip("optuna")
    t0 = time.monotonic()
    _refused(["--storage", "postgresql://u@127.0.0.1:1/db", "--out", str(tmp_path / "o"), *SMALL], capsys,
             "postgresql://u@127.0.0.1:1/db")
    assert time.monotonic() - t0 < 15 and not (tmp_path / "o" / "design.json").exists()


# ---------------------------------------------------------------------------------------------------------------------
# The design study: dead and interrupted trials failed and retried once; Table 1 always there; Optuna's notes
# ---------------------------------------------------------------------------------------------------------------------


def _spec(tmp_path: Path, **kw):
    from agents.design.study import StudySpec

    return StudySpec(out=tmp_path / "study", objects=4, held_out=4, top=1, trials=kw.pop("trials", 3), **kw)


def test_mend_fails_what_dead_processes_left_and_retries_each_failed_trial_once(tmp_path):
    optuna = pytest.importorskip("optuna")
    from agents.design.space import table1_design
    from agents.design.study import _finished, mend, open_study

    study = open_study(_spec(tmp_path))
    TS = optuna.trial.TrialState
    t0 = study.ask()  # Table 1, enqueued by the new study: its worker killed mid-trial
    assert t0.user_attrs.get("table1")
    t0.set_user_attr("worker", f"{socket.gethostname()}:{_dead_pid()}")
    t0.suggest_float("top_thickness_mm", 1.0, 4.0)
    t1 = study.ask()  # interrupted: Optuna marked it failed
    x = t1.suggest_float("top_thickness_mm", 1.0, 4.0)
    study.tell(t1, state=TS.FAIL)
    t2 = study.ask()  # a live process's trial, here
    t2.set_user_attr("worker", f"{socket.gethostname()}:{os.getpid()}")
    done = mend(study)
    assert done == {"orphans": [0], "retried": [0, 1]}
    trials = study.get_trials(deepcopy=False)
    assert trials[0].state is TS.FAIL and "ended" in trials[0].user_attrs["failed"]
    assert trials[2].state is TS.RUNNING  # alive: left to its process
    retries = {t.user_attrs["retry_of"]: t for t in trials if "retry_of" in t.user_attrs}
    assert set(retries) == {0, 1} and all(t.state is TS.WAITING for t in retries.values())
    assert retries[0].user_attrs.get("table1") and retries[0].system_attrs["fixed_params"] == table1_design()
    assert retries[1].system_attrs["fixed_params"] == {"top_thickness_mm": x}
    assert mend(study) == {"orphans": [], "retried": []}  # never twice
    assert len(study.get_trials(deepcopy=False)) == 5 and _finished(study) == 0  # a failed trial counts for nothing


def test_mend_judges_an_unnamed_running_trial_by_its_age(tmp_path, monkeypatch):
    optuna = pytest.importorskip("optuna")
    from agents.design import study as st

    study = st.open_study(_spec(tmp_path))
    study.ask()  # running, no process named (killed between Optuna's ask and the objective's first line)
    monkeypatch.setattr(st, "ORPHAN_S", 0.3)
    t0 = time.monotonic()
    assert st.mend(study)["orphans"] == [0]  # young: waited for, then judged
    assert time.monotonic() - t0 >= 0.25
    assert study.get_trials(deepcopy=False)[0].state is optuna.trial.TrialState.FAIL


def test_optuna_notes_on_what_the_study_uses_knowingly_are_not_shown(tmp_path):
    optuna = pytest.importorskip("optuna")
    import warnings

    from agents.design.study import _importance, open_study

    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        study = open_study(_spec(tmp_path))
        for k in range(12):  # enough finished designs for PED-ANOVA
            t = study.ask()
            t.suggest_float("top_thickness_mm", 1.0, 4.0)
            t.suggest_float("width_mm", 4.0, 10.0)
            t.set_user_attr("score", {"score": float(k % 5)})
            study.tell(t, [0.5, 0.5, 0.5])
        assert _importance(study)
    shown = [str(w.message) for w in caught if issubclass(w.category, optuna.exceptions.ExperimentalWarning)
             or "low `target`" in str(w.message)]
    assert not shown, shown


def test_report_refuses_a_study_without_its_table1_design(tmp_path):
    pytest.importorskip("optuna")
    from agents.design.study import open_study, report

    spec = _spec(tmp_path)
    study = open_study(spec)
    t = study.ask()  # Table 1, cut by a kill and never retried
    t.set_user_attr("worker", f"{socket.gethostname()}:{_dead_pid()}")
    with pytest.raises(ValueError, match="Table 1"):
        report(spec)


def test_an_interrupted_design_study_says_one_line_and_retries_table1(tmp_path, capfd, python_ctrl_c):
    """The issue's case: Ctrl-C during trial 0 (Table 1), then the same command: one line (no Optuna log), and the
    outputs have Table 1."""
    pytest.importorskip("optuna")
    out = tmp_path / "o"
    db = out / "study.db"

    def interrupt_in_trial_0():
        deadline = time.monotonic() + 120
        while time.monotonic() < deadline:
            try:
                with contextlib.closing(sqlite3.connect(db, timeout=5)) as con:  # closed: no read lock left
                    if con.execute("SELECT 1 FROM trials WHERE number = 0 AND state = 'RUNNING'").fetchall():
                        break
            except sqlite3.Error:
                pass
            time.sleep(0.01)
        os.kill(os.getpid(), signal.SIGINT)

    argv = ["design", "--trials", "2", "--out", str(out), *SMALL]
    threading.Thread(target=interrupt_in_trial_0, daemon=True).start()
    assert main(argv) == 130
    err = capfd.readouterr().err
    assert err.strip().splitlines() == ["pneunet-grasp design: interrupted (trial 0 marked failed): the same command "
                                        "retries and goes on"], err
    assert main(argv) == 0
    result = json.loads((out / "design.json").read_text())
    assert result["designs"][0]["label"] == "table1" and result["designs"][0]["params"]["elastomer"] == "table1"
    with contextlib.closing(sqlite3.connect(db)) as con:
        states = dict(con.execute("SELECT number, state FROM trials").fetchall())
    assert states[0] == "FAIL" and sorted(states.values()).count("FAIL") == 1 and len(states) == 3
    assert not _leftovers(out)


# ---------------------------------------------------------------------------------------------------------------------
# Ctrl-C while the command line starts (its imports)
# ---------------------------------------------------------------------------------------------------------------------

START = """
import os, signal, sys, threading
delay = float(sys.argv[1])
sys.argv = ["pneunet-grasp", *sys.argv[2:]]
threading.Timer(delay, os.kill, (os.getpid(), signal.SIGINT)).start()
from pneunet_env.cli import main
sys.exit(main())
"""


@pytest.mark.parametrize("command", [["demo", "--objects", "2"], ["design", "--trials", "1", "--objects", "2",
                                                                    "--out", "o"]])
def test_ctrl_c_while_the_command_line_starts_ends_in_its_one_line(tmp_path, command):
    """The console script's own two lines (``from pneunet_env.cli import main``; ``sys.exit(main())``), a SIGINT
    50 ms in (importing the package) and 400 ms in (the package or the command's module): one line, status 130."""
    env = {**os.environ, "PYTHONPATH": str(ROOT) + os.pathsep + os.environ.get("PYTHONPATH", ""), "MPLBACKEND": "Agg"}
    env.pop("PNEUNET_DEBUG", None)
    for delay in ("0.05", "0.4"):
        proc = subprocess.run([sys.executable, "-c", START, delay, *command], cwd=tmp_path, env=env,
                              capture_output=True, text=True, timeout=120,
                              preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL))
        lines = [line for line in proc.stderr.splitlines() if line.strip()]
        assert proc.returncode == 130 and lines == [f"pneunet-grasp {command[0]}: interrupted"], (delay, proc.stderr)


def test_the_start_up_handler_is_only_the_command_lines(monkeypatch):
    from pneunet_env import files

    monkeypatch.setattr(sys, "argv", ["myscript.py"])
    monkeypatch.setattr(sys, "orig_argv", ["python", "myscript.py"])
    assert not files._is_command_line()
    monkeypatch.setattr(sys, "argv", ["/usr/bin/pneunet-grasp", "demo"])
    assert files._is_command_line()
    monkeypatch.setattr(sys, "argv", ["-m", "demo"])
    monkeypatch.setattr(sys, "orig_argv", ["python", "-m", "pneunet_env.cli", "demo"])
    assert files._is_command_line()
    hook = sys.excepthook
    monkeypatch.setattr(sys, "argv", ["pytest"])
    monkeypatch.setattr(sys, "orig_argv", ["python", "-m", "pytest"])
    files.command_line_interrupts()
    assert sys.excepthook is hook  # a library import, a test: untouched


def test_python_m_agents_design_ends_a_ctrl_c_with_one_line_and_130(monkeypatch, capsys):
    from agents.design import cli

    def interrupted(args):
        raise KeyboardInterrupt("(trial 4 marked failed): the same command retries and goes on")

    monkeypatch.setattr(cli, "run", interrupted)
    assert cli.main(["--trials", "2"]) == 130
    assert capsys.readouterr().err == ("pneunet-grasp design: interrupted (trial 4 marked failed): the same command "
                                       "retries and goes on\n")
