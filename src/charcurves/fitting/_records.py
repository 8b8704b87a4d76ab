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

__all__ = ["RecordSet", "as_record_set", "prepare_any", "record_report"]


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


def record_report(model, record_set: RecordSet, prepared, mask) -> list[dict]:
    """Per record: samples, step, equation-error loss (mean squared residual over its fitted rows) and
    the free-run RMSE of x from the initial state output error estimated for it (separable family,
    after output error; the records of one step run as one batch; None otherwise)."""
    out = []
    r = np.asarray(model.force_residual(prepared), dtype=float)
    r = r.reshape(r.shape[0], -1)
    mask = np.ones(r.shape[0], bool) if mask is None else np.asarray(mask, bool)
    free = _free_runs(model, record_set, prepared)
    for k, (rec, (a, b)) in enumerate(zip(record_set.records, record_set.bounds)):
        rk = r[a:b][mask[a:b]]
        out.append({"name": rec.name, "n_samples": int(b - a), "dt": float(rec.dt), "range": _ranges(rec),
                    "loss_equation_error": float(np.mean(rk**2)) if rk.size else None, "free_run_rmse": free[k],
                    **({} if free[k] is not None else {"free_run": "not run (no output error): see charcurves "
                                                                    "validate"})})
    return out


def _table(curve, n: int = 4097):
    """A vectorised function: linear interpolation in a table over twice the curve's range, continued
    linearly beyond it (as output error's free-run check does per call)."""
    lo, hi = curve.domain
    pad = 0.5 * (hi - lo) + 1e-9
    z = np.linspace(lo - pad, hi + pad, n)
    y = np.asarray(curve(z), dtype=float)
    s0, s1 = (y[1] - y[0]) / (z[1] - z[0]), (y[-1] - y[-2]) / (z[-1] - z[-2])

    def f(u):
        u = np.asarray(u, dtype=float)
        return np.interp(u, z, y) + np.where(u < z[0], (u - z[0]) * s0, 0.0) + np.where(u > z[-1], (u - z[-1]) * s1, 0.0)

    return f


def _free_runs(model, record_set: RecordSet, prepared) -> list:
    """Free-run RMSE of x of every record (None for templates other than the separable one)."""
    from ..data import Trajectory, rk4_sampled, stage_inputs

    K = len(record_set.records)
    if model.template.is_general or not isinstance(record_set.records[0], Trajectory):
        return [None] * K
    oe = model.info.get("output_error") or {}
    y0s = oe.get("record_initial_states")
    if y0s is None:  # equation error alone runs no simulation (as for one record): validate gives the free run
        return [None] * K
    hold, substeps = oe.get("hold", "linear"), int(oe.get("substeps", 4))
    f1, f2 = _table(model.curves["f1"]), _table(model.curves["f2"])
    g, b = float(model.gain), float(model.offset)

    def accel(x, v, u):
        return g * u - f1(v) - f2(x) - b

    out: list = [None] * K
    steps = [float(np.median(np.diff(np.asarray(r.t, dtype=float)))) for r in record_set.records]
    groups: list[list[int]] = []
    for k in range(K):  # records of one step (to round-off) run as one batch
        same = [grp for grp in groups if abs(steps[grp[0]] - steps[k]) <= 1e-9 * steps[k]]
        same[0].append(k) if same else groups.append([k])
    for ks in groups:
        dt = steps[ks[0]]
        n_max = max(record_set.records[k].n_samples for k in ks)
        stages = []
        for k in ks:
            parts = stage_inputs(np.asarray(record_set.records[k].F, dtype=float), substeps, hold)
            stages.append([np.pad(p, (0, (n_max - 1) * substeps - p.size), mode="edge") for p in parts])
        ua, um, ub = (np.stack([st[i] for st in stages], axis=1) for i in range(3))
        x0 = np.array([y0s[k][0] for k in ks], dtype=float)
        v0 = np.array([y0s[k][1] for k in ks], dtype=float)
        x, _, _ = rk4_sampled(accel, ua, um, ub, x0, v0, dt, substeps, time_budget=120.0)
        for col, k in enumerate(ks):
            n = record_set.records[k].n_samples
            d = x[:n, col] - np.asarray(record_set.records[k].x, dtype=float)
            out[k] = float(np.sqrt(np.mean(d * d))) if np.all(np.isfinite(d)) else float("inf")
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
    # the joined rows' residual-test warnings (the loss-over-floor warning stays)
    warnings = [w for w in model.info.get("warnings", []) if not str(w).startswith("self-check: the residual")]
    if warnings or lines:
        model.info["warnings"] = warnings + lines
    else:
        model.info.pop("warnings", None)
