"""A resumable results store of sweep jobs on SQLite.

One row per job, keyed by the job's identity (system, variant, method, noise target, SNR,
realisation, preset, the canonical JSON of its remaining settings, and a free tag) under a
UNIQUE constraint. Each row is written in its own transaction (``INSERT OR REPLACE``) in WAL
mode with ``synchronous=FULL``: a process killed at any moment leaves every finished row in
place and never a duplicate, so a sweep resumes by skipping :meth:`ResultsStore.completed_keys`.

Examples
--------
>>> import tempfile, os
>>> path = os.path.join(tempfile.mkdtemp(), "results.sqlite")
>>> store = ResultsStore(path)
>>> store.write({"system": "duffing", "variant": "paper", "method": "parametric", "noise_on": "force",
...              "snr_db": 20.0, "realization": 0, "preset": "default", "status": "ok", "rmse_f1": 1e-3})
>>> len(store), store.to_dataframe()["rmse_f1"].tolist()
(1, [0.001])
>>> store.close()
"""

from __future__ import annotations

import datetime as _dt
import json
import math
import os
import sqlite3
import threading
from collections.abc import Iterable, Mapping
from typing import Any

from .._errors import ConfigError

__all__ = ["ResultsStore", "KEY_COLUMNS", "VALUE_COLUMNS", "SCHEMA_VERSION", "job_key"]

SCHEMA_VERSION = 1
#: Columns that identify a job (UNIQUE together).
KEY_COLUMNS = ("system", "variant", "method", "noise_on", "snr_db", "realization", "preset", "config", "tag")
#: Result columns (besides ``extra``, a JSON blob).
VALUE_COLUMNS = (
    "eta", "noise_seed", "fit_seed",
    "rmse_f1", "rmse_f2", "gain", "loss",
    "t_sep_mean", "rmse_x_mean", "n_cases", "n_failed_cases", "n_censored",
    "status", "error", "seconds", "started_at", "finished_at", "host", "pid",
)
_TYPES = {
    "system": "TEXT NOT NULL", "variant": "TEXT NOT NULL", "method": "TEXT NOT NULL",
    "noise_on": "TEXT NOT NULL", "snr_db": "REAL NOT NULL", "realization": "INTEGER NOT NULL",
    "preset": "TEXT NOT NULL", "config": "TEXT NOT NULL DEFAULT '{}'", "tag": "TEXT NOT NULL DEFAULT ''",
    "eta": "REAL", "noise_seed": "INTEGER", "fit_seed": "INTEGER",
    "rmse_f1": "REAL", "rmse_f2": "REAL", "gain": "REAL", "loss": "REAL",
    "t_sep_mean": "REAL", "rmse_x_mean": "REAL", "n_cases": "INTEGER", "n_failed_cases": "INTEGER",
    "n_censored": "INTEGER",
    "status": "TEXT NOT NULL CHECK (status IN ('ok', 'failed'))", "error": "TEXT", "seconds": "REAL",
    "started_at": "TEXT", "finished_at": "TEXT", "host": "TEXT", "pid": "INTEGER",
}
_KEY_DEFAULTS = {"config": "{}", "tag": ""}


def _now() -> str:
    return _dt.datetime.now(_dt.timezone.utc).isoformat(timespec="milliseconds")


def _jsonable(obj: Any) -> Any:
    """Plain JSON types; non-finite floats become strings ("nan", "inf") so the blob stays valid JSON."""
    np: Any
    try:
        import numpy as np
    except ImportError:  # pragma: no cover
        np = None
    if isinstance(obj, Mapping):
        return {str(k): _jsonable(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple, set)):
        return [_jsonable(v) for v in obj]
    if np is not None:
        if isinstance(obj, np.ndarray):
            return _jsonable(obj.tolist())
        if isinstance(obj, np.generic):
            return _jsonable(obj.item())
    if isinstance(obj, float):
        return obj if math.isfinite(obj) else str(obj)
    if obj is None or isinstance(obj, (str, int, bool)):
        return obj
    return str(obj)


def job_key(row: Mapping[str, Any]) -> tuple:
    """The identity tuple of a row or job mapping, in :data:`KEY_COLUMNS` order.

    Examples
    --------
    >>> from charcurves.experiments import job_key
    >>> job_key({"system": "duffing", "variant": "paper", "method": "parametric", "noise_on": "force", "snr_db": 20,
    ...          "realization": 0, "preset": "default"})
    ('duffing', 'paper', 'parametric', 'force', 20.0, 0, 'default', '{}', '')
    """
    out = []
    for c in KEY_COLUMNS:
        v = row.get(c, _KEY_DEFAULTS.get(c))
        if v is None:
            raise ConfigError(f"a results row needs {c!r}")
        if c == "snr_db":
            v = float(v)
        elif c == "realization":
            v = int(v)
        else:
            v = str(v)
        out.append(v)
    return tuple(out)


