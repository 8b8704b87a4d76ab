"""Several records in one fit: the curves, scalars and gain shared, the states per record.

``CharacteristicCurves().fit([rec1, rec2, ...])`` wraps the records in a :class:`RecordSet`. The
pipeline prepares each record on its own (its derivatives estimated from its own samples, so no
derivative is taken across a join) and fits the pooled rows by equation error; output error cuts
each record into its own shooting segments (no segment crosses a record boundary, no continuity
is asked across one), so every record has its own initial and segment states. The curves'
training range is the union of the records'. ``model.info["records"]`` gives each record's
equation-error loss and free-run RMSE.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np

from .._errors import ConfigError, DataError

__all__ = ["RecordSet", "as_record_set", "common_step", "prepare_any", "record_report", "record_segments"]


def _columns_of(rec) -> tuple:
    from ..data import Trajectory

    if isinstance(rec, Trajectory):
        return ("x", "F") + (("v",) if rec.v is not None else ()) + (("a",) if rec.a is not None else ())
    return tuple(sorted(rec.to_columns()))


def as_record_set(records) -> RecordSet:
    """Check a list of records for a joint fit (ConfigError/DataError naming the fix) and wrap it."""
    from ..data import MultiTrajectory, Trajectory

    if isinstance(records, (str, bytes)) or not isinstance(records, Sequence):
        raise ConfigError(f"fit takes a Trajectory or a list of Trajectory records, got {type(records).__name__}")
    records = list(records)
    if not records:
        raise ConfigError("fit got an empty list of records; give at least one Trajectory")
    for k, rec in enumerate(records):
        if not isinstance(rec, (Trajectory, MultiTrajectory)):
            raise ConfigError(f"record {k} of the list is a {type(rec).__name__}, not a Trajectory; build each record "
                              "with Trajectory.from_csv or Trajectory(t=..., x=..., F=...)")
    kinds = {type(r).__name__ for r in records}
    if len(kinds) > 1:
        raise DataError(f"the records mix {' and '.join(sorted(kinds))}; give records of one kind (all one-DOF or "
                        "all multi-DOF)")
    first = _columns_of(records[0])
    for k, rec in enumerate(records[1:], start=1):
        cols = _columns_of(rec)
        if cols != first:
            raise DataError(f"record {k} ({rec.name}) has the columns {', '.join(cols)} but record 0 "
                            f"({records[0].name}) has {', '.join(first)}; give every record the same columns "
                            "(drop or add the derivative columns)")
    return RecordSet(records)


def _join(records, offsets, name: str):
    """One record of the rows of ``records`` one after the other, record k's times shifted by offsets[k]."""
    from ..data import MultiTrajectory, Trajectory

    cols = [r.to_columns() for r in records]
    joined = {c: np.concatenate([np.asarray(col[c], dtype=float) for col in cols]) for c in cols[0]}
    joined["t"] = np.concatenate([np.asarray(r.t, dtype=float) + o for r, o in zip(records, offsets)])
    if isinstance(records[0], Trajectory):
        return Trajectory(t=joined["t"], x=joined["x"], F=joined["F"], v=joined.get("v"), a=joined.get("a"),
                          name=name)
    first = records[0]
    return MultiTrajectory.from_columns(joined, states=list(first.states), forces=list(first.forces), name=name)


