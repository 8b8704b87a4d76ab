"""One free run of a whole record (the separable family) and the sampling step a free run needs.

Output error reports the RMSE of one free run of the whole record beside the segmented one
(:func:`charcurves.objectives.output_error_fit`), and the CLI plots it (:func:`free_run_diagnostics`).
"""

from __future__ import annotations

import numpy as np

from .._errors import DataError

__all__ = ["free_run_diagnostics"]


def _free_run_x(model, record, y0, hold, substeps):
    """One free run of the whole record from ``y0`` (separable family): (x, status)."""
    from ..data import rk4_sampled, stage_inputs

    f1, f2 = _fast_float(model.curves["f1"]), _fast_float(model.curves["f2"])
    g, b = float(model.gain), float(model.offset)

    def accel(x, v, u):
        return g * u - f1(v) - f2(x) - b

    ua, um, ub = stage_inputs(np.asarray(record.F, dtype=float), substeps, hold)
    x, _, status = rk4_sampled(accel, ua, um, ub, float(y0[0]), float(y0[1]), _uniform_step(record), substeps)
    return np.asarray(x, dtype=float), status


def _free_run_rmse(model, record, meas_cols, y0, hold, substeps):
    """RMSE of one free run of the whole record (separable family; None for other templates or
    without measured positions)."""
    if model.template.is_general or meas_cols is None:
        return None
    x, status = _free_run_x(model, record, y0, hold, substeps)
    if status != "ok":
        return float("inf")
    return float(np.sqrt(np.mean((x - meas_cols["x"]) ** 2)))


def free_run_diagnostics(model, record):
    """``(t, measured x, free-run x)`` of a model refitted by output error on ``record`` (the
    measured positions, and one free run of the whole record from the initial state output error
    estimated, with its input hold and RK4 steps); None when output error did not run, for
    templates other than the separable one, or when the record has no measured x.

    Examples
    --------
    >>> import charcurves as cc
    >>> from charcurves.fitting import free_run_diagnostics
    >>> from charcurves.systems import get_system
    >>> record = cc.corrupt(get_system("duffing").simulate(t_end=10.0, n_points=251), 30, on="state", seed=0)
    >>> model = cc.fit(record, method="parametric", basis="f1=z; f2=z, z**3", objective=cc.OutputError(segment_length=16, substeps=1, max_iter=2))
    >>> t, x, x_free = free_run_diagnostics(model, record)
    >>> t.shape == x.shape == x_free.shape, float(abs(x - x_free).max()) < 0.1
    (True, True)
    """
    from ..data import Trajectory

    oe = model.info.get("output_error") or {}
    if not str(oe.get("status", "")).startswith(("ok", "interrupted")) or model.template.is_general:
        return None
    if not isinstance(record, Trajectory) or "initial_state" not in oe:
        return None
    x, status = _free_run_x(model, record, oe["initial_state"], oe["hold"], int(oe["substeps"]))
    if status != "ok":
        x = np.where(np.isfinite(x), x, np.nan)
    return np.asarray(record.t, dtype=float), np.asarray(record.x, dtype=float), x


def _fast_float(curve, n: int = 8193):
    """A function of one float: the closed form, or (other curves) linear interpolation in a table
    over twice the training range (error about 1e-8 of the curve's curvature; far faster per call
    than a network evaluation), extrapolated linearly."""
    if curve.closed_form:
        return curve.float_function()
    lo, hi = curve.domain
    pad = 0.5 * (hi - lo) + 1e-9
    z0, z1 = lo - pad, hi + pad
    dz = (z1 - z0) / (n - 1)
    ys = np.asarray(curve(np.linspace(z0, z1, n)), dtype=float).tolist()
    last = n - 2

    def f(z):
        t = (z - z0) / dz
        i = min(max(int(t), 0), last) if t == t else 0
        return ys[i] + (t - i) * (ys[i + 1] - ys[i])

    return f


def _uniform_step(record, tol: float = 1e-3) -> float:
    """The sample step of a uniformly sampled record (ConfigError otherwise: a free run driven by a
    sampled input needs uniform steps)."""
    t = np.asarray(record.t, dtype=float)
    steps = np.diff(t)
    dt = float(np.median(steps))
    if not dt > 0 or float(np.max(np.abs(steps - dt))) > tol * dt:
        raise DataError("output error needs uniform sampling (the free run is driven by the sampled input); "
                        "resample the record onto a uniform grid or use objective='equation-error'")
    return dt