class ResultsStore:
    """SQLite file of job results (one row per job, resumable).

    Parameters
    ----------
    path : str or PathLike
        The database file; created with its schema when missing.
    timeout : float
        Seconds to wait for a lock held by another connection.

    Notes
    -----
    Write from one process (the sweep's driver); any number of readers may open the file
    meanwhile. NaN values are stored as NULL and read back as NaN/None.

    Examples
    --------
    >>> import os, tempfile
    >>> from charcurves.experiments import ResultsStore
    >>> store = ResultsStore(os.path.join(tempfile.mkdtemp(), "results.sqlite"))
    >>> store.write({"system": "duffing", "variant": "paper", "method": "parametric", "noise_on": "force",
    ...              "snr_db": 20.0, "realization": 0, "preset": "default", "status": "ok", "rmse_f1": 1e-3})
    >>> len(store), store.to_dataframe()["rmse_f1"].tolist()
    (1, [0.001])
    >>> store.close()
    """

    def __init__(self, path: str | os.PathLike, *, timeout: float = 60.0):
        self.path = os.fspath(path)
        d = os.path.dirname(os.path.abspath(self.path))
        os.makedirs(d, exist_ok=True)
        self._lock = threading.Lock()
        self._con = sqlite3.connect(self.path, timeout=timeout, isolation_level=None, check_same_thread=False)
        try:
            self._refuse_foreign()
            self._con.execute("PRAGMA journal_mode=WAL")
            self._con.execute("PRAGMA synchronous=FULL")
            self._con.execute(f"PRAGMA busy_timeout={int(timeout * 1000)}")
            self._create()
        except sqlite3.DatabaseError as exc:  # not SQLite at all, or a damaged file (issue 50)
            self._con.close()
            raise ConfigError(f"{self.path!r} is not a charcurves results store ({exc}); move it away or give "
                              "another output folder") from None
        except BaseException:
            self._con.close()
            raise

    def _refuse_foreign(self) -> None:
        """A SQLite file of someone else's (other tables, or a ``results`` table without our ``meta``)
        is refused rather than written into."""
        tables = {r[0] for r in self._con.execute("SELECT name FROM sqlite_master WHERE type = 'table'")}
        if not tables:
            return
        ours = "meta" in tables and "results" in tables and self._con.execute(
            "SELECT value FROM meta WHERE key = 'schema_version'").fetchone() is not None
        if not ours:
            shown = ", ".join(sorted(tables)[:5]) + (" ..." if len(tables) > 5 else "")
            raise ConfigError(f"{self.path!r} is a SQLite file but not a charcurves results store (its tables: "
                              f"{shown}); move it away or give another output folder")

    # ------------------------------------------------------------------ schema
    def _create(self) -> None:
        cols = ",\n  ".join(f"{c} {_TYPES[c]}" for c in KEY_COLUMNS + VALUE_COLUMNS)
        with self._lock:
            self._con.execute("BEGIN IMMEDIATE")
            try:
                self._con.execute(
                    f"CREATE TABLE IF NOT EXISTS results (\n  id INTEGER PRIMARY KEY,\n  {cols},\n"
                    f"  extra TEXT NOT NULL DEFAULT '{{}}',\n  UNIQUE ({', '.join(KEY_COLUMNS)})\n)"
                )
                self._con.execute("CREATE TABLE IF NOT EXISTS meta (key TEXT PRIMARY KEY, value TEXT)")
                self._con.execute(
                    "CREATE TABLE IF NOT EXISTS runs "
                    "(id INTEGER PRIMARY KEY, started_at TEXT, sweep TEXT, settings TEXT, host TEXT)"
                )
                self._con.execute("INSERT OR IGNORE INTO meta VALUES ('schema_version', ?)", (str(SCHEMA_VERSION),))
                self._con.execute("COMMIT")
            except BaseException:
                self._con.execute("ROLLBACK")
                raise
        (version,) = self._con.execute("SELECT value FROM meta WHERE key = 'schema_version'").fetchone()
        if int(version) != SCHEMA_VERSION:
            raise ConfigError(f"{self.path!r} has results schema {version}, this charcurves writes {SCHEMA_VERSION}; "
                              "use a new store file")

    # ------------------------------------------------------------------ writing
    def write(self, row: Mapping[str, Any]) -> None:
        """Insert (or replace) one job's row in a single transaction."""
        self.write_many([row])

    def write_many(self, rows: Iterable[Mapping[str, Any]]) -> None:
        """Insert (or replace) rows; each row is its own transaction, committed before the next."""
        names = KEY_COLUMNS + VALUE_COLUMNS + ("extra",)
        sql = f"INSERT OR REPLACE INTO results ({', '.join(names)}) VALUES ({', '.join('?' * len(names))})"
        for row in rows:
            key = job_key(row)
            status = row.get("status")
            if status not in ("ok", "failed"):
                raise ConfigError(f"status must be 'ok' or 'failed', got {status!r}")
            values = list(key)
            for c in VALUE_COLUMNS:
                v: Any = row.get(c)
                if hasattr(v, "item"):
                    v = v.item()
                if isinstance(v, float) and math.isnan(v):
                    v = None
                values.append(v)
            values.append(json.dumps(_jsonable(row.get("extra") or {}), sort_keys=True))
            with self._lock:
                self._con.execute("BEGIN IMMEDIATE")
                try:
                    self._con.execute(sql, values)
                    self._con.execute("COMMIT")
                except BaseException:
                    self._con.execute("ROLLBACK")
                    raise

    def log_run(self, sweep: Mapping[str, Any], settings: Mapping[str, Any]) -> None:
        """Record that a sweep (re)started, for provenance."""
        import socket

        with self._lock:
            self._con.execute("INSERT INTO runs (started_at, sweep, settings, host) VALUES (?, ?, ?, ?)",
                              (_now(), json.dumps(_jsonable(sweep), sort_keys=True),
                               json.dumps(_jsonable(settings), sort_keys=True), socket.gethostname()))

    def delete(self, key: tuple | Mapping[str, Any]) -> int:
        """Delete the row of one job (a key tuple or a mapping with the key columns); returns rows deleted."""
        k = job_key(key) if isinstance(key, Mapping) else tuple(key)
        where = " AND ".join(f"{c} = ?" for c in KEY_COLUMNS)
        with self._lock:
            cur = self._con.execute(f"DELETE FROM results WHERE {where}", k)
        return cur.rowcount

    # ------------------------------------------------------------------ reading
    def completed_keys(self, status: str | Iterable[str] | None = None) -> set[tuple]:
        """Key tuples (:data:`KEY_COLUMNS` order) of the stored jobs, optionally of one status."""
        sql = f"SELECT {', '.join(KEY_COLUMNS)} FROM results"
        args: tuple = ()
        if status is not None:
            st = [status] if isinstance(status, str) else list(status)
            sql += f" WHERE status IN ({', '.join('?' * len(st))})"
            args = tuple(st)
        return {(s, va, m, n, float(snr), int(r), p, c, t)
                for s, va, m, n, snr, r, p, c, t in self._con.execute(sql, args)}

    def rows(self) -> list[dict[str, Any]]:
        """All rows as dicts (``extra`` decoded)."""
        cur = self._con.execute("SELECT * FROM results ORDER BY id")
        names = [d[0] for d in cur.description]
        out = []
        for values in cur.fetchall():
            r = dict(zip(names, values))
            r["extra"] = json.loads(r["extra"]) if r.get("extra") else {}
            out.append(r)
        return out

    def __len__(self) -> int:
        return int(self._con.execute("SELECT COUNT(*) FROM results").fetchone()[0])

    def count(self, status: str | None = None) -> int:
        if status is None:
            return len(self)
        return int(self._con.execute("SELECT COUNT(*) FROM results WHERE status = ?", (status,)).fetchone()[0])

    def to_dataframe(self, *, extra: bool = False):
        """A pandas DataFrame of the rows (``extra`` as a JSON string column when asked)."""
        import pandas as pd

        cols = ("id",) + KEY_COLUMNS + VALUE_COLUMNS + (("extra",) if extra else ())
        cur = self._con.execute(f"SELECT {', '.join(cols)} FROM results ORDER BY id")
        df = pd.DataFrame(cur.fetchall(), columns=list(cols))
        for c in ("snr_db", "eta", "rmse_f1", "rmse_f2", "gain", "loss", "t_sep_mean", "rmse_x_mean", "seconds"):
            df[c] = pd.to_numeric(df[c], errors="coerce").astype(float)
        return df

    def to_csv(self, path: str | os.PathLike, *, extra: bool = False) -> None:
        """Write :meth:`to_dataframe` to a CSV file atomically (temp file + rename)."""
        from ..io import atomic_write_bytes

        df = self.to_dataframe(extra=extra)
        atomic_write_bytes(path, df.to_csv(index=False).encode("utf-8"))

    def close(self) -> None:
        with self._lock:
            self._con.close()

    def __enter__(self) -> ResultsStore:
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    def __repr__(self) -> str:
        return f"ResultsStore({self.path!r}, rows={len(self)})"
