"""The paper's three validation loops (appendix B) and the hierarchical family search.

* **inner**: the converged data loss against an estimate of the noise floor; a family that
  cannot get near the floor lacks the capacity to describe the system;
* **middle**: curves fitted on independent trajectories (other initial conditions or forcings)
  must agree within their uncertainty; a wrong family deforms its curves differently for each
  trajectory ("structural compensation");
* **outer**: each trajectory's model, integrated forward from another trajectory's initial state
  under that trajectory's forcing, must follow it for a while (separation time); every family
  (first-order, position-damping, two-dof, user equations) is integrated from its template.

:func:`select_family` runs the loops on a hierarchy of candidate families, simplest first, and
accepts the first family that passes all three.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Sequence
from typing import Any

import numpy as np

from .._errors import DataError

from ..data import REL_FLOOR, NoiseFloor, noise_floor

__all__ = ["inner_loop", "middle_loop", "outer_loop", "LoopResult", "INNER_FACTOR", "MIDDLE_THRESHOLD",
           "OUTER_FRACTION", "SEPARATION_EPS", "REL_FLOOR", "NoiseFloor", "noise_floor"]

#: the inner loop accepts a loss up to this multiple of the noise floor
INNER_FACTOR = 1.5
#: the middle loop accepts curves whose RMS normalised difference is at most this
MIDDLE_THRESHOLD = 3.0
#: relative approximation floor of curve differences (fraction of the curve's RMS size)
APPROX_TOL = 0.01
#: the outer loop accepts a median separation time of at least this fraction of the record
OUTER_FRACTION = 0.2
#: separation tolerance, as a fraction of the held-out record's range of x
SEPARATION_EPS = 0.1
#: families tried by ``charcurves select`` when none are named (the paper's hierarchy II, III)
DEFAULT_FAMILIES = ("separable", "position-damping")


# --------------------------------------------------------------------------- loop results
@dataclasses.dataclass
class LoopResult:
    """Outcome of one loop: passed, the statistic, its threshold and the figures behind it.

    Examples
    --------
    >>> import charcurves as cc
    >>> from charcurves.selection import LoopResult, inner_loop
    >>> from charcurves.systems import get_system
    >>> record = cc.corrupt(get_system("duffing").simulate(), 20, seed=0)
    >>> result = inner_loop([cc.fit(record, method="poly-cc")], [record], snr_db=20)
    >>> isinstance(result, LoopResult), result.loop, result.passed, result.threshold
    (True, 'inner', True, 1.5)
    """

    loop: str
    passed: bool
    statistic: float
    threshold: float
    figures: dict = dataclasses.field(default_factory=dict)

    def to_dict(self) -> dict[str, Any]:
        return {"loop": self.loop, "passed": bool(self.passed), "statistic": _num(self.statistic),
                "threshold": _num(self.threshold), "figures": _clean(self.figures)}


def inner_loop(models: Sequence, records: Sequence, *, factor: float = INNER_FACTOR,
               snr_db: float | None = None, floors: Sequence[NoiseFloor] | None = None) -> LoopResult:
    """Loss / noise floor of every fit; passes when the largest ratio is at most ``factor``.

    Examples
    --------
    >>> import charcurves as cc
    >>> from charcurves.selection import inner_loop
    >>> from charcurves.systems import get_system
    >>> record = cc.corrupt(get_system("duffing").simulate(), 20, seed=0)
    >>> result = inner_loop([cc.fit(record, method="poly-cc")], [record], snr_db=20)
    >>> result.passed, round(result.statistic, 2)
    (True, 0.91)
    """
    ratios, losses, fl, source = [], [], [], ""
    for k, (model, rec) in enumerate(zip(models, records)):
        check = (getattr(model, "info", None) or {}).get("self_check") if floors is None else None
        if check and check.get("state_noise_counted"):
            # a measured state's noise reaches the loss (estimated derivatives, noisy measured x and
            # x', output error): the fit's own check has the floor that holds it, the forcing's alone
            # would reject a correct family (Duffing, 40 dB on x: 27 and 194 times it)
            loss, floor, source = float(np.mean(check["loss_value"])), float(np.mean(check["noise_floor"])), \
                str(check["floor_source"])
        else:
            nf = floors[k] if floors is not None else noise_floor(rec, gain=model.gain, snr_db=snr_db)
            loss, floor, source = float(model.loss), nf.floor, nf.source
        ratios.append(loss / floor)
        losses.append(loss)
        fl.append(floor)
    worst = max(ratios)
    return LoopResult("inner", worst <= factor, worst, float(factor),
                      {"loss": losses, "noise_floor": fl, "loss_over_floor": ratios, "floor_source": source})


def _curve_scale(values: np.ndarray) -> float:
    return float(np.sqrt(np.mean(np.asarray(values) ** 2)))


def middle_loop(ensembles: Sequence, *, threshold: float = MIDDLE_THRESHOLD, n_grid: int = 50,
                min_overlap: float = 0.2) -> LoopResult:
    """Do the curves of independent trajectories agree within their uncertainty?

    For every curve and every pair of trajectories, on the common part of their argument
    ranges, ``d(z) = (f_i - f_j) / sqrt(sd_i² + sd_j² + (tol · scale)²)`` with ``sd`` the
    ensembles' spreads; the statistic is the RMS of ``d`` over the grid, and the loop passes
    when the largest statistic is at most ``threshold``. Pairs whose common range is under
    ``min_overlap`` of their joint range are not compared (and reported).

    Examples
    --------
    >>> import charcurves as cc
    >>> from charcurves.selection import fit_ensembles, middle_loop, split_record
    >>> from charcurves.systems import get_system
    >>> halves = split_record(cc.corrupt(get_system("duffing").simulate(t_end=20.0, n_points=500), 20, seed=0), 2)
    >>> ensembles = fit_ensembles(cc.CharacteristicCurves.from_method(method="poly-cc", symmetry="odd"), halves, 4)
    >>> result = middle_loop(ensembles)
    >>> result.passed, result.statistic < result.threshold
    (True, True)
    """
    if len(ensembles) < 2:
        raise DataError("the middle loop compares curves of at least two trajectories; give two records "
                        "(other initial conditions or forcings), or one long record to split")
    stats: dict[str, list] = {}
    worst_max = 0.0
    skipped = []
    names = list(ensembles[0].point.curves)
    for name in names:
        for i in range(len(ensembles)):
            for j in range(i + 1, len(ensembles)):
                ci, cj = ensembles[i].point.curves[name], ensembles[j].point.curves[name]
                lo = max(ci.domain[0], cj.domain[0])
                hi = min(ci.domain[1], cj.domain[1])
                joint = max(ci.domain[1], cj.domain[1]) - min(ci.domain[0], cj.domain[0])
                if hi - lo < min_overlap * joint:
                    skipped.append(f"{name}: trajectories {i + 1} and {j + 1} overlap on {max(hi - lo, 0):.3g} "
                                   f"of {joint:.3g}")
                    continue
                z = np.linspace(lo, hi, n_grid)
                fi, fj = np.asarray(ci(z), dtype=float), np.asarray(cj(z), dtype=float)
                sdi = ensembles[i].curve_values(name, z).std(axis=0, ddof=1)
                sdj = ensembles[j].curve_values(name, z).std(axis=0, ddof=1)
                tol = APPROX_TOL * max(_curve_scale(fi), _curve_scale(fj), 1e-300)
                d = (fi - fj) / np.sqrt(sdi**2 + sdj**2 + tol**2)
                stats.setdefault(name, []).append(float(np.sqrt(np.mean(d**2))))
                worst_max = max(worst_max, float(np.max(np.abs(d))))
    if not stats:
        raise DataError("no two trajectories share enough of a curve's argument range to compare the curves "
                        "(" + "; ".join(skipped) + "); give records that cover a common range")
    worst = max(max(v) for v in stats.values())
    return LoopResult("middle", worst <= threshold, worst, float(threshold),
                      {"rms_normalised_difference": stats, "max_normalised_difference": worst_max,
                       "skipped_pairs": skipped})


def _smooth(y: np.ndarray, window: int = 11, order: int = 3) -> np.ndarray:
    from scipy.signal import savgol_filter

    return savgol_filter(np.asarray(y, dtype=float), window, order) if len(y) > window else np.asarray(y)


def _record_columns(record, states: Sequence[str], forces: Sequence[str]):
    """Displacements, velocities (None where the record has none) and forcings of a record, by the
    template's names: ``x``/``F`` of a Trajectory, ``x1, x2``/``F1, F2`` of a MultiTrajectory."""
    if hasattr(record, "states"):
        vel = record.velocities or {}
        return ({s: np.asarray(record.states[s], dtype=float) for s in states},
                {s: (np.asarray(vel[s], dtype=float) if s in vel else None) for s in states},
                {f: np.asarray(record.forces[f], dtype=float) for f in forces})
    v = None if record.v is None else np.asarray(record.v, dtype=float)
    return ({s: np.asarray(record.x, dtype=float) for s in states}, {s: v for s in states},
            {f: np.asarray(record.F, dtype=float) for f in forces})


