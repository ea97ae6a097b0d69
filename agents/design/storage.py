"""The design study's storage: an Optuna storage named by ``--storage`` (an RDB URL, ``journal:PATH``) or the
output folder's SQLite file, checked before any work (:func:`check_storage`) and opened with a time-out
(:func:`make_storage`); and Optuna itself, imported when a study runs (:func:`_optuna`).
"""

from __future__ import annotations

import contextlib
import json
import os
import threading
import warnings
from pathlib import Path
from typing import Any


@contextlib.contextmanager
def _knowingly():
    """Optuna's notes on what this module uses on purpose, silenced for the calls inside: the ``ExperimentalWarning``
    of the multivariate TPE's ``group`` and of ``set_metric_names`` (features used as they are), and PED-ANOVA's
    note that it looks for low ``target`` values (:func:`_importance`'s target is the negated score, for that)."""
    optuna = _optuna()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", optuna.exceptions.ExperimentalWarning)
        warnings.filterwarnings("ignore", message=r".*low `target` values")
        yield


def _optuna():
    try:
        import optuna
    except ImportError:
        raise ValueError("pneunet-grasp design needs optuna: pip install -e '.[design]'") from None
    optuna.logging.set_verbosity(optuna.logging.WARNING)
    return optuna


STORAGE_TIMEOUT_S = 10.0
"""How long an RDB server may take to answer before ``--storage URL`` is refused (seconds)."""


_RDB_SCHEMES = ("sqlite", "postgresql", "mysql", "oracle", "mssql")


_CONNECT_TIMEOUT = {"postgresql": "connect_timeout", "mysql": "connect_timeout"}
"""The drivers' own connection time-out argument, by dialect (seconds)."""


def _check_file(path: Path, name: str, what: str, is_kind) -> None:
    """Refuse ``path`` (``ValueError`` naming ``name``) unless it is ``what`` (``is_kind(path)`` of a non-empty file),
    or a new or empty file in a writable folder. Reads only: a refused file is left as it was, byte for byte."""
    if path.is_dir():
        raise ValueError(f"{name}: {str(path)!r} is a folder, not {what}")
    folder = path.parent
    if not folder.is_dir():
        raise ValueError(f"{name}: the folder {str(folder)!r} does not exist" if not folder.exists() else
                         f"{name}: {str(folder)!r} is not a folder")
    if not path.exists():
        if not os.access(folder, os.W_OK | os.X_OK):
            raise ValueError(f"{name}: cannot create {str(path)!r}: the folder is not writable")
        return
    if not path.is_file():
        raise ValueError(f"{name}: {str(path)!r} is not a regular file (a device, a pipe or a socket), not {what}")
    if not os.access(path, os.R_OK | os.W_OK):
        raise ValueError(f"{name}: {str(path)!r} cannot be both read and written")
    if path.stat().st_size and not is_kind(path):
        raise ValueError(f"{name}: {str(path)!r} is not {what}; it is left as it is: name a new or empty file, or "
                         f"{what}")


def _is_journal(path: Path) -> bool:
    """Whether ``path``'s first line is an Optuna journal record (a JSON object with an ``op_code``)."""
    try:
        with open(path, "rb") as fh:
            line = fh.readline(1 << 20)
        record = json.loads(line)
    except (OSError, ValueError):
        return False
    return isinstance(record, dict) and isinstance(record.get("op_code"), int)


def _is_optuna_sqlite(path: Path) -> bool:
    """Whether ``path`` is an SQLite database with Optuna's tables, or with none (read-only: nothing is written)."""
    import sqlite3

    try:
        with open(path, "rb") as fh:
            if fh.read(16) != b"SQLite format 3\x00":
                return False
        con = sqlite3.connect(f"{path.resolve().as_uri()}?mode=ro", uri=True)
        try:
            tables = {row[0] for row in con.execute("SELECT name FROM sqlite_master WHERE type = 'table'")}
        finally:
            con.close()
    except (OSError, sqlite3.Error):
        return False
    return not tables or {"studies", "version_info"} <= tables


