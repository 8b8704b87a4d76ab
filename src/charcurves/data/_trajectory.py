"""Measured trajectories: validated samples of time, state and forcing."""

from __future__ import annotations

import dataclasses
import os
from collections.abc import Mapping
from typing import Any, cast

import numpy as np

from .._errors import ConfigError, DataError
from ._quality import (check_offset, check_rows, check_time_step, gap_warnings, offset_warnings, signal_warnings,
                       time_unit_warnings)

__all__ = ["Trajectory", "MultiTrajectory", "MIN_SAMPLES", "MAX_MAGNITUDE"]

#: Fewest samples any fitting method accepts (a degree-10 polynomial per curve needs 22).
MIN_SAMPLES = 30
#: Largest magnitude of a recorded value: the fits square and cube the data (losses, variances,
#: cubic bases), which overflows float64 near 1e103 and above; rescale larger data (change units).
MAX_MAGNITUDE = 1e100


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
    big = np.abs(arr) > MAX_MAGNITUDE
    if big.any():
        row = int(np.flatnonzero(big)[0])
        raise DataError(
            f"column {name!r} has the value {arr[row]:.6g} at row {row}, beyond the {MAX_MAGNITUDE:g} in magnitude "
            "that charcurves computes with (its squares and cubes would overflow); rescale the column, "
            "e.g. change its units"
        )
    return arr


def _closest_column(wanted: str, columns: list) -> str | None:
    """The column name most like ``wanted`` (case first, then spelling), or None if none is close."""
    import difflib

    same_case = [c for c in columns if str(c).lower() == wanted.lower()]
    if same_case:
        return same_case[0]
    lowered = {str(c).lower(): c for c in columns}
    close = difflib.get_close_matches(wanted.lower(), list(lowered), n=1, cutoff=0.5)
    if close:
        return lowered[close[0]]
    prefixed = [c for c in columns if str(c).lower().startswith(wanted.lower())]  # "t" -> "time"
    return prefixed[0] if prefixed else None


class _SampledRecord:
    """What every record with a time axis ``t`` offers (one- and multi-DOF alike)."""

    t: np.ndarray

    @property
    def n_samples(self) -> int:
        return int(self.t.shape[0])

    @property
    def dt(self) -> float:
        """Median sampling step."""
        return float(np.median(np.diff(self.t)))

    def require_samples(self, n_min: int, what: str) -> None:
        if self.n_samples < n_min:
            raise DataError(
                f"{what} needs at least {n_min} samples, the record has {self.n_samples}; "
                "give a longer record"
            )

    def replace(self, **changes: Any):
        return dataclasses.replace(cast(Any, self), **changes)  # the subclasses are dataclasses

    def _gap_warnings(self) -> list[str]:
        return gap_warnings(self.t) + time_unit_warnings(self.t)