def _expanded(lo: float, hi: float) -> tuple[float, float]:
    """A span three times as wide as [lo, hi], centred on it."""
    return lo - (hi - lo), hi + (hi - lo)


#: a forward run that makes this many right-hand-side evaluations without reaching the next
#: sample grinds at a singular point of the model (a coefficient curve such as the first-order
#: f2(x) crossing 0) and is stopped there; a healthy run makes about 20 per sample
MAX_EVALUATIONS_PER_STEP = 2000


class _RunGuard:
    """Ends a forward run of a general template early, through the simulator's own stop (which
    keeps the samples before it): when a curve argument leaves three times its training range
    ("left_box") or the run grinds without reaching the next sample time ("stalled"). Fires
    once: the simulator's rerun up to the stop then completes."""

    def __init__(self, t_eval: np.ndarray, max_calls: int = MAX_EVALUATIONS_PER_STEP):
        self.t_eval, self.max_calls = np.asarray(t_eval, dtype=float), int(max_calls)
        self.next, self.stuck, self.t, self.armed = float(self.t_eval[0]), 0, 0.0, True

    def _stop(self, status: str, message: str):
        from ..simulate import SimulationStopped

        self.armed = False
        raise SimulationStopped(status, message, self.t)

    def tick(self, t: float) -> None:
        self.t = float(t)
        if self.t >= self.next:
            k = int(np.searchsorted(self.t_eval, self.t, side="right"))
            self.next = float(self.t_eval[k]) if k < self.t_eval.size else math.inf
            self.stuck = 0
            return
        self.stuck += 1
        if self.armed and self.stuck > self.max_calls:
            self._stop("stalled", f"{self.max_calls} right-hand-side evaluations without reaching t = "
                                  f"{self.next:.4g} (a singular model?)")

    def left(self, name: str) -> None:
        if self.armed:
            self._stop("left_box", f"the argument of {name} left three times its training range")


