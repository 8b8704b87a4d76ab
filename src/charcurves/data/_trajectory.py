"""Measured trajectories: validated samples of time, state and forcing."""

from __future__ import annotations

import dataclasses
import os
from collections.abc import Mapping
from typing import Any

import numpy as np

from .._errors import DataError

__all__ = ["Trajectory", "MIN_SAMPLES"]

#: Fewest samples any fitting method accepts (a degree-10 polynomial per curve needs 22).
MIN_SAMPLES = 30


def _as_column(name: str, values: Any, n: int | None) -> np.ndarray:
    try:
        arr = np.array(values, dtype=float)  # a private copy: freezing it must not touch the caller's
    except (TypeError, ValueError) as exc:
        raise DataError(
            f"column {name!r} is not numeric ({exc}); give numbers only, e.g. clean the column first"
        ) from None
    if arr.ndim == 2 and 1 in arr.shape:
        arr = arr.reshape(-1)
    if arr.ndim != 1:
        raise DataError(
            f"column {name!r} must be one-dimensional, got shape {arr.shape}; "
            "give a single column of numbers (check for duplicated column names)"
        )
    if n is not None and arr.shape[0] != n:
        raise DataError(
            f"column {name!r} has {arr.shape[0]} samples but 't' has {n}; give columns of equal length"
        )
    bad = ~np.isfinite(arr)
    if bad.any():
        row = int(np.flatnonzero(bad)[0])
        kind = "a NaN" if np.isnan(arr[row]) else "an infinite"
        raise DataError(
            f"column {name!r} has {kind} value at row {row} ({int(bad.sum())} non-finite in all); "
            "remove or interpolate those rows (e.g. --rows to select a clean span)"
        )
    return arr