@dataclasses.dataclass(frozen=True, eq=False)
class Trajectory(_SampledRecord):
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
    >>> from charcurves.data import Trajectory
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
        check_time_step(t)
        for key in ("x", "F"):  # a forcing of 1e9 plus a small motion loses its digits like x does
            if key in cols:
                check_offset(key, cols[key])
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
                close = _closest_column(col, columns)
                hint = f" (did you mean {close!r}?)" if close is not None else ""
                raise DataError(
                    f"no column {col!r} for {what}{hint}; the file has {columns}; "
                    f"name the right one with --{what}-col"
                )
            return np.asarray(df[col])

        if x_col == force_col:
            raise DataError(
                f"x and F are both read from column {x_col!r}; name the forcing with --force-col "
                "(and the state with --x-col)"
            )
        x = need(x_col, "x")
        F = need(force_col, "force")
        n_all = len(x)
        if sample_rate is not None and time_col is not None and time_col in columns:
            raise DataError(
                f"the file has a time column {time_col!r} and a sample rate was given too; drop --sample-rate "
                "to use the file's times, or pass --time-col none (time_col=None) to ignore the column"
            )
        if time_col is not None and time_col in columns:
            t = need(time_col, "time")
        elif sample_rate is not None:
            from .._bounds import check_number

            try:
                rate = check_number("sample_rate", sample_rate, label="the sample rate (--sample-rate)")
            except ConfigError as exc:
                raise DataError(str(exc)) from None
            t = np.arange(n_all) / rate
        else:
            if time_col is None:
                raise DataError("no times: the time column is ignored (--time-col none) and no sample rate was "
                                "given; give --sample-rate HZ")
            close = _closest_column(str(time_col), columns)
            hint = f" (did you mean {close!r}?)" if close is not None else ""
            raise DataError(
                f"no time column {time_col!r}{hint} in {columns}; name it with --time-col "
                "or give --sample-rate HZ"
            )
        v = np.asarray(df[v_col]) if v_col and v_col in columns else None
        a = np.asarray(df[a_col]) if a_col and a_col in columns else None
        if rows is not None:
            check_rows(rows, n_all)
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
        from ..io import read_csv_columns

        columns = read_csv_columns(path)
        kwargs.setdefault("name", os.path.splitext(os.path.basename(os.fspath(path)))[0])
        return cls.from_dataframe(columns, **kwargs)

    # ------------------------------------------------------------------ properties
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


    def quality_warnings(self) -> list[str]:
        """One-line warnings about a record that can be fitted but looks suspicious: a gap in the
        time stamps (a step more than :data:`GAP_FACTOR` times the median), x that looks like white
        noise (lag-1 autocorrelation below :data:`NOISE_LAG1`), a forcing that is zero everywhere
        (then the fit describes a free response), or x and F with identical values.

        >>> t = np.linspace(0, 10, 200)
        >>> Trajectory(t=t, x=np.sin(t), F=np.cos(t)).quality_warnings()
        []
        """
        out = self._gap_warnings() + signal_warnings("x", self.x) + offset_warnings("x", self.x)
        if not np.any(self.F):
            out.append("the forcing F is zero everywhere: the curves then describe a free response "
                       "(x'' + f1 + f2 = 0); check --force-col if the system was forced")
        elif np.array_equal(self.x, self.F):
            out.append("x and F hold identical values; check --x-col and --force-col")
        return out

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
        from ..io import write_csv_columns

        write_csv_columns(path, self.to_columns())