def check_storage(storage: str | None, out: Path) -> None:
    """Refuse a storage the study must not write to, before anything is written (``ValueError`` naming it).

    ``journal:PATH`` must be an Optuna journal, or a new or empty file in a writable folder: a folder, a device
    (``/dev/null``), a missing folder or a file of another kind (a text file) is refused, and left as it was.
    ``sqlite:///PATH`` (and the default ``OUT/study.db``) the same, for an SQLite database with Optuna's tables (a
    database of something else is refused too: the study would add its tables to it). Other RDB URLs are checked
    when they are opened (:func:`make_storage`)."""
    if storage is None:
        path = out / "study.db"
        if path.exists() or path.is_symlink():
            _check_file(path, f"--out {str(out)!r}", "an SQLite database of Optuna", _is_optuna_sqlite)
        return
    name = f"--storage {storage!r}"
    if storage.startswith("journal:"):
        text = storage[len("journal:"):]
        if not text:
            raise ValueError(f"{name}: journal: needs a file path")
        _check_file(Path(text), name, "an Optuna journal", _is_journal)
    elif storage.split(":", 1)[0].split("+")[0] == "sqlite":
        from sqlalchemy.engine import make_url
        from sqlalchemy.exc import ArgumentError

        try:
            database = make_url(storage).database
        except ArgumentError as exc:
            raise ValueError(f"{name} is not a valid URL ({exc})") from None
        if database and database != ":memory:" and not database.startswith("file:"):
            _check_file(Path(database), name, "an SQLite database of Optuna", _is_optuna_sqlite)


def _open_rdb(optuna, storage: str):
    """``RDBStorage(storage)``, or a ``ValueError`` naming the URL if it fails or takes more than
    :data:`STORAGE_TIMEOUT_S` (the driver's own connection time-out set where the dialect has one; the opening runs in
    a daemon thread, so that a server that never answers does not hold the command)."""
    dialect = storage.split("://", 1)[0].split("+")[0]
    kwargs: dict[str, Any] = {}
    if dialect in _CONNECT_TIMEOUT:
        kwargs["engine_kwargs"] = {"connect_args": {_CONNECT_TIMEOUT[dialect]: int(STORAGE_TIMEOUT_S)}}
    result: list[Any] = []

    def opening() -> None:
        try:
            with _knowingly():  # the heartbeat's ExperimentalWarning: used as it is
                result.append(optuna.storages.RDBStorage(storage, heartbeat_interval=60, grace_period=120, **kwargs))
        except BaseException as exc:  # a driver missing, a bad URL, a server that refuses: named below
            result.append(exc)

    thread = threading.Thread(target=opening, name="open --storage", daemon=True)
    thread.start()
    thread.join(STORAGE_TIMEOUT_S)
    if not result:
        raise ValueError(f"--storage {storage!r}: no answer within {STORAGE_TIMEOUT_S:g} s (is the server running "
                         "and reachable?)")
    if isinstance(result[0], BaseException):
        exc = result[0]
        raise ValueError(f"--storage {storage!r}: cannot open it ({type(exc).__name__}: {exc})") from None
    return result[0]


def make_storage(storage: str | None, out: Path):
    """The study's storage: ``None`` -> a SQLite file ``out/study.db``; ``journal:PATH`` -> an Optuna journal file
    (one file several processes append to); any other string -> an Optuna RDB URL (``sqlite:///...``,
    ``postgresql://...``, ``mysql://...``), which workers on several machines can share. Each is checked first
    (:func:`check_storage`: nothing is written to a storage that is refused); an RDB server that does not answer
    within :data:`STORAGE_TIMEOUT_S` is refused by name."""
    optuna = _optuna()
    if storage is not None and (not isinstance(storage, str) or not storage.strip()):
        raise ValueError(f"--storage must be an Optuna storage URL or journal:PATH, got {storage!r}")
    check_storage(storage, out)
    if storage is None:
        return f"sqlite:///{(out / 'study.db').resolve()}"
    if storage.startswith("journal:"):
        from optuna.storages.journal import JournalFileBackend

        return optuna.storages.JournalStorage(JournalFileBackend(storage[len("journal:"):]))
    scheme = storage.split("://", 1)[0] if "://" in storage else ""
    if not scheme or scheme.split("+")[0] not in _RDB_SCHEMES:
        raise ValueError(f"--storage {storage!r} is not an RDB URL (sqlite:///PATH, postgresql://..., mysql://...) "
                         "or journal:PATH")
    return _open_rdb(optuna, storage)