class RecordSet:
    """Several records fitted together (one-DOF or multi-DOF alike; every record has the same columns).

    Attributes
    ----------
    records : tuple of Trajectory or MultiTrajectory
    bounds : tuple of (start, stop)
        The rows of each record in :attr:`joined`.
    joined : Trajectory or MultiTrajectory
        The rows one after the other; record k's times shifted so that they follow record k - 1's
        end by one of its steps (only the fit's bookkeeping sees these times).

    Examples
    --------
    >>> from charcurves.fitting import RecordSet
    >>> from charcurves.systems import get_system
    >>> a = get_system("duffing").simulate(t_end=10.0, n_points=251)
    >>> rs = RecordSet([a, a.slice(slice(0, 100))])
    >>> rs.bounds, rs.n_samples
    (((0, 251), (251, 351)), 351)
    """

    def __init__(self, records):
        self.records = tuple(records)
        starts = np.cumsum([0] + [r.n_samples for r in self.records])
        self.bounds = tuple((int(a), int(b)) for a, b in zip(starts[:-1], starts[1:]))
        offsets, end = [], None
        for r in self.records:
            t = np.asarray(r.t, dtype=float)
            offsets.append(0.0 if end is None else end - float(t[0]))
            end = float(t[-1]) + offsets[-1] + (float(np.median(np.diff(t))) if t.size > 1 else 1.0)
        self.offsets = tuple(offsets)
        self.name = "+".join(r.name for r in self.records)
        self.joined = _join(self.records, self.offsets, self.name)

    def __getattr__(self, attr: str) -> Any:
        if attr.startswith("__") or attr in ("records", "bounds", "joined", "offsets", "name"):
            raise AttributeError(attr)
        return getattr(self.joined, attr)

    def __len__(self) -> int:
        return len(self.records)

    def replace(self, **changes) -> RecordSet:
        """A record set whose records have ``changes`` (columns of the joined rows, split back per record)."""
        out = []
        for rec, (a, b) in zip(self.records, self.bounds):
            mine: dict[str, Any] = {}
            for key, value in changes.items():
                if value is None or isinstance(value, str):
                    mine[key] = value
                elif isinstance(value, dict):
                    mine[key] = {k: np.asarray(v)[a:b] for k, v in value.items()}
                else:
                    mine[key] = np.asarray(value)[a:b]
            out.append(rec.replace(**mine))
        return RecordSet(out)

    def prepare(self, structure, sym, diff, what: str, without_prior=None):
        """Each record prepared on its own (derivatives from its own samples), joined: ``(record, estimated)``."""
        from ..templates import prepare_record

        parts = []
        estimated = False
        plain = {n: "none" for n in (sym or {})}  # a parity prior needs the union on both sides of 0, not each record
        for k, rec in enumerate(self.records):
            try:
                p, e = prepare_record(rec, structure, plain, diff, what, without_prior)
            except (ConfigError, DataError) as exc:
                raise type(exc)(f"record {k} ({rec.name}): {exc}") from None
            parts.append(p)
            estimated = estimated or bool(e)
        joined, _ = prepare_record(_join(parts, self.offsets, self.name), structure, sym, "given", what,
                                   without_prior)  # the checks of the whole: the priors on the union of the ranges
        return joined, estimated


def prepare_any(record, structure, sym, diff, what: str, without_prior=None):
    """:func:`~charcurves.templates.prepare_record` of one record or of a :class:`RecordSet`."""
    if isinstance(record, RecordSet):
        return record.prepare(structure, sym, diff, what, without_prior)
    from ..templates import prepare_record

    return prepare_record(record, structure, sym, diff, what, without_prior)


def common_step(records, uniform_step, tol: float = 1e-3) -> float:
    """The one uniform sample step of every record (``uniform_step(record)`` each; output error
    integrates all segments with one step; DataError naming the steps otherwise)."""
    steps = [uniform_step(r) for r in records]
    if max(steps) - min(steps) > tol * min(steps):
        raise DataError("output error of several records needs one sampling step, got "
                        f"{', '.join(f'{s:.6g}' for s in steps)}; resample the records to one rate, or use "
                        "objective='equation-error' (which takes each record at its own rate)")
    return float(np.median(steps))