@dataclasses.dataclass(frozen=True, eq=False)
class MultiTrajectory(_SampledRecord):
    """A record of a forced system with several degrees of freedom (named states and forcings).

    Parameters
    ----------
    t : array (N,)
        Strictly increasing sample times.
    states : dict of str to array (N,)
        Displacements by name, e.g. ``{"x1": ..., "x2": ...}``.
    forces : dict of str to array (N,)
        Measured forcings by name, e.g. ``{"F1": ..., "F2": ...}``.
    velocities, accelerations : dict of str to array (N,), optional
        Given derivatives of every state (keys as in ``states``).
    name : str

    Examples
    --------
    >>> import numpy as np
    >>> from charcurves.data import MultiTrajectory
    >>> t = np.linspace(0, 10, 100)
    >>> tr = MultiTrajectory(t, {"x1": np.sin(t), "x2": np.cos(t)}, {"F1": t * 0, "F2": np.sin(2 * t)})
    >>> tr.n_samples, tr.has_derivatives
    (100, False)
    """

    t: np.ndarray
    states: dict
    forces: dict
    velocities: dict | None = None
    accelerations: dict | None = None
    name: str = "trajectory"

    def __post_init__(self) -> None:
        t = _as_column("t", self.t, None)
        n = t.shape[0]
        if n < 2:
            raise DataError(f"a trajectory needs at least 2 samples, got {n}; give a longer record")
        if (np.diff(t) <= 0).any():
            row = int(np.flatnonzero(np.diff(t) <= 0)[0]) + 1
            raise DataError(f"time does not increase at row {row}; time stamps must be strictly increasing: "
                            "sort the rows and drop duplicates")
        check_time_step(t)
        t.setflags(write=False)
        object.__setattr__(self, "t", t)
        if not self.states or not self.forces:
            raise DataError("a multi-DOF record needs at least one state and one forcing column")

        def freeze(d, what):
            out = {}
            for k, v in d.items():
                arr = _as_column(str(k), v, n)
                arr.setflags(write=False)
                out[str(k)] = arr
            return out

        object.__setattr__(self, "states", freeze(self.states, "state"))
        for k, v in self.states.items():
            check_offset(k, v)
        object.__setattr__(self, "forces", freeze(self.forces, "forcing"))
        for k, v in self.forces.items():
            check_offset(k, v)
        for key in ("velocities", "accelerations"):
            d = getattr(self, key)
            if d is not None:
                missing = sorted(set(self.states) - set(d))
                if missing:
                    raise DataError(f"{key} are missing for {missing}; give them for every state or for none")
                object.__setattr__(self, key, freeze({k: d[k] for k in self.states}, key))

    @classmethod
    def from_columns(cls, columns, *, states=None, forces=None, name: str = "trajectory",
                     time_col: str = "t", rows: slice | None = None) -> "MultiTrajectory":
        """Build from a mapping of column name to values: ``t``, states ``x1, x2, ...``, forcings
        ``F1, F2, ...`` and optional derivatives ``v1, a1, v2, a2, ...`` (velocity and acceleration of
        ``x1``, ``x2``...).

        ``states``/``forces`` name the columns to use; by default every ``x<k>`` and ``F<k>`` column.
        """
        import re

        names = list(columns.keys()) if isinstance(columns, Mapping) else list(columns.columns)
        if time_col not in names:
            raise DataError(f"no time column {time_col!r} in {names}; name it with --time-col")
        states = list(states) if states else [c for c in names if re.fullmatch(r"x\d+", str(c))]
        forces = list(forces) if forces else [c for c in names if re.fullmatch(r"F\d+", str(c))]
        for need, what in ((states, "state"), (forces, "forcing")):
            missing = [c for c in need if c not in names]
            if missing or not need:
                raise DataError(f"no {what} column {missing[0] if missing else ''!r} in {names}; a multi-DOF record has "
                                "columns t,x1,x2,F1,F2 (optionally v1,a1,v2,a2)")
        if rows is not None:
            check_rows(rows, len(np.asarray(columns[time_col])))
        pick = (lambda arr: np.asarray(arr)[rows]) if rows is not None else np.asarray

        def derivs(prefix):
            keys = {s: prefix + s[1:] for s in states}
            have = [s for s, k in keys.items() if k in names]
            if not have:
                return None
            if len(have) != len(states):
                raise DataError(f"derivative columns {[keys[s] for s in have]} are given but "
                                f"{[keys[s] for s in states if s not in have]} are not; give all or none")
            return {s: pick(columns[k]) for s, k in keys.items()}

        return cls(pick(columns[time_col]), {s: pick(columns[s]) for s in states},
                   {f: pick(columns[f]) for f in forces}, derivs("v"), derivs("a"), name)

    @classmethod
    def from_csv(cls, path: str | os.PathLike, **kwargs: Any) -> "MultiTrajectory":
        """Read ``t,x1,x2,F1,F2[,v1,a1,v2,a2]`` (header row; any column order)."""
        from ..io import read_csv_columns

        kwargs.setdefault("name", os.path.splitext(os.path.basename(os.fspath(path)))[0])
        return cls.from_columns(read_csv_columns(path), **kwargs)

    @property
    def has_derivatives(self) -> bool:
        return self.velocities is not None and self.accelerations is not None


    def quality_warnings(self) -> list[str]:
        """As :meth:`Trajectory.quality_warnings`, for every state and forcing."""
        out = self._gap_warnings()
        for name, values in self.states.items():
            out += signal_warnings(name, values) + offset_warnings(name, values)
        if not any(np.any(f) for f in self.forces.values()):
            out.append(f"the forcings {', '.join(self.forces)} are zero everywhere: the curves then describe a free "
                       "response; check the forcing columns if the system was forced")
        return out

    def dof(self, state: str, force: str | None = None) -> Trajectory:
        """One state as a :class:`Trajectory` (with ``force``, or the first forcing, as F)."""
        F = self.forces[force or next(iter(self.forces))]
        return Trajectory(self.t, self.states[state], F,
                          None if self.velocities is None else self.velocities[state],
                          None if self.accelerations is None else self.accelerations[state], name=self.name)

    def to_columns(self) -> dict[str, np.ndarray]:
        cols = {"t": self.t}
        for s, x in self.states.items():
            cols[s] = x
        for s in self.states:
            k = s[1:]
            if self.velocities is not None:
                cols["v" + k] = self.velocities[s]
            if self.accelerations is not None:
                cols["a" + k] = self.accelerations[s]
        cols.update(self.forces)
        return cols

    def to_csv(self, path: str | os.PathLike) -> None:
        """Write ``t,x1,x2,...[,v1,a1,...],F1,F2,...`` with a header (atomically)."""
        from ..io import write_csv_columns

        write_csv_columns(path, self.to_columns())