@dataclasses.dataclass(frozen=True, eq=False)
class Trajectory:
    """A measured (or simulated) record of a forced one-degree-of-freedom system.

    Parameters
    ----------
    t : array (N,)
        Strictly increasing sample times.
    x : array (N,)
        The state (displacement).
    F : array (N,)
        The measured forcing (input).
    v, a : array (N,), optional
        Given first and second derivatives of ``x``; used as they are when present.
    name : str
        A label used in reports.

    Examples
    --------
    >>> import numpy as np
    >>> t = np.linspace(0, 10, 200)
    >>> tr = Trajectory(t=t, x=np.sin(t), F=np.cos(t))
    >>> tr.n_samples, round(tr.dt, 4)
    (200, 0.0503)
    """

    t: np.ndarray
    x: np.ndarray
    F: np.ndarray
    v: np.ndarray | None = None
    a: np.ndarray | None = None
    name: str = "trajectory"

    def __post_init__(self) -> None:
        t = _as_column("t", self.t, None)
        n = t.shape[0]
        if n < 2:
            raise DataError(f"a trajectory needs at least 2 samples, got {n}; give a longer record")
        cols = {"t": t}
        for key in ("x", "F", "v", "a"):
            val = getattr(self, key)
            if val is not None:
                cols[key] = _as_column(key, val, n)
        steps = np.diff(t)
        if (steps <= 0).any():
            row = int(np.flatnonzero(steps <= 0)[0]) + 1
            what = "repeats" if steps[row - 1] == 0 else "goes back"
            raise DataError(
                f"time {what} at row {row} (t={t[row]:.6g} after {t[row - 1]:.6g}); "
                "time stamps must be strictly increasing: sort the rows and drop duplicates"
            )
        for key, arr in cols.items():
            arr.setflags(write=False)
            object.__setattr__(self, key, arr)

    # ------------------------------------------------------------------ construction
    @classmethod
    def from_arrays(cls, t, x, F, v=None, a=None, name: str = "trajectory") -> Trajectory:
        """Build from arrays (same as the constructor; kept for symmetry with the readers)."""
        return cls(t=t, x=x, F=F, v=v, a=a, name=name)

    @classmethod
    def from_dataframe(
        cls,
        df,
        *,
        time_col: str | None = "t",
        x_col: str = "x",
        force_col: str = "F",
        v_col: str | None = "v",
        a_col: str | None = "a",
        sample_rate: float | None = None,
        rows: slice | None = None,
        name: str = "trajectory",
    ) -> Trajectory:
        """Build from a pandas DataFrame (or any mapping of column name to values).

        ``v_col``/``a_col`` are used when those columns exist. Without a time column give
        ``sample_rate`` (Hz): times are then ``row / sample_rate``.
        """
        columns = list(df.keys()) if isinstance(df, Mapping) else list(df.columns)

        def need(col: str, what: str) -> np.ndarray:
            if col not in columns:
                close = [c for c in columns if str(c).lower() == col.lower()]
                hint = f" (did you mean {close[0]!r}?)" if close else ""
                raise DataError(
                    f"no column {col!r} for {what}{hint}; the file has {columns}; "
                    f"name the right one with --{what}-col"
                )
            return np.asarray(df[col])

        x = need(x_col, "x")
        F = need(force_col, "force")
        n_all = len(x)
        if time_col is not None and time_col in columns and sample_rate is None:
            t = need(time_col, "time")
        elif sample_rate is not None:
            try:
                rate = float(sample_rate)
            except (TypeError, ValueError):
                rate = float("nan")
            if not (np.isfinite(rate) and rate > 0):
                raise DataError(
                    f"sample rate must be a positive number of Hz, got {sample_rate!r}; "
                    "give it as e.g. --sample-rate 1000"
                )
            t = np.arange(n_all) / rate
        else:
            raise DataError(
                f"no time column {time_col!r} in {columns}; name it with --time-col "
                "or give --sample-rate HZ"
            )
        v = np.asarray(df[v_col]) if v_col and v_col in columns else None
        a = np.asarray(df[a_col]) if a_col and a_col in columns else None
        if rows is not None:
            start, stop, _ = rows.indices(n_all)
            if stop - start < 2:
                raise DataError(
                    f"rows {rows.start}:{rows.stop} select {max(stop - start, 0)} of {n_all} rows; "
                    "choose a wider START:STOP"
                )
            t, x, F = t[rows], x[rows], F[rows]
            v = v[rows] if v is not None else None
            a = a[rows] if a is not None else None
        return cls(t=t, x=x, F=F, v=v, a=a, name=name)

    @classmethod
    def from_csv(cls, path: str | os.PathLike, **kwargs: Any) -> Trajectory:
        """Read a CSV file with a header row; keyword arguments as in :meth:`from_dataframe`."""
        from ..io._csv import read_csv_columns

        columns = read_csv_columns(path)
        kwargs.setdefault("name", os.path.splitext(os.path.basename(os.fspath(path)))[0])
        return cls.from_dataframe(columns, **kwargs)

    # ------------------------------------------------------------------ properties
    @property
    def n_samples(self) -> int:
        return int(self.t.shape[0])

    @property
    def dt(self) -> float:
        """Median sampling step."""
        return float(np.median(np.diff(self.t)))

    @property
    def duration(self) -> float:
        return float(self.t[-1] - self.t[0])

    @property
    def has_derivatives(self) -> bool:
        return self.v is not None and self.a is not None

    def sampling_nonuniformity(self) -> float:
        """Largest relative deviation of a time step from the median step."""
        steps = np.diff(self.t)
        return float(np.max(np.abs(steps - self.dt)) / self.dt)

    def require_uniform(self, what: str, tol: float = 1e-3) -> None:
        """Raise :class:`DataError` unless the sampling is uniform within ``tol`` (relative)."""
        dev = self.sampling_nonuniformity()
        if dev > tol:
            steps = np.diff(self.t)
            row = int(np.argmax(np.abs(steps - self.dt))) + 1
            raise DataError(
                f"{what} needs uniform sampling, but the time step at row {row} differs from the "
                f"median step by {100 * dev:.3g} %; resample the record onto a uniform grid "
                "or use --derivatives spline"
            )

    def require_samples(self, n_min: int, what: str) -> None:
        if self.n_samples < n_min:
            raise DataError(
                f"{what} needs at least {n_min} samples, the record has {self.n_samples}; "
                "give a longer record"
            )

    def replace(self, **changes: Any) -> Trajectory:
        return dataclasses.replace(self, **changes)

    def slice(self, rows: slice) -> Trajectory:
        """Rows ``rows`` of the record (derivatives sliced alongside)."""
        return self.replace(
            t=self.t[rows],
            x=self.x[rows],
            F=self.F[rows],
            v=None if self.v is None else self.v[rows],
            a=None if self.a is None else self.a[rows],
        )

    def to_columns(self) -> dict[str, np.ndarray]:
        cols = {"t": self.t, "x": self.x}
        if self.v is not None:
            cols["v"] = self.v
        if self.a is not None:
            cols["a"] = self.a
        cols["F"] = self.F
        return cols

    def to_csv(self, path: str | os.PathLike) -> None:
        """Write ``t,x[,v][,a],F`` with a header (atomically)."""
        from ..io._csv import write_csv_columns

        write_csv_columns(path, self.to_columns())