def record_segments(bounds, L: int, max_segments: int, segments):
    """Shooting segments of each record (none crosses a boundary): ``(L, starts, contiguous)`` with
    one segment length for all (the shortest record's choice when it is shorter), the starts in
    the joined rows and which consecutive pairs abut (never across a boundary)."""
    n_min = min(b - a for a, b in bounds)
    L = min(int(L), n_min)
    starts: list[int] = []
    contiguous: list[bool] = []
    share = max(1, int(max_segments) // len(bounds))
    for a, b in bounds:
        Lk, s, c = segments(b - a, L, share)
        if Lk != L:  # equal segments of this record: keep the common length, the tail rows unused
            count = max(1, (b - a - 1) // (L - 1))
            s = np.arange(count) * (L - 1)
            c = np.diff(s) == L - 1
        if contiguous:
            contiguous.append(False)
        starts.extend((a + s).tolist())
        contiguous.extend(np.asarray(c, bool).tolist())
    return L, np.asarray(starts, dtype=int), np.asarray(contiguous, dtype=bool)


def record_report(model, record_set: RecordSet, prepared, mask, free_run_rmse) -> list[dict]:
    """Per record: samples, step, equation-error loss (mean squared residual over its fitted rows) and
    the free-run RMSE of x from the initial state output error estimated for it (separable family;
    ``free_run_rmse(model, record, columns, y0, hold, substeps)`` runs it)."""
    out = []
    r = np.asarray(model.force_residual(prepared), dtype=float)
    r = r.reshape(r.shape[0], -1)
    mask = np.ones(r.shape[0], bool) if mask is None else np.asarray(mask, bool)
    oe = model.info.get("output_error") or {}
    y0s = oe.get("record_initial_states")
    for k, (rec, (a, b)) in enumerate(zip(record_set.records, record_set.bounds)):
        keep = mask[a:b]
        rk = r[a:b][keep]
        entry: dict[str, Any] = {"name": rec.name, "n_samples": int(b - a), "dt": float(rec.dt),
                                 "range": _ranges(rec),
                                 "loss_equation_error": float(np.mean(rk**2)) if rk.size else None}
        entry["free_run_rmse"] = _free_run(model, rec, prepared.slice(slice(a, b)) if hasattr(prepared, "slice") else None,
                                           None if y0s is None else y0s[k], oe, free_run_rmse)
        out.append(entry)
    return out


def _ranges(rec) -> dict:
    from ..data import Trajectory

    if isinstance(rec, Trajectory):
        cols = {"x": rec.x, "F": rec.F}
        if rec.v is not None:
            cols["v"] = rec.v
    else:
        cols = dict(rec.states)
    return {k: [float(np.min(v)), float(np.max(v))] for k, v in cols.items()}


def _free_run(model, rec, prepared, y0, oe, free_run_rmse) -> float | None:
    """Free-run RMSE of x over one record (separable family): from output error's initial state of
    the record, else from the prepared record's first state (its estimated or given x, x')."""
    from ..data import Trajectory

    if model.template.is_general or not isinstance(rec, Trajectory):
        return None
    if y0 is None:
        y0 = [float(prepared.x[0]), float(prepared.v[0])]
    try:
        rmse = free_run_rmse(model, rec, {"x": np.asarray(rec.x, dtype=float)}, y0, oe.get("hold", "linear"),
                              int(oe.get("substeps", 4)))
    except (ConfigError, DataError):
        return None
    return None if rmse is None else float(rmse)


def per_record_residual_tests(model, record_set: RecordSet, prepared, mask) -> None:
    """The self-check's residual tests record by record (their noise models differ: the AR whitening of
    one series of the joined rows would take one record's correlation for another's), at the level
    shared out over the records; the joined rows' tests and warnings are replaced."""
    from ._self_check import RESIDUAL_LEVEL, residual_check

    check = model.info.get("self_check")
    if not check or "residual_tests" not in check:
        return
    old = check["residual_tests"]
    white = old.get("whiteness") == "applied"
    floors = check.get("equation_error", check)["noise_floor"]
    mask = np.ones(prepared.n_samples, bool) if mask is None else np.asarray(mask, bool)
    joined = residual_check(model, prepared, mask, white_expected=white, floors=floors)["warnings"]
    level = RESIDUAL_LEVEL / len(record_set.records)
    tests, lines = [], []
    for k, (a, b) in enumerate(record_set.bounds):
        res = residual_check(model, prepared.slice(slice(a, b)), mask[a:b], white_expected=white, floors=floors,
                             level=level)
        tests += [{"record": k, **t} for t in res["tests"]]
        lines += [f"record {k} ({record_set.records[k].name}): {w}" for w in res["warnings"]]
    model.info["self_check"]["residual_tests"] = {
        **{k: v for k, v in old.items() if k not in ("tests", "passed", "per_test_level")},
        "level": RESIDUAL_LEVEL, "per_record_level": level, "per_test_level": res["per_test_level"],
        "tests": tests, "passed": bool(all(t["passed"] for t in tests)),
        "records": "each record's residual tested on its own (its own noise model)"}
    warnings = [w for w in model.info.get("warnings", []) if w not in joined]
    if warnings or lines:
        model.info["warnings"] = warnings + lines
    else:
        model.info.pop("warnings", None)