class _TabulatedCurve:
    """A fitted curve evaluated by linear interpolation on a fine grid over three times its
    training range (a network call per right-hand-side evaluation would dominate the run time;
    the interpolation error on 4001 points is far below the tolerances); beyond it the run is
    stopped by ``guard``, or the curve is evaluated exactly."""

    def __init__(self, name: str, curve, guard: _RunGuard, n: int = 4001):
        lo, hi = (float(v) for v in curve.domain)
        if not hi > lo:
            lo, hi = lo - 1.0, hi + 1.0
        self.name, self.curve, self.guard = name, curve, guard
        self.z = np.linspace(*_expanded(lo, hi), n)
        self.y = np.asarray(curve(self.z), dtype=float)
        self.domain = curve.domain

    def __call__(self, z):
        z = np.asarray(z, dtype=float)
        out = np.interp(z, self.z, self.y)
        outside = (z < self.z[0]) | (z > self.z[-1])
        if outside.any():
            self.guard.left(self.name)
            out[outside] = np.asarray(self.curve(z[outside]), dtype=float)
        return out


def _forward(model, t, x0, v0, forcing, box, time_budget):
    """Forward run of a fitted model from ``x0, v0`` (dicts by state) under ``forcing`` (dict of
    callables by forcing column). Returns times, positions ``(n, S)`` and a status.

    The separable family runs through :func:`charcurves.simulate.simulate_model`; every other
    template (first-order, position-damping, two-dof, user equations) through
    :func:`charcurves.simulate._families.simulate_template_model` on tabulated curves. A run that
    leaves ``box`` (per state, on x and x') or three times a curve argument's training range ends
    there with status "left_box"; one that grinds at a singular point ends with "stalled".
    """
    import copy

    family = getattr(model.template, "family", "")
    if family == "separable":
        from ..simulate import simulate_model

        res = simulate_model(model, t, x0["x"], v0["x"], forcing["F"], box={"x": box["x"]["x"], "v": box["x"]["v"]},
                             time_budget=time_budget, rtol=1e-6, atol=1e-8)
        return res.t, np.asarray(res.x, dtype=float).reshape(-1, 1), res.status
    from ..simulate import simulate_template_model

    guard = _RunGuard(t)
    first = next(iter(forcing))
    guarded = dict(forcing)
    guarded[first] = lambda tt, f=forcing[first]: (guard.tick(tt), f(tt))[1]  # once per right-hand side
    fast = copy.copy(model)
    fast.curves = {name: _TabulatedCurve(name, c, guard) for name, c in model.curves.items()}
    states = list(model.template.states)
    res = simulate_template_model(fast, t, x0, {s: (v0[s] if v0[s] is not None else 0.0) for s in states}, guarded,
                                  rtol=1e-6, atol=1e-8, time_budget=time_budget)
    status = res.status
    if len(res.t) == 0:  # stopped before the first sample (e.g. timeout, or diverged at once)
        return res.t, np.zeros((0, len(states))), status
    X = np.asarray(res.x, dtype=float).reshape(len(res.t), -1)
    V = np.asarray(res.v, dtype=float).reshape(len(res.t), -1)
    inside = np.ones(len(res.t), dtype=bool)
    for k, s in enumerate(states):
        for vals, (lo, hi) in ((X[:, k], box[s]["x"]), (V[:, k], box[s]["v"])):
            inside &= (vals >= lo) & (vals <= hi)
    if not inside.all():
        n = int(np.argmin(inside))  # samples before the first one outside
        return res.t[:n], X[:n], "left_box"
    return res.t, X, status


