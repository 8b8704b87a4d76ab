"""The hierarchical family search (the paper's appendix B): the three loops on candidate families,
simplest first; the first family that passes all three is accepted."""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Sequence
from typing import Any

import numpy as np

from .._errors import ConfigError, DataError, SimulationError
from ._loops import (DEFAULT_FAMILIES, INNER_FACTOR, MIDDLE_THRESHOLD, OUTER_FRACTION, SEPARATION_EPS, _clean,
                     inner_loop, middle_loop, outer_loop)

__all__ = ["SelectionReport", "select_family", "split_record"]


# --------------------------------------------------------------------------- the search
def split_record(record, parts: int = 2) -> list:
    """Consecutive segments of one record, used as independent trajectories (each starts from
    another state of the system).

    Examples
    --------
    >>> from charcurves.selection import split_record
    >>> from charcurves.systems import get_system
    >>> halves = split_record(get_system("duffing").simulate(), 2)
    >>> [(h.n_samples, round(float(h.t[0]), 2)) for h in halves]
    [(500, 0.0), (500, 20.02)]
    """
    n = record.n_samples
    edges = np.linspace(0, n, parts + 1).astype(int)
    return [record.slice(slice(int(a), int(b))) for a, b in zip(edges[:-1], edges[1:])]


@dataclasses.dataclass
class SelectionReport:
    """Verdicts of :func:`select_family`, one row per family in the order tried.

    Examples
    --------
    >>> import charcurves as cc
    >>> from charcurves.selection import SelectionReport, select_family, split_record
    >>> from charcurves.systems import get_system
    >>> halves = split_record(cc.corrupt(get_system("duffing").simulate(t_end=20.0, n_points=500), 20, seed=0), 2)
    >>> report = select_family(halves, ["separable"], method="poly-cc", n_members=3, snr_db=20)
    >>> isinstance(report, SelectionReport), report.accepted
    (True, 'separable')
    >>> print(report.table().splitlines()[-1])
    accepted: separable
    """

    rows: list
    accepted: str | None
    settings: dict

    def to_dict(self) -> dict[str, Any]:
        return {"accepted": self.accepted, "settings": _clean(self.settings), "families": _clean(self.rows)}

    def table(self) -> str:
        """The verdict table as text."""
        head = f"{'family':<18} {'verdict':<11} {'by':<7} {'loss/floor':>10} {'curve diff':>10} {'t_sep/T':>8}"
        lines = [head, "-" * len(head)]
        for r in self.rows:
            lines.append(f"{r['family']:<18} {r['verdict']:<11} {r['rejected_by'] or '-':<7} "
                         f"{_fmt(r.get('inner'))!s:>10} {_fmt(r.get('middle'))!s:>10} {_fmt(r.get('outer'))!s:>8}")
        s = self.settings
        lines.append(f"thresholds: loss/floor <= {s['inner_factor']:g}, RMS normalised curve difference <= "
                     f"{s['middle_threshold']:g}, median separation time >= {s['outer_fraction']:g} of the record")
        lines.append(f"accepted: {self.accepted}" if self.accepted else "no family accepted")
        return "\n".join(lines)

    def csv_rows(self) -> list[dict[str, Any]]:
        out = []
        for r in self.rows:
            out.append({"family": r["family"], "verdict": r["verdict"], "rejected_by": r["rejected_by"] or "",
                        "loss_over_floor": _stat(r.get("inner")), "curve_difference": _stat(r.get("middle")),
                        "separation_fraction": _stat(r.get("outer")), "fit_seconds": r.get("fit_seconds", "")})
        return out


def _stat(loop):
    return "" if not loop else loop["statistic"]


def _fmt(loop) -> str:
    if not loop:
        return "-"
    v = loop["statistic"]
    return f"{v:.3g}" if isinstance(v, (int, float)) and math.isfinite(v) else str(v)


