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

from .._errors import ConfigError, DataError, SimulationError

__all__ = ["NoiseFloor", "noise_floor", "inner_loop", "middle_loop", "outer_loop", "select_family",
           "SelectionReport", "LoopResult", "split_record", "INNER_FACTOR", "MIDDLE_THRESHOLD",
           "OUTER_FRACTION", "SEPARATION_EPS"]

#: the inner loop accepts a loss up to this multiple of the noise floor
INNER_FACTOR = 1.5
#: floor on the noise floor, relative to the forcing's variance (a noise-free record is at 40 dB)
REL_FLOOR = 1e-4
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


# --------------------------------------------------------------------------- noise floor
@dataclasses.dataclass
class NoiseFloor:
    """Variance of the measurement noise in the equation's units (what a perfect fit leaves).

    ``floor = g² σ_F² + σ_a² + REL_FLOOR · g² var(F)``; ``source`` says where σ_F came from.
    """

    sigma2_force: float
    sigma2_acceleration: float
    floor: float
    source: str

    def to_dict(self) -> dict[str, Any]:
        return dataclasses.asdict(self)


def _savgol_noise_variance(y: np.ndarray, window: int, order: int) -> float:
    """White-noise variance of ``y`` from the residual of a local polynomial (Savitzky-Golay) fit.

    For white noise of variance s² the residual of a linear smoother with central weight h0
    has variance s² (1 - h0) at interior points, hence the division.
    """
    from scipy.signal import savgol_coeffs, savgol_filter

    y = np.asarray(y, dtype=float)
    if y.size < 3 * window:
        raise DataError(f"a record of {y.size} samples is too short to estimate its noise floor "
                        f"(needs {3 * window}); give a longer record or the noise level (snr_db)")
    h0 = float(savgol_coeffs(window, order)[window // 2])
    resid = (y - savgol_filter(y, window, order))[window:-window]
    return float(np.mean(resid**2) / (1.0 - h0))


#: (window, polynomial order) pairs of the Savitzky-Golay noise estimate; the smallest estimate
#: is kept: every one is unbiased for white noise, and the smallest has the least signal leakage
NOISE_SETTINGS = ((7, 3), (11, 4), (15, 5))


def _noise_variance(y: np.ndarray, settings) -> float:
    return min(_savgol_noise_variance(y, w, o) for w, o in settings)


def noise_floor(record, *, gain: float = 1.0, snr_db: float | None = None,
                settings: Sequence[tuple[int, int]] = NOISE_SETTINGS,
                acceleration_given: bool | None = None) -> NoiseFloor:
    """Estimate the loss a perfect model would leave on ``record``.

    Parameters
    ----------
    record : Trajectory
        With derivatives when ``acceleration_given``.
    gain : float
        The model's input gain g (the loss is in units of x'').
    snr_db : float, optional
        Known signal-to-noise ratio of the forcing (the paper's definition, on its standard
        deviation); otherwise σ_F² is estimated from Savitzky-Golay residuals of F (the smallest
        over ``settings``, pairs of window and polynomial order), which assumes the noise white
        and F smooth over a few samples.
    acceleration_given : bool, optional
        Whether x'' was measured (its noise then adds to the floor); default: the record has it.

    Examples
    --------
    >>> from charcurves.systems import get_system
    >>> from charcurves.data import corrupt
    >>> record = corrupt(get_system("duffing").simulate(), 20, seed=0)
    >>> nf = noise_floor(record)
    >>> round(nf.sigma2_force, 5)   # the noise added has variance 0.00120
    0.00118
    """
    if getattr(record, "forces", None) is not None:
        return _multi_noise_floor(record, gain, snr_db, settings, acceleration_given)
    F = np.asarray(record.F, dtype=float)
    g2 = float(gain) ** 2
    if snr_db is not None:
        from ..data._noise import snr_to_eta

        eta2 = snr_to_eta(snr_db) ** 2
        s2f = float(np.var(F)) * eta2 / (1.0 + eta2)  # var(F) = var(clean) (1 + eta²)
        source = f"given SNR {snr_db:g} dB"
    else:
        s2f = _noise_variance(F, settings)
        source = "Savitzky-Golay residual of F (smallest of windows " + ", ".join(f"{w}/{o}" for w, o in settings) + ")"
    s2a = 0.0
    if acceleration_given is None:
        acceleration_given = record.a is not None
    if acceleration_given and record.a is not None and snr_db is None:
        s2a = _noise_variance(np.asarray(record.a), settings)
    floor = g2 * s2f + s2a + REL_FLOOR * g2 * float(np.var(F))
    return NoiseFloor(sigma2_force=s2f, sigma2_acceleration=s2a, floor=floor, source=source)


def _multi_noise_floor(record, gain, snr_db, settings, acceleration_given) -> NoiseFloor:
    """Several equations, each with its forcing column (and its state's x''): the model's loss is
    the mean squared residual over all of them, so the floor is the mean of their floors."""
    from ..data._trajectory import Trajectory

    accs = record.accelerations or {}
    states = list(record.states)
    parts = []
    for k, name in enumerate(record.forces):
        state = states[min(k, len(states) - 1)]
        a = accs.get(state)
        one = Trajectory(record.t, record.states[state], record.forces[name], None if a is None else
                         record.velocities[state], a, name=record.name)
        parts.append(noise_floor(one, gain=gain, snr_db=snr_db, settings=settings,
                                 acceleration_given=acceleration_given))
    return NoiseFloor(sigma2_force=float(np.mean([p.sigma2_force for p in parts])),
                      sigma2_acceleration=float(np.mean([p.sigma2_acceleration for p in parts])),
                      floor=float(np.mean([p.floor for p in parts])),
                      source=parts[0].source + f", mean over the {len(parts)} forcing columns")


# --------------------------------------------------------------------------- loop results
@dataclasses.dataclass
class LoopResult:
    """Outcome of one loop: passed, the statistic, its threshold and the figures behind it."""

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
    """Loss / noise floor of every fit; passes when the largest ratio is at most ``factor``."""
    ratios, losses, fl, source = [], [], [], ""
    for k, (model, rec) in enumerate(zip(models, records)):
        nf = floors[k] if floors is not None else noise_floor(rec, gain=model.gain, snr_db=snr_db)
        source = nf.source
        ratios.append(float(model.loss) / nf.floor)
        losses.append(float(model.loss))
        fl.append(nf.floor)
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


# --------------------------------------------------------------------------- the search
def split_record(record, parts: int = 2) -> list:
    """Consecutive segments of one record, used as independent trajectories (each starts from
    another state of the system)."""
    n = record.n_samples
    edges = np.linspace(0, n, parts + 1).astype(int)
    return [record.slice(slice(int(a), int(b))) for a, b in zip(edges[:-1], edges[1:])]


@dataclasses.dataclass
class SelectionReport:
    """Verdicts of :func:`select_family`, one row per family in the order tried."""

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
                  random_state: int = 0, threads: int | None = 1, progress=None,
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
    **estimator_params
        Further CharacteristicCurves settings (gauge, preset, derivatives...).

    Returns
    -------
    SelectionReport
    """
    import time

    from ..fitting import CharacteristicCurves
    from ..fitting import fit_ensembles

    trajectories = list(trajectories)
    if not trajectories:
        raise DataError("select needs at least one record")
    families = [f.strip() for f in families if f and f.strip()]
    if not families:
        raise ConfigError("no candidate family given; e.g. --families separable,position-damping")
    for family in families:  # an unknown family or method fails now, not after the first family's fits
        CharacteristicCurves(family=family, method=method, random_state=random_state, threads=threads,
                             **estimator_params).resolve()
    split = len(trajectories) == 1
    if split:
        trajectories = split_record(trajectories[0], 2)
    rows, accepted = [], None
    for family in families:
        row: dict[str, Any] = {"family": family, "verdict": "not tested", "rejected_by": None}
        if accepted is not None and not all_families:
            rows.append(row)
            continue
        t0 = time.perf_counter()
        est = CharacteristicCurves(family=family, method=method, random_state=random_state, threads=threads,
                                   **estimator_params)
        ensembles = fit_ensembles(est, trajectories, n_members, kind="bootstrap")
        row["fit_seconds"] = time.perf_counter() - t0
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