def outer_loop(ensembles: Sequence, *, fraction: float = OUTER_FRACTION, eps: float = SEPARATION_EPS,
               time_budget: float = 60.0) -> LoopResult:
    """Cross-prediction: the model of trajectory i run from trajectory j's initial state under
    j's forcing (smoothed by Savitzky-Golay, window 11), for every i != j, in every family
    (several states and forcing columns for two-dof; the initial x' is not used by first-order
    templates).

    The separation time is the first time at which any state separates, ``|x_model - x_j| >
    eps · range(x_j)`` (per state), relative to the record's duration; the loop passes when its
    median over the pairs is at least ``fraction``. A run that leaves a box of three times the
    training ranges (of each state and its velocity) separates there. ``normalised_rmse`` is
    the worst state's trajectory RMSE over its standard deviation.

    Raises
    ------
    SimulationError
        For a template that cannot be integrated (no derivative of a state, or not one equation
        per state).

    Examples
    --------
    >>> import charcurves as cc
    >>> from charcurves.selection import fit_ensembles, outer_loop, split_record
    >>> from charcurves.systems import get_system
    >>> halves = split_record(cc.corrupt(get_system("duffing").simulate(t_end=20.0, n_points=500), 20, seed=0), 2)
    >>> ensembles = fit_ensembles(cc.CharacteristicCurves.from_method(method="poly-cc", symmetry="odd"), halves, 3)
    >>> result = outer_loop(ensembles, fraction=0.2)
    >>> result.loop, result.passed
    ('outer', True)
    """
    from ..metrics import separation_time, trajectory_rmse

    if len(ensembles) < 2:
        raise DataError("the outer loop needs a held-out trajectory; give at least two records")
    rel, nrmse, statuses = [], [], []
    for i, ens_i in enumerate(ensembles):
        model = ens_i.point
        template = model.template
        states = list(getattr(template, "states", ("x",)))
        forces = list(getattr(template, "forces", ("F",)))
        xs_i, vs_i, _ = _record_columns(ens_i.record, states, forces)
        box = {}
        for s in states:
            box[s] = {"x": _expanded(float(xs_i[s].min()), float(xs_i[s].max())),
                      "v": ((-math.inf, math.inf) if vs_i[s] is None
                            else _expanded(float(vs_i[s].min()), float(vs_i[s].max())))}
        for j, ens_j in enumerate(ensembles):
            if i == j:
                continue
            rec = ens_j.record
            t = np.asarray(rec.t, dtype=float)
            x_true, v_true, F_true = _record_columns(rec, states, forces)
            forcing = {}
            for f in forces:
                Fs = _smooth(F_true[f])
                forcing[f] = (lambda tt, t=t, Fs=Fs: float(np.interp(tt, t, Fs)))
            x0 = {s: float(x_true[s][0]) for s in states}
            v0 = {s: (None if v_true[s] is None else float(v_true[s][0])) for s in states}
            ts, X, status = _forward(model, t, x0, v0, forcing, box, time_budget)
            statuses.append(status)
            if status == "timeout":  # a run cut short by the clock says nothing about the model
                continue
            if len(ts) < 2:
                t_sep, worst = t[0], math.inf
            else:
                t_sep, worst = math.inf, 0.0
                for k, s in enumerate(states):
                    span = float(np.ptp(x_true[s]))
                    t_k, _ = separation_time(ts, X[:, k], x_true[s][:len(ts)], eps=eps * span)
                    t_sep = min(t_sep, t_k)
                    worst = max(worst, trajectory_rmse(X[:, k], x_true[s]) / max(float(np.std(x_true[s])), 1e-300))
                if status != "ok" and len(ts) < len(t):
                    t_sep = min(t_sep, float(ts[-1]))
            rel.append((t_sep - t[0]) / (t[-1] - t[0]))
            nrmse.append(worst)
    if not rel:
        return LoopResult("outer", False, math.nan, float(fraction),
                          {"statuses": statuses, "note": f"every forward run exceeded its time budget of "
                                                         f"{time_budget:g} s; nothing to judge"})
    med = float(np.median(rel))
    return LoopResult("outer", med >= fraction, med, float(fraction),
                      {"separation_fraction": rel, "normalised_rmse": nrmse, "statuses": statuses,
                       "eps_fraction_of_range": eps})


# --------------------------------------------------------------------------- helpers
def _num(v):
    v = float(v)
    return v if math.isfinite(v) else str(v)


def _clean(obj):
    if isinstance(obj, dict):
        return {str(k): _clean(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [_clean(v) for v in obj]
    if isinstance(obj, (np.floating, float)):
        return _num(obj)
    if isinstance(obj, np.integer):
        return int(obj)
    if isinstance(obj, np.bool_):
        return bool(obj)
    return obj