def select_family(trajectories: Sequence, families: Sequence[str] = DEFAULT_FAMILIES, *, method: str = "nn-cc",
                  n_members: int = 6, snr_db: float | None = None, inner_factor: float = INNER_FACTOR,
                  middle_threshold: float = MIDDLE_THRESHOLD, outer_fraction: float = OUTER_FRACTION,
                  separation_eps: float = SEPARATION_EPS, all_families: bool = False, all_loops: bool = False,
                  random_state: int = 0, threads: int | None = 1, progress=None, fit=None,
                  **estimator_params) -> SelectionReport:
    """Run the three loops on candidate families, simplest first; accept the first that passes.

    Parameters
    ----------
    trajectories : sequence of Trajectory
        Independent records of one system (other initial conditions or forcings). One record
        is split into two halves.
    families : sequence of str
        Candidate families in order of complexity (e.g. "separable", "position-damping").
    method : str
        Fitting method for every family (default unconstrained NN-CC: no symmetry assumed).
    n_members : int
        Bootstrap members per trajectory (the curves' uncertainty of the middle loop).
    snr_db : float, optional
        Known SNR of the forcing (otherwise the noise floor is estimated).
    inner_factor, middle_threshold, outer_fraction, separation_eps : float
        Thresholds of the loops (module constants by default; see docs/selection.md).
    all_families : bool
        Also test the families after the accepted one.
    all_loops : bool
        Run every loop even after one rejected the family (more figures, more time).
    random_state : int
    threads : int, optional
    progress : callable, optional
        ``progress(text)`` after each family.
    fit : callable, optional
        ``fit(estimators, trajectories, n_members) -> [ensembles of each estimator]``: where the
        bootstrap ensembles are fitted. By default here, family by family, stopping at the accepted
        one; a given ``fit`` (e.g. :func:`charcurves.experiments.ray_ensemble_fitter`, on a Ray
        cluster) gets every family's estimator at once, so that the families fit in parallel (the
        families after the accepted one are fitted but, without ``all_families``, not tested).
    **estimator_params
        Further settings of ``CharacteristicCurves.from_method`` (gauge, preset, differentiator...).

    Returns
    -------
    SelectionReport

    Examples
    --------
    >>> import charcurves as cc
    >>> from charcurves.selection import select_family, split_record
    >>> from charcurves.systems import get_system
    >>> halves = split_record(cc.corrupt(get_system("duffing").simulate(t_end=20.0, n_points=500), 20, seed=0), 2)
    >>> report = select_family(halves, ["separable", "position-damping"], method="poly-cc", n_members=3, snr_db=20)
    >>> report.accepted, [row["verdict"] for row in report.rows]
    ('separable', ['accepted', 'not tested'])
    """
    import time

    from ..fitting import CharacteristicCurves, fit_ensembles, legacy_options

    from .._bounds import check_number

    trajectories = list(trajectories)
    if not trajectories:
        raise DataError("select needs at least one record")
    check_number("members", n_members, label="n_members (--members)")
    if snr_db is not None:
        check_number("snr_db", snr_db, label="snr_db (--snr)")
    families = [f.strip() for f in families if f and f.strip()]
    if not families:
        raise ConfigError("no candidate family given; e.g. --families separable,position-damping")
    for family in families:  # an unknown family or method fails now, not after the first family's fits
        CharacteristicCurves.from_method(method, family=family, random_state=random_state, threads=threads,
                                         **legacy_options(estimator_params)).resolve()
    split = len(trajectories) == 1
    if split:
        trajectories = split_record(trajectories[0], 2)
    estimator_params = legacy_options(estimator_params)
    estimators = [CharacteristicCurves.from_method(method, family=family, random_state=random_state, threads=threads,
                                                   **estimator_params) for family in families]
    fitted, fit_each = None, 0.0
    if fit is not None:
        t0 = time.perf_counter()
        fitted = list(fit(estimators, trajectories, n_members))
        if len(fitted) != len(estimators):
            raise ConfigError(f"the ensemble fitter returned {len(fitted)} results for {len(estimators)} families")
        fit_each = (time.perf_counter() - t0) / len(estimators)
    rows, accepted = [], None
    for i, family in enumerate(families):
        row: dict[str, Any] = {"family": family, "verdict": "not tested", "rejected_by": None}
        if accepted is not None and not all_families:
            rows.append(row)
            continue
        t0 = time.perf_counter()
        est = estimators[i]
        ensembles = (fitted[i] if fitted is not None else
                     fit_ensembles(est, trajectories, n_members, kind="bootstrap"))
        row["fit_seconds"] = fit_each if fitted is not None else time.perf_counter() - t0
        loops = [
            ("inner", lambda: inner_loop([e.point for e in ensembles], [e.record for e in ensembles],
                                         factor=inner_factor, snr_db=snr_db)),
            ("middle", lambda: middle_loop(ensembles, threshold=middle_threshold)),
            ("outer", lambda: outer_loop(ensembles, fraction=outer_fraction, eps=separation_eps)),
        ]
        for name, run in loops:
            if row["rejected_by"] and not all_loops:
                break
            try:
                res = run()
            except (ConfigError, SimulationError) as exc:  # a user template that cannot be integrated
                if name != "outer":
                    raise
                row[name] = {"loop": name, "passed": None, "statistic": "n/a", "threshold": outer_fraction,
                             "figures": {"note": f"not run: {exc}"}}
                continue
            row[name] = res.to_dict()
            if not res.passed and not row["rejected_by"]:
                row["rejected_by"] = name
        row["verdict"] = "rejected" if row["rejected_by"] else "accepted"
        row["seconds"] = time.perf_counter() - t0
        if row["verdict"] == "accepted" and accepted is None:
            accepted = family
        rows.append(row)
        if progress is not None:
            progress(f"{family}: {row['verdict']}" + (f" by the {row['rejected_by']} loop" if row["rejected_by"] else "")
                     + f" ({row['seconds']:.1f} s)")
    settings = {"method": method, "members": int(n_members), "inner_factor": inner_factor,
                "middle_threshold": middle_threshold, "outer_fraction": outer_fraction,
                "separation_eps": separation_eps, "snr_db": snr_db, "trajectories": len(trajectories),
                "split_one_record": split, "random_state": random_state}
    return SelectionReport(rows=rows, accepted=accepted, settings=settings)
